//! `fov`: cells outside the field of view along x never observed.

use crate::draws::Draws;
use crate::effects::{params, EffectKind, EffectSpec, Family, Limit, Range, Stage};
use crate::evidence::{pct, Context};
use crate::graph::ops::{drop_cells, per_row, Cells};
use dem_core::distribution::Stats;
use dem_core::format::{row_center_x, Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Cells outside the field of view along x never observed.
    #[serde(expecting = "struct variant Effect::Fov")]
    Fov {
        /// Nearest x observed (m).
        x_min: fit Range::lin(-0.65, 0.55), limit Limit::new(-0.65, 0.55).natural_lo();
        /// Farthest x observed (m).
        x_max: fit Range::lin(0.35, 1.45), limit Limit::new(0.35, 1.45).natural_hi();
    }
}

impl EffectKind for Fov {
    const SPEC: EffectSpec = EffectSpec {
        name: "fov",
        family: Family::View,
        emulator: &["fov"],
        formula: "cells whose centre x is outside [x_min, x_max] missing",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::FieldOfView,
        draws: 0,
    };

    fn check(&self) -> Result<(), String> {
        let Self { x_min, x_max } = *self;
        check_fov(x_min, x_max)
    }

    fn apply(&self, d: &mut Dem, _rng: &mut Draws, _time: Option<f64>) {
        let Self { x_min, x_max } = *self;
        cut_to_fov(d, x_min, x_max)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, _u: &str, _time: Option<&str>) -> Cells {
        let Self { x_min, x_max } = *self;
        operators(b, c, x_min, x_max)
    }

    fn evidence(&self, c: &Context) -> String {
        let Self { x_min, x_max } = *self;
        sentence(c, x_min, x_max)
    }

    fn examples() -> Vec<Self> {
        vec![Fov { x_min: -0.33, x_max: 0.97 }]
    }
}

fn check_fov(x_min: f64, x_max: f64) -> Result<(), String> {
    if x_min >= x_max {
        return Err(format!("x_min = {x_min} must be < x_max = {x_max}"));
    }
    Ok(())
}

/// `fov` (formula in its spec).
fn cut_to_fov(d: &mut Dem, x_min: f64, x_max: f64) {
    for r in 0..GRID_ROWS {
        let x = row_center_x(r);
        if x < x_min || x > x_max {
            (0..COLS).for_each(|c| d.set_missing(r, c));
        }
    }
}

/// `fov`.
fn operators(b: &mut Builder, c: &Cells, x_min: f64, x_max: f64) -> Cells {
    let out = per_row(b, |r| f64::from(u8::from(row_center_x(r) < x_min || row_center_x(r) > x_max)));
    let miss = b.gt_const(&out, 0.5);
    drop_cells(b, c, &miss)
}

/// The evidence for `fov`.
fn sentence(c: &Context, x_min: f64, x_max: f64) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let outside: Vec<usize> = (0..20).filter(|&r| !(x_min..=x_max).contains(&dem_core::format::row_center_x(r))).collect();
        let m = |s: &Stats| {
            let t = s.term("missing").map(|t| t.values.clone()).unwrap_or_default();
            outside.iter().map(|&r| t.get(r).copied().unwrap_or(0.0)).sum::<f64>() / outside.len().max(1) as f64
        };
        let (mr, mb) = (m(real), m(before));
        let verdict = if mr >= 0.9 {
            "never in the field of view"
        } else if mr > mb {
            "seen in some records, not in others: a field of view only in part (startup frames, map memory)"
        } else {
            "no more missing in real than in the model: the field of view does not explain them"
        };
        format!(
            "rows outside x in [{x_min:.2}, {x_max:.2}] m ({} rows) are missing in {} of real cells vs {} of model cells: {verdict}",
            outside.len(),
            pct(mr),
            pct(mb),
        )
    };
    c.fitted(body)
}
