//! dem-sensor: apply a sensor model of named measurement effects to DEMs.

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use dem_core::cli;
use dem_sensor::{apply_shard_emit, SensorModel};

/// Sensor models of named effects (noise, dropout, row-dropout, occlusion,
/// fov, view-top, smoothing, bias, quantization, startup, patch-dropout,
/// edge-holes, rim-holes, pit-fill, mixed-cells, hole-growth, drop-blend, riser-blend, floor-lift, drop-holes,
/// tilt, shake, step-jitter, lag, drift, and map-memory, the fused map across
/// frames) as JSON, applied to NPY streams.
#[derive(Parser)]
#[command(
    version,
    after_long_help = "Examples:
  dem-sensor apply --sensor sensor.json --seed 1 < sim.npy > model_sim.npy
  dem-gap --sim sim.npy --real real.npy --out gap/ && dem-sensor apply --sensor gap/sensor.json sim.npy -o sim_as_measured.npy
  dem-sensor apply --sensor gap/sensor.json sim.npy | dem-render - --count 12 -o measured_look.png
  dem-sensor apply --sensor gap/sensor.json --labels sim_labels.csv sim.npy -o out.npy  # startup by time
  # the virtual sensor: G_Y, then the startup rows a sim DEM cannot carry (by the labels' time)
  dem-apply --model gy.onnx sim.npy | dem-sensor apply --sensor gap/sensor.json --only startup \
      --labels sim_labels.csv -o realistic.npy
  dem-sensor show --sensor sensor.json        # the effects, one a line
  dem-sensor effects                          # the vocabulary: effect,family,stage,draws,run_draws,params,emulator_stages,limits
  dem-sensor export --sensor gap/sensor.json -o sensor.onnx   # one ONNX graph: dem, uniform, time -> dem_out
  dem-sensor apply --sensor sensor.json --seed 1 --emit-uniform u.npy sim.npy -o out.npy   # sensor.onnx fed u.npy gives out.npy
  dem-split --shards 4 --out part sim.npy | tail -n +2 | while IFS=, read shard first n; do
      dem-sensor apply --sensor sensor.json --seed 1 --first-index $first $shard -o $shard.out; done

A model file:
  {\"effects\": [{\"effect\": \"occlusion\", \"params\": {\"h\": 0.45, \"x0\": 0.15}},
               {\"effect\": \"noise\", \"params\": {\"sigma0\": 0.003, \"k\": 0.01}}]}"
)]
struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Apply the model's effects, in order, to every record of a stream.
    ///
    /// Deterministic by --seed: each record's random draws come from the
    /// seed, its index in the stream and the effect, so any thread count
    /// or chunking gives the same bytes.
    Apply {
        /// The sensor model (JSON).
        #[arg(long = "sensor", value_name = "JSON")]
        model: String,
        /// Input NPY stream (`-` for stdin).
        #[arg(default_value = "-")]
        input: String,
        /// Output NPY stream (`-` for stdout).
        #[arg(short, long = "out", default_value = "-")]
        output: String,
        /// Seed of the random effects.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Index of the input's first record in the whole data set, when the
        /// input is a shard (`dem-split` prints it): records draw by their
        /// index in the whole, so joined shards equal one run on the whole.
        #[arg(long, default_value_t = 0)]
        first_index: u64,
        /// Labels CSV of the input (one row per record): `startup` uses
        /// each record's `time` in its run (without, its per-record rate
        /// p), and the draws a run keeps (`tilt`, `lag`) its `sequence`.
        #[arg(long, value_name = "CSV")]
        labels: Option<String>,
        /// Apply only these effects of the model (comma-separated names,
        /// e.g. `startup` after a generator: the one effect a sim DEM
        /// cannot carry, since it depends on the frame's time in its run).
        #[arg(long, value_delimiter = ',')]
        only: Vec<String>,
        /// Write each record's uniforms to this NPY file (float32 (N, K)):
        /// fed to the model's ONNX graph (`dem-sensor export`) as its
        /// `uniform` input, with the labels' `time` (NaN without --labels),
        /// any runtime computes the same DEMs.
        #[arg(long, value_name = "NPY")]
        emit_uniform: Option<String>,
    },
    /// Write the model as one ONNX graph: a virtual sensor without a
    /// network, for onnxruntime, PyTorch (onnx2torch) or dem-apply.
    ///
    /// Inputs: `dem` float32 (N, 21, 5, 2); `uniform` float32 (N, K) in
    /// [0, 1), K = the model's draws per record (in the file's metadata,
    /// `dem.uniform_count`), drawn fresh per call; `time` float32 (N),
    /// seconds into the run, NaN where unknown (only with `startup`).
    /// Output `dem_out` float32 (N, 21, 5, 2). Written only after tract,
    /// fed the same uniforms, reproduces dem-sensor apply on check records.
    Export {
        /// The sensor model (JSON).
        #[arg(long = "sensor", value_name = "JSON")]
        model: String,
        /// The ONNX file to write.
        #[arg(short, long = "out")]
        output: String,
        /// Check on these records (an NPY stream) instead of built-in
        /// terrain (flat, risers, drops, stairs, boxes, pits).
        #[arg(long, value_name = "NPY")]
        check: Option<String>,
    },
    /// Check a model and print its effects, one a line.
    Show {
        /// The sensor model (JSON).
        #[arg(long = "sensor", value_name = "JSON")]
        model: String,
    },
    /// Print the vocabulary of effects as CSV, one a line.
    ///
    /// In the order dem-gap tries them: effect, family (the module that
    /// defines it), stage (its place in the physical chain), draws per
    /// record, how many of them a run keeps (drawn once per run when
    /// `--labels` name the runs), parameters, the dem-synth stages
    /// (`--no-<stage>`) it models, and each parameter's physical box; lists
    /// are separated by spaces.
    Effects,
}

fn main() -> ExitCode {
    cli::run(|| match cli::parse::<Args>().command {
        Command::Apply { model, input, output, seed, first_index, labels, only, emit_uniform } => {
            let inputs: Vec<&str> = [Some(&input), Some(&model), labels.as_ref()].into_iter().flatten().map(String::as_str).collect();
            let outputs: Vec<&str> = [Some(&output), emit_uniform.as_ref()].into_iter().flatten().map(String::as_str).collect();
            dem_core::output::check_outputs(&inputs, &outputs)?;
            let mut m = SensorModel::read(&model)?;
            if !only.is_empty() {
                m = m.only(&only).map_err(|why| dem_core::DemError::input(model.as_str(), why))?;
            }
            let moments = match &labels {
                Some(p) => Some(dem_sensor::moments(&dem_core::table::read_labels(p)?)),
                None => None,
            };
            if let Some(why) = dem_sensor::runs_unknown(&m, moments.as_deref()) {
                cli::log(format_args!("note: {why}"));
            }
            let bar = cli::progress(0, "records");
            let t = labels.as_deref().zip(moments.as_deref());
            let n = apply_shard_emit(&m, &input, &output, seed, first_index, t, emit_uniform.as_deref(), |k| bar.inc(k))?;
            bar.finish_and_clear();
            cli::log(format_args!("{n} records through {}", m.summary()));
            Ok(())
        }
        Command::Export { model, output, check } => {
            let inputs: Vec<&str> = [Some(&model), check.as_ref()].into_iter().flatten().map(String::as_str).collect();
            dem_core::output::check_outputs(&inputs, &[&output])?;
            let m = SensorModel::read(&model)?;
            let records = match &check {
                Some(p) => dem_core::npy::read_all(p)?.into_iter().take(4096).collect(),
                None => dem_sensor::export::probe_records(600, 1),
            };
            if records.is_empty() {
                return Err(dem_core::DemError::input(check.as_deref().unwrap_or("-"), "no records to check the graph on").into());
            }
            let source = vec![("dem.residual.source".to_string(), model.clone())];
            let r = dem_sensor::export::export(&m, &records, &output, &source)?;
            cli::log(format_args!(
                "wrote {output} ({} bytes): {}; inputs: {}; tract reproduces dem-sensor on {} check records \
                 (validity {:.4} % of cells apart, heights {:.1e} m)",
                r.bytes,
                m.summary(),
                dem_sensor::graph::input_list(&m),
                r.records,
                100.0 * r.validity_differ,
                r.max_height_diff
            ));
            Ok(())
        }
        Command::Show { model } => {
            dem_core::output::check_outputs(&[&model], &["-"])?;
            let m = SensorModel::read(&model)?;
            use std::io::Write;
            let mut out = std::io::stdout().lock();
            for e in &m.effects {
                writeln!(out, "{e}")?;
            }
            for w in &m.warnings {
                dem_core::cli::log(format_args!("warning: {w}"));
            }
            Ok(())
        }
        Command::Effects => {
            dem_core::output::check_outputs(&[], &["-"])?;
            use std::io::Write;
            std::io::stdout().lock().write_all(dem_sensor::effects::csv().as_bytes())?;
            Ok(())
        }
    })
}
