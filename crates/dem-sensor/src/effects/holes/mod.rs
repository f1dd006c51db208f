//! Cells lost or filled where the map is thin: `dropout`, `row-dropout`,
//! `patch-dropout`, `edge-holes`, `rim-holes`, `pit-fill`, `drop-holes`,
//! `hole-growth`.
//!
//! One file per effect (its parameters, spec, check, apply, ONNX
//! operators, evidence sentence and examples); this module holds what
//! several of them share, and `ops` the operators they share in
//! the graph.

use crate::draws::Draws;
use crate::effects::{cell_heights, exceeds, hit, neighbours4, probability, Limit, Range};
use crate::graph::ops::HALF;
use dem_core::format::{col_center_y, row_center_x, Dem, DemCells, COLS, GRID_ROWS};

pub mod drop_holes;
pub mod dropout;
pub mod edge_holes;
pub mod hole_growth;
pub mod patch_dropout;
pub mod pit_fill;
pub mod rim_holes;
pub mod row_dropout;

/// Blob slots per record of `patch-dropout`: at most this many blobs.
pub const PATCH_SLOTS: usize = 8;

/// The box and limits of a probability that fades out at 0.
const RATE: (Range, Limit) = (Range::lin(0.0, 0.6), Limit::new(0.0, 1.0).natural_lo());

/// The jump of `edge-holes` and `rim-holes`: a natural end at 1 m, where
/// no jump of a DEM qualifies.
const JUMP: (Range, Limit) = (Range::lin(0.02, 0.3), Limit::new(0.005, 1.0).natural_hi());
/// The probability of `edge-holes` and `rim-holes`.
const LOST: (Range, Limit) = (Range::lin(0.0, 1.0), Limit::new(0.0, 1.0).natural_lo());

/// `edge-holes`, `rim-holes` and `pit-fill`: the probability first.
pub(super) fn check_jump(g: f64, p: f64) -> Result<(), String> {
    probability(p)?;
    if g <= 0.0 {
        return Err(format!("g = {g} must be > 0"));
    }
    Ok(())
}

/// The cells of `d` under dark blobs of `radius` centred at `blobs` (x, y):
/// see [`drop_patches`].
///
/// Whether a quarter is covered is decided in float32, operation for
/// operation as the graph decides it (centre minus blob, squared, summed,
/// against radius squared), so every runtime that computes IEEE float32
/// draws the same blobs: in float64 a quarter centre a rounding error from
/// the rim was covered here and not in the graph, and the cell beside a
/// step moved by `a` times the step.
pub(super) fn darken(d: &mut Dem, blobs: &[(f32, f32)], radius: f64, a: f64) {
    let r2 = (radius * radius) as f32;
    let covered = |x: f32, y: f32| {
        blobs.iter().any(|&(px, py)| {
            let (dx, dy) = (x - px, y - py);
            dx * dx + dy * dy <= r2
        })
    };
    let seen: [[usize; COLS]; GRID_ROWS] = std::array::from_fn(|r| {
        std::array::from_fn(|c| {
            let (x, y) = (row_center_x(r), col_center_y(c));
            [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)]
                .into_iter()
                .filter(|&(sx, sy)| !covered((x + sx * HALF / 2.0) as f32, (y + sy * HALF / 2.0) as f32))
                .count()
        })
    });
    // The heights the map still holds once the blobs are dark.
    let z: [[Option<f64>; COLS]; GRID_ROWS] =
        std::array::from_fn(|r| std::array::from_fn(|c| (d.is_valid(r, c) && seen[r][c] >= 2).then(|| d.height(r, c) as f64)));
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            match (z[r][c], seen[r][c]) {
                (None, _) => d.set_missing(r, c),
                (Some(_), 4) => {}
                (Some(h), _) => {
                    let low =
                        [r.checked_sub(1), Some(r + 1).filter(|&n| n < GRID_ROWS)].into_iter().filter_map(|n| z[n?][c]).fold(h, f64::min);
                    d.set_valid(r, c, (h + a * (low - h)) as f32);
                }
            }
        }
    }
}

/// `edge-holes` (`sign` 1: a neighbour higher by more than g) and
/// `rim-holes` (`sign` -1: lower by more than g): the cell is lost with
/// probability p.
pub(super) fn jump_holes(d: &mut Dem, rng: &mut Draws, g: f64, p: f64, sign: f64) {
    let z = cell_heights(d);
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let u: f64 = rng.gen();
            let Some(zc) = z[r][c] else { continue };
            let jump = neighbours4(r, c)
                .any(|(rr, cc)| z[rr][cc].is_some_and(|zn| if sign > 0.0 { exceeds(zn, zc, g) } else { exceeds(zc, zn, g) }));
            if jump && hit(u, p) {
                d.set_missing(r, c);
            }
        }
    }
}

/// `hole-growth`'s probability that a cell with `k` missing 4-neighbours is
/// lost, 1 - (1 - p)^k, as float32: the graph looks it up in the same table.
pub fn growth_threshold(p: f64, k: usize) -> f32 {
    (1.0 - (1.0 - p).powi(k as i32)) as f32
}

/// The operators the family's effects share in the graph.
pub(crate) mod ops {
    use crate::effects::MIXED_JUMP;
    use crate::graph::ops::{below, drop_cells, is_valid, neighbour, Cells, Side};
    use dem_core::format::{COLS, GRID_ROWS};
    use dem_graph::Builder;

    /// `edge-holes` (`sign` 1) and `rim-holes` (-1): a valid 4-neighbour
    /// `sign (z_n - z) > g` loses the cell with probability p.
    pub(crate) fn jump_holes(b: &mut Builder, c: &Cells, u: &str, g: f64, p: f64, sign: f64) -> Cells {
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
    pub(crate) fn drop_ahead(b: &mut Builder, c: &Cells) -> String {
        let (va, za) = neighbour(b, c, Side::Ahead);
        let d = b.bin("Sub", &c.h, &za);
        let big = b.gt_const(&d, MIXED_JUMP as f32);
        let valid = is_valid(b, &c.v);
        b.all(&[&valid, &va, &big])
    }
}
