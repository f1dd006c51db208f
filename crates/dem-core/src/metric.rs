//! The thesis's equation 7.1: the error of a prediction against a measured DEM.
//!
//! ```text
//! e(y, p) = 1/100 * sum_{r<20, c<5} (v * (y_h - p_h))^2 + (y_m - p_m)^2
//! ```
//! with v = 1 where `y_m > 0`, else 0, and `p_m` the raw predicted mask (not
//! thresholded). Row 20 (attitude) is not part of the error. Sums run in f64
//! so the result does not depend on summation order at f32 precision.
//!
//! ```
//! use dem_core::{format::{empty_dem, DemCells}, metric::dem_error};
//! let y = empty_dem();
//! let mut p = y;
//! p[1] = -0.5; // cell (0, 0) mask -0.5 against -1
//! assert!((dem_error(&y, &p) - 0.0025).abs() < 1e-12);
//! ```

use crate::format::{Dem, GRID_CELLS};

/// Equation 7.1: error of prediction `p` against measured `y`.
pub fn dem_error(y: &Dem, p: &Dem) -> f64 {
    let mut sum = 0.0f64;
    for i in 0..GRID_CELLS {
        let (yh, ym) = (y[2 * i] as f64, y[2 * i + 1] as f64);
        let (ph, pm) = (p[2 * i] as f64, p[2 * i + 1] as f64);
        let v = if ym > 0.0 { 1.0 } else { 0.0 };
        let dh = v * (yh - ph);
        let dm = ym - pm;
        sum += dh * dh + dm * dm;
    }
    sum / GRID_CELLS as f64
}

/// Pair error of a prediction against the measured DEMs it is paired with:
/// the smallest [`dem_error`] over them, with the index (into `measured`)
/// of the best one. None when `measured` is empty.
pub fn pair_error<'a>(measured: impl IntoIterator<Item = &'a Dem>, p: &Dem) -> Option<(usize, f64)> {
    measured.into_iter().map(|y| dem_error(y, p)).enumerate().min_by(|a, b| a.1.total_cmp(&b.1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::{empty_dem, level_dem, DemCells, FLAT_GROUND};

    // The worked checks of docs/format.md: whole DEMs differing in one cell.
    #[test]
    fn worked_check_mask_half_against_valid() {
        let y = level_dem(FLAT_GROUND);
        let mut p = y;
        p[crate::format::at(4, 2, 1)] = 0.5;
        assert!((dem_error(&y, &p) - 0.0025).abs() < 1e-12);
    }

    #[test]
    fn worked_check_mask_half_against_missing() {
        let y = empty_dem();
        let mut p = y;
        p[crate::format::at(7, 1, 1)] = 0.5;
        assert!((dem_error(&y, &p) - 0.0225).abs() < 1e-12);
    }

    #[test]
    fn worked_check_valid_height() {
        let y = level_dem(FLAT_GROUND);
        let mut p = y;
        p.set_valid(10, 3, -0.09);
        // (0.02)^2 / 100 = 4e-6, up to f32 rounding of -0.09 and -0.07.
        assert!((dem_error(&y, &p) - 0.000004).abs() < 1e-9);
    }

    #[test]
    fn heights_under_missing_cells_do_not_count() {
        let y = empty_dem();
        let mut p = y;
        p[crate::format::at(3, 3, 0)] = 5.0;
        assert_eq!(dem_error(&y, &p), 0.0);
    }

    #[test]
    fn attitude_row_is_ignored() {
        let y = level_dem(FLAT_GROUND);
        let mut p = y;
        p.set_attitude([1.0; 5]);
        assert_eq!(dem_error(&y, &p), 0.0);
    }

    #[test]
    fn soft_masks_count_raw_and_a_zero_measured_mask_is_missing() {
        // Measured mask 0.3 is valid (> 0): height counts; exactly 0 is
        // missing: height does not. Predicted masks count unthresholded.
        let mut y = empty_dem();
        y[crate::format::at(0, 0, 1)] = 0.3;
        y[crate::format::at(0, 1, 1)] = 0.0;
        let mut p = y;
        p[crate::format::at(0, 0, 0)] = 0.1; // (0.1)^2
        p[crate::format::at(0, 1, 0)] = 0.1; // ignored
        p[crate::format::at(0, 2, 1)] = -0.2; // (-1 - -0.2)^2 = 0.64
        let want = (0.1f64 * 0.1 + 0.8f64.powi(2)) / 100.0;
        assert!((dem_error(&y, &p) - want).abs() < 1e-8, "{}", dem_error(&y, &p));
    }

    #[test]
    fn pair_error_takes_the_best_measured() {
        let p = level_dem(FLAT_GROUND);
        let far = empty_dem();
        let near = level_dem(FLAT_GROUND);
        let (i, e) = pair_error([&far, &near, &far], &p).unwrap();
        assert_eq!((i, e), (1, 0.0));
        assert!(pair_error([], &p).is_none());
    }
}
