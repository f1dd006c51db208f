//! `occlusion`: cells hidden from the sensor by taller terrain.

use super::{blocking_stretch, hidden, sight, OCCLUSION_TOLERANCE};
use crate::draws::Draws;
use crate::effects::{cell_heights, params, EffectKind, EffectSpec, Family, Limit, Range, Stage};
use crate::evidence::{pct, per_rec, Context};
use crate::graph::ops::{drop_cells, is_valid, nb, per_row, Cells, Side, HALF};
use dem_core::format::{row_center_x, Dem, DemCells, COLS, GRID_BACK, GRID_FRONT, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Cells hidden from the sensor by taller terrain.
    #[serde(expecting = "struct variant Effect::Occlusion")]
    Occlusion {
        // A sensor mounted on the robot: above C by 0.2 to 1.2 m (at most
        // 3 m, a mast), along x within the tracks and flippers, and at
        // most anywhere over the grid (GRID_BACK..GRID_FRONT): a sensor behind
        // or ahead of the map is not on the robot the map is around.
        /// Sensor height above C (m).
        h: fit Range::lin(0.2, 1.2), limit Limit::new(0.05, 3.0);
        /// Sensor position along x (m).
        x0: fit Range::lin(-0.4, 0.5), limit Limit::new(GRID_BACK, GRID_FRONT);
    }
}

impl EffectKind for Occlusion {
    const SPEC: EffectSpec = EffectSpec {
        name: "occlusion",
        family: Family::View,
        emulator: &["occlusion"],
        formula:
            "in each column, a sensor at (x0, h) looks at the far edge of each cell's top; the cell is missing when the line of sight \
            passes more than OCCLUSION_TOLERANCE below the top of a valid cell between, or when its top is more than that above the \
            sensor and its valid neighbour toward the sensor is not more than that lower (a top above the sensor faces away from it; \
            only the cell holding the face is seen)",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::Occlusion,
        draws: 0,
    };

    fn check(&self) -> Result<(), String> {
        let Self { h, .. } = *self;
        check_occlusion(h)
    }

    fn apply(&self, d: &mut Dem, _rng: &mut Draws, _time: Option<f64>) {
        let Self { h, x0 } = *self;
        occlude(d, h, x0)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, _u: &str, _time: Option<&str>) -> Cells {
        let Self { h, x0 } = *self;
        operators(b, c, h, x0)
    }

    fn evidence(&self, c: &Context) -> String {
        sentence(c)
    }

    fn examples() -> Vec<Self> {
        vec![Occlusion { h: 0.45, x0: 0.15 }, Occlusion { h: 0.3, x0: -0.2 }]
    }
}

fn check_occlusion(h: f64) -> Result<(), String> {
    if h <= 0.0 {
        return Err(format!("sensor height h = {h} must be > 0"));
    }
    Ok(())
}

/// `occlusion`: every cell [`hidden`] in the DEM as it comes in is lost.
fn occlude(d: &mut Dem, h: f64, x0: f64) {
    let z = cell_heights(d);
    for t in 0..GRID_ROWS {
        for c in 0..COLS {
            if hidden(&z, t, c, h, x0) {
                d.set_missing(t, c);
            }
        }
    }
}

/// `occlusion` (the rule of [`crate::effects::hidden`]) as pair tables:
/// for each target row t and blocker row b, whether b lies between the
/// sensor and t, and the line of sight's height at the ends of b's top as
/// `h + (z_t - h) alpha`, alpha a constant of (t, b).
fn operators(b: &mut Builder, c: &Cells, h: f64, x0: f64) -> Cells {
    let (rows, cols) = (GRID_ROWS, COLS);
    let tol = OCCLUSION_TOLERANCE;
    let mut pair = vec![0.0f32; rows * rows];
    let (mut a_lo, mut a_hi) = (vec![0.0f32; rows * rows], vec![0.0f32; rows * rows]);
    for t in 0..rows {
        let Some((xf, between)) = sight(t, x0) else { continue };
        for bl in between {
            let Some((lo, hi)) = blocking_stretch(bl, x0, xf) else { continue };
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

/// The evidence for `occlusion`.
fn sentence(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let removed = c.removed();
    let effect = c.effect;
    let (gap_before, gap_after) = (c.gap_before, c.gap_after);
    let body = {
        let extra = per_rec(real, "missing") - per_rec(before, "missing");
        let shadow = per_rec(real, "shadow") - per_rec(before, "shadow");
        if extra <= 0.0 || shadow <= 0.0 {
            return format!(
                "shadowed cells (missing behind cells at least 0.08 m taller) real {} vs model {}, missing cells real {} vs model {}: the fitted {effect} changes where cells are missing more than how many; it removes {} of the gap ({gap_before:.3} -> {gap_after:.3})",
                pct(real.mean_over("shadow", 0..20)),
                pct(before.mean_over("shadow", 0..20)),
                pct(real.mean_over("missing", 0..20)),
                pct(before.mean_over("missing", 0..20)),
                pct(removed)
            );
        }
        format!(
            "{} of the extra missing cells lie behind cells at least 0.08 m taller, in the sensor's line of sight (shadowed cells real {} vs model {})",
            pct((shadow / extra.max(1e-9)).clamp(0.0, 1.0)),
            pct(real.mean_over("shadow", 0..20)),
            pct(before.mean_over("shadow", 0..20)),
        )
    };
    c.fitted(body)
}
