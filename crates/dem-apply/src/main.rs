//! dem-apply: run an ONNX model (a generator exported by dem-train) over an
//! NPY stream of DEMs.

use std::io::Write;
use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;
use dem_core::{cli, output};
use dem_onnx::apply::{apply, MaskSampling};
use dem_onnx::OnnxModel;

/// Run an ONNX model over every DEM of an NPY stream, in parallel batches,
/// and write its outputs in input order.
///
/// The model takes and gives float32 (N, 21, 5, 2), N the batch axis (what
/// dem-train exports: input `dem`, output `dem_out`); any model with one such
/// input and one such output runs. Outputs are written as the model gives
/// them (a mask may be any value in [-1, 1]); a NaN or infinite output is an
/// error naming the record. Memory: batch x threads x 4 records.
#[derive(Parser)]
#[command(version, after_long_help = "Examples:
  dem-apply --model g_y.onnx sim.npy -o realistic.npy
  dem-apply --model g_y.onnx --info                 # what it was trained on, how, its val table
  dem-apply --model g_y.onnx --sample-masks --seed 1 sim.npy -o realistic.npy   # holes drawn at the model's rate
  dem-synth --out w --runs 20 --seed 3 && dem-apply --model g_y.onnx w/sim.npy | dem-render - -o fake.png
  dem-filter --labels l.csv --terrain pallet sim.npy | dem-apply --model g_y.onnx --threads 2 > pallets_real.npy
  dem-render --compare sim.npy <(dem-apply --model g_y.onnx sim.npy) real.npy --row-labels 'sim,G(sim),real' -o cmp.png")]
struct Args {
    /// Input NPY stream (`-` for stdin).
    #[arg(default_value = "-")]
    input: String,
    /// Output NPY stream (`-` for stdout).
    #[arg(short, long = "out", alias = "output", default_value = "-")]
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
    /// Seed of --sample-masks.
    #[arg(long, default_value_t = 0, requires = "sample_masks")]
    seed: u64,
    /// With --sample-masks: index of the input's first record in the whole
    /// data set, when the input is a shard (`dem-split` prints it).
    #[arg(long, default_value_t = 0, requires = "sample_masks")]
    first_index: u64,
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
            return print_info(&a.model);
        }
        output::check_outputs(&[&a.input, &a.model], &[&a.output])?;
        let mut pool = rayon::ThreadPoolBuilder::new();
        if let Some(n) = a.threads {
            pool = pool.num_threads(n as usize);
        }
        let pool = pool.build()?;
        let model = OnnxModel::load(&a.model)?;
        let start = Instant::now();
        let bar = cli::progress(dem_core::npy::estimate_records(&a.input), "records");
        let stats = pool.install(|| {
            let sample = a.sample_masks.then_some(MaskSampling { seed: a.seed, first_index: a.first_index });
            apply(&model, &a.input, &a.output, a.batch as usize, a.strict, sample, |done| {
                bar.set_length(bar.length().unwrap_or(0).max(done));
                bar.set_position(done);
            })
        })?;
        bar.finish_and_clear();
        if let Some(w) = stats.attitude.warning(&a.model, &a.input) {
            cli::log(w);
        }
        let secs = start.elapsed().as_secs_f64();
        cli::log(format_args!(
            "{} records in {secs:.2} s ({:.0} records/s), {} threads, batch {}, {}",
            stats.records,
            stats.records as f64 / secs.max(1e-9),
            pool.current_num_threads(),
            a.batch,
            model.engine_name()
        ));
        // After the run: a refused input still gets exactly one line.
        if let Some(note) = model.note() {
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
    out.flush()?;
    Ok(())
}
