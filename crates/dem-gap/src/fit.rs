//! Fitting one candidate effect: a grid search over its parameter box,
//! refined around the best point (four times; for four parameters, whose
//! first grid is coarser, five times around each of its three best), of
//! the gap between
//! model(sim) with the candidate added and real. Every evaluation uses the
//! same random streams (the seed), so the gap changes with the parameters,
//! not with the draws.

use rayon::prelude::*;

use dem_core::format::{row_center_x, Dem, GRID_ROWS};
use dem_sensor::{Effect, SensorModel};

use dem_core::distribution::{gap, hides_too_much, stats, Stats};

mod prefix;

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
        "dropout" | "row-dropout" | "hole-growth" => vec![lin(0.0, 0.6)],
        // A sensor mounted on the robot: above C by 0.2 to 1.2 m, along x
        // within the tracks and flippers.
        "occlusion" => vec![lin(0.2, 1.2), lin(-0.4, 0.5)],
        "fov" => vec![lin(-0.65, 0.55), lin(0.35, 1.45)],
        // A camera 0.2-1.2 m above C whose top ray falls 0-60 degrees.
        "view-top" => vec![lin(0.1, 1.5), lin(0.0, 1.7)],
        "smoothing" => vec![lin(0.05, 1.0)],
        "bias" => vec![lin(-0.1, 0.1), lin(-0.1, 0.1)],
        "quantization" => vec![Range { lo: 0.002, hi: 0.05, log: true }],
        // x0, v, p: v is fitted when the records' times are known, p when
        // not (see `fit`).
        "startup" => vec![lin(-0.3, 1.2), lin(0.02, 0.6), lin(0.0, 0.6)],
        // A blob loses a cell when it covers three of its quarter-cell
        // centres: r from 4 cm (up to four cells around a corner, by the
        // quarters it covers); smaller is `dropout`'s business. a from none
        // to the whole way down to the lower x-neighbour.
        "patch-dropout" => vec![lin(0.0, 4.0), lin(0.04, 0.25), lin(0.0, 1.0)],
        "edge-holes" | "rim-holes" | "pit-fill" => vec![lin(0.02, 0.3), lin(0.0, 1.0)],
        // Reaches from none (the halves' mean alone) to a whole cell.
        "mixed-cells" => vec![lin(0.0, 0.15), lin(0.0, 0.15)],
        "drop-blend" => vec![lin(0.0, 1.0), lin(0.0, 1.0)],
        // Either way across the step; 0 (no move) on the grid.
        "riser-blend" => vec![lin(-0.6, 1.0), lin(-0.6, 1.0)],
        // x from the rows behind the robot (where a camera whose lowest
        // ray meets the ground ahead keeps its grazing view) to past the
        // grid (every row: occlusion alone); a up to 3 (two in three moved
        // cells read the edge's height).
        "floor-lift" => vec![lin(-0.3, 1.45), lin(0.0, 1.0), lin(0.0, 3.0)],
        "drop-holes" => vec![lin(0.0, 1.0)],
        // Sds of the camera's pitch and roll errors up to 3 degrees (0.05
        // rad); x0 from behind the grid (every row tilts) to 1 m ahead; the
        // lever at x0 from none to 4 m (a map fused from far views).
        "tilt" => vec![lin(0.0, 0.05), lin(0.0, 0.05), lin(-0.6, 1.0), lin(0.0, 4.0)],
        // On even ground up to 1 degree; per metre of step under the
        // tracks up to 0.3 rad (a 0.2 m stair edge: 3.4 degrees more).
        "shake" => vec![lin(0.0, 0.02), lin(0.0, 0.3)],
        // A frame misregistered by up to 3 cm sd on even ground, 0.3 m per
        // metre of step under the tracks (a 0.2 m stair edge: 6 cm more).
        "step-jitter" => vec![lin(0.0, 0.03), lin(0.0, 0.3)],
        // Speed times latency: up to 0.15 m, spread from none to all of it.
        "lag" => vec![lin(0.0, 0.15), lin(0.0, 1.0)],
        // Walks up to 0.1 m per sqrt(m) along x, 0.05 in height; x0 as tilt's.
        "drift" => vec![lin(0.0, 0.1), lin(0.0, 0.05), lin(-0.6, 1.0)],
        other => unreachable!("dem-gap has no search box for effect {other}"),
    }
}

/// How far each parameter's box may be widened when a fit lands on its
/// edge (the physical limits), and which edges are natural (the effect
/// fades out there, or covers the whole grid), so a fit on them is no flag.
/// Per parameter: (hard low, hard high, low edge natural, high edge natural).
pub fn limits(name: &str) -> Vec<(f64, f64, bool, bool)> {
    match name {
        "noise" => vec![(0.0, 0.1, true, false), (0.0, 0.1, true, false)],
        "dropout" | "row-dropout" | "hole-growth" => vec![(0.0, 1.0, true, false)],
        "occlusion" => vec![(0.05, 3.0, false, false), (-1.0, 1.2, false, false)],
        "fov" => vec![(-0.65, 0.55, true, false), (0.35, 1.45, false, true)],
        // High enough or flat enough, the ray clears everything: natural ends.
        "view-top" => vec![(0.0, 3.0, false, true), (-1.0, 3.0, true, false)],
        "smoothing" => vec![(0.01, 1.0, false, true)],
        "bias" => vec![(-0.5, 0.5, false, false), (-0.5, 0.5, false, false)],
        "quantization" => vec![(0.0005, 0.2, false, false)],
        "startup" => vec![(-0.6, 1.45, true, true), (0.005, 3.0, false, false), (0.0, 1.0, true, false)],
        // a = 0 (a partly covered cell keeps its height) and a = 1 (it reads
        // its lower neighbour's) are natural ends.
        "patch-dropout" => vec![(0.0, 8.0, true, false), (0.02, 0.5, true, false), (0.0, 1.0, true, true)],
        "edge-holes" | "rim-holes" => vec![(0.005, 1.0, false, true), (0.0, 1.0, true, false)],
        // Every pit filled (p = 1) is a natural end: no gap is ever seen.
        "pit-fill" => vec![(0.005, 1.0, false, true), (0.0, 1.0, true, true)],
        // Past 0.2 m the surface reaches past the far half of the lower
        // cell whatever the step's place: larger reaches change nothing.
        "mixed-cells" => vec![(0.0, 0.2, true, true), (0.0, 0.2, true, true)],
        // Every cell beside a drop blended, or moved all the way: natural ends.
        "drop-blend" => vec![(0.0, 1.0, true, true), (0.0, 1.0, true, true)],
        // Moved all the way to the other surface: a natural end; the other
        // end (away from it) is not.
        "riser-blend" => vec![(-1.0, 1.0, false, true), (-1.0, 1.0, false, true)],
        // No rows (x behind the grid) or all of them, no cell or every one,
        // none moved or (a large) all the way: natural ends.
        "floor-lift" => vec![(-0.6, 1.45, true, true), (0.0, 1.0, true, true), (0.0, 5.0, true, true)],
        // No drop edge lost, or every one: natural ends.
        "drop-holes" => vec![(0.0, 1.0, true, true)],
        // No error (sd 0) is a natural end; x0 behind the grid (every row
        // tilts) or past it (no row pitches) too, and no lever at x0.
        "tilt" => vec![(0.0, 0.2, true, false), (0.0, 0.2, true, false), (-0.6, 1.45, true, true), (0.0, 10.0, true, false)],
        "shake" => vec![(0.0, 0.2, true, false), (0.0, 1.0, true, false)],
        // A cell read more than 0.1 m off is clamped there: 0.1 is no edge.
        "step-jitter" => vec![(0.0, 0.1, true, false), (0.0, 1.0, true, false)],
        // No shift is a natural end, and a backward one is allowed (a
        // robot reversing); spread none or all: natural ends.
        "lag" => vec![(-0.3, 0.5, true, false), (0.0, 1.0, true, true)],
        "drift" => vec![(0.0, 1.0, true, false), (0.0, 0.5, true, false), (-0.6, 1.45, true, true)],
        other => unreachable!("dem-gap has no limits for effect {other}"),
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
    /// Each sim record's time in its run (labels), when known.
    pub times: Option<&'a [f64]>,
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
        model.apply_all_at(&mut out, self.seed, 0, self.times);
        stats(&out, self.paired.then_some(self.sim))
    }

    /// Gap of model(sim) against real; infinite for a model that hides far
    /// more cells than real misses ([`hides_too_much`]).
    pub fn gap(&self, model: &SensorModel) -> f64 {
        let s = self.model_stats(model);
        if hides_too_much(&s, self.real).is_some() {
            return f64::INFINITY;
        }
        gap(&s, self.real)
    }
}

/// A fitted candidate.
#[derive(Debug, Clone)]
pub struct Fitted {
    /// The effect with its fitted parameters.
    pub effect: Effect,
    /// Gap on the fitting subsample with the effect added.
    pub gap: f64,
    /// Parameters that ended on an edge of their box that is no natural
    /// end of the effect, after widening the box up to its limits: the
    /// effect is only the closest of the vocabulary, not the right one.
    pub at_edge: Vec<&'static str>,
    /// The boxes were widened (parameter names), to the limits of [`limits`].
    pub widened: Vec<&'static str>,
}

/// Fit effect `name` on top of `base` by grid search plus refinement; a
/// parameter that lands on an edge of its box that is no natural end gets
/// its box widened toward its limit (twice at most) and is fitted again.
pub fn fit(name: &str, base: &SensorModel, target: &Target) -> Option<Fitted> {
    let mut ranges = ranges(name);
    let lim = limits(name);
    // startup: with times, fit x0 and v (p follows from the times); without,
    // x0 and p (v unknown: 0).
    let fixed: Vec<Option<f64>> = match name {
        "startup" if target.times.is_some() => vec![None, None, Some(0.0)],
        "startup" => vec![None, Some(0.0), None],
        _ => vec![None; ranges.len()],
    };
    let mut widened = Vec::new();
    let mut fitted = fit_in(name, base, target, &ranges, &fixed)?;
    for _ in 0..2 {
        let mut changed = false;
        for (i, (r, &(hlo, hhi, nlo, nhi))) in ranges.iter_mut().zip(&lim).enumerate() {
            let Some(u) = fitted.1.get(i).copied() else { continue };
            let width = r.hi - r.lo;
            if u <= EDGE && !nlo && r.lo > hlo {
                r.lo = (r.lo - width).max(hlo);
                changed = true;
            } else if u >= 1.0 - EDGE && !nhi && r.hi < hhi {
                r.hi = (r.hi + width).min(hhi);
                changed = true;
            } else {
                continue;
            }
            let pname = Effect::from_values(name, &vec![0.0; lim.len()]).map(|e| e.params()[i].0).unwrap_or("?");
            if !widened.contains(&pname) {
                widened.push(pname);
            }
        }
        if !changed {
            break;
        }
        fitted = fit_in(name, base, target, &ranges, &fixed)?;
    }
    let (mut effect, u, g) = fitted;
    let names: Vec<&'static str> = effect.params().iter().map(|p| p.0).collect();
    let at_edge = (0..ranges.len())
        .filter(|&i| fixed[i].is_none())
        .filter(|&i| (u[i] <= EDGE && !lim[i].2) || (u[i] >= 1.0 - EDGE && !lim[i].3))
        .map(|i| names[i])
        .collect();
    if let (Effect::Startup { x0, v, .. }, Some(times)) = (effect, target.times) {
        // The share of records that are startup frames, from the times: the
        // model then also works on records without times.
        let blind = times.iter().filter(|&&t| t.is_finite() && x0 - v * t > -0.55).count();
        let p = blind as f64 / times.len().max(1) as f64;
        effect = Effect::Startup { x0, v, p: (p * 1e4).round() / 1e4 };
    }
    Some(Fitted { effect, gap: g, at_edge, widened })
}

/// A parameter within this share of its box from an edge is on the edge.
const EDGE: f64 = 0.01;

/// Grid search plus refinement in the boxes `ranges`; parameters with a
/// `fixed` value are not searched. Returns the effect, the best point in
/// box units and its gap.
fn fit_in(name: &str, base: &SensorModel, target: &Target, ranges: &[Range], fixed: &[Option<f64>]) -> Option<(Effect, Vec<f64>, f64)> {
    let free: Vec<usize> = (0..ranges.len()).filter(|&i| fixed[i].is_none()).collect();
    let dims = free.len();
    let values = |u: &[f64]| -> Vec<f64> {
        let mut v: Vec<f64> = fixed.iter().map(|f| f.unwrap_or(0.0)).collect();
        for (k, &i) in free.iter().enumerate() {
            v[i] = ranges[i].at(u[k]);
        }
        v
    };
    let probe = Effect::from_values(name, &values(&vec![0.5; dims]))?;
    let prepared = prefix::Prepared::new(target, base, &probe);
    let eval = |u: &[f64]| -> f64 {
        let v = values(u);
        match Effect::from_values(name, &v) {
            Some(e) if e.check().is_ok() => prepared.gap(e),
            _ => f64::INFINITY,
        }
    };
    let n = match (name, dims) {
        ("occlusion", _) => 13,
        // Rounding makes the gap spiky in q (flat ground at -0.07 lands on
        // another multiple for a 3 % change of q): a fine grid.
        ("quantization", _) => 121,
        (_, 1) => 41,
        // Four parameters (tilt): 9^4 first points cost eight times 9^3, so
        // a coarser first grid, refined three points a side for one more
        // round, to the same final step, from the best few points of it
        // that are not neighbours (a coarse grid's best cell can miss the
        // deepest valley).
        (_, 4..) => 5,
        _ => 9,
    };
    let (per, rounds, starts) = if dims >= 4 { (3, 5, 3) } else { (5, 4, 1) };
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
    let order = |a: &(Vec<f64>, f64), b: &(Vec<f64>, f64)| {
        a.1.total_cmp(&b.1).then_with(|| a.0.partial_cmp(&b.0).unwrap_or(std::cmp::Ordering::Equal))
    };
    let scored = |pts: Vec<Vec<f64>>| {
        pts.into_par_iter().map(|p| {
            let g = eval(&p);
            (p, g)
        })
    };
    let best_of = |pts: Vec<Vec<f64>>| -> Option<(Vec<f64>, f64)> { scored(pts).min_by(order) };
    let spacing = 1.0 / (n - 1) as f64;
    let first = grid(&vec![0.5; dims], spacing, n);
    let mut seeds: Vec<(Vec<f64>, f64)> = if starts == 1 {
        vec![best_of(first)?]
    } else {
        let mut all: Vec<(Vec<f64>, f64)> = scored(first).collect();
        all.sort_by(order);
        let mut chosen: Vec<(Vec<f64>, f64)> = Vec::new();
        for (p, g) in all {
            let apart = |q: &Vec<f64>| p.iter().zip(q).any(|(a, b)| (a - b).abs() > 1.5 * spacing);
            if chosen.len() < starts && g.is_finite() && chosen.iter().all(|(q, _)| apart(q)) {
                chosen.push((p, g));
            }
        }
        if chosen.is_empty() {
            return None;
        }
        chosen
    };
    for (best, best_gap) in seeds.iter_mut() {
        let mut step = spacing / 2.0;
        for _ in 0..rounds {
            if let Some((p, g)) = best_of(grid(best, step, per)) {
                if g < *best_gap {
                    (*best, *best_gap) = (p, g);
                }
            }
            step /= 2.0;
        }
    }
    // The best refined start; the better-ranked start on a tie.
    let (best, best_gap) = seeds.into_iter().reduce(|a, b| if b.1 < a.1 { b } else { a })?;
    if !best_gap.is_finite() {
        return None;
    }
    let effect = snap(Effect::from_values(name, &values(&best))?);
    let mut u = vec![0.5; ranges.len()];
    for (k, &i) in free.iter().enumerate() {
        u[i] = best[k];
    }
    Some((effect, u, best_gap))
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Every effect of the vocabulary has a search box and limits, one per
    /// parameter, the box inside the limits and valid at its corners.
    #[test]
    fn every_effect_has_a_box_inside_its_limits() {
        for name in dem_sensor::effects::NAMES {
            let (r, l) = (ranges(name), limits(name));
            let e = Effect::from_values(name, &vec![0.0; r.len()]).unwrap_or_else(|| panic!("{name}: {} values", r.len()));
            assert_eq!(e.params().len(), r.len(), "{name}");
            assert_eq!(l.len(), r.len(), "{name}");
            for (x, &(lo, hi, _, _)) in r.iter().zip(&l) {
                assert!(lo <= x.lo && x.lo < x.hi && x.hi <= hi, "{name}: box {x:?} outside its limits ({lo}, {hi})");
            }
            for corner in [0.0, 1.0] {
                let v: Vec<f64> = r.iter().map(|x| x.at(corner)).collect();
                let e = Effect::from_values(name, &v).unwrap();
                // fov's corners may cross (x_min >= x_max); the fit scores such a point infinite.
                assert!(e.check().is_ok() || name == "fov", "{name} at {v:?}: {:?}", e.check());
            }
        }
    }
}
