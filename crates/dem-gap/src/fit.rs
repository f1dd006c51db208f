//! Fitting one candidate effect: a grid search over its parameter box
//! (the fit boxes and limits of its [`EffectSpec`], defined with the
//! effect in dem-sensor), refined around the best point (four times; for four parameters, whose
//! first grid is coarser, five times around each of its three best; a map's
//! memory fitted after the amplitude, [`fitted_last`]), of the gap between
//! model(sim) with the candidate added and real. Every evaluation uses the
//! same random streams (the seed), so the gap changes with the parameters,
//! not with the draws.

use rayon::prelude::*;

use dem_core::format::{row_center_x, Dem, GRID_ROWS};
use dem_sensor::effects::{EffectSpec, Fov, Limit, Range, Startup};
use dem_sensor::{Effect, SensorModel};

use dem_core::distribution::{gap, hides_too_much, stats_made, Stats};
use dem_core::temporal::Step;

use crate::measurement::summarise;
use dem_sensor::Moment;

/// Records per parallel chunk when a fit makes all its outputs at once.
const CHUNK: usize = 256;

mod prefix;

/// The box searched for each parameter of `spec`, in [`Effect::params`] order.
pub fn ranges(spec: &EffectSpec) -> Vec<Range> {
    spec.params.iter().map(|p| p.fit).collect()
}

/// How far each parameter's box may be widened when a fit lands on its
/// edge, and which edges are natural ([`dem_sensor::effects::Limit`]).
pub fn limits(spec: &EffectSpec) -> Vec<Limit> {
    spec.params.iter().map(|p| p.limit).collect()
}

/// The data a fit compares against: sim records (a subsample), their
/// paired real records' statistics or the real set's statistics.
pub struct Target<'a> {
    /// Sim records to push through the model.
    pub sim: &'a [Dem],
    /// Each sim record's time in its run (labels), when known.
    pub moments: Option<&'a [Moment]>,
    /// The runs' steps between the sim records (positions in `sim`), when
    /// known: the frame terms then count.
    pub steps: Option<&'a [Step]>,
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
        self.stats_after(self.sim, model, None)
    }

    /// Statistics of `model` applied to `from` (the sim records, or their
    /// output of the effects before `model`), record `i` with record `i`'s
    /// draws and time; `drawn`, when given, holds those draws
    /// ([`SensorModel::uniforms_of`] of a model with `model`'s effect
    /// names: the streams depend on the names, not the parameters). Each
    /// chunk is made and summarised in turn ([`stats_made`]), so no copy of
    /// all the records is made; with steps, the frame terms need all of
    /// them at once.
    fn stats_after(&self, from: &[Dem], model: &SensorModel, drawn: Option<&[f32]>) -> Stats {
        let k = model.draws();
        let make = |range: std::ops::Range<usize>| {
            let mut u = vec![0.0f32; k];
            let mut out = from[range.clone()].to_vec();
            for (d, i) in out.iter_mut().zip(range) {
                let moment = dem_sensor::moment_at(self.moments, i);
                match drawn {
                    Some(all) => model.apply_drawn(d, &all[i * k..(i + 1) * k], moment.known_time()),
                    None => {
                        model.uniforms(self.seed, i as u64, moment, &mut u);
                        model.apply_drawn(d, &u, moment.known_time());
                    }
                }
            }
            out
        };
        let paired_sim = self.paired.then_some(self.sim);
        // A map's memory steps the runs: it needs every frame at once.
        let memory = model.map_memory().zip(self.moments.filter(|m| dem_sensor::any_in_run(Some(m))));
        if self.steps.is_none() && memory.is_none() {
            return stats_made(from.len(), paired_sim, make);
        }
        let mut out: Vec<Dem> =
            (0..from.len().div_ceil(CHUNK)).into_par_iter().flat_map_iter(|c| make(c * CHUNK..((c + 1) * CHUNK).min(from.len()))).collect();
        if let Some((memory, moments)) = memory {
            let uniforms = |i: usize| match drawn {
                Some(all) => dem_sensor::fusion::memory_draws(&all[i * k..(i + 1) * k]).to_vec(),
                None => model.memory_uniforms(self.seed, i as u64),
            };
            dem_sensor::fusion::step_set(memory, &mut out, self.sim, moments, uniforms);
        }
        summarise(&out, paired_sim, self.steps)
    }

    /// Gap of model(sim) against real; infinite for a model that hides far
    /// more cells than real misses ([`hides_too_much`]).
    pub fn gap(&self, model: &SensorModel) -> f64 {
        self.gap_of(&self.model_stats(model))
    }

    /// [`Target::gap`] of a model whose output has statistics `s`.
    fn gap_of(&self, s: &Stats) -> f64 {
        if hides_too_much(s, self.real).is_some() {
            return f64::INFINITY;
        }
        gap(s, self.real)
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

/// Fit the effect of `spec` on top of `base` by grid search plus
/// refinement; a parameter that lands on an edge of its box that is no
/// natural end gets its box widened toward its limit (twice at most) and
/// is fitted again.
pub fn fit(spec: &EffectSpec, base: &SensorModel, target: &Target) -> Option<Fitted> {
    let name = spec.name;
    let mut ranges = ranges(spec);
    let lim = limits(spec);
    // startup: with times, fit x0 and v (p follows from the times); without,
    // x0 and p (v unknown: 0).
    let fixed: Vec<Option<f64>> = match name {
        "startup" if dem_sensor::any_time(target.moments) => vec![None, None, Some(0.0)],
        "startup" => vec![None, Some(0.0), None],
        // noise: a map's memory only where runs, times and poses show it.
        "noise" if !dem_sensor::any_in_run(target.moments) => vec![None, None, Some(0.0)],
        _ => vec![None; ranges.len()],
    };
    let last = fitted_last(spec, target);
    // The base's part before the candidate, applied once for every stage
    // and every widened box (the place depends on the name alone; a
    // point of another memory is redrawn by `Prepared`).
    let mid: Vec<f64> = ranges.iter().zip(&fixed).map(|(r, f)| f.unwrap_or(r.at(0.5))).collect();
    let prepared = prefix::Prepared::new(target, base, &Effect::from_values(name, &mid)?);
    let mut widened = Vec::new();
    let mut fitted = search(name, &prepared, &ranges, &fixed, last)?;
    for _ in 0..2 {
        let mut changed = false;
        for (i, (r, l)) in ranges.iter_mut().zip(&lim).enumerate() {
            let Some(u) = fitted.1.get(i).copied() else { continue };
            let width = r.hi - r.lo;
            if u <= EDGE && !l.natural_lo && r.lo > l.lo {
                r.lo = (r.lo - width).max(l.lo);
                changed = true;
            } else if u >= 1.0 - EDGE && !l.natural_hi && r.hi < l.hi {
                r.hi = (r.hi + width).min(l.hi);
                changed = true;
            } else {
                continue;
            }
            let pname = spec.params[i].name;
            if !widened.contains(&pname) {
                widened.push(pname);
            }
        }
        if !changed {
            break;
        }
        fitted = search(name, &prepared, &ranges, &fixed, last)?;
    }
    let (mut effect, u, g) = fitted;
    let at_edge = (0..ranges.len())
        .filter(|&i| fixed[i].is_none())
        .filter(|&i| (u[i] <= EDGE && !lim[i].natural_lo) || (u[i] >= 1.0 - EDGE && !lim[i].natural_hi))
        .map(|i| spec.params[i].name)
        .collect();
    if let (Effect::Startup(Startup { x0, v, .. }), Some(moments)) = (effect, target.moments) {
        // The share of records that are startup frames, from the times: the
        // model then also works on records without times.
        let blind = moments.iter().filter_map(Moment::known_time).filter(|&t| x0 - v * t > -0.55).count();
        let p = blind as f64 / moments.len().max(1) as f64;
        effect = Effect::Startup(Startup { x0, v, p: (p * 1e4).round() / 1e4 });
    }
    Some(Fitted { effect, gap: g, at_edge, widened })
}

/// A parameter within this share of its box from an edge is on the edge.
const EDGE: f64 = 0.01;

/// The parameter fitted after the others: a map's memory (`noise`'s tau,
/// where runs show it) changes the frame terms only, so the amplitude is
/// fitted with it at the middle of its box, then it alone, then all of them
/// around that point. A three-parameter grid costs seven times the
/// two-parameter one, and noise is a candidate at every step.
fn fitted_last(spec: &EffectSpec, target: &Target) -> Option<usize> {
    let tau = spec.params.iter().position(|p| p.name == "tau");
    tau.filter(|_| spec.name == "noise" && dem_sensor::any_in_run(target.moments))
}

/// [`fit_in`] on the whole box, or in stages when parameter `last` is
/// fitted after the others ([`fitted_last`]).
fn search(
    name: &str,
    prepared: &prefix::Prepared,
    ranges: &[Range],
    fixed: &[Option<f64>],
    last: Option<usize>,
) -> Option<(Effect, Vec<f64>, f64)> {
    let Some(last) = last.filter(|&l| fixed[l].is_none()) else {
        return fit_in(name, prepared, ranges, fixed, None);
    };
    let mut first = fixed.to_vec();
    first[last] = Some(ranges[last].at(0.5));
    let (_, u, _) = fit_in(name, prepared, ranges, &first, None)?;
    let others: Vec<Option<f64>> =
        (0..ranges.len()).map(|i| if i == last { None } else { fixed[i].or(Some(ranges[i].at(u[i]))) }).collect();
    let (_, u_last, _) = fit_in(name, prepared, ranges, &others, None)?;
    let mut centre = u;
    centre[last] = u_last[last];
    fit_in(name, prepared, ranges, fixed, Some(&centre))
}

/// Grid search plus refinement in the boxes `ranges`, or refinement alone
/// around `centre` (box units, every parameter) when given; parameters with
/// a `fixed` value are not searched. Returns the effect, the best point in
/// box units and its gap.
fn fit_in(
    name: &str,
    prepared: &prefix::Prepared,
    ranges: &[Range],
    fixed: &[Option<f64>],
    centre: Option<&[f64]>,
) -> Option<(Effect, Vec<f64>, f64)> {
    let free: Vec<usize> = (0..ranges.len()).filter(|&i| fixed[i].is_none()).collect();
    let dims = free.len();
    let values = |u: &[f64]| -> Vec<f64> {
        let mut v: Vec<f64> = fixed.iter().map(|f| f.unwrap_or(0.0)).collect();
        for (k, &i) in free.iter().enumerate() {
            v[i] = ranges[i].at(u[k]);
        }
        v
    };
    let eval = |u: &[f64]| -> f64 {
        let v = values(u);
        match Effect::from_values(name, &v) {
            Some(e) if e.check().is_ok() => prepared.gap(e),
            _ => f64::INFINITY,
        }
    };
    let scored = |pts: Vec<Vec<f64>>| {
        pts.into_par_iter().map(|p| {
            let g = eval(&p);
            (p, g)
        })
    };
    let best_of = |pts: Vec<Vec<f64>>| -> Option<(Vec<f64>, f64)> { scored(pts).min_by(by_gap) };
    let n = first_grid(name, dims);
    let spacing = 1.0 / (n - 1) as f64;
    let (per, rounds, mut seeds) = match centre {
        // Around a staged fit's point: the last rounds of a refinement.
        Some(centre) => {
            let c: Vec<f64> = free.iter().map(|&i| centre[i]).collect();
            let g = eval(&c);
            (3, 3, vec![(c, g)])
        }
        None if dims >= 4 => {
            let mut all: Vec<(Vec<f64>, f64)> = scored(grid(&vec![0.5; dims], spacing, n, dims)).collect();
            all.sort_by(by_gap);
            (3, 5, apart_starts(all, 3, spacing)?)
        }
        None => (5, 4, vec![best_of(grid(&vec![0.5; dims], spacing, n, dims))?]),
    };
    let first_step = if centre.is_some() { spacing / 4.0 } else { spacing / 2.0 };
    for (best, best_gap) in seeds.iter_mut() {
        let mut step = first_step;
        for _ in 0..rounds {
            if let Some((p, g)) = best_of(grid(best, step, per, dims)) {
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

/// Points of the first grid a side.
fn first_grid(name: &str, dims: usize) -> usize {
    match (name, dims) {
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
    }
}

/// The `per`^`dims` points `step` apart around `centre` (box units) that
/// lie inside the box.
fn grid(centre: &[f64], step: f64, per: usize, dims: usize) -> Vec<Vec<f64>> {
    let mut pts = vec![vec![]];
    for &c in centre.iter().take(dims) {
        let offsets: Vec<f64> = (0..per).map(|i| c + step * (i as f64 - (per - 1) as f64 / 2.0)).collect();
        pts = pts
            .into_iter()
            .flat_map(|p| offsets.iter().filter(|u| (-1e-9..=1.0 + 1e-9).contains(*u)).map(move |&u| [p.clone(), vec![u]].concat()))
            .collect();
    }
    pts
}

/// Lower gap first; equal gaps by the point, so the order is total and a
/// parallel search picks the same point on any thread count.
fn by_gap(a: &(Vec<f64>, f64), b: &(Vec<f64>, f64)) -> std::cmp::Ordering {
    a.1.total_cmp(&b.1).then_with(|| a.0.partial_cmp(&b.0).unwrap_or(std::cmp::Ordering::Equal))
}

/// The best `starts` points of a first grid (sorted best first) that are
/// not neighbours on it; `None` when no point has a finite gap.
fn apart_starts(sorted: Vec<(Vec<f64>, f64)>, starts: usize, spacing: f64) -> Option<Vec<(Vec<f64>, f64)>> {
    let mut chosen: Vec<(Vec<f64>, f64)> = Vec::new();
    for (p, g) in sorted {
        let apart = |q: &Vec<f64>| p.iter().zip(q).any(|(a, b)| (a - b).abs() > 1.5 * spacing);
        if chosen.len() < starts && g.is_finite() && chosen.iter().all(|(q, _)| apart(q)) {
            chosen.push((p, g));
        }
    }
    (!chosen.is_empty()).then_some(chosen)
}

/// fov acts on row centres only, so any x_min between two centres gives the
/// same output: report the row boundary between them (the midpoint).
fn snap(e: Effect) -> Effect {
    match e {
        Effect::Fov(Fov { x_min, x_max }) => {
            let below = (0..GRID_ROWS).filter(|&r| row_center_x(r) < x_min).count();
            let upto = (0..GRID_ROWS).filter(|&r| row_center_x(r) <= x_max).count();
            let b = |k: usize| ((-0.6 + 0.1 * k as f64) * 1000.0).round() / 1000.0;
            Effect::Fov(Fov { x_min: b(below), x_max: b(upto).max(b(below) + 0.1) })
        }
        other => other,
    }
}
