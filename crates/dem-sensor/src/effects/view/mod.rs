//! What the sensor can see: `occlusion`, `fov`, `view-top`, `startup`.
//! Each removes cells the camera never observed; none moves a height.
//!
//! One file per effect (its parameters, spec, check, apply, ONNX
//! operators, evidence sentence and examples); this module holds what
//! several of them share.

use crate::graph::ops::HALF;
use dem_core::format::{row_center_x, COLS, GRID_ROWS};

pub mod fov;
pub mod occlusion;
pub mod startup;
pub mod view_top;

/// How far (m) the line of sight may pass below a cell's top before that
/// cell hides what lies behind it: terrain within a centimetre of the ray
/// grazes it rather than blocks it.
pub const OCCLUSION_TOLERANCE: f64 = 0.01;
/// Back edge of the grid (m): where a startup frame's blind edge ends.
const X_BACK: f64 = -0.6;

/// True when cell `(t, c)` of the original heights `z` (None = missing) is
/// hidden from a sensor at `(x0, h)`: see [`occlusion`]'s formula.
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
