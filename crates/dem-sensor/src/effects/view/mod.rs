//! What the sensor can see: `occlusion`, `fov`, `view-top`, `startup`, and
//! what the map keeps of what it saw (`map-memory`). The first four remove
//! cells the camera never observed and move no height.
//!
//! One file per effect (its parameters, spec, check, apply, ONNX
//! operators, evidence sentence and examples); this module holds what
//! several of them share.

use crate::graph::ops::HALF;
use dem_core::format::{row_center_x, COLS, GRID_ROWS};

pub mod fov;
pub mod map_memory;
pub mod occlusion;
pub mod startup;
pub mod view_top;

/// How far (m) the line of sight may pass below a cell's top before that
/// cell hides what lies behind it: terrain within a centimetre of the ray
/// grazes it rather than blocks it.
pub const OCCLUSION_TOLERANCE: f64 = 0.01;
/// Back edge of the grid (m): where a startup frame's blind edge ends.
const X_BACK: f64 = -0.6;

/// Where a sensor at `x0` looks at row `t`: the far edge of `t`'s top (its
/// edge away from the sensor), where the line of sight ends, and the rows
/// between the sensor and `t`; None for the sensor's own row, which
/// nothing hides.
pub(super) fn sight(t: usize, x0: f64) -> Option<(f64, std::ops::Range<usize>)> {
    let xt = row_center_x(t);
    if (xt - x0).abs() <= HALF {
        return None;
    }
    let dir = if xt > x0 { 1.0 } else { -1.0 };
    let between = if dir > 0.0 { 0..t } else { t + 1..GRID_ROWS };
    Some((xt + dir * HALF, between))
}

/// The stretch `(lo, hi)` of row `b`'s top that lies between the sensor at
/// `x0` and the far edge `xf` of a target's top: where `b` can block the
/// line of sight; None when they do not overlap.
pub(super) fn blocking_stretch(b: usize, x0: f64, xf: f64) -> Option<(f64, f64)> {
    let xb = row_center_x(b);
    let (lo, hi) = ((xb - HALF).max(x0.min(xf)), (xb + HALF).min(x0.max(xf)));
    (lo < hi).then_some((lo, hi))
}

/// True when cell `(t, c)` of the original heights `z` (None = missing) is
/// hidden from a sensor at `(x0, h)`: see [`occlusion`]'s formula.
pub fn hidden(z: &[[Option<f64>; COLS]; GRID_ROWS], t: usize, c: usize, h: f64, x0: f64) -> bool {
    // Decided in float32, operation for operation as the graph decides it,
    // so a cell on the line of sight is hidden alike in every runtime.
    let at = |r: usize| z[r][c].map(|v| v as f32);
    let Some(zt) = at(t) else { return false };
    let Some((xf, between)) = sight(t, x0) else { return false };
    let tol = OCCLUSION_TOLERANCE as f32;
    // A top above the sensor faces away from it: only the cell that holds
    // the face toward the sensor (its near neighbour lower) is seen.
    if zt > (h + OCCLUSION_TOLERANCE) as f32 {
        let near = if xf > x0 { t.checked_sub(1) } else { Some(t + 1).filter(|&n| n < GRID_ROWS) };
        if near.and_then(at).is_some_and(|zn| zn > zt + -tol) {
            return true;
        }
    }
    let rise = zt + -(h as f32);
    let share = |x: f64| ((x - x0) / (xf - x0)) as f32;
    for b in between {
        let Some(zb) = at(b) else { continue };
        // The blocker's top, clipped to the stretch between sensor and target.
        let Some((lo, hi)) = blocking_stretch(b, x0, xf) else { continue };
        if zb > (rise * share(lo)).min(rise * share(hi)) + (h + OCCLUSION_TOLERANCE) as f32 {
            return true;
        }
    }
    false
}
