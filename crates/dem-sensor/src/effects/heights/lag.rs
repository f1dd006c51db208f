//! `lag`: latency, the DEM is an older frame's map.

use super::{climb_slope, ops, shift_rows, MAX_LAG};
use crate::draws::Draws;
use crate::effects::{params, EffectKind, EffectSpec, Family, Limit, Range, Stage};
use crate::evidence::{part_way_steps, pct, side_share, Context};
use crate::graph::ops::Cells;
use dem_core::distribution::Stats;
use dem_core::format::{Dem, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Latency: the DEM is an older frame's map, cut at that older pose.
    #[serde(expecting = "struct variant Effect::Lag")]
    Lag {
        // Speed times latency: up to 0.15 m, spread from none to all of it. No
        // shift is a natural end, and a backward one is allowed (a robot
        // reversing); spread none or all: natural ends.
        /// Mean shift ahead (m): speed times latency.
        s: fit Range::lin(0.0, 0.15), limit Limit::new(-0.3, 0.5).natural_lo();
        /// Spread of the shift around s, as a share of s (0..1).
        spread: fit Range::lin(0.0, 1.0), limit Limit::new(0.0, 1.0).natural_lo().natural_hi();
    }
}

impl EffectKind for Lag {
    const SPEC: EffectSpec = EffectSpec {
        name: "lag",
        family: Family::Heights,
        emulator: &["latency"],
        formula: "per run shift s_r = `s` (1 + `spread` (2u - 1)), u uniform, the run's draw; h'(x) = h(x - s_r) + s_r tan(pitch), pitch the record's \
            row 20 column 0 (clamped to +-MAX_CLIMB_PITCH, 0 if not finite): the DEM is the map of a frame s_r / v old, cut at that \
            older pose. See shift_rows for the interpolation; validity is kept",
        params: Self::PARAMS,
        whole_record: false,
        // The shift is the pipeline's latency times the run's speed: both
        // hold for a run, so the shift is the run's.
        run_draws: 1,
        stage: Stage::Pose,
        draws: 1,
    };

    fn check(&self) -> Result<(), String> {
        let Self { s, spread } = *self;
        check_lag(s, spread)
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, _time: Option<f64>) {
        let Self { s, spread } = *self;
        lag(d, rng, s, spread)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, _time: Option<&str>) -> Cells {
        let Self { s, spread } = *self;
        operators(b, c, u, s, spread)
    }

    fn evidence(&self, c: &Context) -> String {
        let Self { s, .. } = *self;
        sentence(c, s)
    }

    fn examples() -> Vec<Self> {
        vec![Lag { s: 0.08, spread: 0.6 }, Lag { s: -0.3, spread: 1.0 }]
    }
}

fn check_lag(s: f64, spread: f64) -> Result<(), String> {
    if s.abs() > MAX_LAG || !(0.0..=1.0).contains(&spread) {
        return Err(format!("s = {s} must be in [-{MAX_LAG}, {MAX_LAG}] m and spread = {spread} in [0, 1]"));
    }
    Ok(())
}

/// `lag` (formula in its spec).
fn lag(d: &mut Dem, rng: &mut Draws, s: f64, spread: f64) {
    let shift = s * (1.0 + spread * (2.0 * rng.gen() - 1.0));
    let climb = shift * climb_slope(d);
    shift_rows(d, &[shift; GRID_ROWS], &[climb; GRID_ROWS]);
}

/// `lag`: one shift per record, s (1 + spread (2u - 1)), and the climb
/// shift tan(pitch), the pitch [`ops::record_pitch`].
fn operators(b: &mut Builder, c: &Cells, u: &str, s: f64, spread: f64) -> Cells {
    let u = b.reshape(u, &[-1, 1, 1]);
    let t = b.mul_const(&u, 2.0);
    let t = b.add_const(&t, -1.0);
    let t = b.mul_const(&t, spread as f32);
    let t = b.add_const(&t, 1.0);
    let shift = b.mul_const(&t, s as f32);
    let p = ops::record_pitch(b);
    let sin = b.un("Sin", &p);
    let cos = b.un("Cos", &p);
    let tan = b.bin("Div", &sin, &cos);
    let climb = b.bin("Mul", &shift, &tan);
    let q = b.mul_const(&shift, (1.0 / dem_core::format::CELL) as f32);
    ops::shift_rows(b, c, &q, &climb)
}

/// The evidence for `lag`.
fn sentence(c: &Context, s: f64) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let ahead = if s >= 0.0 { "ahead" } else { "back" };
        if real.paired {
            // The cells beside steps moved > 2 cm toward the other
            // surface (component 2): a shift ahead moves the far side of
            // each step (riser tops, drop floors), a shift back the near
            // side (riser feet, drop lips).
            let moved = |st: &Stats, sides: [&str; 2]| side_share(st, &sides, 2);
            let (far, near) = (["riser-top", "drop-floor"], ["riser-foot", "drop-lip"]);
            let (lead, trail) = if s >= 0.0 { (far, near) } else { (near, far) };
            let (rl, bl, rt, bt) = (moved(real, lead), moved(before, lead), moved(real, trail), moved(before, trail));
            let verdict = if rl > bl && rl - bl > rt - bt {
                format!("steps read {:.1} cm {ahead} of where sim has them: the DEM is the map of an older frame", 100.0 * s.abs())
            } else {
                "real moves no more cells on that side of steps than the other: the lag is the closest effect, not a clear one".to_string()
            };
            format!(
                "cells on the {} side of steps (riser {}, drop {}) moved more than 2 cm toward the other surface: real {} vs model {}; on the other side real {} vs model {}: {verdict}",
                if s >= 0.0 { "far" } else { "near" },
                if s >= 0.0 { "tops" } else { "feet" },
                if s >= 0.0 { "floors" } else { "lips" },
                pct(rl),
                pct(bl),
                pct(rt),
                pct(bt),
            )
        } else {
            let fitted =
                format!("steps read part of the way across where a shift {ahead} of {:.1} cm puts a cell on both sides", 100.0 * s.abs());
            part_way_steps(real, before, fitted, "the lag is")
        }
    };
    c.fitted(body)
}
