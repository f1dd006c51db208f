//! Sim and real inputs given the wrong way round.
//!
//! A measured DEM has holes (blind spots, startup rows, dropout); a sim DEM
//! has none, or few. Every tool that takes a `--sim` and a `--real` input
//! compares their shares of missing grid cells and warns, on one stderr
//! line naming both files, when the sim side misses clearly more cells
//! than the real side: the inputs are then most likely swapped. The check
//! never changes what a tool does or its exit code; `--no-swap-check`
//! silences it.

use crate::format::{at, Dem, COLS, GRID_ROWS, MISSING};
use crate::{cli, npy, Result};

/// Records read from the start of a file when a tool does not hold the
/// records anyway: a bounded sample, never a second pass over a stream.
pub const SAMPLE_RECORDS: usize = 2048;

/// The sim side is "clearly" missing more when its share of missing cells
/// exceeds the real side's by this much, absolute ...
pub const MARGIN: f64 = 0.05;

/// ... plus this fraction of the real side's share (a generator's holes
/// may run somewhat above the measured ones without being a swap).
pub const RELATIVE_MARGIN: f64 = 0.5;

/// The flag that silences the check, the same in every tool.
pub const FLAG: &str = "--no-swap-check";

/// Missing grid cells among the cells of some records (row 20, the
/// attitude, is not a cell).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MissingCells {
    /// Grid cells whose mask says missing.
    pub missing: u64,
    /// Grid cells seen.
    pub cells: u64,
}

impl MissingCells {
    /// Count the grid cells of `records`.
    pub fn of<'a>(records: impl IntoIterator<Item = &'a Dem>) -> Self {
        let mut m = MissingCells::default();
        for d in records {
            m.add(d);
        }
        m
    }

    /// Count one record's grid cells.
    pub fn add(&mut self, d: &Dem) {
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                self.missing += u64::from(d[at(r, c, 1)] == MISSING);
            }
        }
        self.cells += (GRID_ROWS * COLS) as u64;
    }

    /// The share of missing cells (None when no cell was seen).
    pub fn share(&self) -> Option<f64> {
        (self.cells > 0).then(|| self.missing as f64 / self.cells as f64)
    }

    /// The missing cells of the first [`SAMPLE_RECORDS`] records of the
    /// NPY file at `path`; None for stdin (`-`), which the tool reads once.
    pub fn sample(path: &str) -> Result<Option<Self>> {
        if path == "-" {
            return Ok(None);
        }
        let mut records = Vec::with_capacity(SAMPLE_RECORDS);
        npy::open(path)?.read_up_to(&mut records, SAMPLE_RECORDS)?;
        Ok(Some(MissingCells::of(&records)))
    }
}

/// The warning for a sim side `sim` and a real side `real` with these
/// missing cells, when the sim side misses clearly more than the real one
/// (any missing cell while the real side has none counts); None otherwise
/// or when either side has no cells.
pub fn warning(sim: &str, sim_cells: MissingCells, real: &str, real_cells: MissingCells) -> Option<String> {
    let (s, r) = (sim_cells.share()?, real_cells.share()?);
    let swapped = (r == 0.0 && s > 0.0) || s > r * (1.0 + RELATIVE_MARGIN) + MARGIN;
    swapped.then(|| {
        format!(
            "warning: --sim {sim} misses {:.1}% of its cells, --real {real} {:.1}%: measured DEMs have holes and sim DEMs few; \
             --sim and --real look swapped ({FLAG} silences this)",
            100.0 * s,
            100.0 * r
        )
    })
}

/// Log [`warning`] on stderr when it applies and `silenced` is false.
/// Returns whether a warning was written.
pub fn check(sim: &str, sim_cells: MissingCells, real: &str, real_cells: MissingCells, silenced: bool) -> bool {
    match warning(sim, sim_cells, real, real_cells) {
        Some(w) if !silenced => {
            cli::log(w);
            true
        }
        _ => false,
    }
}

/// [`check`] on a sample of the first records of each file; a side read
/// from stdin is not checked. An unreadable file is left to the tool's own
/// reading, which reports it with its context.
pub fn check_files(sim: &str, real: &str, silenced: bool) -> bool {
    if silenced {
        return false;
    }
    match (MissingCells::sample(sim), MissingCells::sample(real)) {
        (Ok(Some(s)), Ok(Some(r))) => check(sim, s, real, r, false),
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::empty_dem;

    fn with_missing(n: usize) -> Dem {
        let mut d = empty_dem();
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                d[at(r, c, 1)] = 1.0;
            }
        }
        for j in 0..n {
            d[at(j / COLS, j % COLS, 1)] = MISSING;
        }
        d
    }

    #[test]
    fn holes_on_the_sim_side_only_warn_and_the_right_order_does_not() {
        let (full, holey) = (MissingCells::of(&[with_missing(0)]), MissingCells::of(&[with_missing(30)]));
        assert_eq!(holey.share(), Some(0.3));
        let w = warning("real.npy", holey, "sim.npy", full).expect("swapped");
        assert!(w.contains("--sim real.npy") && w.contains("--real sim.npy") && w.contains(FLAG), "{w}");
        assert!(warning("sim.npy", full, "real.npy", holey).is_none());
        assert!(warning("a.npy", full, "b.npy", full).is_none());
        // Any hole against none; a generator's holes a little above the real ones are fine.
        assert!(warning("s", MissingCells::of(&[with_missing(1)]), "r", full).is_some());
        assert!(warning("s", MissingCells::of(&[with_missing(33)]), "r", holey).is_none());
        assert!(warning("s", MissingCells::of(&[with_missing(60)]), "r", holey).is_some());
        assert!(warning("s", MissingCells::default(), "r", full).is_none());
    }
}
