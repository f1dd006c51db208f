//! The training set (sims, reals, pairs by key and split) and how each step
//! draws its batch, from the seed and the step number alone (so a resumed
//! run draws exactly what the uninterrupted one would have).
//!
//! An epoch is `ceil(n_sim / batch)` steps. Each batch's first
//! `round(batch * paired_fraction)` rows are train pairs (a sim key and one
//! of its reals, drawn from a per-epoch permutation of the keys); the other
//! rows take sims and reals from per-epoch permutations of all records.
//!
//! Layer 5 (train), the top: may use net, layers, weights and gemm.

use std::collections::BTreeMap;

use dem_core::format::GRID_LEN;
use dem_core::table::{Pair, Split};
use dem_core::{Dem, DemError};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::cyclegan::Batch;

/// Sim key with all its reals.
pub type KeyReals = (usize, Vec<usize>);

/// Sims, reals and the pairs, grouped by sim key.
#[derive(Debug)]
pub struct TrainData {
    /// Sim records (X).
    pub sim: Vec<Dem>,
    /// Real records (Y).
    pub real: Vec<Dem>,
    /// Keys of the train split (pairs without a split are train).
    pub train: Vec<KeyReals>,
    /// Keys of the val split.
    pub val: Vec<KeyReals>,
}

fn group(pairs: &[Pair], split: Split) -> Vec<KeyReals> {
    let mut m: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for p in pairs.iter().filter(|p| p.split.unwrap_or(Split::Train) == split) {
        m.entry(p.sim_index as usize).or_default().push(p.real_index as usize);
    }
    m.into_iter().collect()
}

impl TrainData {
    /// Check and group; the paths name the files in errors.
    pub fn new(sim: Vec<Dem>, real: Vec<Dem>, pairs: &[Pair], paths: [&str; 3]) -> Result<Self, DemError> {
        let [sim_path, real_path, pairs_path] = paths;
        for (v, path) in [(&sim, sim_path), (&real, real_path)] {
            if v.is_empty() {
                return Err(DemError::Input { path: path.into(), reason: "no records: nothing to train on".into() });
            }
        }
        for (i, p) in pairs.iter().enumerate() {
            let line = i as u64 + 2;
            if p.sim_index as usize >= sim.len() {
                return Err(DemError::Table {
                    path: pairs_path.into(),
                    line,
                    reason: format!("sim_index {} is past the {} records of {sim_path}", p.sim_index, sim.len()),
                });
            }
            if p.real_index as usize >= real.len() {
                return Err(DemError::Table {
                    path: pairs_path.into(),
                    line,
                    reason: format!("real_index {} is past the {} records of {real_path}", p.real_index, real.len()),
                });
            }
        }
        Ok(TrainData { train: group(pairs, Split::Train), val: group(pairs, Split::Val), sim, real })
    }

    /// Steps in one epoch at `batch`.
    pub fn steps_per_epoch(&self, batch: usize) -> u64 {
        self.sim.len().div_ceil(batch) as u64
    }
}

/// How batches are drawn.
#[derive(Clone, Copy, Debug)]
pub struct Sampler {
    /// Seed of every draw.
    pub seed: u64,
    /// Records per batch.
    pub batch: usize,
    /// Share of each batch taken from train pairs (0 without pairs).
    pub paired_fraction: f64,
}

impl Sampler {
    /// Records per batch when a run does not say (the thesis's setting).
    pub const DEFAULT_BATCH: usize = 64;
    /// Share of each batch from train pairs when a run does not say: half,
    /// so the unpaired Cycle GAN terms see as many records as the paired.
    pub const DEFAULT_PAIRED_FRACTION: f64 = 0.5;
}

// Stream numbers: one per step for the step's draws, and a separate range
// for the per-epoch permutations.
const PERM_STREAM: u64 = 1 << 48;

impl Sampler {
    fn perm(&self, n: usize, epoch: u64, which: u64) -> Vec<usize> {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        rng.set_stream(PERM_STREAM + epoch * 4 + which);
        let mut v: Vec<usize> = (0..n).collect();
        v.shuffle(&mut rng);
        v
    }

    /// Paired rows per batch.
    pub fn paired_rows(&self, data: &TrainData) -> usize {
        if data.train.is_empty() {
            0
        } else {
            ((self.batch as f64 * self.paired_fraction).round() as usize).min(self.batch)
        }
    }

    /// The batch of global step `step` (0-based), `k` of its epoch.
    pub fn batch<'a>(&self, data: &'a TrainData, step: u64, steps_per_epoch: u64) -> Batch<'a> {
        let (epoch, k) = (step / steps_per_epoch, (step % steps_per_epoch) as usize);
        let np = self.paired_rows(data);
        let nu = self.batch - np;
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        rng.set_stream(step);
        let mut x: Vec<&Dem> = Vec::with_capacity(self.batch);
        let mut y: Vec<&Dem> = Vec::with_capacity(self.batch);
        let mut pairs = Vec::with_capacity(np);
        if np > 0 {
            let keys = self.perm(data.train.len(), epoch, 0);
            for j in 0..np {
                let (key, reals) = &data.train[keys[(k * np + j) % keys.len()]];
                x.push(&data.sim[*key]);
                y.push(&data.real[reals[rng.gen_range(0..reals.len())]]);
                pairs.push(reals.iter().map(|&r| &data.real[r][..GRID_LEN]).collect());
            }
        }
        if nu > 0 {
            let sims = self.perm(data.sim.len(), epoch, 1);
            let reals = self.perm(data.real.len(), epoch, 2);
            for j in 0..nu {
                x.push(&data.sim[sims[(k * nu + j) % sims.len()]]);
                y.push(&data.real[reals[(k * nu + j) % reals.len()]]);
            }
        }
        Batch::new(&x, &y, pairs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::format::RECORD_LEN;

    fn rec(v: f32) -> Dem {
        let mut d = [0.0; RECORD_LEN];
        d[0] = v;
        d
    }

    fn data() -> TrainData {
        let sim: Vec<Dem> = (0..20).map(|i| rec(i as f32)).collect();
        let real: Vec<Dem> = (0..6).map(|i| rec(100.0 + i as f32)).collect();
        let pairs: Vec<Pair> = (0..6)
            .map(|i| Pair { sim_index: i, real_index: i, split: Some(if i < 4 { Split::Train } else { Split::Val }), distance: None })
            .collect();
        TrainData::new(sim, real, &pairs, ["s", "r", "p"]).unwrap()
    }

    #[test]
    fn batches_depend_only_on_seed_and_step_and_pair_rows_match() {
        let d = data();
        let s = Sampler { seed: 7, batch: 4, paired_fraction: 0.5 };
        let spe = d.steps_per_epoch(4);
        assert_eq!(spe, 5);
        let a = s.batch(&d, 3, spe);
        let b = s.batch(&d, 3, spe);
        assert_eq!(a.x_grid, b.x_grid);
        assert_eq!(a.y_grid, b.y_grid);
        assert_eq!(a.pairs.len(), 2);
        for i in 0..2 {
            // Paired rows: sim key k (value k) with real k (value 100 + k), train keys only.
            let (xv, yv) = (a.x_grid[i * GRID_LEN], a.y_grid[i * GRID_LEN]);
            assert_eq!(yv, 100.0 + xv);
            assert!(xv < 4.0);
        }
    }

    #[test]
    fn pairs_past_the_data_are_refused_naming_the_line() {
        let pairs = vec![Pair { sim_index: 0, real_index: 9, split: None, distance: None }];
        let e = TrainData::new(vec![rec(0.0)], vec![rec(1.0)], &pairs, ["s.npy", "r.npy", "p.csv"]).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("p.csv") && msg.contains("line 2") && msg.contains("real_index 9"), "{msg}");
    }
}
