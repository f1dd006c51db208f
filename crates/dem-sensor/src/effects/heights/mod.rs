//! Heights moved everywhere, by the range, the calibration or the pose:
//! `noise`, `bias`, `quantization`, `tilt`, `shake`, `lag`, `drift`.
//!
//! One file per effect (its parameters, spec, check, apply, ONNX
//! operators, evidence sentence and examples); this module holds what
//! several of them share, and `ops` the operators they share in
//! the graph.

use crate::effects::cell_heights;
use dem_core::format::{col_center_y, row_center_x, Dem, DemCells, COLS, GRID_ROWS};

pub mod bias;
pub mod drift;
pub mod lag;
pub mod noise;
pub mod quantization;
pub mod shake;
pub mod tilt;

/// Where `noise` measures its range from: the nominal depth camera mount,
/// 0.15 m ahead of C and 0.45 m above it (x, z in metres).
pub const NOISE_ORIGIN: (f64, f64) = (0.15, 0.45);
/// The heights (m, either sign) beyond which `noise`'s range stops
/// growing: a cell 2 m above or below the robot is out of any DEM, and the
/// bound keeps every draw finite however many noise effects a model has.
pub const NOISE_RANGE_HEIGHT: f64 = 2.0;
/// Smallest `quantization` step (m): a tenth of a millimetre, finer than
/// any depth camera resolves at a metre, and large enough that h / q stays
/// far from float32's range.
pub const MIN_QUANTUM: f64 = 1e-4;
/// `quantization` rounds h / q up from this fraction of a step, not from
/// exactly a half: sim heights often lie on half steps, and there a
/// rounding error of 1e-7 would decide the step, differently in each
/// runtime. A thousandth of a step is far beyond rounding and far below
/// anything a sensor shows.
pub const ROUND_UP_FROM: f64 = 0.501;
/// Largest sd (rad) of `tilt`'s pitch and roll and of `shake`'s `sigma`:
/// a calibration or a body that far off (29 degrees) is no sensor effect.
pub const MAX_TILT: f64 = 0.5;
/// Largest `range` (m) of `tilt`: the farthest depth the camera measures
/// (dem-synth's RealSense-like camera, `range_max` 3 m; a D435's depth
/// error at 3 m is already about 2 % of the range, and elevation maps
/// built from it discard farther points). A cell seen from no farther
/// than this has no longer lever for an angle: 1 degree lifts it 5 cm.
pub const MAX_TILT_RANGE: f64 = 3.0;
/// The rows under the tracks whose x-neighbour steps `shake` reads: rows
/// 2..=9, centres from x = -0.35 to 0.35 m (tracks 0.7 m long about C).
pub const TRACK_ROWS: (usize, usize) = (2, 9);
/// `shake`'s step under the tracks is capped at this (m): a taller step is
/// no edge the tracks ride, and the cap keeps a stack of shakes finite.
pub const SHAKE_MAX_STEP: f64 = 0.5;
/// Largest `lag` shift `s` (m, either sign): a frame 2 s old at 0.25 m/s.
pub const MAX_LAG: f64 = 0.5;
/// Row shifts (`lag`, `drift`) are clamped to +-this many metres (10
/// rows): with `lag`'s box no shift reaches it; `drift` at absurd rates does.
pub const MAX_SHIFT: f64 = 1.0;
/// `lag` and `view-top` read the record's pitch clamped to +-this (rad, 57
/// degrees).
pub const MAX_CLIMB_PITCH: f64 = 1.0;

/// h += a lever(x) + b y on the valid cells (`tilt`, `shake`).
fn tilt_plane(d: &mut Dem, a: f64, b: f64, lever: impl Fn(f64) -> f64) {
    for r in 0..GRID_ROWS {
        let ax = a * lever(row_center_x(r));
        for c in 0..COLS {
            if d.is_valid(r, c) {
                d.set_valid(r, c, (d.height(r, c) as f64 + ax + b * col_center_y(c)) as f32);
            }
        }
    }
}

/// `shake`'s J: the largest height step (m) between valid x-neighbours of
/// the rows under the tracks ([`TRACK_ROWS`]), at most [`SHAKE_MAX_STEP`];
/// 0 when no such pair is valid.
pub fn step_under_tracks(d: &Dem) -> f64 {
    let mut j: f64 = 0.0;
    for r in TRACK_ROWS.0..TRACK_ROWS.1 {
        for c in 0..COLS {
            if d.is_valid(r, c) && d.is_valid(r + 1, c) {
                j = j.max((d.height(r + 1, c) as f64 - d.height(r, c) as f64).abs());
            }
        }
    }
    j.min(SHAKE_MAX_STEP)
}

/// The record's pitch (row 20, column 0; rad, nose up > 0), clamped to
/// +-[`MAX_CLIMB_PITCH`]; 0 when it is not finite (the contract's "not
/// recorded" is 0 too). `lag` and `view-top` read it.
pub fn record_pitch(d: &Dem) -> f64 {
    let p = d.attitude()[0] as f64;
    if p.is_finite() {
        p.clamp(-MAX_CLIMB_PITCH, MAX_CLIMB_PITCH)
    } else {
        0.0
    }
}

/// `lag`'s climb per metre of shift: tan of [`record_pitch`].
pub fn climb_slope(d: &Dem) -> f64 {
    record_pitch(d).tan()
}

/// `drift`'s displacements per row from its 40 normals (pair j: `z[2j]`
/// along x, `z[2j + 1]` in height): cumulative sums going back from the
/// last row whose centre lies behind `x0`, one step of sd rate sqrt(0.1)
/// (zrate sqrt(0.1)) per row; 0 for the rows from x0 on.
pub fn drift_walk(z: &[f64; 2 * GRID_ROWS], rate: f64, zrate: f64, x0: f64) -> ([f64; GRID_ROWS], [f64; GRID_ROWS]) {
    let step = dem_core::format::CELL.sqrt();
    let (mut dx, mut dz) = ([0.0; GRID_ROWS], [0.0; GRID_ROWS]);
    let (mut sx, mut sz) = (0.0, 0.0);
    for r in (0..GRID_ROWS).rev().filter(|&r| row_center_x(r) < x0) {
        sx += rate * step * z[2 * r];
        sz += zrate * step * z[2 * r + 1];
        dx[r] = sx;
        dz[r] = sz;
    }
    (dx, dz)
}

/// Row `r` of every column reads the column at x - dx[r], plus dz[r]
/// (`lag`, `drift`), on the valid cells; validity is kept. With q = dx / 0.1
/// (in rows, clamped to +-[`MAX_SHIFT`] / 0.1), m = floor(q), g = q - m:
/// h' = (1 - g) src(r - m) + g src(r - m - 1) + dz, where src(k) is row k's
/// height when row k lies in the grid and is valid there, else the cell's
/// own height (nothing seen there: the cell keeps what it had; row 0 keeps
/// its value when nothing lies behind). The same as weights max(0, 1 - |q -
/// m|) on src(r - m) for every integer m, as the graph computes it:
/// continuous in dx, so no runtime's rounding of q decides a cell.
pub fn shift_rows(d: &mut Dem, dx: &[f64; GRID_ROWS], dz: &[f64; GRID_ROWS]) {
    let z = cell_heights(d);
    let lim = MAX_SHIFT / dem_core::format::CELL;
    for r in 0..GRID_ROWS {
        let q = (dx[r] / dem_core::format::CELL).clamp(-lim, lim);
        let m = q.floor();
        let g = q - m;
        let k = r as i64 - m as i64;
        for (c, own) in z[r].iter().enumerate() {
            let Some(own) = *own else { continue };
            let src = |k: i64| usize::try_from(k).ok().filter(|&k| k < GRID_ROWS).and_then(|k| z[k][c]).unwrap_or(own);
            let h = (1.0 - g) * src(k) + g * src(k - 1);
            d.set_valid(r, c, (h + dz[r]) as f32);
        }
    }
}

/// The operators the family's effects share in the graph.
pub(crate) mod ops {
    use super::{MAX_CLIMB_PITCH, MAX_SHIFT, SHAKE_MAX_STEP, TRACK_ROWS};
    use crate::graph::ops::{is_valid, per_row, set_heights, Cells, INPUT};
    use dem_core::format::{col_center_y, row_center_x, COLS, GRID_ROWS};
    use dem_graph::Builder;

    /// [`super::record_pitch`] per record `(N, 1, 1)`, read from row 20 of
    /// the graph's input DEM ([`INPUT`], which every sensor graph passes
    /// through to its output).
    pub(crate) fn record_pitch(b: &mut Builder) -> String {
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
        b.bin("Min", &p, &hi)
    }

    /// Standard normals from `k` Box-Muller pairs of uniforms `(N, 2 k)`: the
    /// cosines and the sines, each `(N, k, 1)`.
    pub(crate) fn normal_pairs(b: &mut Builder, u: &str, k: usize) -> (String, String) {
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
    pub(crate) fn tilt_plane(b: &mut Builder, c: &Cells, a: &str, bb: &str, lever: impl Fn(f64) -> f64) -> Cells {
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
    pub(crate) fn step_under_tracks(b: &mut Builder, c: &Cells) -> String {
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
    pub(crate) fn sd_with_the_step(b: &mut Builder, c: &Cells, sigma: f64, edge: f64) -> String {
        let j = step_under_tracks(b, c);
        let s = b.mul_const(&j, edge as f32);
        b.add_const(&s, sigma as f32)
    }

    /// [`crate::effects::shift_rows`] in the graph: each row reads the column
    /// `q` rows back (`q` broadcast to `(N, 20, 1)`), as weights
    /// max(0, 1 - |q - m|) on the column shifted by m rows, for m in
    /// -10..=10, a cell missing or outside the grid read as the cell's own
    /// height; plus `dz`. No Gather: a shifted copy per m.
    pub(crate) fn shift_rows(b: &mut Builder, c: &Cells, q: &str, dz: &str) -> Cells {
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

    /// One standard normal per cell `(N, 20, 5)` from 50 Box-Muller pairs of
    /// the uniforms (cell 2i takes the cosine of pair i, cell 2i + 1 its sine).
    pub(crate) fn cell_normals(b: &mut Builder, u: &str) -> String {
        let (z1, z2) = normal_pairs(b, u, GRID_ROWS * COLS / 2);
        let z = b.concat(&[&z1, &z2], 2);
        b.reshape(&z, &[-1, GRID_ROWS as i64, COLS as i64])
    }
}
