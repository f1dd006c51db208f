//! dem-train: train G_Y (sim -> real) as a Cycle GAN with paired data, and
//! export a trained generator to ONNX.

mod curves;
mod provenance;
mod session;

use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use dem_core::sensor::SensorModel;
use dem_core::cli::{self, value};
use dem_core::{npy, output, table};
use dem_nn::train::checkpoint::{self, Meta};
use session::RunOptions;
use dem_nn::train::{AdamConfig, CycleGan, GanConfig, Sampler, TrainData};
use dem_nn::weights::Arch;

/// Train the virtual sensor network of spec/network.md: G_Y turns sim DEMs
/// into the DEMs a real sensor + elevation mapping gives, learned from many
/// sims, few reals and (optionally) pairs of the same pose.
///
/// Writes RUN/losses.csv (per step), RUN/val.csv (pair error of the val
/// split per epoch), RUN/checkpoint.bin (each epoch, atomically). The same
/// seed and thread count give the same model; --resume continues a run
/// exactly where its last checkpoint left it.
#[derive(Parser)]
#[command(version, args_conflicts_with_subcommands = true, after_long_help = "Examples:
  dem-pair --match pose --sim-labels sim_labels.csv --real-labels real_labels.csv --val-fraction 0.5 -o pairs.csv
  dem-train --sim sim.npy --real real.npy --pairs pairs.csv --out run/ --epochs 20
  dem-train --sim sim.npy --real real.npy --pairs pairs.csv --out run/ --epochs 40 --resume   # go on to 40
  dem-train export run/ -o gy.onnx
  dem-train curves run/ -o curves.png                   # losses and val error per epoch
  dem-apply --model gy.onnx < sim.npy > realistic.npy")]
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
        #[arg(short, long = "out", alias = "output")]
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
    #[arg(long)]
    sensor: Option<String>,
    /// Run directory.
    #[arg(short, long)]
    out: Option<String>,
    /// Epochs in all (one epoch = ceil(sims / batch) steps).
    #[arg(long, default_value_t = 30, value_parser = value::at_least_one::<u64>)]
    epochs: u64,
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
    /// spec/network.md's network and losses, to reproduce the thesis's rows
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
    #[arg(short, long = "out", alias = "output")]
    output: String,
    /// Which generator: y (sim -> real) or x (real -> sim).
    #[arg(long, default_value = "y", value_parser = ["y", "x"])]
    generator: String,
}

fn main() -> ExitCode {
    cli::run(|| {
        let c: Cli = cli::parse();
        match c.command {
            Some(Command::Export(e)) => export(&e),
            Some(Command::Curves { run, output }) => {
                output::check_outputs(&[&run_file(&run, "losses.csv"), &run_file(&run, "val.csv")], &[&output])?;
                curves::run(&run, &output)
            }
            None => {
                // A refused run leaves no folder behind: remove the one this
                // run made when nothing but its lock is in it.
                let dir = c.train.out.clone();
                let made = dir.as_deref().is_some_and(|d| !std::path::Path::new(d).exists());
                let outcome = train(c.train);
                if let (Err(_), true, Some(d)) = (&outcome, made, dir) {
                    let only_lock = std::fs::read_dir(&d).is_ok_and(|e| e.flatten().all(|f| f.file_name() == ".lock"));
                    if only_lock {
                        let _ = std::fs::remove_dir_all(&d);
                    }
                }
                outcome
            }
        }
    })
}

fn run_file(dir: &str, name: &str) -> String {
    std::path::Path::new(dir).join(name).to_string_lossy().into_owned()
}

fn export(e: &ExportArgs) -> anyhow::Result<()> {
    let inputs = [run_file(&e.run, "checkpoint.bin"), run_file(&e.run, "check_sim.npy"), run_file(&e.run, "check_real.npy")];
    output::check_outputs(&inputs.iter().map(String::as_str).collect::<Vec<_>>(), &[&e.output])?;
    let (meta, gan) = checkpoint::load(&run_file(&e.run, "checkpoint.bin"))?;
    let y = e.generator == "y";
    let check = npy::read_all(&run_file(&e.run, if y { "check_sim.npy" } else { "check_real.npy" }))?;
    let expected = gan.generate(y, &check);
    let metadata = provenance::export_metadata(&meta, &e.generator, std::fs::read_to_string(run_file(&e.run, "val.csv")).ok());
    let report = dem_onnx::export::export_checked_with(&gan.generator_weights(y), &check, &expected, &e.output, &metadata)?;
    cli::log(format!(
        "wrote {} ({} bytes): G_{} of {}, tract reproduces the trainer on {} check records (max |diff| {:.2e})",
        report.path,
        report.bytes,
        e.generator.to_uppercase(),
        e.run,
        report.records,
        report.max_abs_diff
    ));
    Ok(())
}

fn train(a: TrainArgs) -> anyhow::Result<()> {
    let dir = a.out.clone().ok_or_else(|| cli::usage("--out RUN/ is required"))?;
    if let Some(t) = a.threads {
        rayon::ThreadPoolBuilder::new().num_threads(t).build_global()?;
    }
    let sim_path = a.sim.clone().ok_or_else(|| cli::usage("--sim is required"))?;
    let real_path = a.real.clone().ok_or_else(|| cli::usage("--real is required"))?;
    let opts = RunOptions { dir: dir.clone(), epochs: a.epochs, max_steps: a.max_steps, checkpoint_every: a.checkpoint_every, log_every: std::time::Duration::from_secs_f64(a.log_every) };
    // One writer per run folder: a second run, or a --resume beside a
    // running one, is refused while this lock is held (until we return).
    let _lock = session::lock(&dir)?;
    let inputs: Vec<&str> = [&a.sim, &a.real, &a.pairs, &a.sensor].into_iter().flatten().map(String::as_str).collect();
    let run_files: Vec<String> = session::FILES.iter().map(|f| run_file(&dir, f)).collect();
    output::check_outputs(&inputs, &run_files.iter().map(String::as_str).collect::<Vec<_>>())?;
    let mut sim = npy::read_all(&sim_path)?;
    let real = npy::read_all(&real_path)?;
    let pairs = match &a.pairs {
        Some(p) => table::read_pairs(p)?,
        None => Vec::new(),
    };
    let sensor = a.sensor.as_deref().map(SensorModel::read).transpose()?;
    let mut files =
        vec![provenance::data_file("sim", &sim_path, Some(sim.len()))?, provenance::data_file("real", &real_path, Some(real.len()))?];
    if let Some(p) = &a.pairs {
        files.push(provenance::data_file("pairs", p, Some(pairs.len()))?);
    }
    if let Some(p) = &a.sensor {
        files.push(provenance::data_file("sensor", p, None)?);
    }
    let sensor_json = sensor.as_ref().map(|m| serde_json::from_str::<serde_json::Value>(&m.to_json()).expect("json"));
    // A resumed run keeps its settings (and its seed, which the sensor draw uses).
    let resumed = if a.resume {
        let (meta, gan) = session::resume(&opts)?;
        check_same(&a, &meta)?;
        if sensor_json != meta.sensor {
            return Err(cli::usage(format!(
                "--resume: {dir} was trained {} a sensor model; give the same --sensor again",
                if meta.sensor.is_some() { "with" } else { "without" }
            )));
        }
        Some((meta, gan))
    } else {
        None
    };
    let seed = resumed.as_ref().map_or(a.seed.unwrap_or(0), |(m, _)| m.seed);
    if let Some(m) = &sensor {
        // One fixed draw per sim record, so every epoch sees the same inputs
        // (the residual the network learns is then a function of the input).
        m.apply_all(&mut sim, seed, 0);
        cli::log(format!("applied sensor model {} to {} sims: {}", a.sensor.as_deref().unwrap_or(""), sim.len(), m.summary()));
    }
    let data = TrainData::new(sim, real, &pairs, [&sim_path, &real_path, a.pairs.as_deref().unwrap_or("-")])?;
    let (meta, mut gan) = match resumed {
        Some((meta, gan)) => {
            if meta.steps_per_epoch != data.steps_per_epoch(meta.batch) {
                return Err(cli::usage(format!(
                    "--resume: {dir} was trained on data with {} steps per epoch, these inputs give {}",
                    meta.steps_per_epoch,
                    data.steps_per_epoch(meta.batch)
                )));
            }
            cli::log(format!("resuming {dir} at step {}", meta.step));
            (meta, gan)
        }
        None => {
            let base = match a.arch {
                Some(ArchArg::Thesis) => GanConfig::thesis(),
                _ => GanConfig::default(),
            };
            let config = GanConfig {
                width: a.width.unwrap_or(base.width),
                adam: AdamConfig { lr: a.lr.unwrap_or(base.adam.lr), ..base.adam },
                lambda_cyc: a.lambda_cyc.unwrap_or(base.lambda_cyc),
                lambda_pair: a.lambda_pair.unwrap_or(base.lambda_pair),
                lambda_height: a.lambda_height.unwrap_or(base.lambda_height),
                decay_from: a.decay_from.unwrap_or(base.decay_from),
                ..base
            };
            let batch = a.batch.unwrap_or(Sampler::DEFAULT_BATCH);
            let gan = CycleGan::new(config, seed);
            session::start(&opts, &data)?;
            let pf = a.paired_fraction.unwrap_or(Sampler::DEFAULT_PAIRED_FRACTION);
            let mut meta = checkpoint::meta(&gan, seed, batch, pf, 0, data.steps_per_epoch(batch));
            meta.sensor = sensor_json;
            meta.data = files;
            (meta, gan)
        }
    };
    let sampler = Sampler { seed: meta.seed, batch: meta.batch, paired_fraction: meta.paired_fraction };
    cli::log(format!(
        "{} sims, {} reals, {} train keys, {} val keys; {} head, width {}, batch {} ({} paired rows), {} steps per epoch, {} threads",
        data.sim.len(),
        data.real.len(),
        data.train.len(),
        data.val.len(),
        meta.config.arch.name(),
        meta.config.width,
        meta.batch,
        sampler.paired_rows(&data),
        meta.steps_per_epoch,
        rayon::current_num_threads()
    ));
    if data.val.is_empty() {
        cli::log("no val split in the pairs: val.csv stays empty (dem-pair --val-fraction makes one)");
    }
    session::run(&mut gan, &data, sampler, meta, &opts)?;
    Ok(())
}

/// On --resume, settings given again must be the run's.
fn check_same(a: &TrainArgs, m: &Meta) -> anyhow::Result<()> {
    let c = &m.config;
    let clash = [
        ("--width", a.width.is_some_and(|v| v != c.width)),
        ("--batch", a.batch.is_some_and(|v| v != m.batch)),
        ("--lr", a.lr.is_some_and(|v| v != c.adam.lr)),
        ("--lambda-cyc", a.lambda_cyc.is_some_and(|v| v != c.lambda_cyc)),
        ("--lambda-pair", a.lambda_pair.is_some_and(|v| v != c.lambda_pair)),
        ("--lambda-height", a.lambda_height.is_some_and(|v| v != c.lambda_height)),
        ("--decay-from", a.decay_from.is_some_and(|v| v != c.decay_from)),
        ("--arch", a.arch.is_some_and(|v| v.arch() != c.arch)),
        ("--paired-fraction", a.paired_fraction.is_some_and(|v| v != m.paired_fraction)),
        ("--seed", a.seed.is_some_and(|v| v != m.seed)),
    ];
    if let Some((name, _)) = clash.iter().find(|(_, c)| *c) {
        return Err(cli::usage(format!("--resume: {name} differs from the run's checkpoint (leave it out to keep the run's)")));
    }
    Ok(())
}
