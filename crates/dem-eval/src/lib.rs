//! dem-eval's library: one file per command, each with its arguments and
//! its run, as xsv's commands are; the binary only dispatches.
//!
//! - [`evaluate`]: the validation table of one method (identity, a file of
//!   predictions, or an ONNX generator) over the sim records of a pairs CSV.
//! - [`merge`]: the table of the whole from shards' per-record files.
//! - [`compare`]: a table against a baseline; worse rows fail.
//! - [`join`]: tables as one table, in any form.
//! - [`transfer`]: the downstream test (policy-like models trained on each
//!   set, tested on measured DEMs of held-out runs).
//! - [`engine`], [`records`], [`model`]: the evaluation engine (the
//!   selected records, read in bounded memory), the per-record CSV, and the
//!   predictions' sources they share; [`frames`]: the frame columns (how
//!   consecutive frames of a run move).
//! - [`table`]: the validation table itself: its rows (count, lowest,
//!   highest, mean, median of the pair errors, [`table::ErrorSummary`]; the
//!   measures that see heights; by terrain), the comparison against a
//!   baseline, and [`table::forms`], the forms it is written and read in.

pub mod compare;
pub mod engine;
pub mod evaluate;
pub mod frames;
pub mod join;
pub mod merge;
pub mod model;
pub mod records;
pub mod table;
pub mod transfer;
