//! dem-train: train G_Y (sim -> real) as a Cycle GAN with paired data, and
//! export a trained generator to ONNX.

use std::process::ExitCode;
use std::time::Duration;

use clap::{Args, Parser, Subcommand};
use dem_core::cli::{self, value};
use dem_nn::weights::Arch;
use dem_train::{RunOptions, Settings, TrainConfig};

/// Train the virtual sensor network of docs/network.md: G_Y turns sim DEMs
/// into the DEMs a real sensor + elevation mapping gives, learned from many
/// sims, few reals and (optionally) pairs of the same pose.
///
/// Writes RUN/losses.csv (per step), RUN/val.csv (pair error of the val
/// split per epoch), RUN/checkpoint.bin (each epoch, atomically). The same
/// seed and thread count give the same model; --resume continues a run
/// exactly where its last checkpoint left it.
#[derive(Parser)]
#[command(
    version,
    args_conflicts_with_subcommands = true,
    after_long_help = "Examples:
  dem-pair --match pose --sim-labels sim_labels.csv --real-labels real_labels.csv --val-fraction 0.5 -o pairs.csv
  dem-train --sim sim.npy --real real.npy --pairs pairs.csv --out run/ --epochs 20
  dem-train --sim sim.npy --real real.npy --pairs pairs.csv --out run/ --epochs 40 --resume   # go on to 40
  dem-train export run/ -o gy.onnx
  dem-apply --model gy.onnx sim.npy -o gy_sim.npy        # what the network leaves, named by dem-gap (1 min):
  dem-gap --sim gy_sim.npy --real real.npy --sim-labels sim_labels.csv --real-labels real_labels.csv -o gap/
  dem-train export run/ -o gy.onnx --residual gap/sensor.json   # the generator with what its network leaves
  dem-train export run/ -o gy.onnx --heights input --residual gap/sensor.json   # its holes, the sim's heights, then the residual
  dem-train curves run/ -o curves.png                   # losses and val error per epoch
  dem-apply --model gy.onnx < sim.npy > realistic.npy"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    train: TrainArgs,
}

#[derive(Subcommand)]
enum Command {
    /// Export a run's generator to ONNX, checked against the trainer.
    Export(ExportArgs),
    /// Draw a run's training curves (losses per epoch, val pair error) as a PNG.
    #[command(after_long_help = "Example:\n  dem-train curves run/ -o run/curves.png")]
    Curves {
        /// Run directory made by dem-train.
        run: String,
        /// Output PNG.
        #[arg(short, long = "out")]
        output: String,
    },
}

#[derive(Args)]
struct TrainArgs {
    /// Sim DEMs (X), an NPY stream.
    #[arg(long)]
    sim: Option<String>,
    /// Real DEMs (Y), an NPY stream.
    #[arg(long)]
    real: Option<String>,
    /// Pairs CSV (sim_index,real_index[,split]); without it, a plain Cycle GAN.
    #[arg(long)]
    pairs: Option<String>,
    /// Sensor model (dem-gap's sensor.json) applied to the sims first, so the
    /// network learns only what the named effects leave unexplained.
    #[arg(long, value_name = "JSON")]
    sensor: Option<String>,
    /// Run directory.
    #[arg(short, long)]
    out: Option<String>,
    /// Epochs in all (one epoch = ceil(sims / batch) steps) [default: 30,
    /// or fewer when an epoch is long: as many whole epochs as reach 1500
    /// steps].
    #[arg(long, value_parser = value::at_least_one::<u64>)]
    epochs: Option<u64>,
    /// Stop after this many steps in all (e.g. tiny CI runs).
    #[arg(long, value_parser = value::at_least_one::<u64>)]
    max_steps: Option<u64>,
    /// Records per batch [default: 64].
    #[arg(long, value_parser = value::at_least_one::<usize>)]
    batch: Option<usize>,
    /// Generator width w [default: 32].
    #[arg(long, value_parser = value::at_least_one::<usize>)]
    width: Option<usize>,
    /// Generator head: `residual` predicts a height correction over the sim
    /// input and is trained with the paired height term; `thesis` is
    /// docs/network.md's network and losses, to reproduce the thesis's rows
    /// [default: residual].
    #[arg(long, value_enum)]
    arch: Option<ArchArg>,
    /// Weight of the paired height term (mean abs height error in cm on the
    /// cells valid in the paired real) [default: 3 with residual, 0 with thesis].
    #[arg(long, value_parser = value::non_negative::<f32>)]
    lambda_height: Option<f32>,
    /// Share of the epochs at the full learning rate; over the rest it falls
    /// linearly to 0 [default: 0.5 with residual, 1 (constant) with thesis].
    #[arg(long, value_parser = value::fraction::<f32>)]
    decay_from: Option<f32>,
    /// Adam learning rate [default: 2e-4].
    #[arg(long, value_parser = value::positive::<f32>)]
    lr: Option<f32>,
    /// Weight of the cycle terms [default: 10].
    #[arg(long, value_parser = value::non_negative::<f32>)]
    lambda_cyc: Option<f32>,
    /// Weight of the paired terms [default: 30 with residual, 10 with thesis].
    #[arg(long, value_parser = value::non_negative::<f32>)]
    lambda_pair: Option<f32>,
    /// Share of each batch drawn from train pairs [default: 0.5].
    #[arg(long, value_parser = value::fraction::<f64>)]
    paired_fraction: Option<f64>,
    /// Seed of initialisation, sampling and the sensor model [default: 0].
    #[arg(long)]
    seed: Option<u64>,
    /// Worker threads (default: all cores). Results depend on the seed only,
    /// not on the thread count.
    #[arg(long, value_parser = value::at_least_one::<usize>)]
    threads: Option<usize>,
    /// Also checkpoint every N steps (always at each epoch's end).
    #[arg(long, value_parser = value::at_least_one::<u64>)]
    checkpoint_every: Option<u64>,
    /// Seconds between progress lines on stderr when it is not a terminal
    /// (on a terminal, a progress bar).
    #[arg(long, default_value_t = 10.0, value_parser = |s: &str| value::within(s, 0.01, 86_400.0))]
    log_every: f64,
    /// Continue the run in --out from its checkpoint.
    #[arg(long)]
    resume: bool,
    /// Do not warn when --sim misses clearly more cells than --real (the
    /// sign of swapped inputs: measured DEMs have holes, sim DEMs few).
    #[arg(long)]
    no_swap_check: bool,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum ArchArg {
    Thesis,
    Residual,
}

impl ArchArg {
    fn arch(self) -> Arch {
        match self {
            ArchArg::Thesis => Arch::Thesis,
            ArchArg::Residual => Arch::Residual,
        }
    }
}

#[derive(Args)]
struct ExportArgs {
    /// Run directory made by dem-train.
    run: String,
    /// Output ONNX file.
    #[arg(short, long = "out")]
    output: String,
    /// Which generator: y (sim -> real) or x (real -> sim).
    #[arg(long, default_value = "y", value_parser = ["y", "x"])]
    generator: String,
    /// A sensor model JSON that dem-gap fitted between the network's
    /// output and the measured DEMs (what a deterministic network cannot
    /// write: per-record noise, startup rows by time). It is stored in the
    /// model (`dem.residual`) and in its graph, after the network: the file
    /// is then the whole virtual sensor, with inputs `dem`, `uniform` and
    /// `time`, in dem-apply, onnxruntime or PyTorch alike.
    #[arg(long)]
    residual: Option<String>,
    /// Where the model's valid cells take their heights from when dem-apply
    /// runs it: `network` (its height head) or `input` (the input's heights
    /// under the network's holes; fit --residual on `dem-apply --heights
    /// input --network-only`'s output). Stored as `dem.heights`.
    #[arg(long, default_value = "network", value_parser = clap::value_parser!(dem_onnx::Heights))]
    heights: dem_onnx::Heights,
}

fn main() -> ExitCode {
    cli::run(|| {
        let c: Cli = cli::parse();
        match c.command {
            Some(Command::Export(e)) => dem_train::export(&e.run, &e.output, e.generator == "y", e.residual.as_deref(), e.heights),
            Some(Command::Curves { run, output }) => dem_train::draw_curves(&run, &output),
            None => {
                if let Some(t) = c.train.threads {
                    rayon::ThreadPoolBuilder::new().num_threads(t).build_global()?;
                }
                let no_swap_check = c.train.no_swap_check;
                let cfg = config(c.train)?;
                dem_core::swap::check_files(&cfg.sim, &cfg.real, no_swap_check);
                dem_train::train(&cfg)
            }
        }
    })
}

/// The command line as a validated run: the three required paths present.
fn config(a: TrainArgs) -> anyhow::Result<TrainConfig> {
    let dir = a.out.ok_or_else(|| cli::usage("--out RUN/ is required"))?;
    let sim = a.sim.ok_or_else(|| cli::usage("--sim is required"))?;
    let real = a.real.ok_or_else(|| cli::usage("--real is required"))?;
    Ok(TrainConfig {
        sim,
        real,
        pairs: a.pairs,
        sensor: a.sensor,
        run: RunOptions {
            dir,
            epochs: a.epochs,
            max_steps: a.max_steps,
            checkpoint_every: a.checkpoint_every,
            log_every: Duration::from_secs_f64(a.log_every),
        },
        settings: Settings {
            arch: a.arch.map(ArchArg::arch),
            width: a.width,
            batch: a.batch,
            lr: a.lr,
            lambda_cyc: a.lambda_cyc,
            lambda_pair: a.lambda_pair,
            lambda_height: a.lambda_height,
            decay_from: a.decay_from,
            paired_fraction: a.paired_fraction,
            seed: a.seed,
        },
        resume: a.resume,
    })
}
