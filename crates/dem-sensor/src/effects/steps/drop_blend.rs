//! `drop-blend`: cells on both sides of a drop edge read part of the way across.

use super::{ops, SHARE, TIE_MARGIN};
use crate::draws::Draws;
use crate::effects::{cell_heights, hit, params, probability, EffectKind, EffectSpec, Family, Stage, MIXED_JUMP};
use crate::evidence::{mid, mm, pct, Context};
use crate::graph::ops::{below, cell_pairs, is_valid, neighbour, set_heights, Cells, Side};
use dem_core::distribution::Stats;
use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Cells on both sides of a drop edge read part of the way to the other
    /// side, in some records: the stereo matcher's window straddles the
    /// jump in range there and averages across it.
    #[serde(expecting = "struct variant Effect::DropBlend")]
    DropBlend {
        // Every cell beside a drop blended, or moved all the way: natural ends.
        /// Probability that a cell beside a drop is blended.
        p: fit SHARE.0, limit SHARE.1;
        /// Largest share of the drop it moves across.
        a: fit SHARE.0, limit SHARE.1;
    }
}

impl EffectKind for DropBlend {
    const SPEC: EffectSpec = EffectSpec {
        name: "drop-blend",
        family: Family::Steps,
        emulator: &["smoothing"],
        formula: "at a drop along x (valid cells of rows r and r + 1, row r + 1 lower by more than MIXED_JUMP), each of the two cells \
            reads, with probability p, h + u a (h_n - h), u uniform, h_n the other cell (a cell between two drops takes the larger; \
            the one behind only when larger by more than TIE_MARGIN): the stereo window straddles the jump in range at a drop edge \
            and its mean range puts the cell's points part of the way to the other surface",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::DropMoves,
        // Two per cell: whether it is blended, and how far.
        draws: 2 * GRID_ROWS * COLS,
    };

    fn check(&self) -> Result<(), String> {
        let Self { p, a } = *self;
        check_drop_blend(p, a)
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, _time: Option<f64>) {
        let Self { p, a } = *self;
        blend_drops(d, rng, p, a)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, _time: Option<&str>) -> Cells {
        let Self { p, a } = *self;
        operators(b, c, u, p, a)
    }

    fn evidence(&self, c: &Context) -> String {
        sentence(c)
    }

    fn examples() -> Vec<Self> {
        vec![DropBlend { p: 0.6, a: 0.8 }]
    }
}

fn check_drop_blend(p: f64, a: f64) -> Result<(), String> {
    probability(p)?;
    if !(0.0..=1.0).contains(&a) {
        return Err(format!("a = {a} must be in [0, 1]"));
    }
    Ok(())
}

/// `drop-blend`: heights are read on the DEM as it comes in, so a cell
/// between two drops blends toward one of them only. Risers (the higher
/// cell ahead) are left alone: the surface seen is continuous there (a
/// corner, not a jump in range), and the emulator moves their cells by a
/// fifth of the step at most.
fn blend_drops(d: &mut Dem, rng: &mut Draws, p: f64, a: f64) {
    let z = cell_heights(d);
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let (u, v): (f64, f64) = (rng.gen(), rng.gen());
            let Some(zc) = z[r][c] else { continue };
            // The other cell across a drop: ahead and lower, or behind and higher.
            // The steps and the tie between them in float32, operation for
            // operation as the graph decides them.
            let across = |rr: usize, ahead: bool| {
                let step = z.get(rr).and_then(|row| row[c])? as f32 - zc as f32;
                ((if ahead { -step } else { step }) > MIXED_JUMP as f32).then_some(step)
            };
            let step = match (across(r + 1, true), across(r.wrapping_sub(1), false)) {
                (Some(f), Some(b)) => Some(if b.abs() > f.abs() + TIE_MARGIN as f32 { b } else { f }),
                (f, b) => f.or(b),
            };
            if let (Some(s), true) = (step, hit(u, p)) {
                d.set_valid(r, c, (zc + v * a * f64::from(s)) as f32);
            }
        }
    }
}

/// `drop-blend`: beside a drop, with probability p, h += v a s.
fn operators(b: &mut Builder, c: &Cells, u: &str, p: f64, a: f64) -> Cells {
    let (u, v) = cell_pairs(b, u);
    let (va, za) = neighbour(b, c, Side::Ahead);
    let (vb, zb) = neighbour(b, c, Side::Behind);
    let f = b.bin("Sub", &za, &c.h);
    let fneg = b.un("Neg", &f);
    let fbig = b.gt_const(&fneg, MIXED_JUMP as f32);
    let fok = b.all(&[&va, &fbig]);
    let bs = b.bin("Sub", &zb, &c.h);
    let bbig = b.gt_const(&bs, MIXED_JUMP as f32);
    let bok = b.all(&[&vb, &bbig]);
    let (has, step, _) = ops::larger_step(b, (&fok, &f), (&bok, &bs));
    let valid = is_valid(b, &c.v);
    let hit = below(b, &u, p);
    let cond = b.all(&[&valid, &has, &hit]);
    let share = b.mul_const(&v, a as f32);
    let dh = b.bin("Mul", &share, &step);
    let moved = b.bin("Add", &c.h, &dh);
    set_heights(b, c, &cond, &moved)
}

/// The evidence for `drop-blend`.
fn sentence(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let (q, spread) = if real.paired {
            ("spread-q99", "99th percentile of the residual (real - sim)")
        } else {
            ("spread-q90", "90th percentile of the across-robot height difference")
        };
        let tail = |s: &Stats| s.mean_over(q, 0..20);
        let verdict = if mid(real) > mid(before) && tail(real) > tail(before) {
            "cells beside drops read part of the way across in some records"
        } else {
            "no more part-way steps or wide tails in real: blended drops are the closest effect, not a clear one"
        };
        format!(
            "steps between neighbouring rows of 0.02-0.1 m: real {} vs model {}; {spread}: real {} vs model {}: {verdict}",
            pct(mid(real)),
            pct(mid(before)),
            mm(tail(real)),
            mm(tail(before)),
        )
    };
    c.fitted(body)
}
