//! dem-sensor: apply a sensor model of named measurement effects to DEMs.

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use dem_core::cli;
use dem_sensor::{apply_shard, SensorModel};

/// Sensor models of named effects (noise, dropout, row-dropout, occlusion,
/// fov, view-top, smoothing, bias, quantization, startup, patch-dropout,
/// edge-holes, rim-holes, pit-fill, mixed-cells, hole-growth, drop-blend, riser-blend, floor-lift, drop-holes) as JSON, applied to NPY streams.
#[derive(Parser)]
#[command(version, after_long_help = "Examples:
  dem-sensor apply --sensor sensor.json --seed 1 < sim.npy > model_sim.npy
  dem-gap --sim sim.npy --real real.npy --out gap/ && dem-sensor apply --sensor gap/sensor.json sim.npy -o sim_as_measured.npy
  dem-sensor apply --sensor gap/sensor.json sim.npy | dem-render - --count 12 -o measured_look.png
  dem-sensor apply --sensor gap/sensor.json --labels sim_labels.csv sim.npy -o out.npy  # startup by time
  # the virtual sensor: G_Y, then the startup rows a sim DEM cannot carry (by the labels' time)
  dem-apply --model gy.onnx sim.npy | dem-sensor apply --sensor gap/sensor.json --only startup \
      --labels sim_labels.csv -o realistic.npy
  dem-sensor show --sensor sensor.json        # the effects, one a line
  dem-split --shards 4 --out part sim.npy | tail -n +2 | while IFS=, read shard first n; do
      dem-sensor apply --sensor sensor.json --seed 1 --first-index $first $shard -o $shard.out; done

A model file:
  {\"effects\": [{\"effect\": \"occlusion\", \"params\": {\"h\": 0.45, \"x0\": 0.15}},
               {\"effect\": \"noise\", \"params\": {\"sigma0\": 0.003, \"k\": 0.01}}]}")]
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
        #[arg(long = "sensor", alias = "model", value_name = "JSON")]
        model: String,
        /// Input NPY stream (`-` for stdin).
        #[arg(default_value = "-")]
        input: String,
        /// Output NPY stream (`-` for stdout).
        #[arg(short, long = "out", alias = "output", default_value = "-")]
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
        /// each record's `time` in its run; without, its per-record rate p.
        #[arg(long)]
        labels: Option<String>,
        /// Apply only these effects of the model (comma-separated names,
        /// e.g. `startup` after a generator: the one effect a sim DEM
        /// cannot carry, since it depends on the frame's time in its run).
        #[arg(long, value_delimiter = ',')]
        only: Vec<String>,
    },
    /// Check a model and print its effects, one a line.
    Show {
        /// The sensor model (JSON).
        #[arg(long = "sensor", alias = "model", value_name = "JSON")]
        model: String,
    },
}

fn main() -> ExitCode {
    cli::run(|| match cli::parse::<Args>().command {
        Command::Apply { model, input, output, seed, first_index, labels, only } => {
            let inputs: Vec<&str> = [Some(&input), Some(&model), labels.as_ref()].into_iter().flatten().map(String::as_str).collect();
            dem_core::output::check_outputs(&inputs, &[&output])?;
            let mut m = SensorModel::read(&model)?;
            if !only.is_empty() {
                m = m.only(&only).map_err(|why| dem_core::DemError::input(model.as_str(), why))?;
            }
            let times = match &labels {
                Some(p) => Some(dem_core::table::times(&dem_core::table::read_labels(p)?)),
                None => None,
            };
            let bar = cli::progress(0, "records");
            let t = labels.as_deref().zip(times.as_deref());
            let n = apply_shard(&m, &input, &output, seed, first_index, t, |k| bar.inc(k))?;
            bar.finish_and_clear();
            cli::log(format_args!("{n} records through {}", m.summary()));
            Ok(())
        }
        Command::Show { model } => {
            let m = SensorModel::read(&model)?;
            use std::io::Write;
            let mut out = std::io::stdout().lock();
            for e in &m.effects {
                writeln!(out, "{e}")?;
            }
            Ok(())
        }
    })
}
