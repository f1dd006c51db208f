//! A data set of many runs, simulated in parallel and written in run order:
//! `sim.npy` + `sim_labels.csv` (every run), `real.npy` + `real_labels.csv`
//! (measured runs), and `pairs.csv`, the true pairs (same pose) of sim and
//! real records. The output is the same for any thread count.

use std::collections::BTreeMap;
use std::path::Path;

use rayon::prelude::*;

use super::run::{simulate, RunConfig};
use crate::error::{DemError, Result};
use crate::format::Terrain;
use crate::npy;
use crate::output::AtomicOutput;
use crate::table::{Label, Pair};

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
    Ok(summary)
}

/// Labels keep micrometres: enough for pose matching, short CSV lines.
fn round(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}
