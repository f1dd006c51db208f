//! Section 6.3 of the thesis: a simulated pallet, sampled at cell centres,
//! shows the gaps between its top boards as stripes of low cells; a real
//! sensor (stereo window, map fusion keeping the higher surface) sees a solid
//! top. Cleaning fills the gaps so sim pallets look solid too.
//!
//! A gap cell is a valid cell whose two neighbours along x (the rows before
//! and after) are valid, level with each other within `level_tol`, and
//! higher than it by `min_depth` to `max_depth`: a board, a gap, a board.
//! It is filled with the mean of the two boards.

use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};

/// Thresholds of the stripe detector (metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StripeRule {
    /// The boards either side of a gap differ by at most this.
    pub level_tol: f32,
    /// A gap is at least this much lower than the boards.
    pub min_depth: f32,
    /// ... and at most this (deeper is a trench, not a pallet gap).
    pub max_depth: f32,
    /// Without labels: a record is a pallet when some row has at least this
    /// many gap cells (a stripe across the pallet).
    pub min_row_cells: usize,
}

impl Default for StripeRule {
    fn default() -> Self {
        // EUR pallet: top boards 0.144 m up, bottom deck 0.022 m: 0.122 deep.
        StripeRule { level_tol: 0.02, min_depth: 0.05, max_depth: 0.2, min_row_cells: 3 }
    }
}

/// The gap cells of a record.
pub fn gap_cells(d: &Dem, rule: &StripeRule) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    for r in 1..GRID_ROWS - 1 {
        for c in 0..COLS {
            if !(d.is_valid(r - 1, c) && d.is_valid(r, c) && d.is_valid(r + 1, c)) {
                continue;
            }
            let (a, h, b) = (d.height(r - 1, c), d.height(r, c), d.height(r + 1, c));
            let depth = a.min(b) - h;
            if (a - b).abs() <= rule.level_tol && depth >= rule.min_depth && depth <= rule.max_depth {
                out.push((r, c));
            }
        }
    }
    out
}

/// True when the record shows a pallet's stripe: some row with at least
/// `min_row_cells` gap cells.
pub fn looks_like_pallet(gaps: &[(usize, usize)], rule: &StripeRule) -> bool {
    (1..GRID_ROWS - 1).any(|r| gaps.iter().filter(|g| g.0 == r).count() >= rule.min_row_cells)
}

/// Fill the gap cells of `d` (a known pallet); returns how many were filled.
/// Reads all gaps before writing, so filling one cannot create or hide another.
pub fn fill_gaps(d: &mut Dem, gaps: &[(usize, usize)]) -> usize {
    let fills: Vec<(usize, usize, f32)> = gaps.iter().map(|&(r, c)| (r, c, 0.5 * (d.height(r - 1, c) + d.height(r + 1, c)))).collect();
    for &(r, c, h) in &fills {
        d.set_valid(r, c, h);
    }
    fills.len()
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::format::empty_dem;

    fn striped() -> Dem {
        let mut d = empty_dem();
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                let h = match r {
                    10 | 11 | 13 | 15 | 16 => 0.074,
                    12 | 14 => -0.048,
                    _ => -0.07,
                };
                d.set_valid(r, c, h);
            }
        }
        d
    }

    #[test]
    fn finds_and_fills_the_gap_rows_only() {
        let rule = StripeRule::default();
        let mut d = striped();
        let gaps = gap_cells(&d, &rule);
        assert_eq!(gaps.len(), 10);
        assert!(gaps.iter().all(|g| g.0 == 12 || g.0 == 14));
        assert!(looks_like_pallet(&gaps, &rule));
        assert_eq!(fill_gaps(&mut d, &gaps), 10);
        assert!((d.height(12, 0) - 0.074).abs() < 1e-6);
        assert!(gap_cells(&d, &rule).is_empty());
        assert_eq!(d.height(5, 0), -0.07);
    }

    #[test]
    fn a_stair_step_or_a_single_low_cell_is_not_a_pallet() {
        let rule = StripeRule::default();
        let mut d = empty_dem();
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                d.set_valid(r, c, if r < 10 { -0.07 } else { 0.1 });
            }
        }
        assert!(gap_cells(&d, &rule).is_empty());
        d.set_valid(15, 2, 0.0);
        let gaps = gap_cells(&d, &rule);
        assert_eq!(gaps, vec![(15, 2)]);
        assert!(!looks_like_pallet(&gaps, &rule));
    }
}
