//! Section 6.4 of the thesis: records with a large missing area (a run's
//! first frames, before the map has seen the rows behind the robot) teach a
//! generator to invent holes. Keep some of them as they are and, in the
//! others, replace every missing cell by a height drawn at random from the
//! same record's valid cells, marking it valid.
//!
//! Each record draws from its own random stream (seed, record index), so the
//! result does not depend on chunking or threads.

use rand::Rng;

use dem_core::format::{Dem, DemCells, COLS, GRID_CELLS, GRID_ROWS};
pub use dem_core::seeded::{record_rng, record_uniform};

/// Fraction of the 100 grid cells that are missing.
pub fn missing_fraction(d: &Dem) -> f64 {
    1.0 - d.valid_cells() as f64 / GRID_CELLS as f64
}

/// Replace the missing cells of `d` by heights of its valid cells drawn at
/// random; returns false (and leaves `d`) when it has no valid cell.
pub fn fill_from_own_heights(d: &mut Dem, seed: u64, index: u64) -> bool {
    let heights: Vec<f32> = (0..GRID_ROWS)
        .flat_map(|r| (0..COLS).map(move |c| (r, c)))
        .filter(|&(r, c)| d.is_valid(r, c))
        .map(|(r, c)| d.height(r, c))
        .collect();
    if heights.is_empty() {
        return false;
    }
    let mut rng = record_rng(seed, index);
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            if !d.is_valid(r, c) {
                d.set_valid(r, c, heights[rng.gen_range(0..heights.len())]);
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::format::empty_dem;

    #[test]
    fn filled_cells_take_only_heights_the_record_had() {
        let mut d = empty_dem();
        d.set_valid(19, 0, -0.07);
        d.set_valid(19, 1, 0.2);
        assert!((missing_fraction(&d) - 0.98).abs() < 1e-12);
        assert!(fill_from_own_heights(&mut d, 1, 5));
        assert_eq!(d.valid_cells(), 100);
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                assert!(d.height(r, c) == -0.07 || d.height(r, c) == 0.2);
            }
        }
        let mut again = empty_dem();
        again.set_valid(19, 0, -0.07);
        again.set_valid(19, 1, 0.2);
        fill_from_own_heights(&mut again, 1, 5);
        assert_eq!(d, again, "same seed and index, same draw");
    }

    #[test]
    fn an_empty_record_cannot_be_filled() {
        let mut d = empty_dem();
        assert!(!fill_from_own_heights(&mut d, 0, 0));
        assert_eq!(d, empty_dem());
    }
}
