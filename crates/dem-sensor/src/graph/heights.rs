//! `heights`' effects as operators: heights moved everywhere (range,
//! calibration, pose).

use super::*;

/// `bias`.
pub(super) fn bias(b: &mut Builder, c: &Cells, off: f64, t: f64) -> Cells {
    let shift = per_row(b, |r| off + t * row_center_x(r));
    let moved = b.bin("Add", &c.h, &shift);
    let valid = is_valid(b, &c.v);
    set_heights(b, c, &valid, &moved)
}

/// `quantization`, in float32 as the native code rounds.
pub(super) fn quantization(b: &mut Builder, c: &Cells, q: f64) -> Cells {
    let q = b.scalar(q as f32);
    let x = b.bin("Div", &c.h, &q);
    let x = b.add_const(&x, crate::effects::ROUND_UP_FROM as f32);
    let x = b.un("Floor", &x);
    let x = b.bin("Mul", &q, &x);
    let valid = is_valid(b, &c.v);
    set_heights(b, c, &valid, &x)
}

/// `tilt`.
pub(super) fn tilt(b: &mut Builder, c: &Cells, u: &str, pitch: f64, roll: f64, x0: f64, range: f64) -> Cells {
    let (z1, z2) = normal_pairs(b, u, 1);
    let a = b.mul_const(&z1, pitch as f32);
    let bb = b.mul_const(&z2, roll as f32);
    tilt_plane(b, c, &a, &bb, |x| range + x.max(x0) - x0)
}

/// `shake`.
pub(super) fn shake(b: &mut Builder, c: &Cells, u: &str, sigma: f64, edge: f64) -> Cells {
    let (z1, z2) = normal_pairs(b, u, 1);
    let s = sd_with_the_step(b, c, sigma, edge);
    let a = b.bin("Mul", &s, &z1);
    let bb = b.bin("Mul", &s, &z2);
    tilt_plane(b, c, &a, &bb, |x| x)
}

/// Standard normals from `k` Box-Muller pairs of uniforms `(N, 2 k)`: the
/// cosines and the sines, each `(N, k, 1)`.
pub(super) fn normal_pairs(b: &mut Builder, u: &str, k: usize) -> (String, String) {
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
pub(super) fn tilt_plane(b: &mut Builder, c: &Cells, a: &str, bb: &str, lever: impl Fn(f64) -> f64) -> Cells {
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
pub(super) fn step_under_tracks(b: &mut Builder, c: &Cells) -> String {
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
pub(super) fn sd_with_the_step(b: &mut Builder, c: &Cells, sigma: f64, edge: f64) -> String {
    let j = step_under_tracks(b, c);
    let s = b.mul_const(&j, edge as f32);
    b.add_const(&s, sigma as f32)
}

/// [`crate::effects::shift_rows`] in the graph: each row reads the column
/// `q` rows back (`q` broadcast to `(N, 20, 1)`), as weights
/// max(0, 1 - |q - m|) on the column shifted by m rows, for m in
/// -10..=10, a cell missing or outside the grid read as the cell's own
/// height; plus `dz`. No Gather: a shifted copy per m.
pub(super) fn shift_rows(b: &mut Builder, c: &Cells, q: &str, dz: &str) -> Cells {
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
pub(super) fn lag(b: &mut Builder, c: &Cells, u: &str, s: f64, spread: f64) -> Cells {
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
pub(super) fn drift(b: &mut Builder, c: &Cells, u: &str, rate: f64, zrate: f64, x0: f64) -> Cells {
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
pub(super) fn cell_normals(b: &mut Builder, u: &str) -> String {
    let (z1, z2) = normal_pairs(b, u, GRID_ROWS * COLS / 2);
    let z = b.concat(&[&z1, &z2], 2);
    b.reshape(&z, &[-1, GRID_ROWS as i64, COLS as i64])
}

/// `noise`: h += sigma z, z one normal per cell ([`cell_normals`]).
pub(super) fn noise(b: &mut Builder, c: &Cells, u: &str, sigma0: f64, k: f64) -> Cells {
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
