//! `holes`' effects as operators: cells lost or filled where the map is thin.

use super::*;

/// `dropout`.
pub(super) fn dropout(b: &mut Builder, c: &Cells, u: &str, p: f64) -> Cells {
    let u = b.reshape(u, &[-1, GRID_ROWS as i64, COLS as i64]);
    let miss = below(b, &u, p);
    drop_cells(b, c, &miss)
}

/// `row-dropout`.
pub(super) fn row_dropout(b: &mut Builder, c: &Cells, u: &str, p: f64) -> Cells {
    let u = b.reshape(u, &[-1, GRID_ROWS as i64, 1]);
    let miss = below(b, &u, p);
    drop_cells(b, c, &miss)
}

/// `patch-dropout`: blobs from slots of three uniforms (present, x, y);
/// a cell's four quarter-cell centres counted under them.
pub(super) fn patches(b: &mut Builder, c: &Cells, u: &str, n: f64, radius: f64, a: f64) -> Cells {
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
pub(super) fn jump_holes(b: &mut Builder, c: &Cells, u: &str, g: f64, p: f64, sign: f64) -> Cells {
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
pub(super) fn drop_ahead(b: &mut Builder, c: &Cells) -> String {
    let (va, za) = neighbour(b, c, Side::Ahead);
    let d = b.bin("Sub", &c.h, &za);
    let big = b.gt_const(&d, MIXED_JUMP as f32);
    let valid = is_valid(b, &c.v);
    b.all(&[&valid, &va, &big])
}

/// `drop-holes`: at a drop, with probability p, the lip (v < 0.5) or the
/// floor loses the cell.
pub(super) fn drop_holes(b: &mut Builder, c: &Cells, u: &str, p: f64) -> Cells {
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
pub(super) fn hole_growth(b: &mut Builder, c: &Cells, u: &str, p: f64) -> Cells {
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
pub(super) fn pit_fill(b: &mut Builder, c: &Cells, u: &str, g: f64, p: f64) -> Cells {
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
