//! A fit evaluates hundreds of parameter points of one candidate on top of
//! the same base model. The base effects that act before the candidate
//! ([`SensorModel::with`] inserts it after every effect of an earlier or
//! equal stage) give the same output at every point, so they are applied
//! once and each point applies only the candidate and the effects after it.
//!
//! The result is the same, bit for bit, as applying the whole model: each
//! effect's draws come from its own stream, keyed by its name, its
//! occurrence among effects of that name and the record
//! ([`dem_sensor::effect_rng`]), not by its position; splitting the model
//! keeps every occurrence count when no name of the part applied later
//! also occurs in the part applied first (otherwise the whole model is
//! applied at every point).

use dem_core::format::Dem;
use dem_sensor::{Effect, SensorModel};

use super::Target;

/// The base model's output before a candidate's place, ready for every
/// parameter point of that candidate.
pub struct Prepared<'a> {
    target: &'a Target<'a>,
    base: &'a SensorModel,
    /// None when the model cannot be split there.
    split: Option<Split>,
}

/// What every parameter point of a candidate shares when the model splits
/// at its place.
struct Split {
    /// Where the candidate goes in the base model.
    at: usize,
    /// The candidate's name.
    name: &'static str,
    /// The sim records after `base.effects[..at]`.
    before: Vec<Dem>,
    /// Each sim record's draws of the candidate and the effects after it:
    /// the same at every parameter point of the same memory, so drawn once.
    drawn: Vec<f32>,
    /// The probe's memory ([`Effect::memory`]), which `drawn` follows.
    memory: Option<f64>,
}

/// Where [`SensorModel::with`] inserts `e` into `base`.
fn place(base: &SensorModel, e: &Effect) -> usize {
    base.effects.iter().position(|x| x.stage() > e.stage()).unwrap_or(base.effects.len())
}

/// `e` followed by the effects of `base` from `at` on.
fn rest(base: &SensorModel, at: usize, e: Effect) -> SensorModel {
    SensorModel::new(std::iter::once(e).chain(base.effects[at..].iter().cloned()).collect())
}

impl<'a> Prepared<'a> {
    /// Apply the part of `base` before `probe`'s place once (`probe`: any
    /// parameter point of the candidate; its name decides the place).
    pub fn new(target: &'a Target<'a>, base: &'a SensorModel, probe: &Effect) -> Self {
        let at = place(base, probe);
        let (first, later) = base.effects.split_at(at);
        let shared = later.iter().chain(std::iter::once(probe)).any(|l| first.iter().any(|f| f.name() == l.name()));
        let split = (!shared).then(|| {
            let mut before = target.sim.to_vec();
            SensorModel::new(first.to_vec()).apply_all_at(&mut before, target.seed, 0, target.moments);
            let drawn = rest(base, at, *probe).uniforms_of(target.seed, 0, target.sim.len(), target.moments);
            Split { at, name: probe.name(), before, drawn, memory: probe.memory() }
        });
        Prepared { target, base, split }
    }

    /// [`Target::gap`] of `base` with `e` added.
    pub fn gap(&self, e: Effect) -> f64 {
        let split = match &self.split {
            Some(s) if place(self.base, &e) == s.at && e.name() == s.name => s,
            _ => return self.target.gap(&self.base.with(e)),
        };
        let rest = rest(self.base, split.at, e);
        // A map's memory makes the draws depend on its time constant.
        let redrawn =
            (e.memory() != split.memory).then(|| rest.uniforms_of(self.target.seed, 0, self.target.sim.len(), self.target.moments));
        self.target.gap_of(&self.target.stats_after(&split.before, &rest, Some(redrawn.as_deref().unwrap_or(&split.drawn))))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::distribution::stats;
    use dem_core::format::{col_center_y, empty_dem, row_center_x, DemCells, COLS, GRID_ROWS};
    use dem_sensor::effects::{Bias, Dropout, EdgeHoles, Fov, Noise, Occlusion, RowDropout, Smoothing};

    /// Stairs with a missing cell, a few records apart in height.
    fn records(n: usize) -> Vec<Dem> {
        (0..n)
            .map(|i| {
                let mut d = empty_dem();
                for r in 0..GRID_ROWS {
                    for c in 0..COLS {
                        let step = if row_center_x(r) > 0.3 { 0.17 } else { 0.0 };
                        d.set_valid(r, c, (step - 0.07 + 0.01 * i as f64 + 0.001 * col_center_y(c)) as f32);
                    }
                }
                d.set_missing(3 + i % 5, i % COLS);
                d
            })
            .collect()
    }

    #[test]
    fn the_split_model_gives_the_whole_model_s_gap_bit_for_bit() {
        let sim = records(40);
        let mut real_recs = sim.clone();
        SensorModel::new(vec![Effect::Noise(Noise { sigma0: 0.004, k: 0.01, tau: 0.0 }), Effect::Dropout(Dropout { p: 0.1 })]).apply_all(
            &mut real_recs,
            9,
            0,
        );
        for paired in [true, false] {
            let real = stats(&real_recs, paired.then_some(sim.as_slice()));
            let target = Target { sim: &sim, moments: None, steps: None, paired, real: &real, seed: 3 };
            let base = SensorModel::new(vec![
                Effect::Occlusion(Occlusion { h: 0.5, x0: 0.1 }),
                Effect::Smoothing(Smoothing { w: 0.6 }),
                Effect::Noise(Noise { sigma0: 0.002, k: 0.0, tau: 0.0 }),
                Effect::RowDropout(RowDropout { p: 0.05 }),
            ]);
            for e in [
                Effect::Dropout(Dropout { p: 0.07 }),
                Effect::Bias(Bias { b: 0.01, t: 0.0 }),
                Effect::EdgeHoles(EdgeHoles { g: 0.1, p: 0.5 }),
                Effect::Fov(Fov { x_min: -0.3, x_max: 1.2 }),
                // A second noise: the model cannot be split after the first.
                Effect::Noise(Noise { sigma0: 0.001, k: 0.002, tau: 0.0 }),
            ] {
                let prepared = Prepared::new(&target, &base, &e);
                let (split, whole) = (prepared.gap(e), target.gap(&base.with(e)));
                assert_eq!(split.to_bits(), whole.to_bits(), "{e}, paired {paired}: {split} vs {whole}");
            }
        }
    }
}
