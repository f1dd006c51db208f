//! `riser-blend`: cells beside a riser read part of the way up or down the step.

use super::{ops, TIE_MARGIN};
use crate::draws::Draws;
use crate::effects::{cell_heights, params, EffectKind, EffectSpec, Family, Limit, Range, Stage, MIXED_JUMP};
use crate::evidence::{part_way_steps, pct, Context};
use crate::graph::ops::{is_valid, neighbour, set_heights, Cells, Side};
use dem_core::distribution::Stats;
use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Cells beside a riser read part of the way up or down the step: the
    /// stereo window over the riser's corners moves their points along the
    /// rays, by a share and in a direction that depend on the view angle.
    #[serde(expecting = "struct variant Effect::RiserBlend")]
    RiserBlend {
        // Either way across the step; 0 (no move) on the grid. Moved all the
        // way to the other surface: a natural end; the other end (away from
        // it) is not.
        /// Largest share of the step the cell at the riser's foot moves toward the top (negative: down, away
        /// from it).
        foot: fit Range::lin(-0.6, 1.0), limit Limit::new(-1.0, 1.0).natural_hi();
        /// Largest share of the step the cell on the riser's top moves toward the foot (negative: up, away from
        /// it).
        top: fit Range::lin(-0.6, 1.0), limit Limit::new(-1.0, 1.0).natural_hi();
    }
}

impl EffectKind for RiserBlend {
    const SPEC: EffectSpec = EffectSpec {
        name: "riser-blend",
        family: Family::Steps,
        emulator: &["fov", "smoothing"],
        formula: "at a riser along x (valid cells of rows r and r + 1, row r + 1 higher by more than MIXED_JUMP), the cell at its foot \
            reads h + u `foot` (h_n - h) and the cell on its top h + u `top` (h_n - h), u uniform per cell, h_n the other cell (a \
            cell beside two risers takes the larger step; the one behind only when larger by more than TIE_MARGIN); `foot`, `top` in \
            [-1, 1], negative: away from the other surface: the stereo window over a riser's corners moves the points there along \
            their rays, up or down the step as the view angle gives",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::RiserMoves,
        // One per cell.
        draws: GRID_ROWS * COLS,
    };

    fn check(&self) -> Result<(), String> {
        let Self { foot, top } = *self;
        check_riser_blend(foot, top)
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, _time: Option<f64>) {
        let Self { foot, top } = *self;
        blend_risers(d, rng, foot, top)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, _time: Option<&str>) -> Cells {
        let Self { foot, top } = *self;
        operators(b, c, u, foot, top)
    }

    fn evidence(&self, c: &Context) -> String {
        let Self { foot, top } = *self;
        sentence(c, foot, top)
    }

    fn examples() -> Vec<Self> {
        vec![RiserBlend { foot: 0.4, top: -0.3 }]
    }
}

fn check_riser_blend(foot: f64, top: f64) -> Result<(), String> {
    if !(-1.0..=1.0).contains(&foot) || !(-1.0..=1.0).contains(&top) {
        return Err(format!("foot = {foot} and top = {top} must be in [-1, 1]"));
    }
    Ok(())
}

/// `riser-blend`: heights are read on the DEM as it comes in; a cell beside
/// two risers (a one-cell tread) moves across the larger step only.
fn blend_risers(d: &mut Dem, rng: &mut Draws, foot: f64, top: f64) {
    let z = cell_heights(d);
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let u: f64 = rng.gen();
            let Some(zc) = z[r][c] else { continue };
            // (step to the other cell, share): the riser ahead (this cell
            // at its foot) or behind (this cell on its top).
            // The steps and the tie between them in float32, operation for
            // operation as the graph decides them.
            let across = |rr: usize, share: f64| {
                let step = z.get(rr).and_then(|row| row[c])? as f32 - zc as f32;
                let riser = if rr > r { step } else { -step } > MIXED_JUMP as f32;
                riser.then_some((step, share))
            };
            let moved = match (across(r + 1, foot), across(r.wrapping_sub(1), top)) {
                (Some(f), Some(b)) => Some(if b.0.abs() > f.0.abs() + TIE_MARGIN as f32 { b } else { f }),
                (f, b) => f.or(b),
            };
            if let Some((step, share)) = moved {
                d.set_valid(r, c, (zc + u * share * f64::from(step)) as f32);
            }
        }
    }
}

/// `riser-blend`: the foot of a riser moves u foot of the step, its top u top.
fn operators(b: &mut Builder, c: &Cells, u: &str, foot: f64, top: f64) -> Cells {
    let u = b.reshape(u, &[-1, GRID_ROWS as i64, COLS as i64]);
    let (va, za) = neighbour(b, c, Side::Ahead);
    let (vb, zb) = neighbour(b, c, Side::Behind);
    let f = b.bin("Sub", &za, &c.h);
    let fbig = b.gt_const(&f, MIXED_JUMP as f32);
    let fok = b.all(&[&va, &fbig]);
    let bs = b.bin("Sub", &zb, &c.h);
    let bneg = b.un("Neg", &bs);
    let bbig = b.gt_const(&bneg, MIXED_JUMP as f32);
    let bok = b.all(&[&vb, &bbig]);
    let (has, step, pick_behind) = ops::larger_step(b, (&fok, &f), (&bok, &bs));
    // The share goes with the side that won.
    let (foot, top) = (b.scalar(foot as f32), b.scalar(top as f32));
    let share = b.select(&pick_behind, &top, &foot);
    let valid = is_valid(b, &c.v);
    let cond = b.all(&[&valid, &has]);
    let x = b.bin("Mul", &u, &share);
    let dh = b.bin("Mul", &x, &step);
    let moved = b.bin("Add", &c.h, &dh);
    set_heights(b, c, &cond, &moved)
}

/// The evidence for `riser-blend`.
fn sentence(c: &Context, foot: f64, top: f64) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let way = |share: f64, toward: &'static str, away: &'static str| if share >= 0.0 { toward } else { away };
        let fitted = format!("the foot {}, the top {}", way(foot, "up", "down"), way(top, "down", "up"));
        if real.paired {
            // The step-side terms' shares of cells moved > 2 cm toward
            // the other surface and away (components 2 and 3).
            let moved = |s: &Stats, side: &str| s.term(side).map_or(0.0, |t| t.values[2] + t.values[3]);
            let more = |side: &str| moved(real, side) > moved(before, side);
            let verdict = if more("riser-foot") || more("riser-top") {
                format!("cells beside risers read part of the way across the step: {fitted}")
            } else {
                "real moves no more riser cells than the model: blended risers are the closest effect, not a clear one".to_string()
            };
            format!(
                "cells beside risers moved more than 2 cm: at the foot real {} vs model {}, on the top real {} vs model {}: {verdict}",
                pct(moved(real, "riser-foot")),
                pct(moved(before, "riser-foot")),
                pct(moved(real, "riser-top")),
                pct(moved(before, "riser-top")),
            )
        } else {
            part_way_steps(
                real,
                before,
                format!("cells beside risers read part of the way across the step: {fitted}"),
                "blended risers are",
            )
        }
    };
    c.fitted(body)
}
