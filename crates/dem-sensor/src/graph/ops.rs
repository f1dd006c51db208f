//! The graph's building blocks: the grid as [`Cells`], its neighbours, per-row
//! and per-cell constants, uniforms. It names no effect, so every effect's
//! operators can build on it.

use dem_core::format::{COLS, GRID_ROWS};
use dem_graph::Builder;

/// Name of a sensor graph's DEM input (`(N, 21, 5, 2)`, the file layout).
pub const INPUT: &str = "dem";
/// Half a cell's edge (m).
pub const HALF: f64 = 0.05;
/// Stands in for "no value" in maxima and minima (heights are never near it).
pub const FAR: f32 = 1e9;

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
pub enum Side {
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
pub fn nb(b: &mut Builder, x: &str, side: Side, fill: f32) -> String {
    let (rows, cols) = (GRID_ROWS as i64, COLS as i64);
    match side {
        Side::Ahead => b.shift(x, 1, 3, rows, 1, fill),
        Side::Behind => b.shift(x, 1, 3, rows, -1, fill),
        Side::Left => b.shift(x, 2, 3, cols, -1, fill),
        Side::Right => b.shift(x, 2, 3, cols, 1, fill),
    }
}

/// A per-row constant `(1, 20, 1)`.
pub fn per_row(b: &mut Builder, f: impl Fn(usize) -> f64) -> String {
    let data: Vec<f32> = (0..GRID_ROWS).map(|r| f(r) as f32).collect();
    b.constant(&[1, GRID_ROWS, 1], &data)
}

/// A per-cell constant `(1, 20, 5)`.
pub fn per_cell(b: &mut Builder, f: impl Fn(usize, usize) -> f64) -> String {
    let data: Vec<f32> = (0..GRID_ROWS * COLS).map(|i| f(i / COLS, i % COLS) as f32).collect();
    b.constant(&[1, GRID_ROWS, COLS], &data)
}

/// A boolean tensor: where `v` (1/0) is valid.
pub fn is_valid(b: &mut Builder, v: &str) -> String {
    b.gt_const(v, 0.5)
}

/// The cells with `miss` (boolean, broadcast to the grid) made missing.
pub fn drop_cells(b: &mut Builder, c: &Cells, miss: &str) -> Cells {
    let zero = b.scalar(0.0);
    Cells { v: b.select(miss, &zero, &c.v), h: b.select(miss, &zero, &c.h) }
}

/// The cells with height `new` where `cond` (boolean) holds.
pub fn set_heights(b: &mut Builder, c: &Cells, cond: &str, new: &str) -> Cells {
    Cells { v: c.v.clone(), h: b.select(cond, new, &c.h) }
}

/// `u < p`, the uniform against a probability.
pub fn below(b: &mut Builder, u: &str, p: f64) -> String {
    b.lt_const(u, p as f32)
}

/// A valid neighbour on `side` and its height: `(valid (bool), height)`.
pub fn neighbour(b: &mut Builder, c: &Cells, side: Side) -> (String, String) {
    let v = nb(b, &c.v, side, 0.0);
    let h = nb(b, &c.h, side, 0.0);
    (is_valid(b, &v), h)
}

/// The uniforms of one effect: `u[:, at..at + n]` reshaped to `shape`
/// (batch axis first, as `-1`).
pub fn uniforms(b: &mut Builder, u: &str, at: usize, n: usize, shape: &[i64]) -> String {
    let s = b.take(u, 1, at as i64, (at + n) as i64);
    b.reshape(&s, shape)
}

/// The per-cell uniform pairs `(u, v)` of a 200-draw effect: two `(N, 20, 5)`.
pub fn cell_pairs(b: &mut Builder, u: &str) -> (String, String) {
    let pairs = b.reshape(u, &[-1, GRID_ROWS as i64, COLS as i64, 2]);
    let first = b.take(&pairs, 3, 0, 1);
    let second = b.take(&pairs, 3, 1, 2);
    let grid = [-1, GRID_ROWS as i64, COLS as i64];
    (b.reshape(&first, &grid), b.reshape(&second, &grid))
}
