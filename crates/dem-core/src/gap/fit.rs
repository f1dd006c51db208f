//! Fitting one candidate effect: a grid search over its parameter box,
//! refined four times around the best point, of the gap between
//! model(sim) with the candidate added and real. Every evaluation uses the
//! same random streams (the seed), so the gap changes with the parameters,
//! not with the draws.

use rayon::prelude::*;

use crate::format::{row_center_x, Dem, GRID_ROWS};
use crate::sensor::{Effect, SensorModel};

use super::stats::{gap, stats, Stats};

/// One parameter's search range; `log` searches log(value).
#[derive(Debug, Clone, Copy)]
pub struct Range {
    /// Smallest value searched.
    pub lo: f64,
    /// Largest value searched.
    pub hi: f64,
    /// Search on a log scale.
    pub log: bool,
}

const fn lin(lo: f64, hi: f64) -> Range {
    Range { lo, hi, log: false }
}

/// The box searched for each effect (parameters in [`Effect::params`] order).
pub fn ranges(name: &str) -> Vec<Range> {
    match name {
        "noise" => vec![lin(0.0, 0.03), lin(0.0, 0.03)],
        "dropout" | "row-dropout" => vec![lin(0.0, 0.6)],
        // A sensor mounted on the robot: above C by 0.2 to 1.2 m, along x
        // within the tracks and flippers.
        "occlusion" => vec![lin(0.2, 1.2), lin(-0.4, 0.5)],
        "fov" => vec![lin(-0.65, 0.55), lin(0.35, 1.45)],
        "smoothing" => vec![lin(0.05, 1.0)],
        "bias" => vec![lin(-0.1, 0.1), lin(-0.1, 0.1)],
        "quantization" => vec![Range { lo: 0.002, hi: 0.05, log: true }],
        _ => vec![],
    }
}

impl Range {
    fn at(&self, u: f64) -> f64 {
        let u = u.clamp(0.0, 1.0);
        if self.log {
            (self.lo.ln() + u * (self.hi.ln() - self.lo.ln())).exp()
        } else {
            self.lo + u * (self.hi - self.lo)
        }
    }
}

/// The data a fit compares against: sim records (a subsample), their
/// paired real records' statistics or the real set's statistics.
pub struct Target<'a> {
    /// Sim records to push through the model.
    pub sim: &'a [Dem],
    /// True when `sim[i]` is paired with the i-th real record of `real`.
    pub paired: bool,
    /// Statistics of the real records.
    pub real: &'a Stats,
    /// Seed of the model's random effects.
    pub seed: u64,
}

impl Target<'_> {
    /// Statistics of model(sim).
    pub fn model_stats(&self, model: &SensorModel) -> Stats {
        let mut out = self.sim.to_vec();
        model.apply_all(&mut out, self.seed, 0);
        stats(&out, self.paired.then_some(self.sim))
    }

    /// Gap of model(sim) against real.
    pub fn gap(&self, model: &SensorModel) -> f64 {
        gap(&self.model_stats(model), self.real)
    }
}

/// A fitted candidate.
#[derive(Debug, Clone)]
pub struct Fitted {
    /// The effect with its fitted parameters.
    pub effect: Effect,
    /// Gap on the fitting subsample with the effect added.
    pub gap: f64,
}

/// Fit effect `name` on top of `base` by grid search plus refinement.
pub fn fit(name: &str, base: &SensorModel, target: &Target) -> Option<Fitted> {
    let ranges = ranges(name);
    let dims = ranges.len();
    let eval = |u: &[f64]| -> f64 {
        let v: Vec<f64> = u.iter().zip(&ranges).map(|(&u, r)| r.at(u)).collect();
        match Effect::from_values(name, &v) {
            Some(e) if e.check().is_ok() => target.gap(&base.with(e)),
            _ => f64::INFINITY,
        }
    };
    let n = match (name, dims) {
        ("occlusion", _) => 13,
        // Rounding makes the gap spiky in q (flat ground at -0.07 lands on
        // another multiple for a 3 % change of q): a fine grid.
        ("quantization", _) => 121,
        (_, 1) => 41,
        _ => 9,
    };
    let grid = |centre: &[f64], step: f64, per: usize| -> Vec<Vec<f64>> {
        let mut pts = vec![vec![]];
        for &c in centre.iter().take(dims) {
            let offsets: Vec<f64> = (0..per).map(|i| c + step * (i as f64 - (per - 1) as f64 / 2.0)).collect();
            pts = pts
                .into_iter()
                .flat_map(|p| offsets.iter().filter(|u| (-1e-9..=1.0 + 1e-9).contains(*u)).map(move |&u| [p.clone(), vec![u]].concat()))
                .collect();
        }
        pts
    };
    let best_of = |pts: Vec<Vec<f64>>| -> Option<(Vec<f64>, f64)> {
        pts.into_par_iter().map(|p| {
            let g = eval(&p);
            (p, g)
        }).min_by(|a, b| a.1.total_cmp(&b.1).then_with(|| a.0.partial_cmp(&b.0).unwrap_or(std::cmp::Ordering::Equal)))
    };
    let (mut best, mut best_gap) = best_of(grid(&vec![0.5; dims], 1.0 / (n - 1) as f64, n))?;
    let mut step = 1.0 / (n - 1) as f64 / 2.0;
    for _ in 0..4 {
        if let Some((p, g)) = best_of(grid(&best, step, 5)) {
            if g < best_gap {
                (best, best_gap) = (p, g);
            }
        }
        step /= 2.0;
    }
    let v: Vec<f64> = best.iter().zip(&ranges).map(|(&u, r)| r.at(u)).collect();
    let effect = snap(Effect::from_values(name, &v)?);
    Some(Fitted { effect, gap: best_gap })
}

/// fov acts on row centres only, so any x_min between two centres gives the
/// same output: report the row boundary between them (the midpoint).
fn snap(e: Effect) -> Effect {
    match e {
        Effect::Fov { x_min, x_max } => {
            let below = (0..GRID_ROWS).filter(|&r| row_center_x(r) < x_min).count();
            let upto = (0..GRID_ROWS).filter(|&r| row_center_x(r) <= x_max).count();
            let b = |k: usize| ((-0.6 + 0.1 * k as f64) * 1000.0).round() / 1000.0;
            Effect::Fov { x_min: b(below), x_max: b(upto).max(b(below) + 0.1) }
        }
        other => other,
    }
}
