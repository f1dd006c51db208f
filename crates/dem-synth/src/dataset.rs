//! A data set of many runs, simulated in parallel and written in run order:
//! `sim.npy` + `sim_labels.csv` (every run), `real.npy` + `real_labels.csv`
//! (measured runs), and `pairs.csv`, the true pairs (same pose) of sim and
//! real records. The output is the same for any thread count.
//!
//! With [`RunConfig::emit_maps`](super::RunConfig::emit_maps), also
//! `maps.npy` and `maps.csv`: the 5 cm elevation map window after every
//! measured frame, one per real record in the same order (see [`MapsOut`]).

use std::collections::BTreeMap;
use std::path::Path;

use rayon::prelude::*;

use super::elevation_map::MapWindow;
use super::pose::Pose;
use super::run::{simulate, RunConfig};
use dem_core::error::{DemError, Result};
use dem_core::format::Terrain;
use dem_core::npy::{self, F32ArrayWriter};
use dem_core::output::AtomicOutput;
use dem_core::table::{Label, Pair};

/// What to generate.
#[derive(Debug, Clone)]
pub struct DatasetConfig {
    /// Index of the first run to make (0 for a whole world; a shard of a
    /// world starts later): run i depends on the seed and i only.
    pub first_run: u64,
    /// Runs to make, from `first_run`; every run gives sim records.
    pub runs: u64,
    /// Runs 0..real_runs of the world are also measured (real records).
    pub real_runs: u64,
    /// Terrains, cycled over the runs (run i has terrain i mod len).
    pub terrains: Vec<Terrain>,
    /// Per-run settings.
    pub run: RunConfig,
}

/// Counts of what was written.
#[derive(Debug, Clone, Default)]
pub struct Summary {
    /// Sim records.
    pub sim: u64,
    /// Real (measured) records.
    pub real: u64,
    /// Sim and real records per terrain.
    pub per_terrain: BTreeMap<Terrain, (u64, u64)>,
}

/// Runs simulated together; bounds memory to a batch.
const BATCH: u64 = 32;

struct CsvOut<T> {
    w: csv::Writer<AtomicOutput>,
    path: String,
    _row: std::marker::PhantomData<T>,
}

impl<T: serde::Serialize> CsvOut<T> {
    fn create(path: String) -> Result<Self> {
        Ok(CsvOut { w: csv::Writer::from_writer(AtomicOutput::create(&path)?), path, _row: Default::default() })
    }
    fn row(&mut self, row: &T) -> Result<()> {
        self.w.serialize(row).map_err(|e| DemError::io(self.path.as_str(), std::io::Error::other(e)))
    }
    fn commit(self) -> Result<()> {
        let path = self.path;
        self.w.into_inner().map_err(|e| DemError::io(path.as_str(), e.into_error()))?.commit()
    }
}

/// `maps.npy` + `maps.csv` of `--emit-maps`.
///
/// - `maps.npy`: `<f4` `(M, 2, n, n)`, n = [`MapConfig::window_cells`](super::MapConfig::window_cells)
///   (80): record k holds the [`MapWindow`] of real record k, layer 0 its
///   elevation (world z, NaN where invalid), layer 1 its variance (NaN where
///   never seen), `[k, layer, i, j]` at grid_map's unwrapped index (i, j)
///   (i = 0 at the largest x, j = 0 at the largest y).
/// - `maps.csv`: `index,sequence,time,center_x,center_y,resolution,x,y,z,yaw,pitch,
///   flipper_fl,flipper_fr,flipper_rl,flipper_rr`: `index` the real record,
///   `sequence` the run, `time` as in `real_labels.csv`, then the window's
///   centre and resolution and the robot's pose the DEM was cut around
///   ([`Step::map_pose`](super::run::Step::map_pose): with drift and
///   latency, the believed pose at the frame; pitch and flippers the
///   current ones), at full precision (Rust's shortest round-trip
///   formatting of f64).
pub struct MapsOut {
    npy: F32ArrayWriter,
    csv: csv::Writer<AtomicOutput>,
    csv_path: String,
    cells: usize,
    record: Vec<f32>,
}

/// Header of `maps.csv`.
pub const MAPS_CSV_HEADER: [&str; 15] = [
    "index",
    "sequence",
    "time",
    "center_x",
    "center_y",
    "resolution",
    "x",
    "y",
    "z",
    "yaw",
    "pitch",
    "flipper_fl",
    "flipper_fr",
    "flipper_rl",
    "flipper_rr",
];

impl MapsOut {
    /// Start `dir/maps.npy` and `dir/maps.csv` for windows of `cells` x `cells`.
    pub fn create(dir: &Path, cells: usize) -> Result<Self> {
        let path = |name: &str| dir.join(name).to_string_lossy().into_owned();
        let n = cells as u64;
        let npy = F32ArrayWriter::create(&path("maps.npy"), &[2, n, n])?;
        let csv_path = path("maps.csv");
        let mut csv = csv::Writer::from_writer(AtomicOutput::create(&csv_path)?);
        csv.write_record(MAPS_CSV_HEADER).map_err(|e| DemError::io(csv_path.as_str(), std::io::Error::other(e)))?;
        Ok(MapsOut { npy, csv, csv_path, cells, record: Vec::with_capacity(2 * cells * cells) })
    }

    /// Append the window of real record `index` (run `sequence`, `time` s
    /// into it, the robot at `pose`).
    pub fn write(&mut self, index: u64, sequence: u64, time: f64, pose: &Pose, map: &MapWindow) -> Result<()> {
        assert_eq!(map.cells, self.cells, "map window size");
        self.record.clear();
        self.record.extend_from_slice(&map.elevation);
        self.record.extend_from_slice(&map.variance);
        self.npy.write(&self.record)?;
        let f = pose.flippers;
        let row = [index.to_string(), sequence.to_string()].into_iter().chain(
            [time, map.center_x, map.center_y, map.resolution, pose.x, pose.y, pose.z, pose.yaw, pose.pitch, f[0], f[1], f[2], f[3]]
                .map(|v| format!("{v}")),
        );
        self.csv.write_record(row).map_err(|e| DemError::io(self.csv_path.as_str(), std::io::Error::other(e)))
    }

    /// Complete both files.
    pub fn finish(self) -> Result<()> {
        self.npy.finish()?;
        let path = self.csv_path;
        self.csv.into_inner().map_err(|e| DemError::io(path.as_str(), e.into_error()))?.commit()
    }
}

/// Generate the data set into `dir`; `progress` is called with the number
/// of runs finished so far.
pub fn generate(cfg: &DatasetConfig, dir: &Path, progress: impl Fn(u64)) -> Result<Summary> {
    if cfg.terrains.is_empty() {
        return Err(DemError::Usage("no terrains to simulate".into()));
    }
    std::fs::create_dir_all(dir).map_err(|source| DemError::Open { path: dir.display().to_string(), source })?;
    let path = |name: &str| dir.join(name).to_string_lossy().into_owned();
    let mut sim = npy::create(&path("sim.npy"))?;
    let mut real = npy::create(&path("real.npy"))?;
    let mut sim_labels = CsvOut::<Label>::create(path("sim_labels.csv"))?;
    let mut real_labels = CsvOut::<Label>::create(path("real_labels.csv"))?;
    let mut pairs = CsvOut::<Pair>::create(path("pairs.csv"))?;
    let mut maps = if cfg.run.emit_maps { Some(MapsOut::create(dir, cfg.run.map.window_cells())?) } else { None };
    let mut summary = Summary::default();

    let last = cfg.first_run + cfg.runs;
    let mut start = cfg.first_run;
    while start < last {
        let end = (start + BATCH).min(last);
        let runs: Vec<_> = (start..end)
            .into_par_iter()
            .map(|i| {
                let terrain = cfg.terrains[(i % cfg.terrains.len() as u64) as usize];
                (i, simulate(&cfg.run, i, terrain, i < cfg.real_runs))
            })
            .collect();
        for (i, run) in runs {
            let counts = summary.per_terrain.entry(run.terrain).or_default();
            for step in &run.steps {
                let label = |index| Label {
                    index,
                    terrain: run.terrain,
                    x: Some(round(step.pose.x)),
                    y: Some(round(step.pose.y)),
                    yaw: Some(round(step.pose.yaw)),
                    sequence: Some(i),
                    time: Some(round(step.time)),
                };
                sim.write(std::slice::from_ref(&step.sim))?;
                sim_labels.row(&label(summary.sim))?;
                if let Some(m) = &step.measured {
                    real.write(std::slice::from_ref(m))?;
                    real_labels.row(&label(summary.real))?;
                    pairs.row(&Pair { sim_index: summary.sim, real_index: summary.real, split: None, distance: None })?;
                    if let Some(maps) = maps.as_mut() {
                        let map = step.map.as_ref().expect("a measured step keeps its map with emit_maps");
                        let pose = step.map_pose.as_ref().expect("a measured step has the pose its DEM was cut around");
                        maps.write(summary.real, i, round(step.time), pose, map)?;
                    }
                    summary.real += 1;
                    counts.1 += 1;
                }
                summary.sim += 1;
                counts.0 += 1;
            }
        }
        progress(end - cfg.first_run);
        start = end;
    }
    sim.finish()?;
    real.finish()?;
    sim_labels.commit()?;
    real_labels.commit()?;
    pairs.commit()?;
    if let Some(maps) = maps {
        maps.finish()?;
    }
    Ok(summary)
}

/// Labels keep micrometres: enough for pose matching, short CSV lines.
fn round(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}
