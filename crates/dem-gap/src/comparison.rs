//! model(sim) measured against real, and what one run holds fixed while
//! it does so (`Comparison`): real's statistics, the sampling floor of
//! the split, the two halves the gains must hold on and the fitting
//! subsample. The loop's steps ([`crate::search`], [`crate::ties`]) all
//! measure against these, so they are taken once.

use std::borrow::Cow;
use std::sync::OnceLock;

use rand::seq::index::sample;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use dem_core::distribution::{gap, Stats};
use dem_core::format::Dem;
use dem_sensor::effects::{EffectSpec, Stage};
use dem_sensor::SensorModel;

use crate::fit;
use crate::held_out::HeldOut;
use crate::load::{pick, GapConfig, Sets};
use crate::measurement::{measure_at, summarise};
use crate::sampling::{draw_floor, real_halves, sampling_floor, sim_halves, Half};
use dem_core::temporal::Step;
use dem_sensor::Moment;

/// One run's comparison of model(sim) with real.
pub(crate) struct Comparison<'a> {
    pub cfg: &'a GapConfig,
    pub sets: &'a Sets,
    /// Compared per position.
    pub paired: bool,
    /// Each sim record's time in its run, when the labels give it.
    pub moments: Option<&'a [Moment]>,
    /// The steps of the sim records' runs, when the frame terms count.
    pub steps: Option<&'a [Step]>,
    /// Statistics of real (residuals against sim when paired).
    pub real: Stats,
    /// Unpaired, the sampling floor of two halves of real
    /// ([`sampling_floor`]); 0 paired.
    pub split_floor: f64,
    /// Sim-side records of each half, with their steps when the frame
    /// terms count, and real's statistics on it ([`comparison_halves`]).
    halves: Vec<Half>,
    /// The same halves for re-fits held out ([`Self::held_out`]), made
    /// when a step first falls below the floor: most runs never do.
    held_out: OnceLock<HeldOut>,
    /// The records the candidates are fitted on.
    fit_sim: Vec<Dem>,
    fit_moments: Option<Vec<Moment>>,
    fit_steps: Option<Vec<Step>>,
    /// Real's statistics on the fitting subsample (all of real unpaired).
    fit_real: Stats,
    /// Unpaired, and the fitting subsample is not all of sim.
    subsampled: bool,
}

impl<'a> Comparison<'a> {
    /// True when the run may fit `spec`: an effect that moves whole
    /// records only where both sides hold the same terrain mix (paired,
    /// over pairs, drawn to one mix) or when the user asked for it.
    /// A map's memory only where the runs are known in time on both
    /// sides: it is judged on consecutive frames.
    pub fn fits(&self, spec: &EffectSpec) -> bool {
        let runs_known = dem_sensor::any_in_run(self.sets.sim_moments.as_deref()) && self.sets.real_steps.is_some();
        (!spec.whole_record || self.whole_record_left_out().is_none()) && (spec.stage != Stage::Memory || runs_known)
    }

    /// Why the effects that move whole records are left out, when they are.
    pub fn whole_record_left_out(&self) -> Option<&'static str> {
        self.sets.unmatched_mix.filter(|_| !self.cfg.whole_record)
    }

    /// The comparison of `sets` as `cfg` asks for it.
    pub fn new(cfg: &'a GapConfig, sets: &'a Sets) -> Comparison<'a> {
        let paired = sets.paired;
        let real = summarise(&sets.real, paired.then_some(&sets.sim[..]), sets.real_steps.as_deref());
        let split_floor = if paired { 0.0 } else { sampling_floor(sets) };
        let moments = sets.sim_moments.as_deref();
        let steps = sets.sim_steps.as_deref();
        let halves = comparison_halves(sets);
        let idx = fitting_subsample(cfg, sets.sim.len());
        let fit_sim = pick(&sets.sim, &idx);
        let fit_moments = moments.map(|t| pick(t, &idx));
        let fit_steps = sets.sim_steps_in(&idx);
        let fit_real = if paired { summarise(&pick(&sets.real, &idx), Some(&fit_sim), fit_steps.as_deref()) } else { real.clone() };
        let subsampled = !paired && idx.len() < sets.sim.len();
        Comparison {
            cfg,
            sets,
            paired,
            moments,
            steps,
            real,
            split_floor,
            halves,
            held_out: OnceLock::new(),
            fit_sim,
            fit_moments,
            fit_steps,
            fit_real,
            subsampled,
        }
    }

    /// model(sim) on all records with the draws of `seed`, and its statistics.
    pub fn measure(&self, model: &SensorModel, seed: u64) -> (Vec<Dem>, Stats) {
        measure_at(model, &self.sets.sim, self.moments, self.steps, self.paired, seed)
    }

    /// The gap of model(sim) with the draws of `seed` on all records.
    pub fn gap_with(&self, model: &SensorModel, seed: u64) -> f64 {
        gap(&self.measure(model, seed).1, &self.real)
    }

    /// The sampling floor of `model`: the larger of the split's and the
    /// model's own draws'.
    pub fn floor_of(&self, model: &SensorModel) -> f64 {
        self.split_floor.max(draw_floor(model, &self.sets.sim, self.moments, self.steps, self.paired, self.cfg.seed))
    }

    /// Whether `gap`, of `model`, is below the sampling floor: paired, the
    /// model's draws' floor; unpaired, the split's (the draws' floor is
    /// smaller there and costs two applications of the model).
    pub fn below_floor(&self, model: &SensorModel, gap: f64) -> bool {
        if self.paired {
            gap < self.floor_of(model)
        } else {
            gap < self.split_floor
        }
    }

    /// The halves ready for held-out re-fits ([`HeldOut`]).
    pub fn held_out(&self) -> &HeldOut {
        self.held_out.get_or_init(|| HeldOut::new(self.sets, &self.halves, self.cfg.fit_records, self.cfg.seed))
    }

    /// Statistics of model(sim) `out` on each half.
    pub fn half_stats(&self, out: &[Dem]) -> Vec<Stats> {
        self.halves
            .iter()
            .map(|h| {
                let sim_half = self.paired.then(|| pick(&self.sets.sim, &h.sim));
                summarise(&pick(out, &h.sim), sim_half.as_deref(), h.steps.as_deref())
            })
            .collect()
    }

    /// The gap on each half, of statistics per half from [`Self::half_stats`].
    pub fn half_gaps(&self, per_half: &[Stats]) -> Vec<f64> {
        self.halves.iter().zip(per_half).map(|(h, s)| gap(s, &h.real)).collect()
    }

    /// What the candidates are fitted against with `model` in place, whose
    /// statistics on all records are `all`.
    ///
    /// Unpaired on a subsample, real is moved by what the subsample's draw
    /// of records does to model(sim) at the current model
    /// (`Stats::shifted`), so a small gap is not drowned by the subsample's
    /// own sampling: on the emulator's dark-patch stage over 100 runs the
    /// right effect removed 11% of the gap on 1,000 records against all of
    /// real, 80% on all records.
    pub fn fitting_real(&self, model: &SensorModel, all: &Stats) -> Cow<'_, Stats> {
        if !self.subsampled {
            return Cow::Borrowed(&self.fit_real);
        }
        Cow::Owned(self.fit_real.shifted(all, &self.target(&self.fit_real).model_stats(model)))
    }

    /// The fitting subsample against `real` ([`Self::fitting_real`]).
    pub fn target<'s>(&'s self, real: &'s Stats) -> fit::Target<'s> {
        fit::Target {
            sim: &self.fit_sim,
            moments: self.fit_moments.as_deref(),
            steps: self.fit_steps.as_deref(),
            paired: self.paired,
            real,
            seed: self.cfg.seed,
        }
    }
}

/// Two halves of the comparison, sim half k against real half k, with
/// real's statistics on each; none with fewer than 100 real records.
/// Unpaired (and paired below the sampling floor), a gain must also hold
/// on both, replicates at half the size (whole sim when it is too small
/// to split); in both modes they tell a named effect from a close rival
/// ([`crate::Tie`]). Paired, sim record i is real record i's pair, and the
/// halves are real's (whole runs when labelled).
fn comparison_halves(sets: &Sets) -> Vec<Half> {
    if sets.real.len() < 100 {
        Vec::new()
    } else if sets.paired {
        real_halves(sets)
            .into_iter()
            .filter(|h| !h.is_empty())
            .map(|h| {
                let steps = sets.real_steps_in(&h);
                let real = summarise(&pick(&sets.real, &h), Some(&pick(&sets.sim, &h)), steps.as_deref());
                Half { sim: h, steps, real }
            })
            .collect()
    } else {
        let mut sh = sim_halves(sets);
        if sh.iter().any(Vec::is_empty) {
            sh = [(0..sets.sim.len()).collect(), (0..sets.sim.len()).collect()];
        }
        sh.into_iter()
            .zip(real_halves(sets))
            .map(|(s, r)| {
                let real = summarise(&pick(&sets.real, &r), None, sets.real_steps_in(&r).as_deref());
                Half { steps: sets.sim_steps_in(&s), sim: s, real }
            })
            .collect()
    }
}

/// The records the candidates are fitted on, of `n` sim records: a seeded
/// subsample of `cfg.fit_records`, ascending (all records when few).
fn fitting_subsample(cfg: &GapConfig, n: usize) -> Vec<usize> {
    let mut rng = ChaCha8Rng::seed_from_u64(dem_core::seeded::mix(cfg.seed ^ 0x5eed));
    let mut idx: Vec<usize> = if n > cfg.fit_records { sample(&mut rng, n, cfg.fit_records).into_vec() } else { (0..n).collect() };
    idx.sort_unstable();
    idx
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::measure;
    use dem_core::distribution;
    use dem_core::format::{empty_dem, DemCells};
    use dem_core::metric;
    use dem_sensor::effects::Noise;
    use dem_sensor::Effect;

    /// The point: the gap compares distributions, so sim with the
    /// right noise (other draws) beats noise-free sim, while the paired
    /// equation 7.1 error prefers the noise-free one.
    #[test]
    fn the_right_noise_lowers_the_gap_but_raises_equation_7_1() {
        let sim: Vec<Dem> = (0..400)
            .map(|i| {
                let mut d = empty_dem();
                for r in 0..20 {
                    for c in 0..5 {
                        d.set_valid(r, c, if r > 8 + i % 7 { 0.1 } else { -0.07 });
                    }
                }
                d
            })
            .collect();
        let noise = SensorModel::new(vec![Effect::Noise(Noise { sigma0: 0.004, k: 0.01, tau: 0.0 })]);
        let (real, _) = measure(&noise, &sim, true, 1);
        for paired in [true, false] {
            let rs = distribution::stats(&real, paired.then_some(&sim[..]));
            let (plain, s0) = measure(&SensorModel::default(), &sim, paired, 2);
            let (model, s1) = measure(&noise, &sim, paired, 2);
            assert!(gap(&s1, &rs) < 0.05 * gap(&s0, &rs), "paired {paired}: {} vs {}", gap(&s1, &rs), gap(&s0, &rs));
            let e = |p: &[Dem]| p.iter().zip(&real).map(|(p, y)| metric::dem_error(y, p)).sum::<f64>();
            assert!(e(&model) > e(&plain));
        }
    }
}
