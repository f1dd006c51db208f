//! `view`'s effects as operators: what the sensor can see.

use super::*;

/// `fov`.
pub(super) fn fov(b: &mut Builder, c: &Cells, x_min: f64, x_max: f64) -> Cells {
    let out = per_row(b, |r| f64::from(u8::from(row_center_x(r) < x_min || row_center_x(r) > x_max)));
    let miss = b.gt_const(&out, 0.5);
    drop_cells(b, c, &miss)
}

/// `view-top`.
pub(super) fn view_top(b: &mut Builder, c: &Cells, h: f64, t: f64) -> Cells {
    let top = per_row(b, |r| h - t * row_center_x(r));
    let above = b.bin("Greater", &c.h, &top);
    let valid = is_valid(b, &c.v);
    let miss = b.all(&[&valid, &above]);
    drop_cells(b, c, &miss)
}

/// `occlusion` (the rule of [`crate::effects::hidden`]) as pair tables:
/// for each target row t and blocker row b, whether b lies between the
/// sensor and t, and the line of sight's height at the ends of b's top as
/// `h + (z_t - h) alpha`, alpha a constant of (t, b).
pub(super) fn occlusion(b: &mut Builder, c: &Cells, h: f64, x0: f64) -> Cells {
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

/// `startup`: rows whose centre lies behind the blind edge go missing; the
/// edge from the time where known (and v > 0), else drawn.
pub(super) fn startup(b: &mut Builder, c: &Cells, u: &str, time: Option<&str>, x0: f64, v: f64, p: f64) -> Cells {
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
pub(super) const X_BACK: f64 = -0.6;
