//! dem-pair: pair sim keys with real records, by pose or by content.

use std::collections::BTreeSet;
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};
use dem_core::cli::{self, value};
use dem_core::output;
use dem_core::table::{self, Pair};
use dem_pair::pairing::{pair, Method, PairConfig};
use dem_pair::{counts, PoseRule};

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum MethodArg {
    /// Same terrain and pose (from the labels CSVs) within tolerances.
    Pose,
    /// The k nearest sim DEMs by the height error over the real record's valid cells.
    Content,
}

/// Build the pairs CSV of sim keys to real records (the thesis's paired data):
/// one sim key to one or many real records, deduplicated (identical sim
/// records are one key: the first), split into train and val by key.
///
/// Writes `sim_index,real_index,split,distance`; counts per split (and per
/// terrain, with labels) go to stderr.
#[derive(Parser)]
#[command(
    version,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true,
    after_long_help = "Examples:
  dem-pair --match pose --sim-labels sim_labels.csv --real-labels real_labels.csv --same-sequence -o pairs.csv
  dem-pair --match content --sim sim.npy --real real.npy --k 3 --val-fraction 0.5 --seed 1 -o pairs.csv
  dem-filter --labels l.csv --drop-other sim.npy -o s.npy && dem-pair --match content --sim s.npy --real real.npy
  dem-pair expand --pairs pairs.csv --sim sim.npy --real real.npy --split val --out val/   # one record per pair"
)]
struct Args {
    #[command(subcommand)]
    cmd: Option<Cmd>,
    /// How to pair.
    #[arg(long = "match", value_name = "METHOD", value_enum, required = true)]
    by: Option<MethodArg>,
    /// Sim NPY (needed by content; used to deduplicate keys by pose too).
    #[arg(long)]
    sim: Option<String>,
    /// Real NPY (needed by content).
    #[arg(long)]
    real: Option<String>,
    /// Labels CSV of the sim records (needed by pose).
    #[arg(long, value_name = "CSV")]
    sim_labels: Option<String>,
    /// Labels CSV of the real records (needed by pose).
    #[arg(long, value_name = "CSV")]
    real_labels: Option<String>,
    /// Pose: largest position distance (m).
    #[arg(long = "max-offset", value_name = "METRES", default_value_t = 0.05, value_parser = value::non_negative::<f64>)]
    max_dist: f64,
    /// Pose: largest heading difference (rad).
    #[arg(long, default_value_t = 0.1, value_parser = value::non_negative::<f64>)]
    max_yaw: f64,
    /// Pose: pair only within the same sequence (run).
    #[arg(long)]
    same_sequence: bool,
    /// Content: sim keys per real record.
    #[arg(long, default_value_t = 1, value_parser = value::at_least_one::<usize>)]
    k: usize,
    /// Content: largest distance (the pair error's height part; default: no limit).
    #[arg(long = "max-error", value_name = "ERROR", value_parser = value::non_negative::<f64>)]
    max_distance: Option<f64>,
    /// Fraction of sim keys in the val split.
    #[arg(long, default_value_t = 0.5, value_parser = value::fraction::<f64>)]
    val_fraction: f64,
    /// Seed of the split.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output pairs CSV (`-` for stdout).
    #[arg(short, long = "out", default_value = "-")]
    output: String,
    /// Do not warn when --sim misses clearly more cells than --real (the
    /// sign of swapped inputs: measured DEMs have holes, sim DEMs few).
    #[arg(long)]
    no_swap_check: bool,
}

#[derive(Subcommand)]
enum Cmd {
    /// One record per pair: the sim record and the real record of pair i
    /// become record i of OUT/sim.npy and OUT/real.npy, with OUT/pairs.csv
    /// pairing them 1:1 (split and distance kept). With labels, each pair's
    /// sim labels row has the sim's terrain and the real partner's pose,
    /// sequence and time: a deduplicated sim key keeps its first pose's time,
    /// which a time-based effect (`startup`) must not read for every
    /// partner. Then dem-gap fits, and dem-sensor or dem-apply draws, once
    /// per pair at the pair's time; dem-eval's gap over the expanded pairs
    /// is the gap over the original pairs.
    #[command(after_long_help = "Examples:
  dem-pair expand --pairs pairs.csv --sim sim.npy --real real.npy --sim-labels sim_labels.csv \\
      --real-labels real_labels.csv --split val --out val/
  dem-apply --model gy.onnx --labels val/sim_labels.csv --seed 1 val/sim.npy -o val/gy.npy   # a draw per pair
  dem-eval --sim val/sim.npy --real val/real.npy --pairs val/pairs.csv --pred val/gy.npy")]
    Expand {
        /// Pairs CSV (sim_index,real_index[,split][,distance]).
        #[arg(long)]
        pairs: String,
        /// Sim NPY the pairs index.
        #[arg(long)]
        sim: String,
        /// Real NPY the pairs index.
        #[arg(long)]
        real: String,
        /// Labels CSV of the sim records.
        #[arg(long, value_name = "CSV")]
        sim_labels: Option<String>,
        /// Labels CSV of the real records (the pairs' pose and time).
        #[arg(long, value_name = "CSV")]
        real_labels: Option<String>,
        /// Only the pairs of this split [default: every pair].
        #[arg(long, value_enum)]
        split: Option<table::Split>,
        /// Output folder (sim.npy, real.npy, pairs.csv, and with labels sim_labels.csv, real_labels.csv).
        #[arg(short, long)]
        out: String,
        /// Do not warn when --sim misses clearly more cells than --real (the
        /// sign of swapped inputs: measured DEMs have holes, sim DEMs few).
        #[arg(long)]
        no_swap_check: bool,
    },
}

fn expand(cfg: dem_pair::expand::ExpandConfig) -> anyhow::Result<()> {
    let inputs: Vec<&str> = [Some(&cfg.pairs), Some(&cfg.sim), Some(&cfg.real), cfg.sim_labels.as_ref(), cfg.real_labels.as_ref()]
        .into_iter()
        .flatten()
        .map(String::as_str)
        .collect();
    cli::one_stdin(inputs.iter().copied())?;
    // The folder first: the output check tries a file in it.
    let folder = output::OutputFolder::create(&cfg.out)?;
    folder.check(&inputs, &["sim.npy", "real.npy", "pairs.csv", "sim_labels.csv", "real_labels.csv"])?;
    let done = dem_pair::expand::run(&cfg)?;
    folder.keep();
    cli::log(format_args!("{} pairs of {} sim keys expanded into {}", done.pairs, done.sim_keys, cfg.out));
    if !done.stale_removed.is_empty() {
        cli::log(format_args!("removed {}: an earlier expansion's labels, which these records do not have", done.stale_removed.join(", ")));
    }
    Ok(())
}

fn main() -> ExitCode {
    cli::run(|| {
        let a: Args = cli::parse();
        if let Some(Cmd::Expand { pairs, sim, real, sim_labels, real_labels, split, out, no_swap_check }) = a.cmd {
            dem_core::swap::check_files(&sim, &real, no_swap_check);
            return expand(dem_pair::expand::ExpandConfig { pairs, sim, real, sim_labels, real_labels, split, out });
        }
        let inputs: Vec<&str> = [&a.sim, &a.real, &a.sim_labels, &a.real_labels].into_iter().flatten().map(String::as_str).collect();
        output::check_outputs(&inputs, &[&a.output])?;
        let cfg = PairConfig {
            by: match a.by.expect("clap requires --match without a subcommand") {
                MethodArg::Pose => Method::Pose,
                MethodArg::Content => Method::Content,
            },
            sim: a.sim,
            real: a.real,
            sim_labels: a.sim_labels,
            real_labels: a.real_labels,
            rule: PoseRule { max_dist: a.max_dist, max_yaw: a.max_yaw, same_sequence: a.same_sequence },
            k: a.k,
            max_distance: a.max_distance.unwrap_or(f64::INFINITY),
            val_fraction: a.val_fraction,
            seed: a.seed,
            no_swap_check: a.no_swap_check,
        };
        let paired = pair(&cfg)?;
        table::write_rows(&a.output, &paired.rows)?;
        report(&paired.rows, paired.sim_labels.as_deref());
        Ok(())
    })
}

fn report(rows: &[Pair], labels: Option<&[table::Label]>) {
    for ((terrain, split), (keys, n)) in counts(rows, labels) {
        cli::log(format_args!("{terrain:>11} {split:>5}: {keys} sim keys, {n} pairs"));
    }
    let reals: BTreeSet<u64> = rows.iter().map(|p| p.real_index).collect();
    cli::log(format_args!("{} pairs of {} real records", rows.len(), reals.len()));
}
