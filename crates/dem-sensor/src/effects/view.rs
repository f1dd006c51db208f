//! What the sensor can see: `occlusion`, `fov`, `view-top`, `startup`.
//! Each removes cells the camera never observed; none moves a height.

use dem_core::format::{row_center_x, Dem, DemCells, COLS, GRID_ROWS};

use super::{cell_heights, probability, EffectSpec, Family, Limit, ParamSpec, Range, Stage, HALF};
use crate::draws::Draws;

/// How far (m) the line of sight may pass below a cell's top before that
/// cell hides what lies behind it: terrain within a centimetre of the ray
/// grazes it rather than blocks it.
pub const OCCLUSION_TOLERANCE: f64 = 0.01;
/// Back edge of the grid (m): where a startup frame's blind edge ends.
const X_BACK: f64 = -0.6;

/// `occlusion`: cells hidden from the sensor by taller terrain.
pub const OCCLUSION: EffectSpec = EffectSpec {
    name: "occlusion",
    family: Family::View,
    emulator: &["occlusion"],
    formula: "in each column, a sensor at (x0, h) looks at the far edge of each cell's top; the cell is missing when the line of sight \
        passes more than OCCLUSION_TOLERANCE below the top of a valid cell between, or when its top is more than that above the \
        sensor and its valid neighbour toward the sensor is not more than that lower (a top above the sensor faces away from it; \
        only the cell holding the face is seen)",
    // A sensor mounted on the robot: above C by 0.2 to 1.2 m, along x
    // within the tracks and flippers.
    params: &[
        ParamSpec { name: "h", doc: "Sensor height above C (m).", fit: Range::lin(0.2, 1.2), limit: Limit::new(0.05, 3.0) },
        ParamSpec { name: "x0", doc: "Sensor position along x (m).", fit: Range::lin(-0.4, 0.5), limit: Limit::new(-1.0, 1.2) },
    ],
    stage: Stage::Occlusion,
    draws: 0,
};

/// `fov`: cells outside the field of view along x never observed.
pub const FOV: EffectSpec = EffectSpec {
    name: "fov",
    family: Family::View,
    emulator: &["fov"],
    formula: "cells whose centre x is outside [x_min, x_max] missing",
    params: &[
        ParamSpec {
            name: "x_min",
            doc: "Nearest x observed (m).",
            fit: Range::lin(-0.65, 0.55),
            limit: Limit::new(-0.65, 0.55).natural_lo(),
        },
        ParamSpec {
            name: "x_max",
            doc: "Farthest x observed (m).",
            fit: Range::lin(0.35, 1.45),
            limit: Limit::new(0.35, 1.45).natural_hi(),
        },
    ],
    stage: Stage::FieldOfView,
    draws: 0,
};

/// `view-top`: the upper edge of the vertical field of view.
pub const VIEW_TOP: EffectSpec = EffectSpec {
    name: "view-top",
    family: Family::View,
    emulator: &["fov"],
    formula: "cells whose height lies above the line z = h - t x (the upper edge of the camera's vertical field of view) missing",
    // A camera 0.2-1.2 m above C whose top ray falls 0-60 degrees. High
    // enough or flat enough, the ray clears everything: natural ends.
    params: &[
        ParamSpec {
            name: "h",
            doc: "Height (m) of the top ray above C at x = 0.",
            fit: Range::lin(0.1, 1.5),
            limit: Limit::new(0.0, 3.0).natural_hi(),
        },
        ParamSpec {
            name: "t",
            doc: "Its fall per metre along x (the tangent of its depression angle).",
            fit: Range::lin(0.0, 1.7),
            limit: Limit::new(-1.0, 3.0).natural_lo(),
        },
    ],
    stage: Stage::FieldOfView,
    draws: 0,
};

/// `startup`: the first frames of a run, blind behind the nearest ray.
pub const STARTUP: EffectSpec = EffectSpec {
    name: "startup",
    family: Family::View,
    emulator: &["fov"],
    formula: "rows whose centre x < e missing: e = x0 - v t for a record t seconds into its run (labels' `time`, v > 0); without a \
        time, with probability p the record is a startup frame and e = x0 - u (x0 + 0.6), u uniform",
    // v is fitted when the records' times are known, p when not (dem-gap's fit).
    params: &[
        ParamSpec {
            name: "x0",
            doc: "Blind edge at the start of a run (m along x).",
            fit: Range::lin(-0.3, 1.2),
            limit: Limit::new(-0.6, 1.45).natural_lo().natural_hi(),
        },
        ParamSpec {
            name: "v",
            doc: "Speed at which the blind edge recedes (m/s); 0: unknown.",
            fit: Range::lin(0.02, 0.6),
            limit: Limit::new(0.005, 3.0),
        },
        ParamSpec {
            name: "p",
            doc: "Share of records that are startup frames (used without times).",
            fit: Range::lin(0.0, 0.6),
            limit: Limit::new(0.0, 1.0).natural_lo(),
        },
    ],
    stage: Stage::Startup,
    // u1: whether a record without a time is a startup frame; u2: its edge.
    draws: 2,
};

pub(super) fn check_occlusion(h: f64) -> Result<(), String> {
    if h <= 0.0 {
        return Err(format!("sensor height h = {h} must be > 0"));
    }
    Ok(())
}

pub(super) fn check_fov(x_min: f64, x_max: f64) -> Result<(), String> {
    if x_min >= x_max {
        return Err(format!("x_min = {x_min} must be < x_max = {x_max}"));
    }
    Ok(())
}

pub(super) fn check_startup(v: f64, p: f64) -> Result<(), String> {
    probability(p)?;
    if v < 0.0 {
        return Err(format!("v = {v} must be >= 0"));
    }
    Ok(())
}

/// `fov` (formula in its spec).
pub(super) fn cut_to_fov(d: &mut Dem, x_min: f64, x_max: f64) {
    for r in 0..GRID_ROWS {
        let x = row_center_x(r);
        if x < x_min || x > x_max {
            (0..COLS).for_each(|c| d.set_missing(r, c));
        }
    }
}

/// `view-top` (formula in its spec).
pub(super) fn cut_above_top_ray(d: &mut Dem, h: f64, t: f64) {
    for r in 0..GRID_ROWS {
        let top = h - t * row_center_x(r);
        for c in 0..COLS {
            if d.is_valid(r, c) && d.height(r, c) as f64 > top {
                d.set_missing(r, c);
            }
        }
    }
}

/// `startup` (formula in its spec): the record's `time` in its run when
/// known, else its two uniforms decide.
pub(super) fn blind_startup_rows(d: &mut Dem, rng: &mut Draws, time: Option<f64>, x0: f64, v: f64, p: f64) {
    let (u1, u2): (f64, f64) = (rng.gen(), rng.gen());
    let edge = match time {
        Some(t) if v > 0.0 => Some(x0 - v * t),
        _ => (u1 < p).then_some(x0 - u2 * (x0 - X_BACK)),
    };
    if let Some(e) = edge {
        for r in (0..GRID_ROWS).filter(|&r| row_center_x(r) < e) {
            (0..COLS).for_each(|c| d.set_missing(r, c));
        }
    }
}

/// True when cell `(t, c)` of the original heights `z` (None = missing) is
/// hidden from a sensor at `(x0, h)`: see [`OCCLUSION`]'s formula.
pub fn hidden(z: &[[Option<f64>; COLS]; GRID_ROWS], t: usize, c: usize, h: f64, x0: f64) -> bool {
    let Some(zt) = z[t][c] else { return false };
    let xt = row_center_x(t);
    if (xt - x0).abs() <= HALF {
        return false;
    }
    let dir = if xt > x0 { 1.0 } else { -1.0 };
    // A top above the sensor faces away from it: only the cell that holds
    // the face toward the sensor (its near neighbour lower) is seen.
    if zt > h + OCCLUSION_TOLERANCE {
        let near = if dir > 0.0 { t.checked_sub(1) } else { Some(t + 1).filter(|&n| n < GRID_ROWS) };
        if near.and_then(|n| z[n][c]).is_some_and(|zn| zn > zt - OCCLUSION_TOLERANCE) {
            return true;
        }
    }
    let xf = xt + dir * HALF;
    let line = |x: f64| h + (zt - h) * (x - x0) / (xf - x0);
    let rows: Box<dyn Iterator<Item = usize>> = if dir > 0.0 { Box::new(0..t) } else { Box::new(t + 1..GRID_ROWS) };
    for b in rows {
        let Some(zb) = z[b][c] else { continue };
        let xb = row_center_x(b);
        // The blocker's top, clipped to the stretch between sensor and target.
        let (lo, hi) = ((xb - HALF).max(x0.min(xf)), (xb + HALF).min(x0.max(xf)));
        if lo >= hi {
            continue;
        }
        if zb > line(lo).min(line(hi)) + OCCLUSION_TOLERANCE {
            return true;
        }
    }
    false
}

/// `occlusion`: every cell [`hidden`] in the DEM as it comes in is lost.
pub(super) fn occlude(d: &mut Dem, h: f64, x0: f64) {
    let z = cell_heights(d);
    for t in 0..GRID_ROWS {
        for c in 0..COLS {
            if hidden(&z, t, c, h, x0) {
                d.set_missing(t, c);
            }
        }
    }
}
