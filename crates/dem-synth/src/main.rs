//! dem-synth: make sim and measured DEM data sets from a physical emulator.

use std::process::ExitCode;

use clap::Parser;
use dem_core::cli::{self, value};
use dem_core::Terrain;
use dem_synth::{self as synth, CameraConfig, DatasetConfig, DriftConfig, MapConfig, RunConfig, Stages, VibrationConfig};

/// Simulate robot runs across flat ground, stairs, pallets and other terrain,
/// and write for every step the exact sim DEM and, for the first
/// --real-runs runs, the DEM a RealSense-like depth camera plus a Kalman
/// elevation map would measure (noise, holes, shadows, smoothing, startup)
/// on a robot that moves: its pose estimate drifts, the map lags, the
/// camera mount is miscalibrated and the body shakes on edges.
///
/// Writes DIR/sim.npy, DIR/sim_labels.csv, DIR/real.npy, DIR/real_labels.csv
/// and DIR/pairs.csv (sim and real records of the same pose). The same
/// --seed gives the same files on any number of threads. With --emit-maps
/// also DIR/maps.npy and DIR/maps.csv: the 5 cm elevation map after every
/// measured frame, for testing dem-import (docs/dem-synth.md).
#[derive(Parser)]
#[command(
    version,
    after_long_help = "Examples:
  dem-synth --out run/ --runs 400 --real-runs 20 --seed 1
  dem-synth --out shadowless/ --no-occlusion --seed 1      # same worlds, one effect hidden
  dem-synth --out still/ --no-drift --no-latency --no-extrinsic --no-vibration --seed 1   # sensor stages only
  dem-synth --out forgetful/ --no-memory --seed 1      # each DEM one frame's points alone
  dem-synth --out slow/ --latency 0.4 --drift 0.05 --seed 1    # a laggier map, a worse odometry
  dem-synth --out high/ --camera-height 0.7 --camera-tilt 25 --seed 2   # another camera mount
  dem-synth --out maps/ --runs 4 --real-runs 2 --seed 1 --emit-maps     # + the 5 cm maps behind real.npy
  dem-synth --out run/ && dem-render --compare run/sim.npy run/real.npy \\
      --row-labels sim,measured --start 40 --count 12 -o pairs.png"
)]
struct Args {
    /// Output directory (created if missing).
    #[arg(short, long)]
    out: std::path::PathBuf,
    /// Runs in all; each gives sim DEMs.
    #[arg(long, default_value_t = 400, value_parser = value::at_least_one::<u64>)]
    runs: u64,
    /// Make runs FIRST..FIRST+runs of the world (a shard: the joined shards'
    /// sim.npy and real.npy equal one run's, byte for byte; labels keep the
    /// run in `sequence` and are indexed from 0 in each shard).
    #[arg(long, default_value_t = 0)]
    first_run: u64,
    /// Runs 0..this of the world are measured too (real DEMs).
    #[arg(long, default_value_t = 20)]
    real_runs: u64,
    /// Terrains, cycled over the runs.
    #[arg(long, value_delimiter = ',', default_value = "flat,stairs-up,stairs-down,pallet,other")]
    terrains: Vec<Terrain>,
    /// Seconds between DEMs.
    #[arg(long, default_value_t = 0.4, value_parser = |s: &str| value::within(s, 1e-3, 60.0))]
    dt: f64,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = value::at_least_one::<usize>)]
    threads: Option<usize>,
    /// Dark or reflective patches per square metre.
    #[arg(long, default_value_t = 0.4, value_parser = |s: &str| value::within(s, 0.0, 100.0))]
    dark_patches: f64,
    /// Camera height above C (m, 0.05..=5).
    #[arg(long, default_value_t = 0.45, value_parser = |s: &str| value::within(s, 0.05, 5.0))]
    camera_height: f64,
    /// Camera offset ahead of C (m, -1..=1).
    #[arg(long, default_value_t = 0.15, allow_negative_numbers = true, value_parser = |s: &str| value::within(s, -1.0, 1.0))]
    camera_forward: f64,
    /// Camera tilt below the body axis (degrees, 0..=90: level to straight down).
    #[arg(long, default_value_t = 35.0, value_parser = |s: &str| value::within(s, 0.0, 90.0))]
    camera_tilt: f64,
    /// Map cells whose height variance exceeds this become holes (m^2).
    #[arg(long, default_value_t = 4e-4, value_parser = value::positive::<f64>)]
    max_variance: f64,
    /// Switch off the field of view and depth cutoffs (see every DEM cell).
    #[arg(long)]
    no_fov: bool,
    /// Switch off occlusion (rays pass through surfaces).
    #[arg(long)]
    no_occlusion: bool,
    /// Switch off range and lateral noise.
    #[arg(long)]
    no_noise: bool,
    /// Switch off stereo-window smoothing.
    #[arg(long)]
    no_smoothing: bool,
    /// Switch off dark patches.
    #[arg(long)]
    no_dropout: bool,
    /// Switch off the map's holes: no maximum variance, and one valid 5 cm
    /// map cell (of 4) is enough for a DEM cell.
    #[arg(long)]
    no_holes: bool,
    /// Switch off pose drift (the map believes the true pose).
    #[arg(long)]
    no_drift: bool,
    /// Pose drift: horizontal random walk, sd of x and y each per sqrt of
    /// the metres travelled (m/sqrt(m), 0..=1).
    #[arg(long, default_value_t = 0.02, value_name = "M", value_parser = |s: &str| value::within(s, 0.0, 1.0))]
    drift: f64,
    /// Pose drift: vertical random walk (m/sqrt(m), 0..=1).
    #[arg(long, default_value_t = 0.005, value_name = "M", value_parser = |s: &str| value::within(s, 0.0, 1.0))]
    drift_vertical: f64,
    /// Pose drift: heading random walk (degrees/sqrt(m), 0..=20).
    #[arg(long, default_value_t = 0.6, value_name = "DEG", value_parser = |s: &str| value::within(s, 0.0, 20.0))]
    drift_yaw: f64,
    /// Pose drift: factor on the drift while the tracks ride on an edge (a
    /// height step over 3 cm under them: stairs, pallets) (1..=20).
    #[arg(long, default_value_t = 3.0, value_name = "FACTOR", value_parser = |s: &str| value::within(s, 1.0, 20.0))]
    drift_slip: f64,
    /// Switch off latency (the DEM is of the current frame).
    #[arg(long)]
    no_latency: bool,
    /// Latency: the DEM handed out is the map of the frame taken this many
    /// seconds earlier, cut around that pose (s, 0..=2).
    #[arg(long, default_value_t = 0.15, value_name = "S", value_parser = |s: &str| value::within(s, 0.0, 2.0))]
    latency: f64,
    /// Switch off the camera mount's miscalibration.
    #[arg(long)]
    no_extrinsic: bool,
    /// Miscalibrated mount: sd of the camera's true pitch and roll against
    /// the nominal, drawn once per run (degrees, 0..=10).
    #[arg(long, default_value_t = 0.5, value_name = "DEG", value_parser = |s: &str| value::within(s, 0.0, 10.0))]
    extrinsic: f64,
    /// Switch off vibration (rays cast with the estimated attitude).
    #[arg(long)]
    no_vibration: bool,
    /// Vibration: sd of the body's true pitch and roll against the
    /// estimate per frame on even ground (degrees, 0..=10).
    #[arg(long, default_value_t = 0.1, value_name = "DEG", value_parser = |s: &str| value::within(s, 0.0, 10.0))]
    vibration: f64,
    /// Vibration: extra sd per metre of height step under the tracks
    /// (degrees/m, 0..=100; 4: +0.7 degree on a 0.17 m stair edge).
    #[arg(long, default_value_t = 4.0, value_name = "DEG", value_parser = |s: &str| value::within(s, 0.0, 100.0))]
    vibration_edge: f64,
    /// Switch off the map's memory: each DEM is the fusion of its own
    /// frame's points alone (the cells no ray of the frame reaches are
    /// missing).
    #[arg(long)]
    no_memory: bool,
    /// Also write DIR/maps.npy ((M, 2, 80, 80) float32: elevation and
    /// variance of the 4 m elevation map window after each measured frame,
    /// grid_map's unwrapped index order, NaN where invalid) and DIR/maps.csv
    /// (window centre and the pose the DEM was cut around per map, full
    /// precision). Changes no other output.
    #[arg(long)]
    emit_maps: bool,
}

fn main() -> ExitCode {
    cli::run(|| {
        let a: Args = cli::parse();
        if a.first_run == 0 && a.real_runs > a.runs {
            return Err(cli::usage(format!("--real-runs {} is more than --runs {}", a.real_runs, a.runs)));
        }
        if let Some(n) = a.threads {
            rayon::ThreadPoolBuilder::new().num_threads(n).build_global()?;
        }
        let camera =
            CameraConfig { height: a.camera_height, forward: a.camera_forward, tilt_deg: a.camera_tilt, ..CameraConfig::default() };
        let stages = Stages {
            fov: !a.no_fov,
            occlusion: !a.no_occlusion,
            noise: !a.no_noise,
            smoothing: !a.no_smoothing,
            dropout: !a.no_dropout,
            holes: !a.no_holes,
            drift: !a.no_drift,
            latency: !a.no_latency,
            extrinsic: !a.no_extrinsic,
            vibration: !a.no_vibration,
            memory: !a.no_memory,
        };
        let drift = DriftConfig {
            horizontal: a.drift,
            vertical: a.drift_vertical,
            yaw: a.drift_yaw.to_radians(),
            slip: a.drift_slip,
            ..DriftConfig::default()
        };
        let vibration = VibrationConfig { flat: a.vibration.to_radians(), per_edge: a.vibration_edge.to_radians() };
        let map = MapConfig { max_variance: a.max_variance, ..MapConfig::default() };
        let cfg = DatasetConfig {
            first_run: a.first_run,
            runs: a.runs,
            real_runs: a.real_runs,
            terrains: a.terrains,
            run: RunConfig {
                seed: a.seed,
                dt: a.dt,
                dark_patch_density: a.dark_patches,
                camera,
                map,
                stages,
                drift,
                latency: a.latency,
                extrinsic: a.extrinsic.to_radians(),
                vibration,
                emit_maps: a.emit_maps,
            },
        };
        let bar = cli::progress(cfg.runs, "runs");
        let started = std::time::Instant::now();
        let summary = synth::generate(&cfg, &a.out, |done| bar.set_position(done))?;
        bar.finish_and_clear();
        let secs = started.elapsed().as_secs_f64();
        for (t, (s, r)) in &summary.per_terrain {
            cli::log(format_args!("{t:>11}: {s} sim, {r} real"));
        }
        cli::log(format_args!(
            "wrote {} sim and {} real records to {} in {secs:.1} s ({:.0} records/s)",
            summary.sim,
            summary.real,
            a.out.display(),
            (summary.sim + summary.real) as f64 / secs
        ));
        Ok(())
    })
}
