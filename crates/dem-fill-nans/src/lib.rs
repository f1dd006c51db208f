//! Section 6.4 of the thesis: records with a large missing area (a run's
//! first frames, before the map has seen the rows behind the robot) teach a
//! generator to invent holes. Keep some of them as they are and, in the
//! others, replace every missing cell by a height drawn at random from the
//! same record's valid cells, marking it valid.
//!
//! Each record draws from its own random stream (seed, record index), so the
//! result does not depend on chunking or threads.

use std::collections::HashSet;

use dem_core::npy;
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

/// Whether `d` has a large missing area: at least `min_missing` of its
/// grid cells missing (with a little slack for the fraction's rounding).
pub fn is_large(d: &Dem, min_missing: f64) -> bool {
    missing_fraction(d) >= min_missing - 1e-9
}

/// `--keep N`: the indices of the `n` large-missing records of the file
/// `path` with the lowest random key [`record_uniform`]`(seed, index)`: a
/// choice of exactly n at random, fixed by the seed. Reads the file once
/// (the caller reads it again to fill), so it needs a file, not a pipe.
pub fn keep_exactly(path: &str, n: u64, seed: u64, min_missing: f64) -> dem_core::Result<HashSet<u64>> {
    let mut keys = Vec::new();
    npy::open(path)?.for_each_chunk(npy::CHUNK_RECORDS, |first, chunk| {
        for (k, _) in chunk.iter().enumerate().filter(|(_, d)| is_large(d, min_missing)) {
            let i = first + k as u64;
            keys.push((record_uniform(seed, i), i));
        }
        Ok::<_, dem_core::DemError>(())
    })?;
    keys.sort_by(|x, y| x.0.total_cmp(&y.0));
    Ok(keys.into_iter().take(n as usize).map(|(_, i)| i).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::format::empty_dem;

    #[test]
    fn keep_exactly_takes_the_n_lowest_keys_of_the_large_records() {
        let dir = dem_testkit::tempdir();
        let path = dir.path().join("r.npy").display().to_string();
        // Even records: 98 % missing; odd records: none missing.
        let mut full = empty_dem();
        (0..GRID_ROWS).for_each(|r| (0..COLS).for_each(|c| full.set_valid(r, c, 0.1)));
        let mut sparse = empty_dem();
        sparse.set_valid(0, 0, 0.1);
        sparse.set_valid(0, 1, 0.1);
        let records: Vec<Dem> = (0..40).map(|i| if i % 2 == 0 { sparse } else { full }).collect();
        npy::write_all(&path, &records).unwrap();
        let kept = keep_exactly(&path, 5, 7, 0.3).unwrap();
        assert_eq!(kept.len(), 5);
        assert!(kept.iter().all(|i| i % 2 == 0), "{kept:?}");
        let mut keys: Vec<(f64, u64)> = (0..40).step_by(2).map(|i| (record_uniform(7, i), i)).collect();
        keys.sort_by(|x, y| x.0.total_cmp(&y.0));
        assert_eq!(kept, keys[..5].iter().map(|k| k.1).collect());
        assert_eq!(keep_exactly(&path, 100, 7, 0.3).unwrap().len(), 20, "at most the large records");
    }

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
