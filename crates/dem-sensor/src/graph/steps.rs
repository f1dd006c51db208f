//! `steps`' effects as operators: heights moved at steps.

use super::heights::{cell_normals, sd_with_the_step};
use super::*;

/// `step-jitter`: dx = clamp((sigma + edge J) z, +-0.1 m) per cell, h +=
/// dx (h ahead - h behind) / 0.2, a missing or outside neighbour read as
/// the cell's own height.
pub(super) fn step_jitter(b: &mut Builder, c: &Cells, u: &str, sigma: f64, edge: f64) -> Cells {
    let cell = dem_core::format::CELL as f32;
    let z = cell_normals(b, u);
    let s = sd_with_the_step(b, c, sigma, edge);
    let dx = b.bin("Mul", &s, &z);
    let (lo, hi) = (b.scalar(-cell), b.scalar(cell));
    let dx = b.bin("Max", &dx, &lo);
    let dx = b.bin("Min", &dx, &hi);
    let (va, ha) = neighbour(b, c, Side::Ahead);
    let (vb, hb) = neighbour(b, c, Side::Behind);
    let ahead = b.select(&va, &ha, &c.h);
    let behind = b.select(&vb, &hb, &c.h);
    let rise = b.bin("Sub", &ahead, &behind);
    let slope = b.mul_const(&rise, 1.0 / (2.0 * cell));
    let dh = b.bin("Mul", &dx, &slope);
    let moved = b.bin("Add", &c.h, &dh);
    let valid = is_valid(b, &c.v);
    set_heights(b, c, &valid, &moved)
}

/// `smoothing`: the valid-weighted 3x3 mean, as two convolutions.
pub(super) fn smoothing(b: &mut Builder, c: &Cells, w: f64) -> Cells {
    let wn = (1.0 - w) / 8.0;
    let kernel: Vec<f32> = (0..9).map(|i| if i == 4 { 0.0 } else { 1.0 }).collect();
    let k = b.constant(&[1, 1, 3, 3], &kernel);
    let img = [-1, 1, GRID_ROWS as i64, COLS as i64];
    let attrs = || vec![dem_graph::attr_ints("kernel_shape", &[3, 3]), dem_graph::attr_ints("pads", &[1, 1, 1, 1])];
    let h4 = b.reshape(&c.h, &img);
    let v4 = b.reshape(&c.v, &img);
    let sum = b.op("Conv", &[&h4, &k], attrs());
    let count = b.op("Conv", &[&v4, &k], attrs());
    let grid = [-1, GRID_ROWS as i64, COLS as i64];
    let sum = b.reshape(&sum, &grid);
    let count = b.reshape(&count, &grid);
    let num = b.mul_const(&sum, wn as f32);
    let own = b.mul_const(&c.h, w as f32);
    let num = b.bin("Add", &own, &num);
    let den = b.mul_const(&count, wn as f32);
    let den = b.add_const(&den, w as f32);
    let mean = b.bin("Div", &num, &den);
    let valid = is_valid(b, &c.v);
    set_heights(b, c, &valid, &mean)
}

/// The step across the cell's larger x-jump of two: `(has, step, behind)`
/// where `ahead` is `(valid, step)` toward the cell ahead and `behind`
/// toward the one behind; behind wins (`behind` true) only when its step
/// is larger in magnitude or there is none ahead.
pub(super) fn larger_step(b: &mut Builder, ahead: (&str, &str), behind: (&str, &str)) -> (String, String, String) {
    let fa = b.un("Abs", ahead.1);
    let fa = b.add_const(&fa, crate::effects::TIE_MARGIN as f32);
    let ba = b.un("Abs", behind.1);
    let bigger = b.bin("Greater", &ba, &fa);
    let no_ahead = b.un("Not", ahead.0);
    let pick = b.any(&[&no_ahead, &bigger]);
    let pick_behind = b.all(&[behind.0, &pick]);
    let step = b.select(&pick_behind, behind.1, ahead.1);
    let has = b.any(&[ahead.0, behind.0]);
    (has, step, pick_behind)
}

/// `drop-blend`: beside a drop, with probability p, h += v a s.
pub(super) fn drop_blend(b: &mut Builder, c: &Cells, u: &str, p: f64, a: f64) -> Cells {
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
    let (has, step, _) = larger_step(b, (&fok, &f), (&bok, &bs));
    let valid = is_valid(b, &c.v);
    let hit = below(b, &u, p);
    let cond = b.all(&[&valid, &has, &hit]);
    let share = b.mul_const(&v, a as f32);
    let dh = b.bin("Mul", &share, &step);
    let moved = b.bin("Add", &c.h, &dh);
    set_heights(b, c, &cond, &moved)
}

/// `floor-lift`: beyond a drop, in rows behind x, with probability p,
/// h += min(1, v a) (edge - h).
pub(super) fn floor_lift(b: &mut Builder, c: &Cells, u: &str, x: f64, p: f64, a: f64) -> Cells {
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

/// `riser-blend`: the foot of a riser moves u foot of the step, its top u top.
pub(super) fn riser_blend(b: &mut Builder, c: &Cells, u: &str, foot: f64, top: f64) -> Cells {
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
    let (has, step, pick_behind) = larger_step(b, (&fok, &f), (&bok, &bs));
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

/// `mixed-cells`: per row boundary a step position s and per column a
/// reach; each half cell takes the higher surface that reaches it, else the
/// lower one, else its own height; the cell is the mean of its halves.
pub(super) fn mixed_cells(b: &mut Builder, c: &Cells, u: &str, up: f64, down: f64) -> Cells {
    let (rows, cols) = (GRID_ROWS as i64, COLS as i64);
    let bounds = rows - 1;
    let u = b.reshape(u, &[-1, bounds, 1 + cols]);
    let s = b.take(&u, 2, 0, 1);
    let reach_u = b.take(&u, 2, 1, 1 + cols);
    // s = (1 - 2 u) HALF, the step's distance past the boundary into row b.
    let s = b.mul_const(&s, (-2.0 * HALF) as f32);
    let s = b.add_const(&s, HALF as f32);
    let z0 = b.take(&c.h, 1, 0, bounds);
    let z1 = b.take(&c.h, 1, 1, rows);
    let v0 = b.take(&c.v, 1, 0, bounds);
    let v1 = b.take(&c.v, 1, 1, rows);
    let v0 = is_valid(b, &v0);
    let v1 = is_valid(b, &v1);
    let dz = b.bin("Sub", &z1, &z0);
    let adz = b.un("Abs", &dz);
    let big = b.gt_const(&adz, MIXED_JUMP as f32);
    let jump = b.all(&[&v0, &v1, &big]);
    let riser = b.gt_const(&dz, 0.0);
    let drop = b.un("Not", &riser);
    let minus_s = b.un("Neg", &s);
    let depth = b.select(&riser, &s, &minus_s);
    let (upc, downc) = (b.scalar(up as f32), b.scalar(down as f32));
    let reach = b.select(&riser, &upc, &downc);
    let into = b.bin("Mul", &reach_u, &reach);
    let into = b.bin("Add", &depth, &into);
    let out_of = b.un("Neg", &into);
    let zhi = b.bin("Max", &z0, &z1);
    let zlo = b.bin("Min", &z0, &z1);
    let (near, far) = ((0.5 * HALF) as f32, (1.5 * HALF) as f32);
    let a_near = b.gt_const(&into, near);
    let a_far = b.gt_const(&into, far);
    let b_near = b.gt_const(&out_of, near);
    let b_far = b.gt_const(&out_of, far);
    let cond = |b: &mut Builder, kind: &str, reach: &str| b.all(&[&jump, kind, reach]);
    // Boundary b's upper row is b (its half 1 is near), its lower row b + 1
    // (its half 0 is near). (raise, lower) conditions per half.
    let top = [
        // half 0 of row b: far from boundary b
        (cond(b, &riser, &a_far), cond(b, &drop, &b_far)),
        // half 1 of row b: near
        (cond(b, &riser, &a_near), cond(b, &drop, &b_near)),
    ];
    let bottom = [
        // half 0 of row b + 1: near
        (cond(b, &drop, &a_near), cond(b, &riser, &b_near)),
        // half 1 of row b + 1: far
        (cond(b, &drop, &a_far), cond(b, &riser, &b_far)),
    ];
    let (lowest, highest) = (b.scalar(-FAR), b.scalar(FAR));
    // Place a boundary's (N, 19, 5) tensor on the grid's rows: as the upper
    // row (pad at the end) or the lower row (pad at the start).
    let place = |b: &mut Builder, x: &str, upper: bool, fill: f32| {
        let pads = if upper { [0, 0, 0, 0, 1, 0] } else { [0, 1, 0, 0, 0, 0] };
        let pads = b.ints(&pads);
        let fill = b.scalar(fill);
        b.op("Pad", &[x, &pads, &fill], vec![])
    };
    let mut halves = Vec::new();
    for half in 0..2 {
        let mut raise = Vec::new();
        let mut lower = Vec::new();
        for (upper, (r_cond, l_cond)) in [(true, &top[half]), (false, &bottom[half])] {
            let r = b.select(r_cond, &zhi, &lowest);
            raise.push(place(b, &r, upper, -FAR));
            let l = b.select(l_cond, &zlo, &highest);
            lower.push(place(b, &l, upper, FAR));
        }
        let raise = b.bin("Max", &raise[0], &raise[1]);
        let lower = b.bin("Min", &lower[0], &lower[1]);
        let raised = b.gt_const(&raise, -FAR / 2.0);
        let lowered = b.lt_const(&lower, FAR / 2.0);
        let x = b.select(&lowered, &lower, &c.h);
        halves.push(b.select(&raised, &raise, &x));
    }
    let sum = b.bin("Add", &halves[0], &halves[1]);
    let mean = b.mul_const(&sum, 0.5);
    let valid = is_valid(b, &c.v);
    set_heights(b, c, &valid, &mean)
}
