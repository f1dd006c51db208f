//! dem-apply: run an ONNX model (a generator exported by dem-train) over an
//! NPY stream of DEMs; the work is in the library (`dem_apply::run`).

use std::io::Write;
use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;
use dem_apply::Config;
use dem_core::{cli, output};
use dem_onnx::OnnxModel;

/// Run an ONNX model over every DEM of an NPY stream, in parallel batches,
/// and write its outputs in input order.
///
/// The model takes and gives float32 (N, 21, 5, 2), N the batch axis (what
/// dem-train exports: input `dem`, output `dem_out`); any model with one such
/// input and one such output runs. Outputs are written as the model gives
/// them (a mask may be any value in [-1, 1]); a NaN or infinite output is an
/// error naming the record. Memory: batch x threads x 4 records.
///
/// A generator exported with `dem-train export --residual SENSOR.json`
/// carries a sensor model fitted by dem-gap on what its network leaves
/// (per-record noise, startup rows by time): it is applied after the
/// network, each record's time taken from --labels, the same bytes as
/// `dem-apply --network-only | dem-sensor apply --sensor SENSOR.json`.
#[derive(Parser)]
#[command(
    version,
    after_long_help = "Examples:
  dem-apply --model g_y.onnx sim.npy -o realistic.npy
  dem-apply --model g_y.onnx --info                 # what it was trained on, how, its val table
  dem-apply --model g_y.onnx --sample-masks --seed 1 sim.npy -o realistic.npy   # holes drawn at the model's rate
  dem-apply --model g_y.onnx --labels sim_labels.csv --seed 1 sim.npy -o realistic.npy  # with its residual model, startup by time
  dem-apply --model gy-sensor.onnx --labels l.csv --seed 1 --emit-uniform u.npy sim.npy -o out.npy   # onnxruntime fed u.npy gives out.npy
  dem-apply --model g_y.onnx --network-only sim.npy -o expected.npy    # the network alone
  dem-apply --model g_y.onnx --network-only --heights input sim.npy -o holes.npy   # its holes, the sim's heights
  dem-synth --out w --runs 20 --seed 3 && dem-apply --model g_y.onnx w/sim.npy | dem-render - -o fake.png
  dem-filter --labels l.csv --terrain pallet sim.npy | dem-apply --model g_y.onnx --threads 2 > pallets_real.npy
  dem-render --compare sim.npy <(dem-apply --model g_y.onnx sim.npy) real.npy --row-labels 'sim,G(sim),real' -o cmp.png"
)]
struct Args {
    /// Input NPY stream (`-` for stdin).
    #[arg(default_value = "-")]
    input: String,
    /// Output NPY stream (`-` for stdout).
    #[arg(short, long = "out", default_value = "-")]
    output: String,
    /// The ONNX model: float32 (N, 21, 5, 2) in and out.
    #[arg(short, long)]
    model: String,
    /// Records per model call.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    batch: u32,
    /// Refuse a model that changes row 20 (the attitude, which must pass
    /// through); without it, such a model gets a warning.
    #[arg(long)]
    strict: bool,
    /// Draw each cell's validity from the model's raw mask m (valid with
    /// probability (m + 1) / 2) instead of writing m: holes keep the rate
    /// the model predicts, as a sensor's do; masks come out +-1.
    #[arg(long)]
    sample_masks: bool,
    /// Run the network alone: leave out the residual sensor model the
    /// model carries (`dem-train export --residual`).
    #[arg(long)]
    network_only: bool,
    /// Where valid cells take their heights from: `network` (its height
    /// head) or `input` (the input's height on every cell the network keeps
    /// valid and the input has; masks come out +-1). Default: what the
    /// model was exported with (`dem-train export --heights`), else
    /// `network`. --network-only does not change it: it leaves out only the
    /// residual model.
    #[arg(long, value_parser = clap::value_parser!(dem_onnx::Heights))]
    heights: Option<dem_onnx::Heights>,
    /// Labels CSV of the input's records: their `time` in the run places
    /// the residual model's startup rows (without it, startup frames are
    /// drawn at the model's rate), and their `sequence` gives the draws a
    /// run keeps (`tilt`'s mount angle, `lag`'s shift) once per run.
    #[arg(long, value_name = "CSV")]
    labels: Option<String>,
    /// Seed of every draw: --sample-masks and the residual sensor model.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Index of the input's first record in the whole data set, when the
    /// input is a shard (`dem-split` prints it): the draws of a shard equal
    /// the whole's.
    #[arg(long, default_value_t = 0)]
    first_index: u64,
    /// Write each record's uniforms to this NPY file (float32 (N, K), K in
    /// `--info`): fed as the graph's `uniform` input (with the labels'
    /// `time`, NaN without --labels), onnxruntime or PyTorch computes the
    /// same DEMs from the model file.
    #[arg(long, value_name = "NPY")]
    emit_uniform: Option<String>,
    /// Worker threads (default: one per core).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,
    /// Print what the model says about itself (producer, opset, the engine
    /// that runs it, and dem-train's metadata: data files with record counts
    /// and SHA-256, seed, architecture, steps, validation table) on stdout,
    /// and run nothing.
    #[arg(long)]
    info: bool,
}

fn main() -> ExitCode {
    cli::run(|| {
        let a: Args = cli::parse();
        if a.info {
            output::check_outputs(&[&a.model], &["-"])?;
            return print_info(&a.model);
        }
        let inputs: Vec<&str> = [Some(&a.input), Some(&a.model), a.labels.as_ref()].into_iter().flatten().map(String::as_str).collect();
        let outputs: Vec<&str> = [Some(&a.output), a.emit_uniform.as_ref()].into_iter().flatten().map(String::as_str).collect();
        output::check_outputs(&inputs, &outputs)?;
        let mut pool = rayon::ThreadPoolBuilder::new();
        if let Some(n) = a.threads {
            pool = pool.num_threads(n as usize);
        }
        let pool = pool.build()?;
        let model = OnnxModel::load(&a.model)?;
        let start = Instant::now();
        let bar = cli::progress(dem_core::npy::estimate_records(&a.input), "records");
        let config = Config {
            model: a.model.clone(),
            input: a.input.clone(),
            output: a.output.clone(),
            batch: a.batch as usize,
            strict: a.strict,
            sample_masks: a.sample_masks,
            network_only: a.network_only,
            heights: a.heights,
            labels: a.labels.clone(),
            seed: a.seed,
            first_index: a.first_index,
            emit_uniform: a.emit_uniform.clone(),
        };
        let report = pool.install(|| {
            dem_apply::run(&config, &model, |done| {
                bar.set_length(bar.length().unwrap_or(0).max(done));
                bar.set_position(done);
            })
        })?;
        bar.finish_and_clear();
        let stats = report.stats;
        if let Some(w) = stats.attitude.warning(&a.model, &a.input) {
            cli::log(w);
        }
        let secs = start.elapsed().as_secs_f64();
        cli::log(format_args!(
            "{} records in {secs:.2} s ({:.0} records/s), {} threads, batch {}, {}{}{}",
            stats.records,
            stats.records as f64 / secs.max(1e-9),
            pool.current_num_threads(),
            a.batch,
            model.engine_name(),
            if report.heights == dem_onnx::Heights::Input { ", the input's heights under its holes" } else { "" },
            report.residual.map_or(String::new(), |r| format!(", then its residual sensor model: {r}"))
        ));
        // After the run: a refused input still gets exactly one line.
        for note in model.note().map(str::to_string).into_iter().chain(report.notes) {
            cli::log(note);
        }
        Ok(())
    })
}

/// `--info`: what the model says about itself, on stdout.
fn print_info(path: &str) -> anyhow::Result<()> {
    let info = dem_onnx::read_info(path)?;
    let engine = OnnxModel::load(path)?.engine_name();
    let mut out = std::io::stdout().lock();
    for l in info.lines(path, &engine) {
        writeln!(out, "{l}")?;
    }
    writeln!(out, "{}", dem_apply::runtime_line(path, &info)?)?;
    out.flush()?;
    Ok(())
}
