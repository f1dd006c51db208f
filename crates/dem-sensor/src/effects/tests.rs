use super::*;
use dem_core::format::{col_center_y, empty_dem, row_center_x, FLAT_GROUND};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn flat() -> Dem {
    let mut d = empty_dem();
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            d.set_valid(r, c, FLAT_GROUND);
        }
    }
    d
}

fn rng() -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(1)
}

#[test]
fn flat_ground_is_never_occluded_and_a_box_casts_a_shadow() {
    let mut d = flat();
    Effect::Occlusion(Occlusion { h: 0.45, x0: 0.15 }).apply(&mut d, &mut rng());
    assert_eq!(d.valid_cells(), 100);
    // A 0.2 m box on rows 10..12 (x 0.45..0.65): shadow behind it.
    let mut d = flat();
    for r in 10..12 {
        (0..COLS).for_each(|c| d.set_valid(r, c, 0.13));
    }
    Effect::Occlusion(Occlusion { h: 0.45, x0: 0.15 }).apply(&mut d, &mut rng());
    assert!(d.is_valid(11, 0) && d.is_valid(9, 0), "the box and what is before it are seen");
    // The box (x 0.4..0.6) is 0.2 m tall, the sensor 0.52 m above the
    // ground: the shadow reaches (0.6 - 0.15) * 0.2 / 0.32 = 0.28 m past
    // the box, to x = 0.88; a cell is seen when its far edge is.
    assert!(!d.is_valid(12, 2) && !d.is_valid(13, 2));
    assert!(d.is_valid(14, 2), "x 0.8..0.9: its far edge is in sight");
}

#[test]
fn fov_bias_quantization_smoothing_follow_their_formulas() {
    let mut d = flat();
    Effect::Fov(Fov { x_min: -0.1, x_max: 1.0 }).apply(&mut d, &mut rng());
    assert!(!d.is_valid(4, 0) && d.is_valid(5, 0) && d.is_valid(15, 0) && !d.is_valid(16, 0));
    let mut d = flat();
    Effect::Bias(Bias { b: 0.01, t: 0.02 }).apply(&mut d, &mut rng());
    assert!((d.height(0, 0) as f64 - (-0.07 + 0.01 - 0.02 * 0.55)).abs() < 1e-6);
    Effect::Quantization(Quantization { q: 0.025 }).apply(&mut d, &mut rng());
    assert!(((d.height(0, 0) as f64) / 0.025).fract().abs() < 1e-4 || ((d.height(0, 0) as f64) / 0.025).fract().abs() > 0.9999);
    let mut d = flat();
    d.set_valid(10, 2, 0.73);
    Effect::Smoothing(Smoothing { w: 0.5 }).apply(&mut d, &mut rng());
    assert!((d.height(10, 2) - (0.5 * 0.73 + 0.5 * -0.07)).abs() < 1e-6);
    assert!((d.height(9, 1) - (-0.07 + 0.8 / 16.0 / (0.5 + 0.5))).abs() < 1e-6);
}

/// riser-blend on the same terrain (a drop at 9/10, a riser at 14/15):
/// only the two cells beside the riser move, the foot cell by u foot of
/// the step toward the top (foot > 0: up), the top cell by u top toward
/// the foot (top < 0: up, away from it), u uniform: mean share foot / 2
/// and top / 2.
#[test]
fn riser_blend_moves_cells_beside_risers_only() {
    let (foot, top) = (0.5, -0.3);
    let mut r = rng();
    let (mut share, n) = ([0.0f64; 2], 4000);
    for _ in 0..n {
        let mut d = flat();
        for row in (0..10).chain(15..GRID_ROWS) {
            (0..COLS).for_each(|c| d.set_valid(row, c, 0.1));
        }
        let before = d;
        Effect::RiserBlend(RiserBlend { foot, top }).apply(&mut d, &mut r);
        for row in 0..GRID_ROWS {
            for c in 0..COLS {
                let (h0, h1) = (before.height(row, c) as f64, d.height(row, c) as f64);
                match row {
                    14 => {
                        let toward = (h1 - h0) / 0.17;
                        assert!((-1e-6..=foot + 1e-6).contains(&toward), "foot: {h0} -> {h1}");
                        share[0] += toward;
                    }
                    15 => {
                        let toward = (h0 - h1) / 0.17;
                        assert!((top - 1e-6..=1e-6).contains(&toward), "top: {h0} -> {h1}");
                        share[1] += toward;
                    }
                    _ => assert_eq!(h0, h1, "row {row} is beside no riser (a drop at 9/10)"),
                }
            }
        }
    }
    let cells = (n * COLS) as f64;
    assert!((share[0] / cells - foot / 2.0).abs() < 0.01, "{share:?}");
    assert!((share[1] / cells - top / 2.0).abs() < 0.01, "{share:?}");
    assert!(Effect::RiserBlend(RiserBlend { foot: 1.2, top: 0.0 }).check().is_err());
}

/// floor-lift on the same terrain: only the floor beyond the drop (row
/// 10, x = 0.45 m) moves, and only when its row lies behind x; with p
/// it reads min(1, u a) of the 0.17 m step up, u uniform: for a = 2 the
/// mean share is p (1/4 + 1/2) and half the moved cells read the edge.
#[test]
fn floor_lift_raises_the_floor_beyond_a_drop_in_the_rows_behind_x_only() {
    let (p, a) = (0.6, 2.0);
    let terrain = || {
        let mut d = flat();
        for row in (0..10).chain(15..GRID_ROWS) {
            (0..COLS).for_each(|c| d.set_valid(row, c, 0.1));
        }
        d
    };
    let mut r = rng();
    let (mut share, mut whole, n) = (0.0f64, 0usize, 4000);
    for _ in 0..n {
        let before = terrain();
        let mut d = before;
        Effect::FloorLift(FloorLift { x: 0.5, p, a }).apply(&mut d, &mut r);
        for row in 0..GRID_ROWS {
            for c in 0..COLS {
                let (h0, h1) = (before.height(row, c) as f64, d.height(row, c) as f64);
                if row == 10 {
                    let up = (h1 - h0) / 0.17;
                    assert!((-1e-6..=1.0 + 1e-6).contains(&up), "{h0} -> {h1}");
                    share += up;
                    whole += usize::from(up > 1.0 - 1e-6);
                } else {
                    assert_eq!(h0, h1, "row {row} lies beyond no drop");
                }
            }
        }
        // Row 10's centre (0.45 m) is not behind x = 0.4: nothing moves.
        let mut d = before;
        Effect::FloorLift(FloorLift { x: 0.4, p: 1.0, a }).apply(&mut d, &mut r);
        assert_eq!(d, before);
    }
    let cells = (n * COLS) as f64;
    assert!((share / cells - p * 0.75).abs() < 0.01, "{share}");
    assert!((whole as f64 / cells - p * 0.5).abs() < 0.015, "{whole}");
    assert!(Effect::FloorLift(FloorLift { x: 0.5, p: 1.2, a }).check().is_err());
    assert!(Effect::FloorLift(FloorLift { x: 0.5, p, a: -1.0 }).check().is_err());
}

#[test]
fn a_patch_loses_the_cells_it_covers_and_lowers_the_ones_it_partly_covers_beside_a_step() {
    // A riser between rows 9 (0.0 m) and 10 (0.15 m); rows 10.. are its top.
    let stair = || {
        let mut d = flat();
        for r in 10..GRID_ROWS {
            (0..COLS).for_each(|c| d.set_valid(r, c, FLAT_GROUND + 0.15));
        }
        d
    };
    let (x11, y2) = (row_center_x(11), col_center_y(2));
    // Centred on cell (11, 2), radius 9 cm: its four quarters covered
    // (3.5 cm away), and the near two quarters (7.9 cm) of the four
    // cells around it, none of the diagonal cells' (10.6 cm).
    let mut d = stair();
    holes::darken(&mut d, &[(x11 as f32, y2 as f32)], 0.09, 0.5);
    assert!(!d.is_valid(11, 2));
    // Row 10 (the riser's top) keeps half its quarters: it reads half
    // way down to its lower neighbour, row 9.
    assert!((d.height(10, 2) - (FLAT_GROUND + 0.075)).abs() < 1e-6, "{}", d.height(10, 2));
    // Row 12 and the cells beside along y have no lower x-neighbour
    // left: they keep their heights.
    for (r, c) in [(12, 2), (11, 1), (11, 3)] {
        assert!((d.height(r, c) - (FLAT_GROUND + 0.15)).abs() < 1e-6, "({r}, {c})");
    }
    assert_eq!(d.valid_cells(), 99);
    // Centred on the riser's foot (row 9): the foot is lost, so the top
    // beside it has no lower neighbour left and keeps its height.
    let mut d = stair();
    holes::darken(&mut d, &[(row_center_x(9) as f32, y2 as f32)], 0.09, 1.0);
    assert!(!d.is_valid(9, 2));
    assert!((d.height(10, 2) - (FLAT_GROUND + 0.15)).abs() < 1e-6);
    // a = 0: the partly covered cells keep their heights.
    let mut d = stair();
    holes::darken(&mut d, &[(x11 as f32, y2 as f32)], 0.09, 0.0);
    assert!((d.height(10, 2) - (FLAT_GROUND + 0.15)).abs() < 1e-6);
    // Too small to cover three quarters of any cell: nothing is lost.
    let mut d = stair();
    holes::darken(&mut d, &[(x11 as f32, y2 as f32)], 0.03, 0.0);
    assert_eq!(d.valid_cells(), 100);
}

/// drop-blend on a drop (rows 0..10 at 0.1 m, rows 10.. at -0.07 m) and
/// a riser (rows 15.. back up at 0.1 m): only the two cells beside the
/// drop move, each with probability p, toward the other by u a of the
/// drop, u uniform: mean moved share p a / 2.
#[test]
fn drop_blend_moves_cells_beside_drops_only() {
    let (p, a) = (0.4, 0.6);
    let mut r = rng();
    let (mut moved, mut share, n) = ([0usize; 2], [0.0f64; 2], 4000);
    for _ in 0..n {
        let mut d = flat();
        for row in (0..10).chain(15..GRID_ROWS) {
            (0..COLS).for_each(|c| d.set_valid(row, c, 0.1));
        }
        let before = d;
        Effect::DropBlend(DropBlend { p, a }).apply(&mut d, &mut r);
        for row in 0..GRID_ROWS {
            for c in 0..COLS {
                let (h0, h1) = (before.height(row, c) as f64, d.height(row, c) as f64);
                match row {
                    9 | 10 => {
                        let toward = if row == 9 { h0 - h1 } else { h1 - h0 };
                        assert!((-1e-6..=a * 0.17 + 1e-6).contains(&toward), "row {row}: {h0} -> {h1}");
                        let k = row - 9;
                        moved[k] += usize::from(toward > 0.0);
                        share[k] += toward / 0.17;
                    }
                    _ => assert_eq!(h0, h1, "row {row} is beside no drop (a riser at 14/15)"),
                }
            }
        }
    }
    for k in 0..2 {
        let cells = (n * COLS) as f64;
        assert!((moved[k] as f64 / cells - p).abs() < 0.02, "{moved:?}");
        assert!((share[k] / cells - p * a / 2.0).abs() < 0.01, "{share:?}");
    }
}

/// drop-holes on the same terrain (a drop between rows 9 and 10, a
/// riser between 14 and 15): per column, with probability p one of the
/// two cells at the drop is lost, the lip or the floor as often, never
/// both; nothing else is touched, heights are kept.
#[test]
fn drop_holes_lose_one_cell_at_a_drop_and_none_at_a_riser() {
    let p = 0.3;
    let mut r = rng();
    let (mut lost, n) = ([0usize; 2], 4000);
    for _ in 0..n {
        let mut d = flat();
        for row in (0..10).chain(15..GRID_ROWS) {
            (0..COLS).for_each(|c| d.set_valid(row, c, 0.1));
        }
        let before = d;
        Effect::DropHoles(DropHoles { p }).apply(&mut d, &mut r);
        for c in 0..COLS {
            assert!(d.is_valid(9, c) || d.is_valid(10, c), "both cells of the drop lost");
            for row in 0..GRID_ROWS {
                if d.is_valid(row, c) {
                    assert_eq!(d.height(row, c), before.height(row, c));
                } else {
                    assert!(row == 9 || row == 10, "row {row} is beside no drop (a riser at 14/15)");
                    lost[row - 9] += 1;
                }
            }
        }
    }
    let cells = (n * COLS) as f64;
    assert!(((lost[0] + lost[1]) as f64 / cells - p).abs() < 0.02, "{lost:?}");
    assert!((lost[0] as f64 / cells - p / 2.0).abs() < 0.02, "{lost:?}");
    assert!(Effect::DropHoles(DropHoles { p: 1.5 }).check().is_err());
}

/// Without reach, mixed-cells is the mean of two half cells with the
/// step uniform between the centres: the lower cell next to a riser
/// reads half way up when the step lies in its front quarter
/// (probability 1/4), else its own height; the higher cell half way down
/// with probability 1/4; slopes (jumps up to 5 cm) are left alone.
#[test]
fn mixed_cells_without_reach_is_the_mean_of_half_cells() {
    let (mut low_half, mut high_half) = (0usize, 0usize);
    let mut r1 = rng();
    let n = 4000;
    for _ in 0..n {
        let mut d = flat();
        for r in 10..GRID_ROWS {
            (0..COLS).for_each(|c| d.set_valid(r, c, 0.13));
        }
        d.set_valid(5, 2, -0.03); // a 4 cm bump: a slope, not a step
        Effect::MixedCells(MixedCells { up: 0.0, down: 0.0 }).apply(&mut d, &mut r1);
        let (lo, hi) = (d.height(9, 0) as f64, d.height(10, 0) as f64);
        assert!([-0.07, 0.03].iter().any(|v| (lo - v).abs() < 1e-6), "lower cell reads {lo}");
        assert!([0.13, 0.03].iter().any(|v| (hi - v).abs() < 1e-6), "higher cell reads {hi}");
        low_half += usize::from((lo - 0.03).abs() < 1e-6);
        high_half += usize::from((hi - 0.03).abs() < 1e-6);
        assert_eq!(d.height(5, 2), -0.03);
        assert_eq!(d.height(8, 0), FLAT_GROUND);
        assert!((0..COLS).all(|c| d.height(9, c) == d.height(9, 0)), "one step position per row boundary");
    }
    for k in [low_half, high_half] {
        assert!((k as f64 / n as f64 - 0.25).abs() < 0.03, "{k} of {n}");
    }
    // A long reach past a drop: the cell beyond the edge reads the top
    // unless the step lies deep in it and the reach is short.
    let mut full = 0;
    for _ in 0..n {
        let mut d = flat();
        for r in 0..10 {
            (0..COLS).for_each(|c| d.set_valid(r, c, 0.13));
        }
        Effect::MixedCells(MixedCells { up: 0.0, down: 1.0 }).apply(&mut d, &mut r1);
        full += usize::from((d.height(10, 0) - 0.13).abs() < 1e-6);
        assert_eq!(d.height(11, 0), FLAT_GROUND);
    }
    assert!(full as f64 / n as f64 > 0.85, "{full}");
}

#[test]
fn pit_fill_rim_holes_and_view_top_follow_their_formulas() {
    let mut d = flat();
    d.set_valid(8, 1, -0.2); // a pallet gap: a pit along x and y
    d.set_valid(12, 2, 0.2); // a post: its rim cell is lost
    Effect::PitFill(PitFill { g: 0.05, p: 1.0 }).apply(&mut d, &mut rng());
    assert_eq!(d.height(8, 1), FLAT_GROUND);
    Effect::RimHoles(RimHoles { g: 0.05, p: 1.0 }).apply(&mut d, &mut rng());
    assert!(!d.is_valid(12, 2) && d.is_valid(11, 2) && d.is_valid(12, 1));
    let mut d = flat();
    d.set_valid(15, 0, 0.2); // x = 0.95: above 0.4 - 0.3 x = 0.115
    d.set_valid(5, 0, 0.2); // x = -0.05: below 0.415
    Effect::ViewTop(ViewTop { h: 0.4, t: 0.3 }).apply(&mut d, &mut rng());
    assert!(!d.is_valid(15, 0) && d.is_valid(5, 0) && d.valid_cells() == 99);
}

/// view-top turns with the record's pitch: a cell is out of view when,
/// seen in the body's frame (turned back by the pitch about C), it lies
/// above h - t x. Nose up the ray clears a post far ahead; nose down it
/// meets the floor far ahead.
#[test]
fn view_top_turns_with_the_pitch() {
    let with_pitch = |p: f32| {
        let mut d = flat();
        d.set_valid(15, 0, 0.2); // x = 0.95: above the level ray 0.115
        let mut att = d.attitude();
        att[0] = p;
        d.set_attitude(att);
        Effect::ViewTop(ViewTop { h: 0.4, t: 0.3 }).apply(&mut d, &mut rng());
        d
    };
    let level = with_pitch(0.0);
    assert!(!level.is_valid(15, 0) && level.is_valid(19, 1) && level.valid_cells() == 99);
    let up = with_pitch(0.3);
    assert!(up.is_valid(15, 0) && up.valid_cells() == 100, "nose up: all in view");
    let down = with_pitch(-0.3);
    assert!(!down.is_valid(15, 0) && !down.is_valid(19, 1) && down.is_valid(8, 1), "nose down: the far floor out of view");
    // Against the body frame on rough DEMs, pitches either way, NaN read as 0.
    for (p, h, t) in [(0.25, 0.3, 0.5), (-0.4, 0.5, 0.2), (0.7, 0.2, 1.2), (-0.9, 0.6, 0.8), (f32::NAN, 0.3, 0.3)] {
        let mut d = rough();
        let mut att = d.attitude();
        att[0] = p;
        d.set_attitude(att);
        Effect::ViewTop(ViewTop { h, t }).apply(&mut d, &mut rng());
        let pf = if p.is_nan() { 0.0 } else { f64::from(p) };
        for (r, row) in grid(&rough()).iter().enumerate() {
            for (c, z) in row.iter().enumerate() {
                let x = row_center_x(r);
                let seen = z.is_some_and(|z| {
                    let (xb, zb) = (x * pf.cos() + z * pf.sin(), -x * pf.sin() + z * pf.cos());
                    zb <= h - t * xb
                });
                assert_eq!(d.is_valid(r, c), seen, "pitch {p} h {h} t {t} cell ({r}, {c})");
            }
        }
    }
}

/// Heights of `d` as f64 (None where missing), for the references below.
fn grid(d: &Dem) -> Vec<Vec<Option<f64>>> {
    (0..GRID_ROWS).map(|r| (0..COLS).map(|c| d.is_valid(r, c).then(|| d.height(r, c) as f64)).collect()).collect()
}

/// A slow reference of a row shift: the column read at x_r - dx[r] by
/// finding the two row centres around it (x_k = -0.55 + 0.1 k, any
/// integer k) and interpolating, a row outside the grid or missing
/// reading the cell's own height; plus dz[r].
fn reference_shift(z: &[Vec<Option<f64>>], dx: &[f64], dz: &[f64]) -> Vec<Vec<Option<f64>>> {
    let xk = |k: i64| -0.55 + 0.1 * k as f64;
    (0..GRID_ROWS)
        .map(|r| {
            (0..COLS)
                .map(|c| {
                    let own = z[r][c]?;
                    let p = xk(r as i64) - dx[r].clamp(-MAX_SHIFT, MAX_SHIFT);
                    let k = (-40..40).filter(|&k| xk(k) <= p + 1e-12).max().unwrap();
                    let w = ((p - xk(k)) / 0.1).clamp(0.0, 1.0);
                    let val = |k: i64| if (0..GRID_ROWS as i64).contains(&k) { z[k as usize][c].unwrap_or(own) } else { own };
                    Some((1.0 - w) * val(k) + w * val(k + 1) + dz[r])
                })
                .collect()
        })
        .collect()
}

fn assert_close(got: &Dem, want: &[Vec<Option<f64>>], tol: f64, what: &str) {
    for (r, row) in want.iter().enumerate().take(GRID_ROWS) {
        for (c, &cell) in row.iter().enumerate().take(COLS) {
            match cell {
                None => assert!(!got.is_valid(r, c), "{what}: ({r}, {c}) stays missing"),
                Some(h) => {
                    assert!(got.is_valid(r, c), "{what}: ({r}, {c}) stays valid");
                    assert!((got.height(r, c) as f64 - h).abs() <= tol, "{what}: ({r}, {c}) {} vs {h}", got.height(r, c));
                }
            }
        }
    }
}

/// A DEM of varied heights (a riser, a drop, a slope) with a few
/// missing cells.
fn rough() -> Dem {
    let mut d = empty_dem();
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let h = match r {
                0..=6 => -0.07 + 0.01 * c as f64,
                7..=11 => 0.1 + 0.02 * r as f64,
                _ => -0.2 + 0.03 * (r as f64 - 12.0),
            };
            d.set_valid(r, c, h as f32);
        }
    }
    for (r, c) in [(0, 1), (5, 2), (6, 2), (12, 4), (19, 0), (10, 3)] {
        d.set_missing(r, c);
    }
    d
}

/// tilt on flat ground is exactly the plane h + a (range + max(x, x0) -
/// x0) + b y, a = pitch z1, b = roll z2 from the record's Box-Muller
/// pair; a missing cell stays missing.
#[test]
fn tilt_on_flat_ground_is_the_plane() {
    for (u, x0, range) in [([0.3f32, 0.1f32], 0.45, 0.0), ([0.93, 0.71], -0.6, 2.5), ([0.01, 0.5], 1.2, 0.8)] {
        let (pitch, roll) = (0.02, 0.015);
        let (z1, z2) = crate::draws::box_muller(u[0], u[1]);
        let mut d = flat();
        d.set_missing(3, 3);
        Effect::Tilt(Tilt { pitch, roll, x0, range }).apply_drawn(&mut d, &u, None);
        let mut want = grid(&flat());
        want[3][3] = None;
        for (r, row) in want.iter_mut().enumerate() {
            for (c, h) in row.iter_mut().enumerate() {
                let x = row_center_x(r);
                *h = h.map(|h| h + pitch * z1 * (range + x.max(x0) - x0) + roll * z2 * col_center_y(c));
            }
        }
        assert_close(&d, &want, 1e-7, "tilt");
        // Behind x0 every row reads the same as x0's: no pitch there.
        if x0 > -0.5 {
            assert_eq!(d.height(0, 0), d.height(1, 0));
        }
    }
    assert!(Effect::Tilt(Tilt { pitch: 0.6, roll: 0.0, x0: 0.0, range: 0.0 }).check().is_err());
    assert!(Effect::Tilt(Tilt { pitch: 0.01, roll: -0.01, x0: 0.0, range: 0.0 }).check().is_err());
    assert!(Effect::Tilt(Tilt { pitch: 0.01, roll: 0.01, x0: 0.0, range: -0.1 }).check().is_err());
}

/// shake: the same plane about C (x from C, every row) with sd sigma +
/// edge J, J the largest step between x-neighbours of rows 2..=9; a
/// step farther ahead is not under the tracks.
#[test]
fn shake_rocks_about_c_with_the_step_under_the_tracks() {
    let u = [0.2f32, 0.3f32];
    let (z1, z2) = crate::draws::box_muller(u[0], u[1]);
    let (sigma, edge) = (0.003, 0.07);
    for (step_row, rise, j) in [(8, 0.12, 0.12), (13, 0.12, 0.0), (6, 0.9, SHAKE_MAX_STEP), (2, 0.1, 0.0)] {
        let mut d = flat();
        for r in step_row..GRID_ROWS {
            (0..COLS).for_each(|c| d.set_valid(r, c, FLAT_GROUND + rise as f32));
        }
        let before = grid(&d);
        assert!((step_under_tracks(&d) - j).abs() < 1e-6, "step at {step_row}: {}", step_under_tracks(&d));
        Effect::Shake(Shake { sigma, edge }).apply_drawn(&mut d, &u, None);
        let s = sigma + edge * j;
        let want: Vec<Vec<Option<f64>>> = (0..GRID_ROWS)
            .map(|r| (0..COLS).map(|c| before[r][c].map(|h| h + s * z1 * row_center_x(r) + s * z2 * col_center_y(c))).collect())
            .collect();
        assert_close(&d, &want, 1e-6, "shake");
    }
    assert!(Effect::Shake(Shake { sigma: 0.01, edge: -0.1 }).check().is_err());
}

/// step-jitter on a 0.12 m riser between rows 8 and 9 (under the
/// tracks, so s = sigma + edge 0.12): flat cells away from the step keep
/// their heights; the foot and the top move by dx 0.12 / 0.2 each, dx
/// their own draw clamped to one cell; a missing neighbour reads as the
/// cell's own height; row 0 and row 19 use the one-sided slope.
#[test]
fn step_jitter_moves_only_cells_beside_steps() {
    let (sigma, edge) = (0.01, 0.2);
    let u: Vec<f32> = (0..GRID_ROWS * COLS).map(|i| ((i * 37 % 97) as f32 + 0.5) / 97.0).collect();
    let z: [f64; GRID_ROWS * COLS] = Draws::new(&u).normals();
    let mut d = flat();
    for r in 9..GRID_ROWS {
        (0..COLS).for_each(|c| d.set_valid(r, c, FLAT_GROUND + 0.12));
    }
    d.set_missing(8, 4);
    d.set_valid(19, 0, FLAT_GROUND + 0.2);
    let before = grid(&d);
    Effect::StepJitter(StepJitter { sigma, edge }).apply_drawn(&mut d, &u, None);
    let s = sigma + edge * 0.12;
    let dx = |r: usize, c: usize| (s * z[r * COLS + c]).clamp(-0.1, 0.1);
    let mut want = before.clone();
    for c in 0..COLS {
        if c != 4 {
            want[8][c] = Some(before[8][c].unwrap() + dx(8, c) * 0.12 / 0.2);
        }
        // Row 9's foot neighbour at (8, 4) is missing: it reads its own height.
        let drop = if c == 4 { 0.0 } else { 0.12 };
        want[9][c] = Some(before[9][c].unwrap() + dx(9, c) * drop / 0.2);
    }
    want[19][0] = Some(before[19][0].unwrap() + dx(19, 0) * (0.2 - 0.12) / 0.2);
    want[18][0] = Some(before[18][0].unwrap() + dx(18, 0) * (0.2 - 0.12) / 0.2);
    assert_close(&d, &want, 1e-6, "step-jitter");
    assert!(!d.is_valid(8, 4), "a missing cell stays missing");
    assert!((0..COLS).any(|c| (d.height(8, c) as f64 - before[8][c].unwrap_or(0.0)).abs() > 1e-3), "the foot moves");
    assert!(Effect::StepJitter(StepJitter { sigma: 0.01, edge: -0.1 }).check().is_err());
}

/// lag of a step moves it by s: at s = 0.1 m the row beyond the riser
/// reads the lower surface; at 0.05 m it reads the mean; the climb
/// s tan(pitch) is added from row 20; row 0 keeps its value; a missing
/// cell behind is read as the cell's own height; validity is kept.
#[test]
fn lag_moves_a_step_by_s_and_adds_the_climb() {
    let step = || {
        let mut d = flat();
        for r in 10..GRID_ROWS {
            (0..COLS).for_each(|c| d.set_valid(r, c, 0.1));
        }
        d
    };
    let mut d = step();
    Effect::Lag(Lag { s: 0.1, spread: 0.0 }).apply_drawn(&mut d, &[0.77], None);
    assert!((d.height(10, 0) - FLAT_GROUND).abs() < 1e-6 && (d.height(11, 0) - 0.1).abs() < 1e-6);
    assert!((d.height(0, 0) - FLAT_GROUND).abs() < 1e-6, "row 0 keeps its value");
    let mut d = step();
    Effect::Lag(Lag { s: 0.05, spread: 0.0 }).apply_drawn(&mut d, &[0.3], None);
    assert!((d.height(10, 2) as f64 - (0.1 + -0.07) / 2.0).abs() < 1e-6 && (d.height(11, 2) - 0.1).abs() < 1e-6);
    // The climb: pitch 0.3 rad, u = 0.75 with spread 0.4: s_r = 0.06 (1 + 0.2).
    let mut d = step();
    let mut att = d.attitude();
    att[0] = 0.3;
    d.set_attitude(att);
    d.set_missing(4, 1);
    Effect::Lag(Lag { s: 0.06, spread: 0.4 }).apply_drawn(&mut d, &[0.75], None);
    let sr = 0.06 * 1.2;
    let mut z = grid(&step());
    z[4][1] = None;
    let want = reference_shift(&z, &[sr; GRID_ROWS], &[sr * 0.3f64.tan(); GRID_ROWS]);
    assert_close(&d, &want, 1e-6, "lag with a climb");
    assert!(!d.is_valid(4, 1) && d.attitude()[0] == 0.3);
    // A missing cell behind a valid one: the valid one reads its own
    // height in its place (row 5, column 1: row 4 is missing).
    assert!((d.height(5, 1) as f64 - (FLAT_GROUND as f64 + sr * 0.3f64.tan())).abs() < 1e-6);
    assert!(Effect::Lag(Lag { s: 0.6, spread: 0.0 }).check().is_err() && Effect::Lag(Lag { s: 0.1, spread: 1.5 }).check().is_err());
}

/// lag against the slow reference on a rough DEM, shifts either way
/// and across whole rows.
#[test]
fn lag_equals_the_reference() {
    let mut r = rng();
    for (s, spread) in [(0.04, 0.5), (0.15, 1.0), (-0.12, 0.3), (0.5, 1.0), (-0.5, 1.0), (0.1, 0.0)] {
        for _ in 0..50 {
            let u = [crate::draws::uniform(&mut r)];
            let mut d = rough();
            let mut att = d.attitude();
            att[0] = -0.4;
            d.set_attitude(att);
            Effect::Lag(Lag { s, spread }).apply_drawn(&mut d, &u, None);
            let sr = s * (1.0 + spread * (2.0 * f64::from(u[0]) - 1.0));
            let want = reference_shift(&grid(&rough()), &[sr; GRID_ROWS], &[sr * (-0.4f64).tan(); GRID_ROWS]);
            assert_close(&d, &want, 1e-6, &format!("lag s {s} spread {spread} u {}", u[0]));
        }
    }
}

/// drift with rates 0 is the identity; rows from x0 on never move; the
/// rest equals the slow reference (walks summed by hand), and the
/// height walk's spread grows as the square root of the rows behind x0.
#[test]
fn drift_is_a_walk_back_from_x0() {
    let mut r = rng();
    let mut u = vec![0.0f32; 40];
    for x0 in [-1.0, 0.3, 0.45, 2.0] {
        crate::draws::fill_uniform(&mut r, &mut u);
        let mut d = rough();
        Effect::Drift(Drift { rate: 0.0, zrate: 0.0, x0 }).apply_drawn(&mut d, &u, None);
        assert_eq!(d, rough(), "rates 0: the identity");
    }
    for (rate, zrate, x0) in [(0.05, 0.02, 0.3), (0.2, 0.0, 1.5), (3.0, 0.1, 0.0), (0.1, 0.05, -0.7)] {
        for _ in 0..50 {
            crate::draws::fill_uniform(&mut r, &mut u);
            let mut d = rough();
            Effect::Drift(Drift { rate, zrate, x0 }).apply_drawn(&mut d, &u, None);
            let normals: Vec<(f64, f64)> = u.chunks(2).map(|p| crate::draws::box_muller(p[0], p[1])).collect();
            let (mut dx, mut dz) = (vec![0.0; GRID_ROWS], vec![0.0; GRID_ROWS]);
            for row in 0..GRID_ROWS {
                if row_center_x(row) < x0 {
                    for (j, n) in normals.iter().enumerate().take(GRID_ROWS).skip(row) {
                        if row_center_x(j) < x0 {
                            dx[row] += rate * 0.1f64.sqrt() * n.0;
                            dz[row] += zrate * 0.1f64.sqrt() * n.1;
                        }
                    }
                }
            }
            let want = reference_shift(&grid(&rough()), &dx, &dz);
            assert_close(&d, &want, 2e-6, &format!("drift {rate} {zrate} {x0}"));
            for row in (0..GRID_ROWS).filter(|&row| row_center_x(row) >= x0) {
                (0..COLS).for_each(|c| assert_eq!(d.height(row, c), rough().height(row, c)));
            }
        }
    }
    // On flat ground the height walk alone shows: sd zrate sqrt(0.1 k)
    // in the k-th row behind x0 = 0.3 (rows 8, 7, ...: k = 1, 2, ...).
    let (zrate, n) = (0.02, 4000);
    let mut sq = [0.0f64; GRID_ROWS];
    for _ in 0..n {
        crate::draws::fill_uniform(&mut r, &mut u);
        let mut d = flat();
        Effect::Drift(Drift { rate: 0.05, zrate, x0: 0.3 }).apply_drawn(&mut d, &u, None);
        (0..GRID_ROWS).for_each(|row| sq[row] += (d.height(row, 0) as f64 - FLAT_GROUND as f64).powi(2));
    }
    for (row, &s2) in sq.iter().enumerate() {
        let sd = (s2 / n as f64).sqrt();
        let k = (0..GRID_ROWS).filter(|&j| j >= row && row_center_x(j) < 0.3).count() as f64;
        let want = zrate * (0.1 * k).sqrt();
        assert!((sd - want).abs() <= 0.04 * want + 1e-9, "row {row}: sd {sd} vs {want}");
    }
}

#[test]
fn random_effects_have_their_rates_and_spread() {
    let (mut miss, mut rows, mut sq) = (0usize, 0usize, 0.0);
    let mut r1 = rng();
    for _ in 0..200 {
        let mut d = flat();
        Effect::Dropout(Dropout { p: 0.2 }).apply(&mut d, &mut r1);
        miss += 100 - d.valid_cells();
        let mut d = flat();
        Effect::RowDropout(RowDropout { p: 0.3 }).apply(&mut d, &mut r1);
        rows += (100 - d.valid_cells()) / 5;
        let mut d = flat();
        Effect::Noise(Noise { sigma0: 0.01, k: 0.0, tau: 0.0 }).apply(&mut d, &mut r1);
        sq += (0..100).map(|i| (d[2 * i] as f64 + 0.07).powi(2)).sum::<f64>();
    }
    assert!((miss as f64 / 20000.0 - 0.2).abs() < 0.02);
    assert!((rows as f64 / 4000.0 - 0.3).abs() < 0.03);
    assert!(((sq / 20000.0).sqrt() - 0.01).abs() < 0.0005);
}
