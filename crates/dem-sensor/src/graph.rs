//! A sensor model as ONNX operators: the same effects as [`crate::effects`],
//! on a batch, with the record's uniforms and time as graph inputs.
//!
//! The grid travels through the graph as two float32 tensors `(N, 20, 5)`
//! ([`Cells`]): `v`, 1 where a cell is valid and 0 where it is missing, and
//! `h`, its height (0 where missing, as the contract stores it). Each effect
//! reads the cells as they come in (a snapshot, as the native code reads
//! [`heights`](crate::effects) before it writes) and returns new ones.
//! Neighbours are the grid shifted by one row or column, padded with
//! missing cells ([`dem_graph::Builder::shift`]).
//!
//! The graph computes in float32 where the native code computes in float64
//! from float32 heights: heights agree within ~1e-6 m, and a cell's validity
//! differs only where a comparison lies within float32's rounding of its
//! threshold. Comparisons of a uniform with a probability are exact in both
//! (24-bit uniforms, [`crate::draws`]).

use dem_core::format::{col_center_y, row_center_x, COLS, GRID_ROWS};
use dem_graph::{Builder, Input};

use crate::effects::{
    Effect, MAX_CLIMB_PITCH, MAX_SHIFT, MIXED_JUMP, NOISE_ORIGIN, NOISE_RANGE_HEIGHT, OCCLUSION_TOLERANCE, PATCH_SLOTS, SHAKE_MAX_STEP,
    TRACK_ROWS,
};
use crate::SensorModel;

/// Name of a sensor graph's DEM input (`(N, 21, 5, 2)`, the file layout).
pub const INPUT: &str = "dem";
/// Name of the uniforms input: `(N, K)`, float32 in [0, 1), K =
/// [`SensorModel::draws`], each effect's slice in the model's order.
pub const UNIFORM: &str = "uniform";
/// Name of the time input: `(N,)`, float32 seconds into the run; NaN where
/// unknown (`startup` then draws startup frames at its rate `p`).
pub const TIME: &str = "time";
/// Name of the output DEM (`(N, 21, 5, 2)`).
pub const OUTPUT: &str = "dem_out";

/// Half a cell's edge (m).
const HALF: f64 = 0.05;
/// Stands in for "no value" in maxima and minima (heights are never near it).
const FAR: f32 = 1e9;

/// The grid of a batch inside a graph: `h` heights and `v` validity (1/0),
/// both float32 `(N, 20, 5)`.
#[derive(Clone, Debug)]
pub struct Cells {
    /// Heights, 0 where missing.
    pub h: String,
    /// 1 where valid, 0 where missing.
    pub v: String,
}

/// Neighbour directions on the grid.
#[derive(Clone, Copy)]
enum Side {
    /// Row r + 1 (farther along x).
    Ahead,
    /// Row r - 1.
    Behind,
    /// Column c - 1.
    Left,
    /// Column c + 1.
    Right,
}

/// `x` at each cell's neighbour on `side`; `fill` outside the grid.
fn nb(b: &mut Builder, x: &str, side: Side, fill: f32) -> String {
    let (rows, cols) = (GRID_ROWS as i64, COLS as i64);
    match side {
        Side::Ahead => b.shift(x, 1, 3, rows, 1, fill),
        Side::Behind => b.shift(x, 1, 3, rows, -1, fill),
        Side::Left => b.shift(x, 2, 3, cols, -1, fill),
        Side::Right => b.shift(x, 2, 3, cols, 1, fill),
    }
}

/// A per-row constant `(1, 20, 1)`.
fn per_row(b: &mut Builder, f: impl Fn(usize) -> f64) -> String {
    let data: Vec<f32> = (0..GRID_ROWS).map(|r| f(r) as f32).collect();
    b.constant(&[1, GRID_ROWS, 1], &data)
}

/// A per-cell constant `(1, 20, 5)`.
fn per_cell(b: &mut Builder, f: impl Fn(usize, usize) -> f64) -> String {
    let data: Vec<f32> = (0..GRID_ROWS * COLS).map(|i| f(i / COLS, i % COLS) as f32).collect();
    b.constant(&[1, GRID_ROWS, COLS], &data)
}

/// A boolean tensor: where `v` (1/0) is valid.
fn is_valid(b: &mut Builder, v: &str) -> String {
    b.gt_const(v, 0.5)
}

/// The cells with `miss` (boolean, broadcast to the grid) made missing.
fn drop_cells(b: &mut Builder, c: &Cells, miss: &str) -> Cells {
    let zero = b.scalar(0.0);
    Cells { v: b.select(miss, &zero, &c.v), h: b.select(miss, &zero, &c.h) }
}

/// The cells with height `new` where `cond` (boolean) holds.
fn set_heights(b: &mut Builder, c: &Cells, cond: &str, new: &str) -> Cells {
    Cells { v: c.v.clone(), h: b.select(cond, new, &c.h) }
}

/// `u < p`, the uniform against a probability.
fn below(b: &mut Builder, u: &str, p: f64) -> String {
    b.lt_const(u, p as f32)
}

/// A valid neighbour on `side` and its height: `(valid (bool), height)`.
fn neighbour(b: &mut Builder, c: &Cells, side: Side) -> (String, String) {
    let v = nb(b, &c.v, side, 0.0);
    let h = nb(b, &c.h, side, 0.0);
    (is_valid(b, &v), h)
}

/// The uniforms of one effect: `u[:, at..at + n]` reshaped to `shape`
/// (batch axis first, as `-1`).
fn uniforms(b: &mut Builder, u: &str, at: usize, n: usize, shape: &[i64]) -> String {
    let s = b.take(u, 1, at as i64, (at + n) as i64);
    b.reshape(&s, shape)
}

/// The per-cell uniform pairs `(u, v)` of a 200-draw effect: two `(N, 20, 5)`.
fn cell_pairs(b: &mut Builder, u: &str) -> (String, String) {
    let pairs = b.reshape(u, &[-1, GRID_ROWS as i64, COLS as i64, 2]);
    let first = b.take(&pairs, 3, 0, 1);
    let second = b.take(&pairs, 3, 1, 2);
    let grid = [-1, GRID_ROWS as i64, COLS as i64];
    (b.reshape(&first, &grid), b.reshape(&second, &grid))
}

/// The input DEM `(N, 21, 5, 2)` split into [`Cells`] (a cell is valid
/// where its mask is > 0) and row 20 `(N, 1, 5, 2)`.
pub fn split_dem(b: &mut Builder, dem: &str) -> (Cells, String) {
    let grid = b.take(dem, 1, 0, GRID_ROWS as i64);
    let row20 = b.take(dem, 1, GRID_ROWS as i64, GRID_ROWS as i64 + 1);
    let shape = [-1, GRID_ROWS as i64, COLS as i64];
    let h = b.take(&grid, 3, 0, 1);
    let h = b.reshape(&h, &shape);
    let m = b.take(&grid, 3, 1, 2);
    let m = b.reshape(&m, &shape);
    let valid = b.gt_const(&m, 0.0);
    let v = b.to_float(&valid);
    let zero = b.scalar(0.0);
    let h = b.select(&valid, &h, &zero);
    (Cells { h, v }, row20)
}

/// [`Cells`] and row 20 joined into a DEM `(N, 21, 5, 2)` named `out`:
/// valid cells with mask +1, missing ones height 0 and mask -1.
pub fn join_dem(b: &mut Builder, c: &Cells, row20: &str, out: &str) -> String {
    let valid = is_valid(b, &c.v);
    let (one, minus, zero) = (b.scalar(1.0), b.scalar(-1.0), b.scalar(0.0));
    let m = b.select(&valid, &one, &minus);
    let h = b.select(&valid, &c.h, &zero);
    let shape = [-1, GRID_ROWS as i64, COLS as i64, 1];
    let h = b.reshape(&h, &shape);
    let m = b.reshape(&m, &shape);
    let grid = b.concat(&[&h, &m], 3);
    b.node("Concat", &[&grid, row20], vec![dem_graph::attr_int("axis", 1)], out)
}

/// Every effect of `model`, in order, on `cells`; `uniform` is the graph's
/// `(N, K)` uniforms (needed when K > 0), `time` its `(N,)` times (needed
/// when the model has `startup`).
pub fn apply(b: &mut Builder, model: &SensorModel, cells: Cells, uniform: Option<&str>, time: Option<&str>) -> Cells {
    let mut at = 0;
    let mut c = cells;
    let base = b.prefix().to_string();
    for (i, e) in model.effects.iter().enumerate() {
        let scope = format!("sensor.{i}.{}", e.name());
        b.set_prefix(&if base.is_empty() { scope } else { format!("{base}.{scope}") });
        let n = e.draws();
        let u = (n > 0).then(|| uniforms(b, uniform.expect("a model with draws has a uniform input"), at, n, &[-1, n as i64]));
        c = effect(b, e, &c, u.as_deref(), time);
        at += n;
    }
    b.set_prefix(&base);
    c
}

/// One effect on `c`; `u` its uniforms `(N, draws)`.
fn effect(b: &mut Builder, e: &Effect, c: &Cells, u: Option<&str>, time: Option<&str>) -> Cells {
    let grid = [-1, GRID_ROWS as i64, COLS as i64];
    let u = || u.expect("an effect with draws gets its uniforms").to_string();
    match *e {
        Effect::Noise { sigma0, k } => noise(b, c, &u(), sigma0, k),
        Effect::Dropout { p } => {
            let u = b.reshape(&u(), &grid);
            let miss = below(b, &u, p);
            drop_cells(b, c, &miss)
        }
        Effect::RowDropout { p } => {
            let u = b.reshape(&u(), &[-1, GRID_ROWS as i64, 1]);
            let miss = below(b, &u, p);
            drop_cells(b, c, &miss)
        }
        Effect::Occlusion { h, x0 } => occlusion(b, c, h, x0),
        Effect::Fov { x_min, x_max } => {
            let out = per_row(b, |r| f64::from(u8::from(row_center_x(r) < x_min || row_center_x(r) > x_max)));
            let miss = b.gt_const(&out, 0.5);
            drop_cells(b, c, &miss)
        }
        Effect::ViewTop { h, t } => {
            let top = per_row(b, |r| h - t * row_center_x(r));
            let above = b.bin("Greater", &c.h, &top);
            let valid = is_valid(b, &c.v);
            let miss = b.all(&[&valid, &above]);
            drop_cells(b, c, &miss)
        }
        Effect::Smoothing { w } => smoothing(b, c, w),
        Effect::Bias { b: off, t } => {
            let shift = per_row(b, |r| off + t * row_center_x(r));
            let moved = b.bin("Add", &c.h, &shift);
            let valid = is_valid(b, &c.v);
            set_heights(b, c, &valid, &moved)
        }
        Effect::Quantization { q } => {
            let q = b.scalar(q as f32);
            let x = b.bin("Div", &c.h, &q);
            let x = b.add_const(&x, crate::effects::ROUND_UP_FROM as f32);
            let x = b.un("Floor", &x);
            let x = b.bin("Mul", &q, &x);
            let valid = is_valid(b, &c.v);
            set_heights(b, c, &valid, &x)
        }
        Effect::Startup { x0, v, p } => startup(b, c, &u(), time, x0, v, p),
        Effect::PatchDropout { n, r, a } => patches(b, c, &u(), n, r, a),
        Effect::EdgeHoles { g, p } => jump_holes(b, c, &u(), g, p, 1.0),
        Effect::RimHoles { g, p } => jump_holes(b, c, &u(), g, p, -1.0),
        Effect::DropHoles { p } => drop_holes(b, c, &u(), p),
        Effect::HoleGrowth { p } => hole_growth(b, c, &u(), p),
        Effect::PitFill { g, p } => pit_fill(b, c, &u(), g, p),
        Effect::DropBlend { p, a } => drop_blend(b, c, &u(), p, a),
        Effect::FloorLift { x, p, a } => floor_lift(b, c, &u(), x, p, a),
        Effect::RiserBlend { foot, top } => riser_blend(b, c, &u(), foot, top),
        Effect::MixedCells { up, down } => mixed_cells(b, c, &u(), up, down),
        Effect::Tilt { pitch, roll, x0, range } => {
            let (z1, z2) = normal_pairs(b, &u(), 1);
            let a = b.mul_const(&z1, pitch as f32);
            let bb = b.mul_const(&z2, roll as f32);
            tilt_plane(b, c, &a, &bb, |x| range + x.max(x0) - x0)
        }
        Effect::Shake { sigma, edge } => {
            let (z1, z2) = normal_pairs(b, &u(), 1);
            let s = sd_with_the_step(b, c, sigma, edge);
            let a = b.bin("Mul", &s, &z1);
            let bb = b.bin("Mul", &s, &z2);
            tilt_plane(b, c, &a, &bb, |x| x)
        }
        Effect::StepJitter { sigma, edge } => step_jitter(b, c, &u(), sigma, edge),
        Effect::Lag { s, spread } => lag(b, c, &u(), s, spread),
        Effect::Drift { rate, zrate, x0 } => drift(b, c, &u(), rate, zrate, x0),
    }
}

/// Standard normals from `k` Box-Muller pairs of uniforms `(N, 2 k)`: the
/// cosines and the sines, each `(N, k, 1)`.
fn normal_pairs(b: &mut Builder, u: &str, k: usize) -> (String, String) {
    let pairs = b.reshape(u, &[-1, k as i64, 2]);
    let u1 = b.take(&pairs, 2, 0, 1);
    let u2 = b.take(&pairs, 2, 1, 2);
    let one = b.scalar(1.0);
    let x = b.bin("Sub", &one, &u1);
    let x = b.un("Log", &x);
    let x = b.mul_const(&x, -2.0);
    let radius = b.un("Sqrt", &x);
    let angle = b.mul_const(&u2, (2.0 * std::f64::consts::PI) as f32);
    let cos = b.un("Cos", &angle);
    let sin = b.un("Sin", &angle);
    (b.bin("Mul", &radius, &cos), b.bin("Mul", &radius, &sin))
}

/// `tilt`, `shake`: h += a lever(x) + b y on the valid cells, `a` and `bb`
/// per record `(N, 1, 1)`.
fn tilt_plane(b: &mut Builder, c: &Cells, a: &str, bb: &str, lever: impl Fn(f64) -> f64) -> Cells {
    let lx = per_row(b, |r| lever(row_center_x(r)));
    let ys: Vec<f32> = (0..COLS).map(|col| col_center_y(col) as f32).collect();
    let ys = b.constant(&[1, 1, COLS], &ys);
    let along = b.bin("Mul", a, &lx);
    let across = b.bin("Mul", bb, &ys);
    let dh = b.bin("Add", &along, &across);
    let moved = b.bin("Add", &c.h, &dh);
    let valid = is_valid(b, &c.v);
    set_heights(b, c, &valid, &moved)
}

/// `shake`'s J `(N, 1, 1)`: the largest step between valid x-neighbours of
/// the rows under the tracks, capped.
fn step_under_tracks(b: &mut Builder, c: &Cells) -> String {
    let (first, last) = (TRACK_ROWS.0 as i64, TRACK_ROWS.1 as i64);
    let h0 = b.take(&c.h, 1, first, last);
    let h1 = b.take(&c.h, 1, first + 1, last + 1);
    let v0 = b.take(&c.v, 1, first, last);
    let v1 = b.take(&c.v, 1, first + 1, last + 1);
    let both = b.bin("Mul", &v0, &v1);
    let both = is_valid(b, &both);
    let d = b.bin("Sub", &h1, &h0);
    let d = b.un("Abs", &d);
    let zero = b.scalar(0.0);
    let d = b.select(&both, &d, &zero);
    let j = b.reduce("ReduceMax", &d, &[1, 2]);
    let j = b.reshape(&j, &[-1, 1, 1]);
    let cap = b.scalar(SHAKE_MAX_STEP as f32);
    b.bin("Min", &j, &cap)
}

/// `shake`'s and `step-jitter`'s sd per record `(N, 1, 1)`: sigma + edge J.
fn sd_with_the_step(b: &mut Builder, c: &Cells, sigma: f64, edge: f64) -> String {
    let j = step_under_tracks(b, c);
    let s = b.mul_const(&j, edge as f32);
    b.add_const(&s, sigma as f32)
}

/// [`crate::effects::shift_rows`] in the graph: each row reads the column
/// `q` rows back (`q` broadcast to `(N, 20, 1)`), as weights
/// max(0, 1 - |q - m|) on the column shifted by m rows, for m in
/// -10..=10, a cell missing or outside the grid read as the cell's own
/// height; plus `dz`. No Gather: a shifted copy per m.
fn shift_rows(b: &mut Builder, c: &Cells, q: &str, dz: &str) -> Cells {
    let lim = (MAX_SHIFT / dem_core::format::CELL).round() as i64;
    let lo = b.scalar(-lim as f32);
    let hi = b.scalar(lim as f32);
    let q = b.bin("Max", q, &lo);
    let q = b.bin("Min", &q, &hi);
    let (zero, one) = (b.scalar(0.0), b.scalar(1.0));
    let mut acc: Option<String> = None;
    for m in -lim..=lim {
        let src = if m == 0 {
            c.h.clone()
        } else {
            let hm = b.shift(&c.h, 1, 3, GRID_ROWS as i64, -m, 0.0);
            let vm = b.shift(&c.v, 1, 3, GRID_ROWS as i64, -m, 0.0);
            let ok = is_valid(b, &vm);
            b.select(&ok, &hm, &c.h)
        };
        let off = b.add_const(&q, -(m as f32));
        let off = b.un("Abs", &off);
        let w = b.bin("Sub", &one, &off);
        let w = b.bin("Max", &w, &zero);
        let term = b.bin("Mul", &w, &src);
        acc = Some(match acc {
            None => term,
            Some(a) => b.bin("Add", &a, &term),
        });
    }
    let moved = b.bin("Add", &acc.expect("at least one shift"), dz);
    let valid = is_valid(b, &c.v);
    set_heights(b, c, &valid, &moved)
}

/// `lag`: one shift per record, s (1 + spread (2u - 1)), and the climb
/// shift tan(pitch), the pitch read from row 20 of the graph's input DEM
/// ([`INPUT`], which every sensor graph passes through to its output).
fn lag(b: &mut Builder, c: &Cells, u: &str, s: f64, spread: f64) -> Cells {
    let u = b.reshape(u, &[-1, 1, 1]);
    let t = b.mul_const(&u, 2.0);
    let t = b.add_const(&t, -1.0);
    let t = b.mul_const(&t, spread as f32);
    let t = b.add_const(&t, 1.0);
    let shift = b.mul_const(&t, s as f32);
    let p = b.take(INPUT, 1, GRID_ROWS as i64, GRID_ROWS as i64 + 1);
    let p = b.take(&p, 2, 0, 1);
    let p = b.take(&p, 3, 0, 1);
    let p = b.reshape(&p, &[-1, 1, 1]);
    // NaN: p - p is not 0.
    let diff = b.bin("Sub", &p, &p);
    let zero = b.scalar(0.0);
    let known = b.bin("Equal", &diff, &zero);
    let p = b.select(&known, &p, &zero);
    let lo = b.scalar(-MAX_CLIMB_PITCH as f32);
    let hi = b.scalar(MAX_CLIMB_PITCH as f32);
    let p = b.bin("Max", &p, &lo);
    let p = b.bin("Min", &p, &hi);
    let sin = b.un("Sin", &p);
    let cos = b.un("Cos", &p);
    let tan = b.bin("Div", &sin, &cos);
    let climb = b.bin("Mul", &shift, &tan);
    let q = b.mul_const(&shift, (1.0 / dem_core::format::CELL) as f32);
    shift_rows(b, c, &q, &climb)
}

/// `drift`: the walks as the normals times a constant triangular matrix
/// (a cumulative sum going back from x0, as MatMul: CumSum is not in every
/// runtime), then [`shift_rows`].
fn drift(b: &mut Builder, c: &Cells, u: &str, rate: f64, zrate: f64, x0: f64) -> Cells {
    let rows = GRID_ROWS as i64;
    let (xi, zeta) = normal_pairs(b, u, GRID_ROWS);
    // sum[r] = sum of z[j] over r <= j, j behind x0: T[j][r] = 1 there.
    let behind = |r: usize| row_center_x(r) < x0;
    let t: Vec<f32> = (0..GRID_ROWS * GRID_ROWS)
        .map(|i| {
            let (j, r) = (i / GRID_ROWS, i % GRID_ROWS);
            f32::from(u8::from(r <= j && behind(j)))
        })
        .collect();
    let t = b.constant(&[GRID_ROWS, GRID_ROWS], &t);
    let step = dem_core::format::CELL.sqrt();
    let walk = |b: &mut Builder, z: &str, sd: f64| {
        let z = b.reshape(z, &[-1, rows]);
        let z = b.mul_const(&z, (sd * step) as f32);
        let w = b.op("MatMul", &[&z, &t], vec![]);
        b.reshape(&w, &[-1, rows, 1])
    };
    let dx = walk(b, &xi, rate);
    let dz = walk(b, &zeta, zrate);
    let q = b.mul_const(&dx, (1.0 / dem_core::format::CELL) as f32);
    shift_rows(b, c, &q, &dz)
}

/// One standard normal per cell `(N, 20, 5)` from 50 Box-Muller pairs of
/// the uniforms (cell 2i takes the cosine of pair i, cell 2i + 1 its sine).
fn cell_normals(b: &mut Builder, u: &str) -> String {
    let (z1, z2) = normal_pairs(b, u, GRID_ROWS * COLS / 2);
    let z = b.concat(&[&z1, &z2], 2);
    b.reshape(&z, &[-1, GRID_ROWS as i64, COLS as i64])
}

/// `step-jitter`: dx = clamp((sigma + edge J) z, +-0.1 m) per cell, h +=
/// dx (h ahead - h behind) / 0.2, a missing or outside neighbour read as
/// the cell's own height.
fn step_jitter(b: &mut Builder, c: &Cells, u: &str, sigma: f64, edge: f64) -> Cells {
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

/// `noise`: h += sigma z, z one normal per cell ([`cell_normals`]).
fn noise(b: &mut Builder, c: &Cells, u: &str, sigma0: f64, k: f64) -> Cells {
    let z = cell_normals(b, u);
    let (sx, sz) = NOISE_ORIGIN;
    // d^2 = (x - sx)^2 + y^2 + (clamp(h) - sz)^2: the first two are constants.
    let flat = per_cell(b, |r, col| (row_center_x(r) - sx).powi(2) + col_center_y(col).powi(2));
    let lo = b.scalar(-NOISE_RANGE_HEIGHT as f32);
    let hi = b.scalar(NOISE_RANGE_HEIGHT as f32);
    let hc = b.bin("Max", &c.h, &lo);
    let hc = b.bin("Min", &hc, &hi);
    let dz = b.add_const(&hc, -sz as f32);
    let dz2 = b.bin("Mul", &dz, &dz);
    let d2 = b.bin("Add", &flat, &dz2);
    let sigma = b.mul_const(&d2, k as f32);
    let sigma = b.add_const(&sigma, sigma0 as f32);
    let dh = b.bin("Mul", &sigma, &z);
    let moved = b.bin("Add", &c.h, &dh);
    let valid = is_valid(b, &c.v);
    set_heights(b, c, &valid, &moved)
}

/// `occlusion` (the rule of [`crate::effects::hidden`]) as pair tables:
/// for each target row t and blocker row b, whether b lies between the
/// sensor and t, and the line of sight's height at the ends of b's top as
/// `h + (z_t - h) alpha`, alpha a constant of (t, b).
fn occlusion(b: &mut Builder, c: &Cells, h: f64, x0: f64) -> Cells {
    let (rows, cols) = (GRID_ROWS, COLS);
    let tol = OCCLUSION_TOLERANCE;
    let mut pair = vec![0.0f32; rows * rows];
    let (mut a_lo, mut a_hi) = (vec![0.0f32; rows * rows], vec![0.0f32; rows * rows]);
    for t in 0..rows {
        let xt = row_center_x(t);
        if (xt - x0).abs() <= HALF {
            continue;
        }
        let dir = if xt > x0 { 1.0 } else { -1.0 };
        let xf = xt + dir * HALF;
        let between: Vec<usize> = if dir > 0.0 { (0..t).collect() } else { (t + 1..rows).collect() };
        for bl in between {
            let xb = row_center_x(bl);
            let (lo, hi) = ((xb - HALF).max(x0.min(xf)), (xb + HALF).min(x0.max(xf)));
            if lo >= hi {
                continue;
            }
            pair[t * rows + bl] = 1.0;
            a_lo[t * rows + bl] = ((lo - x0) / (xf - x0)) as f32;
            a_hi[t * rows + bl] = ((hi - x0) / (xf - x0)) as f32;
        }
    }
    let shape4 = [1, rows, rows, 1];
    let pair = b.constant(&shape4, &pair);
    let pair = b.gt_const(&pair, 0.5);
    let a_lo = b.constant(&shape4, &a_lo);
    let a_hi = b.constant(&shape4, &a_hi);
    // Targets along axis 1, blockers along axis 2: (N, t, b, c).
    let zt = b.reshape(&c.h, &[-1, rows as i64, 1, cols as i64]);
    let vt = b.reshape(&c.v, &[-1, rows as i64, 1, cols as i64]);
    let zb = b.reshape(&c.h, &[-1, 1, rows as i64, cols as i64]);
    let vb = b.reshape(&c.v, &[-1, 1, rows as i64, cols as i64]);
    let rise = b.add_const(&zt, -h as f32);
    let lo_line = b.bin("Mul", &rise, &a_lo);
    let hi_line = b.bin("Mul", &rise, &a_hi);
    let line = b.bin("Min", &lo_line, &hi_line);
    let line = b.add_const(&line, (h + tol) as f32);
    let over = b.bin("Greater", &zb, &line);
    let vt_ok = is_valid(b, &vt);
    let vb_ok = is_valid(b, &vb);
    let blocked = b.all(&[&pair, &vt_ok, &vb_ok, &over]);
    let blocked = b.to_float(&blocked);
    let blocked = b.reduce("ReduceMax", &blocked, &[2]);
    let blocked = b.reshape(&blocked, &[-1, rows as i64, cols as i64]);
    let by_line = b.gt_const(&blocked, 0.5);
    // A top above the sensor facing away: its near neighbour (toward the
    // sensor) is valid and not more than the tolerance lower.
    let toward_ahead = per_row(b, |t| f64::from(u8::from(row_center_x(t) < x0)));
    let toward_ahead = b.gt_const(&toward_ahead, 0.5);
    let seen_face = per_row(b, |t| f64::from(u8::from((row_center_x(t) - x0).abs() > HALF)));
    let seen_face = b.gt_const(&seen_face, 0.5);
    // Selected as floats: onnxruntime's Where takes no booleans.
    let v_behind = nb(b, &c.v, Side::Behind, 0.0);
    let v_ahead = nb(b, &c.v, Side::Ahead, 0.0);
    let z_behind = nb(b, &c.h, Side::Behind, 0.0);
    let z_ahead = nb(b, &c.h, Side::Ahead, 0.0);
    let v_near = b.select(&toward_ahead, &v_ahead, &v_behind);
    let v_near = is_valid(b, &v_near);
    let z_near = b.select(&toward_ahead, &z_ahead, &z_behind);
    let high = b.gt_const(&c.h, (h + tol) as f32);
    let floor = b.add_const(&c.h, -tol as f32);
    let near_high = b.bin("Greater", &z_near, &floor);
    let valid = is_valid(b, &c.v);
    let by_face = b.all(&[&seen_face, &valid, &high, &v_near, &near_high]);
    let miss = b.any(&[&by_line, &by_face]);
    drop_cells(b, c, &miss)
}

/// `smoothing`: the valid-weighted 3x3 mean, as two convolutions.
fn smoothing(b: &mut Builder, c: &Cells, w: f64) -> Cells {
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

/// `startup`: rows whose centre lies behind the blind edge go missing; the
/// edge from the time where known (and v > 0), else drawn.
fn startup(b: &mut Builder, c: &Cells, u: &str, time: Option<&str>, x0: f64, v: f64, p: f64) -> Cells {
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

/// Back edge of the grid (m): where a startup frame's blind edge ends.
const X_BACK: f64 = -0.6;

/// `patch-dropout`: blobs from slots of three uniforms (present, x, y);
/// a cell's four quarter-cell centres counted under them.
fn patches(b: &mut Builder, c: &Cells, u: &str, n: f64, radius: f64, a: f64) -> Cells {
    let (rows, cols) = (GRID_ROWS, COLS);
    let slots = PATCH_SLOTS as i64;
    let u = b.reshape(u, &[-1, slots, 3]);
    let (ylo, yhi) = (col_center_y(cols - 1) - HALF, col_center_y(0) + HALF);
    let (xlo, xhi) = (row_center_x(0) - HALF, row_center_x(rows - 1) + HALF);
    let present = b.take(&u, 2, 0, 1);
    let present = below(b, &present, n / PATCH_SLOTS as f64);
    let s = b.take(&u, 2, 1, 2);
    let t = b.take(&u, 2, 2, 3);
    let cx = b.mul_const(&s, (xhi - xlo + 2.0 * radius) as f32);
    let cx = b.add_const(&cx, (xlo - radius) as f32);
    let cy = b.mul_const(&t, (yhi - ylo + 2.0 * radius) as f32);
    let cy = b.add_const(&cy, (ylo - radius) as f32);
    // (N, slot, 1, 1, 1) against the quarter centres (1, 1, 20, 5, 4).
    let blob = [-1, slots, 1, 1, 1];
    let present = b.reshape(&present, &blob);
    let cx = b.reshape(&cx, &blob);
    let cy = b.reshape(&cy, &blob);
    let quarters = [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)];
    let qx: Vec<f32> = (0..rows * cols * 4).map(|i| (row_center_x(i / (cols * 4)) + quarters[i % 4].0 * HALF / 2.0) as f32).collect();
    let qy: Vec<f32> = (0..rows * cols * 4).map(|i| (col_center_y(i / 4 % cols) + quarters[i % 4].1 * HALF / 2.0) as f32).collect();
    let qx = b.constant(&[1, 1, rows, cols, 4], &qx);
    let qy = b.constant(&[1, 1, rows, cols, 4], &qy);
    let dx = b.bin("Sub", &qx, &cx);
    let dy = b.bin("Sub", &qy, &cy);
    let dx2 = b.bin("Mul", &dx, &dx);
    let dy2 = b.bin("Mul", &dy, &dy);
    let d2 = b.bin("Add", &dx2, &dy2);
    let r2 = b.scalar((radius * radius) as f32);
    // Not(Greater): onnx2torch has no LessOrEqual.
    let outside = b.bin("Greater", &d2, &r2);
    let inside = b.un("Not", &outside);
    let covered = b.all(&[&inside, &present]);
    let covered = b.to_float(&covered);
    let covered = b.reduce("ReduceMax", &covered, &[1]);
    let covered = b.reduce("ReduceSum", &covered, &[4]);
    let covered = b.reshape(&covered, &[-1, rows as i64, cols as i64]);
    // Seen quarters: 4 - covered; a cell needs two.
    let valid = is_valid(b, &c.v);
    let enough = b.lt_const(&covered, 2.5);
    let keep = b.all(&[&valid, &enough]);
    let keep_f = b.to_float(&keep);
    let zero = b.scalar(0.0);
    let kept = Cells { v: keep_f, h: b.select(&keep, &c.h, &zero) };
    // A partly covered cell moves toward its lowest kept x-neighbour.
    let (v_behind, z_behind) = neighbour(b, &kept, Side::Behind);
    let (v_ahead, z_ahead) = neighbour(b, &kept, Side::Ahead);
    let lb = b.select(&v_behind, &z_behind, &kept.h);
    let la = b.select(&v_ahead, &z_ahead, &kept.h);
    let low = b.bin("Min", &lb, &la);
    let low = b.bin("Min", &low, &kept.h);
    let diff = b.bin("Sub", &low, &kept.h);
    let diff = b.mul_const(&diff, a as f32);
    let moved = b.bin("Add", &kept.h, &diff);
    let partly = b.gt_const(&covered, 0.5);
    let cond = b.all(&[&keep, &partly]);
    set_heights(b, &kept, &cond, &moved)
}

/// `edge-holes` (`sign` 1) and `rim-holes` (-1): a valid 4-neighbour
/// `sign (z_n - z) > g` loses the cell with probability p.
fn jump_holes(b: &mut Builder, c: &Cells, u: &str, g: f64, p: f64, sign: f64) -> Cells {
    let u = b.reshape(u, &[-1, GRID_ROWS as i64, COLS as i64]);
    let mut jumps = Vec::new();
    for side in [Side::Behind, Side::Ahead, Side::Left, Side::Right] {
        let (vn, zn) = neighbour(b, c, side);
        let d = b.bin("Sub", &zn, &c.h);
        let d = b.mul_const(&d, sign as f32);
        let big = b.gt_const(&d, g as f32);
        jumps.push(b.all(&[&vn, &big]));
    }
    let refs: Vec<&str> = jumps.iter().map(String::as_str).collect();
    let jump = b.any(&refs);
    let valid = is_valid(b, &c.v);
    let hit = below(b, &u, p);
    let miss = b.all(&[&valid, &jump, &hit]);
    drop_cells(b, c, &miss)
}

/// A drop from each cell to the cell ahead: both valid, this one higher by
/// more than [`MIXED_JUMP`]. Boolean `(N, 20, 5)`.
fn drop_ahead(b: &mut Builder, c: &Cells) -> String {
    let (va, za) = neighbour(b, c, Side::Ahead);
    let d = b.bin("Sub", &c.h, &za);
    let big = b.gt_const(&d, MIXED_JUMP as f32);
    let valid = is_valid(b, &c.v);
    b.all(&[&valid, &va, &big])
}

/// `drop-holes`: at a drop, with probability p, the lip (v < 0.5) or the
/// floor loses the cell.
fn drop_holes(b: &mut Builder, c: &Cells, u: &str, p: f64) -> Cells {
    let (u, v) = cell_pairs(b, u);
    let drop = drop_ahead(b, c);
    let hit = below(b, &u, p);
    let lost = b.all(&[&drop, &hit]);
    let lip = b.lt_const(&v, 0.5);
    let lip_lost = b.all(&[&lost, &lip]);
    let not_lip = b.un("Not", &lip);
    let floor_lost = b.all(&[&lost, &not_lip]);
    // The floor is the cell ahead of the boundary's row: shift it on.
    let floor_lost = b.to_float(&floor_lost);
    let floor_lost = nb(b, &floor_lost, Side::Behind, 0.0);
    let floor_lost = b.gt_const(&floor_lost, 0.5);
    let miss = b.any(&[&lip_lost, &floor_lost]);
    drop_cells(b, c, &miss)
}

/// `hole-growth`: k missing 4-neighbours inside the grid lose the cell with
/// probability 1 - (1 - p)^k (a table of k = 0..4, computed as the native
/// code does, selected by k).
fn hole_growth(b: &mut Builder, c: &Cells, u: &str, p: f64) -> Cells {
    let u = b.reshape(u, &[-1, GRID_ROWS as i64, COLS as i64]);
    let mut k = b.scalar(0.0);
    for side in [Side::Behind, Side::Ahead, Side::Left, Side::Right] {
        // Outside the grid counts as valid.
        let vn = nb(b, &c.v, side, 1.0);
        let one = b.scalar(1.0);
        let missing = b.bin("Sub", &one, &vn);
        k = b.bin("Add", &k, &missing);
    }
    // The table as a chain of selections (onnx2torch's Gather cannot take it).
    let mut thr = b.scalar(crate::effects::growth_threshold(p, 0));
    for n in 1..=4 {
        let is_n = b.lt_const(&k, n as f32 - 0.5);
        let not_below = b.un("Not", &is_n);
        let t = b.scalar(crate::effects::growth_threshold(p, n));
        thr = b.select(&not_below, &t, &thr);
    }
    let hit = b.bin("Less", &u, &thr);
    let valid = is_valid(b, &c.v);
    let miss = b.all(&[&valid, &hit]);
    drop_cells(b, c, &miss)
}

/// `pit-fill`: a cell deeper than g below both neighbours of a line reads
/// the lower of them (the larger of the two lines' rims), with probability p.
fn pit_fill(b: &mut Builder, c: &Cells, u: &str, g: f64, p: f64) -> Cells {
    let u = b.reshape(u, &[-1, GRID_ROWS as i64, COLS as i64]);
    let none = b.scalar(-FAR);
    let mut rims = Vec::new();
    for (s1, s2) in [(Side::Behind, Side::Ahead), (Side::Left, Side::Right)] {
        let (v1, z1) = neighbour(b, c, s1);
        let (v2, z2) = neighbour(b, c, s2);
        let rim = b.bin("Min", &z1, &z2);
        let depth = b.bin("Sub", &rim, &c.h);
        let deep = b.gt_const(&depth, g as f32);
        let ok = b.all(&[&v1, &v2, &deep]);
        rims.push(b.select(&ok, &rim, &none));
    }
    let fill = b.bin("Max", &rims[0], &rims[1]);
    let has = b.gt_const(&fill, -FAR / 2.0);
    let valid = is_valid(b, &c.v);
    let hit = below(b, &u, p);
    let cond = b.all(&[&valid, &has, &hit]);
    set_heights(b, c, &cond, &fill)
}

/// The step across the cell's larger x-jump of two: `(has, step, behind)`
/// where `ahead` is `(valid, step)` toward the cell ahead and `behind`
/// toward the one behind; behind wins (`behind` true) only when its step
/// is larger in magnitude or there is none ahead.
fn larger_step(b: &mut Builder, ahead: (&str, &str), behind: (&str, &str)) -> (String, String, String) {
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
fn drop_blend(b: &mut Builder, c: &Cells, u: &str, p: f64, a: f64) -> Cells {
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
fn floor_lift(b: &mut Builder, c: &Cells, u: &str, x: f64, p: f64, a: f64) -> Cells {
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
fn riser_blend(b: &mut Builder, c: &Cells, u: &str, foot: f64, top: f64) -> Cells {
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
fn mixed_cells(b: &mut Builder, c: &Cells, u: &str, up: f64, down: f64) -> Cells {
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

/// The ONNX model of `model` alone: a virtual sensor without a network.
/// Inputs [`INPUT`] `(N, 21, 5, 2)`, [`UNIFORM`] `(N, K)` when the model
/// draws (K = [`SensorModel::draws`]), [`TIME`] `(N,)` when it has
/// `startup`; output [`OUTPUT`] `(N, 21, 5, 2)`. The metadata says what
/// the inputs are (see [`io_metadata`]).
pub fn sensor_model(model: &SensorModel, name: &str, extra_metadata: &[(String, String)]) -> dem_graph::proto::ModelProto {
    let mut b = Builder::new();
    let (cells, row20) = split_dem(&mut b, INPUT);
    let k = model.draws();
    let uniform = (k > 0).then_some(UNIFORM);
    let time = model.uses_time().then_some(TIME);
    let cells = apply(&mut b, model, cells, uniform, time);
    join_dem(&mut b, &cells, &row20, OUTPUT);
    let mut metadata = vec![(GRAPH_KEY.to_string(), GRAPH_SENSOR_ONLY.to_string())];
    metadata.extend(io_metadata(model));
    metadata.push((RESIDUAL_JSON_KEY.into(), serde_json::to_string(model).expect("a model serialises")));
    metadata.extend_from_slice(extra_metadata);
    let doc = format!(
        "dem-tools virtual sensor of named effects ({}), no network. Inputs: {}. Output: dem_out float32 (N,21,5,2), \
         masks +-1, missing cells height 0, row 20 passed through.",
        model.summary(),
        input_list(model)
    );
    b.model(name, graph_inputs(model), vec![dem_graph::batch_value(OUTPUT, &[21, 5, 2])], doc, &metadata)
}

/// The `metadata_props` key that says what a dem-tools graph holds.
pub const GRAPH_KEY: &str = "dem.graph";
/// [`GRAPH_KEY`]'s value for a sensor model alone (`dem-sensor export`).
pub const GRAPH_SENSOR_ONLY: &str = "sensor";
/// [`GRAPH_KEY`]'s value for a generator followed by its sensor tail.
pub const GRAPH_NETWORK_SENSOR: &str = "network+sensor";

/// The `metadata_props` key holding the sensor model's JSON.
pub const RESIDUAL_JSON_KEY: &str = "dem.residual";
/// The key stating K, the uniforms per record.
pub const UNIFORM_COUNT_KEY: &str = "dem.uniform_count";
/// The key stating the graph's inputs, comma-separated.
pub const INPUTS_KEY: &str = "dem.inputs";

/// The graph's inputs for `model`: `dem`, then `uniform` and `time` as needed.
pub fn graph_inputs(model: &SensorModel) -> Vec<dem_graph::proto::ValueInfoProto> {
    let mut v = vec![dem_graph::batch_value(INPUT, &[21, 5, 2])];
    if model.draws() > 0 {
        v.push(dem_graph::batch_value(UNIFORM, &[model.draws() as i64]));
    }
    if model.uses_time() {
        v.push(dem_graph::batch_value(TIME, &[]));
    }
    v
}

/// One line naming each input and its meaning.
pub fn input_list(model: &SensorModel) -> String {
    let mut parts = vec!["dem float32 (N,21,5,2)".to_string()];
    if model.draws() > 0 {
        parts.push(format!("uniform float32 (N,{}) in [0,1), drawn fresh per call", model.draws()));
    }
    if model.uses_time() {
        parts.push("time float32 (N) seconds into the run, NaN where unknown".to_string());
    }
    parts.join("; ")
}

/// `metadata_props` that say what the inputs are: K and the input names.
pub fn io_metadata(model: &SensorModel) -> Vec<(String, String)> {
    let mut names = vec![INPUT];
    if model.draws() > 0 {
        names.push(UNIFORM);
    }
    if model.uses_time() {
        names.push(TIME);
    }
    vec![(UNIFORM_COUNT_KEY.into(), model.draws().to_string()), (INPUTS_KEY.into(), names.join(","))]
}

/// Run `proto` (a sensor graph, or any graph with the same inputs) with
/// tract on `records`, with their uniforms (`records.len() x K`, row-major)
/// and times (NaN where unknown).
pub fn run_tract(
    proto: &dem_graph::proto::ModelProto,
    model: &SensorModel,
    records: &[dem_core::Dem],
    uniform: &[f32],
    times: &[f32],
) -> anyhow::Result<Vec<dem_core::Dem>> {
    let n = records.len();
    let flat: Vec<f32> = records.iter().flat_map(|d| d.iter().copied()).collect();
    let mut inputs = vec![Input { name: INPUT, shape: vec![n, 21, 5, 2], data: &flat }];
    if model.draws() > 0 {
        inputs.push(Input { name: UNIFORM, shape: vec![n, model.draws()], data: uniform });
    }
    if model.uses_time() {
        inputs.push(Input { name: TIME, shape: vec![n], data: times });
    }
    let out = dem_graph::run(proto, &inputs)?;
    Ok(out.chunks(dem_core::format::RECORD_LEN).map(|c| std::array::from_fn(|i| c[i])).collect())
}
