//! dem-eval: the validation table of a generator (pair error, equation 7.1)
//! and `dem-eval compare`, the regression check of such tables.

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use dem_core::cli;
use dem_eval::table::forms::Format;
use dem_eval::{compare, evaluate, join, merge, table, transfer};

/// Score predictions of real DEMs for the sim records of a pairs CSV: each
/// sim record's pair error is the smallest DEM error (docs/format.md) of its
/// prediction against the real records paired with it (raw predicted mask,
/// no threshold). Prints the table: count, lowest, highest, mean and median,
/// and the measures that see heights: height_cm (mean abs height error
/// against the closest real record, cells valid in both), the roughness
/// across and along of the predictions and of the closest real records
/// (mean abs difference of neighbouring valid cells, cm), and gap (dem-gap's
/// distribution gap of the predictions against their real partners, over
/// the evaluated pairs: a sim with k partners counts k times).
///
/// The prediction is the sim record itself (--identity), record i of a file
/// made by another tool (--pred), or an ONNX generator run on the selected
/// sim records (--model). `dem-eval compare` checks a table against a baseline.
#[derive(Parser)]
#[command(
    version,
    args_conflicts_with_subcommands = true,
    after_long_help = "Examples:
  dem-eval --sim sim.npy --real real.npy --pairs pairs.csv --split val --identity
  dem-eval --sim sim.npy --real real.npy --pairs pairs.csv --split val --model g.onnx \\
      --sim-labels sim_labels.csv --by terrain --emit-records per_record.csv --format md
  dem-apply --model g.onnx sim.npy -o gen.npy && dem-eval --sim sim.npy --real real.npy --pairs pairs.csv --pred gen.npy
  dem-eval --sim sim.npy --real real.npy --pairs pairs.csv --identity --emit-records r.csv \\
      --emit-input in.npy --emit-closest closest.npy && \\
      dem-render --compare in.npy closest.npy --row-labels input,closest --error-rows 2,1 -o fig.png
  dem-eval join identity.csv model.csv -o table.csv    # one table, one header
  dem-eval compare testdata/eval_baseline.csv table.csv --tolerance 0.02 --height-tolerance 0.5 || echo regression"
)]
struct Args {
    #[command(subcommand)]
    cmd: Option<Cmd>,
    #[command(flatten)]
    eval: evaluate::EvalArgs,
    /// Worker threads (default: all cores).
    #[arg(long, global = true, value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,
}

#[derive(Subcommand)]
enum Cmd {
    /// The downstream test: train small policy-like models (flipper angles
    /// by ridge regression, terrain by a linear classifier) on each training
    /// set, test all on measured DEMs of held-out runs; report each error and
    /// the share of the sim -> measured drop each set between the first
    /// (sim) and the last (measured, other runs) closes.
    #[command(after_long_help = "Examples:
  dem-eval transfer --test real_test.npy --test-labels real_test_labels.csv \\
      --train sim sim.npy sim_labels.csv --train gy gy_sim.npy sim_labels.csv \\
      --train measured real_train.npy real_train_labels.csv --by-terrain
  dem-apply --model gy.onnx sim.npy -o gy_sim.npy     # G_Y(sim) has sim's labels
  scripts/transfer.sh                                  # the whole test on testdata/")]
    Transfer(transfer::TransferArgs),
    /// The table of the whole from shards: each shard evaluated with
    /// `--first-index N --emit-records FILE --emit-pred FILE` (the pairs and real
    /// file of the whole), then the records files merged in shard order, and
    /// the predictions joined for the gap. The table equals one run's on
    /// the whole, bit for bit.
    #[command(after_long_help = "Examples:
  dem-split --shards 4 --labels sim_labels.csv --out part sim.npy > shards.csv
  parallel --will-cite --colsep , --header : dem-eval --sim {shard} --sim-labels {labels} \\
      --first-index {first_index} --real real.npy --pairs pairs.csv --split val --model gy.onnx \\
      --emit-records {shard}.rec.csv --emit-pred {shard}.pred.npy -o /dev/null :::: shards.csv
  dem-cat part-*.npy.pred.npy | dem-eval merge part-*.npy.rec.csv --name gy --by terrain \\
      --emitted-pred - --real real.npy --pairs pairs.csv --split val --format csv \\
      --sim-labels sim_labels.csv --sim sim.npy")]
    Merge(merge::MergeArgs),
    /// Join tables (CSV or JSON written by dem-eval) into one: the rows in
    /// order under one header, in any --format. A (method, terrain) row may
    /// appear once.
    #[command(after_long_help = "Examples:
  dem-eval join identity.csv model.csv -o table.csv
  dem-eval join table.csv --format md > table.md
  dem-eval join a.json b.csv --format json
  dem-eval join table.csv --terrain all --format md                 # the rows over all records
  dem-eval join table.csv --pivot mean,median --format md           # methods by terrain")]
    Join(join::JoinArgs),
    /// Compare a table against a baseline; exit 1 when a row got worse.
    ///
    /// Rows match by (method, terrain). A row is worse when CURRENT's mean or
    /// median pair error exceeds BASELINE's by more than --tolerance, an
    /// absolute difference in pair error units; when height_cm grows by
    /// more than --height-tolerance (cm); when the roughness's distance from
    /// the real one, |rough - real_rough| across or along, grows by more than
    /// --rough-tolerance (cm); when gap grows by more than --gap-tolerance;
    /// or when the predictions' frame-to-frame change moves away from the
    /// real records', |frame_dh_mm - real_frame_dh_mm| by more than
    /// --frame-dh-tolerance (mm) or |frame - real_frame| of the correlation,
    /// the flip share or the persistence by more than --frame-tolerance. A measure the baseline lacks (an older table) is not
    /// checked; one CURRENT lacks (no valid cells left) fails. A baseline row
    /// missing from CURRENT fails too. Prints both tables side by side with
    /// the differences (current minus baseline) and the measures that
    /// failed. Exit 0: no row worse; 1: some row worse or missing (stderr
    /// names the rows and measures); 2: a file is not a table (CSV or JSON
    /// of dem-eval).
    #[command(after_long_help = "Examples:
  dem-eval compare testdata/eval_baseline.csv out/eval_ci/table.csv
  dem-eval compare base.json current.json --tolerance 0.05 --format md >> $GITHUB_STEP_SUMMARY
  dem-eval compare base.csv current.csv --height-tolerance 0.2 --rough-tolerance 0.2 --gap-tolerance 1
  dem-eval compare old_7_column_table.csv current.csv   # only mean and median are checked")]
    Compare {
        /// Baseline table (CSV or JSON written by dem-eval).
        baseline: String,
        /// Current table (CSV or JSON written by dem-eval).
        current: String,
        /// Largest allowed growth of the mean and of the median pair error (absolute).
        #[arg(long, default_value_t = 0.02, value_parser = cli::value::non_negative::<f64>)]
        tolerance: f64,
        /// Largest allowed growth of height_cm (cm).
        #[arg(long, default_value_t = 0.5, value_parser = cli::value::non_negative::<f64>)]
        height_tolerance: f64,
        /// Largest allowed growth of |rough - real_rough|, across or along (cm).
        #[arg(long, default_value_t = 0.5, value_parser = cli::value::non_negative::<f64>)]
        rough_tolerance: f64,
        /// Largest allowed growth of the gap.
        #[arg(long, default_value_t = table::DEFAULT_GAP_TOLERANCE, value_parser = cli::value::non_negative::<f64>)]
        gap_tolerance: f64,
        /// Largest allowed growth of |frame_dh_mm - real_frame_dh_mm| (mm).
        #[arg(long, default_value_t = 1.0, value_parser = cli::value::non_negative::<f64>)]
        frame_dh_tolerance: f64,
        /// Largest allowed growth of |frame - real_frame| of frame_rcorr, frame_flip and frame_persist.
        #[arg(long, default_value_t = 0.05, value_parser = cli::value::non_negative::<f64>)]
        frame_tolerance: f64,
        /// Output format.
        #[arg(long, value_enum, default_value = "text")]
        format: Format,
    },
}

fn main() -> ExitCode {
    cli::run(|| {
        let a: Args = cli::parse();
        if let Some(n) = a.threads {
            rayon::ThreadPoolBuilder::new().num_threads(n as usize).build_global()?;
        }
        match a.cmd {
            Some(Cmd::Compare {
                baseline,
                current,
                tolerance,
                height_tolerance,
                rough_tolerance,
                gap_tolerance,
                frame_dh_tolerance,
                frame_tolerance,
                format,
            }) => {
                dem_core::output::check_outputs(&[&baseline, &current], &["-"])?;
                // Infinite errors are refused as join refuses them (stdin is read once, by compare).
                for t in [&baseline, &current].into_iter().filter(|t| *t != "-") {
                    join::check_finite(t, &table::forms::read_table(t)?)?;
                }
                let tol = table::Tolerances {
                    pair: tolerance,
                    height_cm: height_tolerance,
                    rough_cm: rough_tolerance,
                    gap: gap_tolerance,
                    frame_dh_mm: frame_dh_tolerance,
                    frame: frame_tolerance,
                };
                compare::run(&baseline, &current, &tol, format)
            }
            Some(Cmd::Transfer(t)) => transfer::run(t),
            Some(Cmd::Merge(m)) => merge::run(m),
            Some(Cmd::Join(j)) => join::run(j),
            None => evaluate::run(a.eval),
        }
    })
}
