//! The evaluation: arguments to a checked [`Request`], then the table, the
//! per-record results and the records behind them.

use std::path::Path;

use clap::{Args as ClapArgs, ValueEnum};
use dem_core::cli;
use dem_core::table::Split;

use crate::engine::{self, Method, Request};
use crate::table::forms::{self as report, Format};

/// The arguments of an evaluation (dem-eval without a subcommand).
#[derive(ClapArgs)]
pub struct EvalArgs {
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
    split: Option<Split>,
    /// The prediction is the sim record as is (the thesis's Identity row).
    #[arg(long, group = "method")]
    identity: bool,
    /// NPY of predictions, record i for sim record i (as many records as --sim).
    #[arg(long, group = "method")]
    pred: Option<String>,
    /// ONNX generator (one float32 input and output, (N, 21, 5, 2)) run on the selected sim records.
    #[arg(short, long, group = "method")]
    model: Option<String>,
    /// Name of the table row [default: identity, or the --pred / --model file stem].
    #[arg(long)]
    name: Option<String>,
    /// Labels CSV of the sim file: terrain of each record (--emit-records,
    /// --by terrain); with runs, times and poses, the frame columns.
    #[arg(long = "sim-labels", value_name = "CSV")]
    labels_sim: Option<String>,
    /// Labels CSV of the real file: its runs, times and poses give the
    /// real_frame_* columns (the real records of the scored pairs).
    #[arg(long = "real-labels", value_name = "CSV")]
    labels_real: Option<String>,
    #[command(flatten)]
    table: TableOut,
    /// Write per-record results here: sim_index,real_index (the best pair),error,terrain,height_cm.
    #[arg(long = "emit-records", value_name = "FILE")]
    records: Option<String>,
    /// Write the sim record of each evaluated record (the --emit-records rows, in order) to this NPY.
    #[arg(long, value_name = "FILE")]
    emit_input: Option<String>,
    /// Write the prediction of each evaluated record to this NPY.
    #[arg(long, value_name = "FILE")]
    emit_pred: Option<String>,
    /// Write the closest real record of each evaluated record to this NPY.
    #[arg(long, value_name = "FILE")]
    emit_closest: Option<String>,
    /// With --model: refuse a model that changes row 20 (the attitude,
    /// which must pass through); without it, such a model gets a warning.
    #[arg(long, requires = "model")]
    strict: bool,
    /// With --model: score the network alone, without the residual sensor
    /// model the generator carries (`dem-train export --residual`); a
    /// generator exported with `--heights input` keeps the sim's heights
    /// under its holes either way, as dem-apply does.
    #[arg(long, requires = "model")]
    network_only: bool,
    /// With --model: seed of the residual sensor model's draws (as
    /// dem-apply's --seed; the records' times come from --sim-labels).
    #[arg(long, default_value_t = 0, requires = "model")]
    seed: u64,
    /// Index of the sim file's first record in the whole data set, when it
    /// is a shard (`dem-split` prints it): the pairs keep the whole set's
    /// indices and only this shard's sims are scored; `dem-eval merge` joins
    /// the shards' --emit-records (and --emit-pred) into the whole table.
    #[arg(long)]
    first_index: Option<u64>,
    /// Do not warn when --sim misses clearly more cells than --real (the
    /// sign of swapped inputs: measured DEMs have holes, sim DEMs few).
    #[arg(long)]
    no_swap_check: bool,
    /// Records per model call with --model.
    #[arg(long, default_value_t = 512, value_parser = cli::value::at_least_one::<usize>)]
    batch: usize,
}

/// How the table is split and written (an evaluation's and a merge's).
#[derive(ClapArgs)]
pub(crate) struct TableOut {
    /// Split the table: one row over all records, then one per terrain
    /// (the terrain comes from --sim-labels).
    #[arg(long, value_enum)]
    pub(crate) by: Option<By>,
    /// Table format; csv or json is what `compare` reads.
    #[arg(long, value_enum, default_value = "text")]
    pub(crate) format: Format,
    /// Table output (`-` for stdout).
    #[arg(short, long = "out", default_value = "-")]
    pub(crate) output: String,
}

impl TableOut {
    /// Write `ev`'s table of `method`.
    pub(crate) fn write(&self, ev: &crate::engine::Evaluation, method: &str) -> anyhow::Result<()> {
        Ok(report::write_table(&self.output, &ev.table(method, self.by.is_some()), self.format)?)
    }
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum By {
    Terrain,
}

fn stem(path: &str) -> String {
    Path::new(path).file_stem().map_or_else(|| "pred".into(), |s| s.to_string_lossy().into_owned())
}

/// Evaluate as `a` asks and write the outputs.
pub fn run(a: EvalArgs) -> anyhow::Result<()> {
    let (method, name) = match (a.identity, a.pred, a.model) {
        (true, _, _) => (Method::Identity, "identity".to_string()),
        (_, Some(p), _) => (Method::Pred(p.clone()), if p == "-" { "pred".into() } else { stem(&p) }),
        (_, _, Some(m)) => (Method::Model(m.clone()), stem(&m)),
        _ => return Err(cli::usage("choose what to evaluate: --identity, --pred FILE or --model FILE")),
    };
    let need = |v: Option<String>, flag: &str| v.ok_or_else(|| cli::usage(format!("{flag} is required")));
    if a.table.by.is_some() && a.labels_sim.is_none() {
        return Err(cli::usage("--by terrain needs --sim-labels"));
    }
    let to_stdout = [Some(&a.table.output), a.records.as_ref(), a.emit_input.as_ref(), a.emit_pred.as_ref(), a.emit_closest.as_ref()];
    if to_stdout.iter().filter(|p| p.is_some_and(|p| p == "-")).count() > 1 {
        return Err(cli::usage("only one output can be `-` (stdout); give the table a file with -o"));
    }
    let method_file = match &method {
        Method::Pred(p) | Method::Model(p) => Some(p),
        Method::Identity => None,
    };
    let inputs: Vec<&str> = [a.sim.as_ref(), a.real.as_ref(), a.pairs.as_ref(), a.labels_sim.as_ref(), a.labels_real.as_ref(), method_file]
        .into_iter()
        .flatten()
        .map(String::as_str)
        .collect();
    let outputs: Vec<&str> = to_stdout.into_iter().flatten().map(String::as_str).collect();
    dem_core::output::check_outputs(&inputs, &outputs)?;
    if let (Some(sim), Some(real)) = (&a.sim, &a.real) {
        dem_core::swap::check_files(sim, real, a.no_swap_check);
    }
    let q = Request {
        sim: need(a.sim, "--sim")?,
        real: need(a.real, "--real")?,
        pairs: need(a.pairs, "--pairs")?,
        split: a.split,
        labels_sim: a.labels_sim,
        labels_real: a.labels_real,
        method,
        records: a.records,
        by_terrain: a.table.by.is_some(),
        batch: a.batch,
        strict: a.strict,
        network_only: a.network_only,
        seed: a.seed,
        emit_input: a.emit_input,
        emit_pred: a.emit_pred,
        emit_closest: a.emit_closest,
        first_index: a.first_index,
    };
    let ev = engine::run(&q)?;
    a.table.write(&ev, a.name.as_deref().unwrap_or(&name))
}
