//! Stream an NPY stream through a model: what `dem-apply` does.
//!
//! Memory is one group of `batch x threads x` [`GROUP_BATCHES`] records in and
//! out, whatever the stream's length. The batches of a group run in parallel
//! on the current rayon pool and are written in input order, so the output is
//! the same for any number of threads.

use dem_core::format::RECORD_LEN;
use dem_core::{npy, Dem, DemError};
use rayon::prelude::*;

use crate::run::OnnxModel;

/// Batches per thread in a group: enough that a slow batch does not leave
/// the other threads idle at the end of each group.
pub const GROUP_BATCHES: usize = 4;

/// What [`apply`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ApplyStats {
    /// Records read and written.
    pub records: u64,
}

/// Run `model` over every record of `input` (`-` for stdin) and write the
/// outputs to `output` (`-` for stdout; a named file appears atomically), in
/// batches of `batch` records (`>= 1`). `progress` gets the records done so
/// far after each group. A non-finite output value (the model made a NaN or
/// an infinity) is an error naming the record; a named output file is then
/// not written.
pub fn apply(
    model: &OnnxModel,
    input: &str,
    output: &str,
    batch: usize,
    mut progress: impl FnMut(u64),
) -> Result<ApplyStats, DemError> {
    assert!(batch >= 1, "batch must be at least 1");
    let mut reader = npy::open(input)?;
    let mut writer = npy::create(output)?;
    let group = batch * rayon::current_num_threads().max(1) * GROUP_BATCHES;
    let mut chunk: Vec<Dem> = Vec::with_capacity(group);
    loop {
        chunk.clear();
        let first = reader.records_read();
        while chunk.len() < group {
            let want = group - chunk.len();
            if reader.read_chunk(&mut chunk, want)? == 0 {
                break;
            }
        }
        if chunk.is_empty() {
            break;
        }
        let outs: Vec<Vec<Dem>> = chunk.par_chunks(batch).map(|c| model.run(c)).collect::<Result<_, _>>()?;
        for (k, out) in outs.iter().enumerate() {
            check_finite(out, first + (k * batch) as u64, input, model.name())?;
            writer.write(out)?;
        }
        progress(reader.records_read());
    }
    let records = writer.records_written();
    writer.finish()?;
    Ok(ApplyStats { records })
}

/// Refuse a NaN or infinite output value: tools never write NaN.
fn check_finite(out: &[Dem], first: u64, input: &str, model: &str) -> Result<(), DemError> {
    for (i, d) in out.iter().enumerate() {
        if let Some(j) = d.iter().position(|v| !v.is_finite()) {
            let (row, col, ch) = (j / 10, j % 10 / 2, j % 2);
            debug_assert!(j < RECORD_LEN);
            return Err(DemError::input(
                model,
                format!(
                    "the model's output for record {} of {input} is {} at row {row}, column {col}, channel {ch}",
                    first + i as u64,
                    d[j]
                ),
            ));
        }
    }
    Ok(())
}
