//! Core of the dem-* tools for virtual depth sensors on tracked robots.
//!
//! - [`format`](mod@format): the DEM record of `docs/format.md` (shape, cells,
//!   terrains) and the NaN rule.
//! - [`npy`]: NPY stream reader and writer (concatenated arrays, stdin/stdout,
//!   atomic files, numpy-identical bytes).
//! - [`table`]: labels, pairs and index CSVs; [`raw_labels`]: a labels CSV
//!   re-indexed a row at a time, every other byte kept.
//! - [`metric`]: the thesis's equation 7.1 error and the pair error.
//! - [`seeded`]: random streams fixed by (seed, record index).
//! - [`distribution`]: the distribution gap between two sets of DEMs (what
//!   dem-gap fits and dem-eval's `gap` column reports).
//! - [`temporal`]: how consecutive frames of a run move (the labels' runs,
//!   times and poses; dem-eval's `frame_*` columns).
//! - [`output`]: atomic output files.
//! - [`swap`]: the warning when `--sim` and `--real` look swapped.
//! - [`cli`]: exit codes, error printing, logs and progress for the binaries.
//! - [`error`]: the typed errors everything returns.
//!
//! dem-eval's validation tables (rows, measures, their forms and the
//! comparison against a baseline) live in dem-eval's library, `dem_eval::table`.
#![deny(missing_docs)]

pub mod cli;
pub mod distribution;
pub mod error;
pub mod format;
pub mod metric;
pub mod npy;
pub mod output;
pub mod raw_labels;
pub mod seeded;
pub mod swap;
pub mod table;
pub mod temporal;

pub use error::{DemError, Result};
pub use format::{Dem, DemCells, Terrain};
