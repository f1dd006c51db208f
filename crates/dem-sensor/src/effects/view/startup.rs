//! `startup`: the first frames of a run, blind behind the nearest ray.

use super::X_BACK;
use crate::draws::Draws;
use crate::effects::{params, probability, EffectKind, EffectSpec, Family, Limit, Range, Stage};
use crate::evidence::{pct, Context};
use crate::graph::ops::{below, drop_cells, per_row, Cells, FAR};
use dem_core::distribution::Stats;
use dem_core::format::{row_center_x, Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// The first frames of a run: the map has not yet seen the ground
    /// behind the nearest ray, and that blind edge recedes as the robot drives.
    #[serde(expecting = "struct variant Effect::Startup")]
    Startup {
        // v is fitted when the records' times are known, p when not (dem-gap's fit).
        /// Blind edge at the start of a run (m along x).
        x0: fit Range::lin(-0.3, 1.2), limit Limit::new(-0.6, 1.45).natural_lo().natural_hi();
        /// Speed at which the blind edge recedes (m/s); 0: unknown.
        v: fit Range::lin(0.02, 0.6), limit Limit::new(0.0, 3.0);
        /// Share of records that are startup frames (used without times).
        p: fit Range::lin(0.0, 0.6), limit Limit::new(0.0, 1.0).natural_lo();
    }
}

impl EffectKind for Startup {
    const SPEC: EffectSpec = EffectSpec {
        name: "startup",
        family: Family::View,
        emulator: &["fov"],
        formula: "rows whose centre x < e missing: e = x0 - v t for a record t seconds into its run (labels' `time`, v > 0); without a \
            time, with probability p the record is a startup frame and e = x0 - u (x0 + 0.6), u uniform",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::Startup,
        // u1: whether a record without a time is a startup frame; u2: its edge.
        draws: 2,
    };

    fn check(&self) -> Result<(), String> {
        let Self { v, p, .. } = *self;
        check_startup(v, p)
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, time: Option<f64>) {
        let Self { x0, v, p } = *self;
        blind_startup_rows(d, rng, time, x0, v, p)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, time: Option<&str>) -> Cells {
        let Self { x0, v, p } = *self;
        operators(b, c, u, time, x0, v, p)
    }

    fn evidence(&self, c: &Context) -> String {
        let Self { x0, v, p } = *self;
        sentence(c, x0, v, p)
    }

    fn examples() -> Vec<Self> {
        vec![Startup { x0: 0.4, v: 0.3, p: 0.4 }, Startup { x0: 0.4, v: 0.0, p: 0.4 }]
    }
}

fn check_startup(v: f64, p: f64) -> Result<(), String> {
    probability(p)?;
    if v < 0.0 {
        return Err(format!("v = {v} must be >= 0"));
    }
    Ok(())
}

/// `startup` (formula in its spec): the record's `time` in its run when
/// known, else its two uniforms decide.
fn blind_startup_rows(d: &mut Dem, rng: &mut Draws, time: Option<f64>, x0: f64, v: f64, p: f64) {
    let (u1, u2): (f64, f64) = (rng.gen(), rng.gen());
    let edge = match time {
        Some(t) if v > 0.0 => Some(x0 - v * t),
        _ => (u1 < p).then_some(x0 - u2 * (x0 - X_BACK)),
    };
    if let Some(e) = edge {
        for r in (0..GRID_ROWS).filter(|&r| row_center_x(r) < e) {
            (0..COLS).for_each(|c| d.set_missing(r, c));
        }
    }
}

/// `startup`: rows whose centre lies behind the blind edge go missing; the
/// edge from the time where known (and v > 0), else drawn.
fn operators(b: &mut Builder, c: &Cells, u: &str, time: Option<&str>, x0: f64, v: f64, p: f64) -> Cells {
    let u = b.reshape(u, &[-1, 2, 1, 1]);
    let u1 = b.take(&u, 1, 0, 1);
    let u2 = b.take(&u, 1, 1, 2);
    let drawn = below(b, &u1, p);
    let edge = b.mul_const(&u2, -(x0 - X_BACK) as f32);
    let edge = b.add_const(&edge, x0 as f32);
    let none = b.scalar(-FAR);
    let mut edge = b.select(&drawn, &edge, &none);
    if v > 0.0 {
        let t = b.reshape(time.expect("startup gets the time input"), &[-1, 1, 1, 1]);
        // NaN and infinities: t - t is not 0.
        let diff = b.bin("Sub", &t, &t);
        let zero = b.scalar(0.0);
        let known = b.bin("Equal", &diff, &zero);
        let t = b.select(&known, &t, &zero);
        let by_time = b.mul_const(&t, -v as f32);
        let by_time = b.add_const(&by_time, x0 as f32);
        edge = b.select(&known, &by_time, &edge);
    }
    let edge = b.reshape(&edge, &[-1, 1, 1]);
    let x = per_row(b, row_center_x);
    let miss = b.bin("Less", &x, &edge);
    drop_cells(b, c, &miss)
}

/// The evidence for `startup`.
fn sentence(c: &Context, x0: f64, v: f64, p: f64) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let back = |s: &Stats| s.mean_over("missing", 0..6);
        let how = if v > 0.0 {
            format!(
                "a blind edge at x = {x0:.2} m at the start of a run that recedes at {v:.2} m/s ({} of records are startup frames)",
                pct(p)
            )
        } else {
            format!("{} of records are startup frames whose blind edge starts at x = {x0:.2} m", pct(p))
        };
        format!(
            "cells behind the robot (rows 0-5) missing: real {} vs model {}, whole rows in some records and none in others: {how}",
            pct(back(real)),
            pct(back(before)),
        )
    };
    c.fitted(body)
}
