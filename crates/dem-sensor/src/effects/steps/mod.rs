//! Heights moved at steps, where a cell holds points of two surfaces:
//! `riser-blend`, `drop-blend`, `mixed-cells`, `floor-lift`,
//! `step-jitter`, `smoothing`.
//!
//! One file per effect (its parameters, spec, check, apply, ONNX
//! operators, evidence sentence and examples); this module holds what
//! several of them share, and `ops` the operators they share in
//! the graph.

use crate::effects::{cell_heights, Limit, Range};
use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};

pub mod drop_blend;
pub mod floor_lift;
pub mod mixed_cells;
pub mod riser_blend;
pub mod smoothing;
pub mod step_jitter;

/// A cell between two jumps (`drop-blend`, `riser-blend`) takes the one
/// behind only when its step is larger by more than this (m): a cell made
/// the mean of its neighbours (`mixed-cells`, `smoothing`) lies exactly
/// between two equal steps, where rounding alone would choose.
pub const TIE_MARGIN: f64 = 1e-5;

/// A share from 0 to 1 whose both ends are natural (none, or all of it).
const SHARE: (Range, Limit) = (Range::lin(0.0, 1.0), Limit::new(0.0, 1.0).natural_lo().natural_hi());

/// `step-jitter` with sd `s`: each valid cell reads dx = clamp(s z, +-0.1
/// m) off along x (`z` its normal, row-major):
/// h += dx (src(r + 1) - src(r - 1)) / 0.2, where src(k) is row k's height
/// where row k lies in the grid and is valid, else the cell's own (a
/// one-sided slope at an edge of what was seen, none on even ground).
pub fn jitter_steps(d: &mut Dem, z: &[f64; GRID_ROWS * COLS], s: f64) {
    let h = cell_heights(d);
    let cell = dem_core::format::CELL;
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let Some(own) = h[r][c] else { continue };
            let src = |k: Option<usize>| k.filter(|&k| k < GRID_ROWS).and_then(|k| h[k][c]).unwrap_or(own);
            let slope = (src(Some(r + 1)) - src(r.checked_sub(1))) / (2.0 * cell);
            let dx = (s * z[r * COLS + c]).clamp(-cell, cell);
            d.set_valid(r, c, (own + dx * slope) as f32);
        }
    }
}

/// The operators the family's effects share in the graph.
pub(crate) mod ops {
    use dem_graph::Builder;

    /// The step across the cell's larger x-jump of two: `(has, step, behind)`
    /// where `ahead` is `(valid, step)` toward the cell ahead and `behind`
    /// toward the one behind; behind wins (`behind` true) only when its step
    /// is larger in magnitude or there is none ahead.
    pub(crate) fn larger_step(b: &mut Builder, ahead: (&str, &str), behind: (&str, &str)) -> (String, String, String) {
        let fa = b.un("Abs", ahead.1);
        let fa = b.add_const(&fa, crate::effects::TIE_MARGIN as f32);
        let ba = b.un("Abs", behind.1);
        let bigger = b.bin("Greater", &ba, &fa);
        let no_ahead = b.un("Not", ahead.0);
        let pick = b.any(&[&no_ahead, &bigger]);
        let pick_behind = b.all(&[behind.0, &pick]);
        let step = b.select(&pick_behind, behind.1, ahead.1);
        let has = b.any(&[ahead.0, behind.0]);
        (has, step, pick_behind)
    }
}
