//! dem-train's library: train G_Y (sim -> real) as a Cycle GAN with paired
//! data in a run folder, export a trained generator to ONNX, draw the
//! training curves. dem-nn is the engine (networks, losses, steps,
//! checkpoints); this crate is the run around it.
//!
//! - [`settings`]: the network and training settings a user may set, their
//!   defaults, and the resume policy (a resumed run keeps its own).
//! - [`train`]: a training run from a validated [`TrainConfig`].
//! - [`export`]: a run's generator to ONNX, checked against the trainer.
//! - [`session`]: the step loop, logs, checkpoints and resumption in a folder.
//! - [`curves`]: the losses and val error per epoch as a PNG.
//! - [`provenance`]: what an exported model records about its data.

pub mod curves;
pub mod provenance;
pub mod session;
pub mod settings;

use std::path::Path;

use anyhow::Result;
use dem_core::{cli, npy, output, table, DemError};
use dem_nn::train::checkpoint;
use dem_nn::train::{CycleGan, Sampler, TrainData};
use dem_onnx::generator::RESIDUAL_KEY;
use dem_onnx::Heights;
use dem_sensor::SensorModel;

pub use session::RunOptions;
pub use settings::Settings;

/// A training run, validated: inputs, the run folder and its options, the
/// settings given on the command line.
#[derive(Clone, Debug)]
pub struct TrainConfig {
    /// Sim DEMs (X).
    pub sim: String,
    /// Real DEMs (Y).
    pub real: String,
    /// Pairs CSV, if any.
    pub pairs: Option<String>,
    /// Sensor model applied to the sims first, if any.
    pub sensor: Option<String>,
    /// Folder, epochs, checkpoints, logging.
    pub run: RunOptions,
    /// What the user set (unset: the default, or the resumed run's own).
    pub settings: Settings,
    /// Continue the run in the folder from its checkpoint.
    pub resume: bool,
}

/// `dir/name` as a string.
pub fn run_file(dir: &str, name: &str) -> String {
    Path::new(dir).join(name).to_string_lossy().into_owned()
}

/// Train as `cfg` says. A refused run leaves no folder behind: the folder
/// this run made is removed when nothing but its lock is in it.
pub fn train(cfg: &TrainConfig) -> Result<()> {
    let dir = &cfg.run.dir;
    let made = !Path::new(dir).exists();
    let outcome = train_in_folder(cfg);
    if outcome.is_err() && made {
        let only_lock = std::fs::read_dir(dir).is_ok_and(|e| e.flatten().all(|f| f.file_name() == ".lock"));
        if only_lock {
            let _ = std::fs::remove_dir_all(dir);
        }
    }
    outcome
}

fn train_in_folder(cfg: &TrainConfig) -> Result<()> {
    let dir = &cfg.run.dir;
    // One writer per run folder: a second run, or a --resume beside a
    // running one, is refused while this lock is held (until we return).
    let _lock = session::lock(dir)?;
    let inputs: Vec<&str> =
        [Some(&cfg.sim), Some(&cfg.real), cfg.pairs.as_ref(), cfg.sensor.as_ref()].into_iter().flatten().map(String::as_str).collect();
    let run_files: Vec<String> = session::FILES.iter().map(|f| run_file(dir, f)).collect();
    output::check_outputs(&inputs, &run_files.iter().map(String::as_str).collect::<Vec<_>>())?;
    let mut sim = npy::read_all(&cfg.sim)?;
    let real = npy::read_all(&cfg.real)?;
    let pairs = match &cfg.pairs {
        Some(p) => table::read_pairs(p)?,
        None => Vec::new(),
    };
    let sensor = cfg.sensor.as_deref().map(SensorModel::read).transpose()?;
    let mut files =
        vec![provenance::data_file("sim", &cfg.sim, Some(sim.len()))?, provenance::data_file("real", &cfg.real, Some(real.len()))?];
    if let Some(p) = &cfg.pairs {
        files.push(provenance::data_file("pairs", p, Some(pairs.len()))?);
    }
    if let Some(p) = &cfg.sensor {
        files.push(provenance::data_file("sensor", p, None)?);
    }
    let sensor_json = sensor.as_ref().map(|m| serde_json::from_str::<serde_json::Value>(&m.to_json()).expect("json"));
    // A resumed run keeps its settings (and its seed, which the sensor draw uses).
    let resumed = if cfg.resume {
        let (meta, gan) = session::resume(&cfg.run)?;
        cfg.settings.check_same(&meta).map_err(cli::usage)?;
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
    let seed = resumed.as_ref().map_or(cfg.settings.seed(), |(m, _)| m.seed);
    if let Some(m) = &sensor {
        // One fixed draw per sim record, so every epoch sees the same inputs
        // (the residual the network learns is then a function of the input).
        m.apply_all(&mut sim, seed, 0);
        cli::log(format!("applied sensor model {} to {} sims: {}", cfg.sensor.as_deref().unwrap_or(""), sim.len(), m.summary()));
    }
    let data = TrainData::new(sim, real, &pairs, [&cfg.sim, &cfg.real, cfg.pairs.as_deref().unwrap_or("-")])?;
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
            let s = &cfg.settings;
            let gan = CycleGan::new(s.gan_config(), seed);
            session::start(&cfg.run, &data)?;
            let mut meta = checkpoint::meta(&gan, seed, s.batch(), s.paired_fraction(), 0, data.steps_per_epoch(s.batch()));
            meta.sensor = sensor_json;
            meta.data = files;
            (meta, gan)
        }
    };
    let sampler = Sampler { seed: meta.seed, batch: meta.batch, paired_fraction: meta.paired_fraction };
    let epochs = session::epochs_of(&cfg.run, meta.steps_per_epoch);
    cli::log(format!(
        "{} sims, {} reals, {} train keys, {} val keys; {} head, width {}, batch {} ({} paired rows), {} steps per epoch, {epochs} epochs{}, {} threads",
        data.sim.len(),
        data.real.len(),
        data.train.len(),
        data.val.len(),
        meta.config.arch.name(),
        meta.config.width,
        meta.batch,
        sampler.paired_rows(&data),
        meta.steps_per_epoch,
        match cfg.run.epochs {
            Some(_) => String::new(),
            None if epochs < session::DEFAULT_EPOCHS => format!(" (the default {}, cut to about {} steps)", session::DEFAULT_EPOCHS, session::STEP_BUDGET),
            None => " (the default)".into(),
        },
        rayon::current_num_threads()
    ));
    if data.val.is_empty() {
        cli::log("no val split in the pairs: val.csv stays empty (dem-pair --val-fraction makes one)");
    }
    session::run(&mut gan, &data, sampler, meta, &cfg.run)?;
    Ok(())
}

/// Export generator `y` (G_Y, sim -> real) or G_X of the run in `run` to
/// the ONNX file `out`, after tract reproduces the trainer on the run's
/// check records; the model records its provenance, and where its valid
/// cells take their heights from when not the network's (`heights`).
pub fn export(run: &str, out: &str, y: bool, residual: Option<&str>, heights: Heights) -> Result<()> {
    let mut inputs = vec![run_file(run, "checkpoint.bin"), run_file(run, "check_sim.npy"), run_file(run, "check_real.npy")];
    inputs.extend(residual.map(String::from));
    output::check_outputs(&inputs.iter().map(String::as_str).collect::<Vec<_>>(), &[out])?;
    let residual = residual.map(|p| Ok::<_, anyhow::Error>((p, SensorModel::read(p)?))).transpose()?;
    if residual.is_some() && !y {
        return Err(DemError::Usage("--residual is a sensor model of G_Y's output: it needs --generator y".into()).into());
    }
    if heights == Heights::Input && !y {
        return Err(DemError::Usage("--heights input keeps the sim's heights under G_Y's holes: it needs --generator y".into()).into());
    }
    let (meta, gan) = checkpoint::load(&run_file(run, "checkpoint.bin"))?;
    let which = if y { "y" } else { "x" };
    let check = npy::read_all(&run_file(run, if y { "check_sim.npy" } else { "check_real.npy" }))?;
    let expected = gan.generate(y, &check);
    let mut metadata = provenance::export_metadata(&meta, which, std::fs::read_to_string(run_file(run, "val.csv")).ok());
    if let Some((path, _)) = &residual {
        metadata.push((format!("{RESIDUAL_KEY}.source"), format!("{path}, sha256 {}", provenance::sha256_file(path)?)));
    }
    let stored = dem_onnx::sensor::Stored { residual: residual.as_ref().map(|(_, m)| m.clone()), heights };
    let report = dem_onnx::export::export_sensor_checked(&gan.generator_weights(y), &stored, &check, &expected, out, &metadata)?;
    cli::log(format!(
        "wrote {} ({} bytes): G_{} of {run}, tract reproduces the trainer on {} check records (max |diff| {:.2e}){}{}{}",
        report.path,
        report.bytes,
        which.to_uppercase(),
        report.records,
        report.max_abs_diff,
        residual.map_or(String::new(), |(_, m)| format!(", with the residual sensor model {}", m.summary())),
        if heights == Heights::Input { ", heights from the input under its holes" } else { "" },
        report.tail.map_or(String::new(), |t| format!(
            "; one graph: tract's whole virtual sensor matches dem-apply's ({:.4} % of cells decided apart in validity, \
             {:.4} % in height; the rest within {:.1e} m)",
            100.0 * t.validity_differ,
            100.0 * t.height_differ,
            t.max_height_diff
        ))
    ));
    Ok(())
}

/// Draw the run's curves (`losses.csv`, `val.csv`) into the PNG `out`.
pub fn draw_curves(run: &str, out: &str) -> Result<()> {
    output::check_outputs(&[&run_file(run, "losses.csv"), &run_file(run, "val.csv")], &[out])?;
    curves::run(run, out)
}
