//! `floor-lift`: the ground just beyond a drop edge reads part of the way up to it.

use super::SHARE;
use crate::draws::Draws;
use crate::effects::{cell_heights, exceeds, hit, params, probability, EffectKind, EffectSpec, Family, Limit, Range, Stage, MIXED_JUMP};
use crate::evidence::{mid, pct, Context};
use crate::graph::ops::{below, cell_pairs, is_valid, neighbour, per_row, set_heights, Cells, Side};
use dem_core::distribution::Stats;
use dem_core::format::{row_center_x, Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// The ground just beyond a drop edge reads part of the way up to it:
    /// the edge hides the floor nearest it from the camera, and the cell
    /// keeps the points it got near the edge. Everywhere where occlusion
    /// acts; in the rows the camera's lowest ray no longer reaches, the map
    /// keeps that grazing view where a closer, steeper look would see the
    /// floor (the field of view).
    #[serde(expecting = "struct variant Effect::FloorLift")]
    FloorLift {
        // x from the rows behind the robot (where a camera whose lowest ray
        // meets the ground ahead keeps its grazing view) to past the grid
        // (every row: occlusion alone); a up to 3 (two in three moved cells
        // read the edge's height). No rows (x behind the grid) or all of them,
        // no cell or every one, none moved or (a large) all the way: natural ends.
        /// Only rows whose centre lies behind this x (m) (past the grid: all).
        x: fit Range::lin(-0.3, 1.45), limit Limit::new(-0.6, 1.45).natural_lo().natural_hi();
        /// Probability that a cell beyond a drop there reads higher.
        p: fit SHARE.0, limit SHARE.1;
        /// Reach: the share moved is min(1, u a), u uniform (a > 1: some cells read the edge's height).
        a: fit Range::lin(0.0, 3.0), limit Limit::new(0.0, 5.0).natural_lo().natural_hi();
    }
}

impl EffectKind for FloorLift {
    const SPEC: EffectSpec = EffectSpec {
        name: "floor-lift",
        family: Family::Steps,
        emulator: &["fov", "occlusion", "smoothing"],
        formula: "in rows whose centre x < `x`, a valid cell whose valid neighbour behind (row r - 1) is higher by more than MIXED_JUMP \
            (the ground just beyond a drop edge) reads, with probability p, h + min(1, u a) (h_n - h), u uniform, h_n that \
            neighbour: the edge hides the floor nearest it, and the cell keeps points lifted toward the edge (x past the grid: every \
            row; x at the cone's lowest ray: the rows where the map keeps that grazing view)",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::DropMoves,
        // Two per cell: whether it is lifted, and how far.
        draws: 2 * GRID_ROWS * COLS,
    };

    fn check(&self) -> Result<(), String> {
        let Self { p, a, .. } = *self;
        check_floor_lift(p, a)
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, _time: Option<f64>) {
        let Self { x, p, a } = *self;
        lift_floors(d, rng, x, p, a)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, _time: Option<&str>) -> Cells {
        let Self { x, p, a } = *self;
        operators(b, c, u, x, p, a)
    }

    fn evidence(&self, c: &Context) -> String {
        let Self { x, .. } = *self;
        sentence(c, x)
    }

    fn examples() -> Vec<Self> {
        vec![FloorLift { x: 0.6, p: 0.7, a: 1.5 }]
    }
}

fn check_floor_lift(p: f64, a: f64) -> Result<(), String> {
    probability(p)?;
    if a < 0.0 {
        return Err(format!("a = {a} must be >= 0"));
    }
    Ok(())
}

/// `floor-lift` (formula in its spec): heights are read on the DEM as it
/// comes in, so a cell beyond two drops (a one-cell tread) moves toward
/// the edge just behind it only.
fn lift_floors(d: &mut Dem, rng: &mut Draws, x: f64, p: f64, a: f64) {
    let z = cell_heights(d);
    for (r, row) in z.iter().enumerate() {
        for (c, &zc) in row.iter().enumerate() {
            let (u, v): (f64, f64) = (rng.gen(), rng.gen());
            let (Some(zc), true) = (zc, r > 0 && row_center_x(r) < x) else { continue };
            let Some(edge) = z[r - 1][c] else { continue };
            if exceeds(edge, zc, MIXED_JUMP) && hit(u, p) {
                d.set_valid(r, c, (zc + (v * a).min(1.0) * (edge - zc)) as f32);
            }
        }
    }
}

/// `floor-lift`: beyond a drop, in rows behind x, with probability p,
/// h += min(1, v a) (edge - h).
fn operators(b: &mut Builder, c: &Cells, u: &str, x: f64, p: f64, a: f64) -> Cells {
    let (u, v) = cell_pairs(b, u);
    let rows = per_row(b, |r| f64::from(u8::from(r > 0 && row_center_x(r) < x)));
    let rows = b.gt_const(&rows, 0.5);
    let (vb, zb) = neighbour(b, c, Side::Behind);
    let up = b.bin("Sub", &zb, &c.h);
    let big = b.gt_const(&up, MIXED_JUMP as f32);
    let valid = is_valid(b, &c.v);
    let hit = below(b, &u, p);
    let cond = b.all(&[&rows, &valid, &vb, &big, &hit]);
    let share = b.mul_const(&v, a as f32);
    let one = b.scalar(1.0);
    let share = b.bin("Min", &share, &one);
    let dh = b.bin("Mul", &share, &up);
    let moved = b.bin("Add", &c.h, &dh);
    set_heights(b, c, &cond, &moved)
}

/// The evidence for `floor-lift`.
fn sentence(c: &Context, x: f64) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let rows = if x > row_center_x(GRID_ROWS - 1) { "in every row".to_string() } else { format!("in the rows behind x = {x:.2} m") };
        let verdict = format!("the ground just beyond a drop edge reads part of the way up ({rows}): the edge hides the floor nearest it");
        if real.paired {
            // The drop floors' share moved > 2 cm toward the edge (component 2).
            let up = |s: &Stats| s.term("drop-floor").map_or(0.0, |t| t.values[2]);
            let v = if up(real) > up(before) {
                verdict
            } else {
                "real moves no more cells beyond drops than the model: lifted floors are the closest effect, not a clear one".into()
            };
            format!("cells beyond a drop read more than 2 cm up toward its edge: real {} vs model {}: {v}", pct(up(real)), pct(up(before)))
        } else {
            let v = if mid(real) > mid(before) {
                verdict
            } else {
                "no more part-way steps in real: lifted floors are the closest effect, not a clear one".into()
            };
            format!("steps between neighbouring rows of 0.02-0.1 m: real {} vs model {}: {v}", pct(mid(real)), pct(mid(before)))
        }
    };
    c.fitted(body)
}
