//! dem-eval: the validation table of a generator (pair error, equation 7.1)
//! and `dem-eval compare`, the regression check of such tables.

mod inputs;
mod model;
mod report;

use std::path::Path;
use std::process::ExitCode;

use clap::{Args as ClapArgs, Parser, Subcommand, ValueEnum};
use dem_core::eval::{self, Status};
use dem_core::table::{self, Split};
use dem_core::{cli, npy};
use inputs::{Method, Request};
use report::Format;

/// Score predictions of real DEMs for the sim records of a pairs CSV: each
/// sim record's pair error is the smallest equation 7.1 error of its
/// prediction against the real records paired with it (raw predicted mask,
/// no threshold). Prints the table: count, lowest, highest, mean and median.
///
/// The prediction is the sim record itself (--identity), record i of a file
/// made by another tool (--pred), or an ONNX generator run on the selected
/// sim records (--model). `dem-eval compare` checks a table against a baseline.
#[derive(Parser)]
#[command(version, args_conflicts_with_subcommands = true, after_long_help = "Examples:
  dem-eval --sim sim.npy --real real.npy --pairs pairs.csv --split val --identity
  dem-eval --sim sim.npy --real real.npy --pairs pairs.csv --split val --model g.onnx \\
      --labels-sim sim_labels.csv --by terrain --records per_record.csv --format md
  dem-apply g.onnx sim.npy -o gen.npy && dem-eval --sim sim.npy --real real.npy --pairs pairs.csv --pred gen.npy
  dem-eval ... --identity --records r.csv --emit-input in.npy --emit-closest real.npy && \\
      dem-render --compare in.npy real.npy --row-labels input,closest --error-rows 2,1 -o fig.png
  cat identity.csv model.csv > table.csv      # CSV tables join with cat
  dem-eval compare testdata/eval_baseline.csv table.csv --tolerance 0.02 || echo regression")]
struct Args {
    #[command(subcommand)]
    cmd: Option<Cmd>,
    #[command(flatten)]
    eval: EvalArgs,
}

#[derive(ClapArgs)]
struct EvalArgs {
    /// Sim NPY: the generator's inputs.
    #[arg(long)]
    sim: Option<String>,
    /// Real (measured) NPY.
    #[arg(long)]
    real: Option<String>,
    /// Pairs CSV (sim_index,real_index[,split]): the sim records scored and their real partners.
    #[arg(long)]
    pairs: Option<String>,
    /// Only the pairs of this split [default: every pair].
    #[arg(long, value_enum)]
    split: Option<SplitArg>,
    /// The prediction is the sim record as is (the thesis's Identity row).
    #[arg(long, group = "method")]
    identity: bool,
    /// NPY of predictions, record i for sim record i (as many records as --sim).
    #[arg(long, group = "method")]
    pred: Option<String>,
    /// ONNX generator (input `dem`, output `dem_out`, (N, 21, 5, 2)) run on the selected sim records.
    #[arg(long, group = "method")]
    model: Option<String>,
    /// Name of the table row [default: identity, or the --pred / --model file stem].
    #[arg(long)]
    name: Option<String>,
    /// Labels CSV of the sim file: terrain of each record (--records, --by terrain).
    #[arg(long)]
    labels_sim: Option<String>,
    /// Split the table: one row over all records, then one per terrain.
    #[arg(long, value_enum)]
    by: Option<By>,
    /// Table format; csv or json is what `compare` reads.
    #[arg(long, value_enum, default_value = "text")]
    format: Format,
    /// Table output (`-` for stdout).
    #[arg(short, long, default_value = "-")]
    output: String,
    /// Write per-record results here: sim_index,real_index (the best pair),error,terrain.
    #[arg(long, value_name = "FILE")]
    records: Option<String>,
    /// Write the sim record of each --records row to this NPY (for dem-render --compare).
    #[arg(long, value_name = "FILE")]
    emit_input: Option<String>,
    /// Write the prediction of each --records row to this NPY.
    #[arg(long, value_name = "FILE")]
    emit_pred: Option<String>,
    /// Write the closest real record of each --records row to this NPY.
    #[arg(long, value_name = "FILE")]
    emit_closest: Option<String>,
    /// Records per model call with --model.
    #[arg(long, default_value_t = 512)]
    batch: usize,
}

#[derive(Clone, Copy, ValueEnum)]
enum SplitArg {
    Train,
    Val,
}

#[derive(Clone, Copy, ValueEnum)]
enum By {
    Terrain,
}

#[derive(Subcommand)]
enum Cmd {
    /// Compare a table against a baseline; exit 1 when a row got worse.
    ///
    /// Rows match by (method, terrain). A row is worse when CURRENT's mean or
    /// median pair error exceeds BASELINE's by more than --tolerance, an
    /// absolute difference in equation 7.1 units; a baseline row missing
    /// from CURRENT fails too. Prints both tables side by side with the
    /// differences (current minus baseline). Exit 0: no row worse; 1: some
    /// row worse or missing; 2: a file is not a table (CSV or JSON of dem-eval).
    #[command(after_long_help = "Examples:
  dem-eval compare testdata/eval_baseline.csv out/eval/table.csv
  dem-eval compare base.json current.json --tolerance 0.05 --format md >> $GITHUB_STEP_SUMMARY")]
    Compare {
        /// Baseline table (CSV or JSON written by dem-eval).
        baseline: String,
        /// Current table (CSV or JSON written by dem-eval).
        current: String,
        /// Largest allowed growth of the mean and of the median (absolute).
        #[arg(long, default_value_t = 0.02)]
        tolerance: f64,
        /// Output format.
        #[arg(long, value_enum, default_value = "text")]
        format: Format,
    },
}

fn stem(path: &str) -> String {
    Path::new(path).file_stem().map_or_else(|| "pred".into(), |s| s.to_string_lossy().into_owned())
}

fn evaluate(a: EvalArgs) -> anyhow::Result<()> {
    let (method, name) = match (a.identity, a.pred, a.model) {
        (true, _, _) => (Method::Identity, "identity".to_string()),
        (_, Some(p), _) => (Method::Pred(p.clone()), if p == "-" { "pred".into() } else { stem(&p) }),
        (_, _, Some(m)) => (Method::Model(m.clone()), stem(&m)),
        _ => return Err(cli::usage("choose what to evaluate: --identity, --pred FILE or --model FILE")),
    };
    let need = |v: Option<String>, flag: &str| v.ok_or_else(|| cli::usage(format!("{flag} is required")));
    if a.by.is_some() && a.labels_sim.is_none() {
        return Err(cli::usage("--by terrain needs --labels-sim"));
    }
    if a.batch == 0 {
        return Err(cli::usage("--batch must be at least 1"));
    }
    let q = Request {
        sim: need(a.sim, "--sim")?,
        real: need(a.real, "--real")?,
        pairs: need(a.pairs, "--pairs")?,
        split: a.split.map(|s| match s {
            SplitArg::Train => Split::Train,
            SplitArg::Val => Split::Val,
        }),
        labels_sim: a.labels_sim,
        method,
        batch: a.batch,
        keep: a.emit_input.is_some() || a.emit_pred.is_some() || a.emit_closest.is_some(),
    };
    let ev = inputs::run(&q)?;
    let rows = eval::table(a.name.as_deref().unwrap_or(&name), &ev.results, a.by.is_some());
    if let Some(path) = &a.records {
        table::write_rows(path, &ev.results)?;
    }
    for (path, records) in [(&a.emit_input, &ev.input), (&a.emit_pred, &ev.pred), (&a.emit_closest, &ev.closest)] {
        if let Some(path) = path {
            npy::write_all(path, records)?;
        }
    }
    report::write_table(&a.output, &rows, a.format)
}

fn read_table(path: &str) -> anyhow::Result<Vec<eval::TableRow>> {
    let text = if path == "-" { None } else { std::fs::read(path).ok() };
    if text.as_deref().is_some_and(|t| t.trim_ascii_start().starts_with(b"[")) {
        // Back-to-back JSON arrays, as `cat a.json b.json` makes them.
        let text = text.unwrap_or_default();
        let mut rows = Vec::new();
        for v in serde_json::Deserializer::from_slice(&text).into_iter::<Vec<eval::TableRow>>() {
            rows.extend(v.map_err(|e| dem_core::DemError::Table { path: path.into(), line: e.line() as u64, reason: e.to_string() })?);
        }
        return Ok(eval::check_table(path, rows)?);
    }
    Ok(eval::read_table_csv(path)?)
}

fn compare(baseline: &str, current: &str, tolerance: f64, format: Format) -> anyhow::Result<()> {
    if tolerance.is_nan() || tolerance < 0.0 {
        return Err(cli::usage("--tolerance must be a number >= 0"));
    }
    let (b, c) = (read_table(baseline)?, read_table(current)?);
    let rows = eval::compare(&b, &c, tolerance);
    report::write_comparison("-", &rows, format)?;
    for r in rows.iter().filter(|r| r.status == Status::Ok) {
        if let (Some(b), Some(c)) = (&r.baseline, &r.current) {
            if b.count != c.count {
                cli::log(format_args!("warning: {}/{}: {} records in the baseline, {} now", r.method, r.terrain, b.count, c.count));
            }
        }
    }
    let failed: Vec<String> =
        rows.iter().filter(|r| r.fails()).map(|r| format!("{}/{} {}", r.method, r.terrain, if r.status == Status::Worse { "worse" } else { "missing" })).collect();
    if !failed.is_empty() {
        anyhow::bail!("{} of {} baseline rows failed (mean or median worse by more than {tolerance}, or missing): {}", failed.len(), b.len(), failed.join(", "));
    }
    cli::log(format_args!("{} baseline rows within tolerance {tolerance}", b.len()));
    Ok(())
}

fn main() -> ExitCode {
    cli::run(|| {
        let a = Args::parse();
        match a.cmd {
            Some(Cmd::Compare { baseline, current, tolerance, format }) => compare(&baseline, &current, tolerance, format),
            None => evaluate(a.eval),
        }
    })
}
