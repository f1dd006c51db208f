//! Stream an NPY stream through a model: what `dem-apply` does.
//!
//! Memory is one group of `batch x threads x` [`GROUP_BATCHES`] records in and
//! out, whatever the stream's length. The batches of a group run in parallel
//! on the current rayon pool and are written in input order, so the output is
//! the same for any number of threads. A group never spans two input
//! arrays (`NpyReader::for_each_chunk`): in a live pipeline each array
//! flows on as it arrives; from a file (one array) every group is full.

use dem_core::format::{cell_of, RECORD_LEN};
use dem_core::{npy, Dem, DemError};
use rayon::prelude::*;

use crate::model::OnnxModel;

/// Batches per thread in a group: enough that a slow batch does not leave
/// the other threads idle at the end of each group.
pub const GROUP_BATCHES: usize = 4;

/// What [`apply`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ApplyStats {
    /// Records read and written.
    pub records: u64,
    /// Records whose attitude row the model changed.
    pub attitude: AttitudeCheck,
}

/// Run `model` over every record of `input` (`-` for stdin) and write the
/// outputs to `output` (`-` for stdout; a named file appears atomically), in
/// batches of `batch` records (`>= 1`). `progress` gets the records done so
/// far after each group. A non-finite output value (the model made a NaN or
/// an infinity) is an error naming the record; a named output file is then
/// not written. A model that changes row 20 (the attitude) is counted in
/// the stats, and refused when `strict`. `finish`, when given, then changes
/// each batch's checked outputs before they are written (holes drawn, a
/// residual sensor model): it gets the batch's inputs, its outputs and the
/// index of its first record in the input stream, batches in stream order.
/// `at_end`, when given, gets the number of records before the output is
/// completed, and when it refuses, a named output file is not written
/// (both in `after`).
pub fn apply(
    model: &OnnxModel,
    input: &str,
    output: &str,
    batch: usize,
    strict: bool,
    after: After,
    mut progress: impl FnMut(u64),
) -> Result<ApplyStats, DemError> {
    let After { finish, at_end } = after;
    let mut attitude = AttitudeCheck::default();
    assert!(batch >= 1, "batch must be at least 1");
    let mut reader = npy::open(input)?;
    let mut writer = npy::create(output)?;
    let group = batch * rayon::current_num_threads().max(1) * GROUP_BATCHES;
    reader.for_each_chunk(group, |first, chunk| {
        let mut outs: Vec<Vec<Dem>> = chunk.par_chunks(batch).map(|c| model.run(c)).collect::<Result<_, _>>()?;
        for (k, (inp, out)) in chunk.chunks(batch).zip(outs.iter_mut()).enumerate() {
            let at = first + (k * batch) as u64;
            check_outputs(inp, out, at, input, model.name(), strict, &mut attitude)?;
            if let Some(f) = finish {
                f(inp, out, at)?;
            }
            writer.write(out)?;
        }
        progress(first + chunk.len() as u64);
        Ok::<_, DemError>(())
    })?;
    let records = writer.records_written();
    if let Some(check) = at_end {
        check(records)?;
    }
    writer.finish()?;
    Ok(ApplyStats { records, attitude })
}

/// What [`apply`] does after the model: to each batch's outputs
/// (`finish`), and with the number of records before the output is
/// completed (`at_end`, which may refuse).
#[derive(Clone, Copy, Default)]
pub struct After<'a> {
    /// Changes each batch's checked outputs before they are written.
    pub finish: Option<Finish<'a>>,
    /// A last check that needs the whole stream.
    pub at_end: Option<&'a dyn Fn(u64) -> Result<(), DemError>>,
}

/// What [`apply`] does to a batch's outputs after the model: `(inputs,
/// outputs, index of the batch's first record in the input stream)`.
pub type Finish<'a> = &'a (dyn Fn(&[Dem], &mut [Dem], u64) -> Result<(), DemError> + Sync);

/// Draw the holes from the model's raw masks ([`crate::masks::sample_masks`]):
/// the seed, and the index of the input's first record in the whole data set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MaskSampling {
    /// Seed of the draws.
    pub seed: u64,
    /// Index of the input's first record in the whole data set (shards).
    pub first_index: u64,
}

impl MaskSampling {
    /// Draw the holes of `out`, the outputs for `inp`, whose first record is
    /// record `first` of the input stream.
    pub fn draw(&self, inp: &[Dem], out: &mut [Dem], first: u64) {
        for (i, (x, y)) in inp.iter().zip(out.iter_mut()).enumerate() {
            crate::masks::sample_masks(x, y, self.seed, self.first_index + first + i as u64);
        }
    }
}

/// What a model did with row 20 (the attitude, which docs/network.md says
/// passes through): how many records it changed, and the first.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AttitudeCheck {
    /// Records whose output row 20 differs from the input's.
    pub changed: u64,
    /// The first such record (index in the input stream).
    pub first: Option<u64>,
}

impl AttitudeCheck {
    /// The warning to print, when some record's attitude was changed.
    pub fn warning(&self, model: &str, input: &str) -> Option<String> {
        self.first.map(|f| {
            format!(
                "warning: {model} does not pass row 20 (the attitude) through: {} record(s) of {input} changed, first record {f} (--strict refuses such a model)",
                self.changed
            )
        })
    }
}

/// Check a model's outputs `out` for the inputs `inp` (records `first..` of
/// `input`): a NaN or infinite value is refused naming the record (tools
/// never write one); an attitude row that does not pass through is counted
/// in `att`, and refused when `strict`.
pub fn check_outputs(
    inp: &[Dem],
    out: &[Dem],
    first: u64,
    input: &str,
    model: &str,
    strict: bool,
    att: &mut AttitudeCheck,
) -> Result<(), DemError> {
    for (i, (x, d)) in inp.iter().zip(out).enumerate() {
        let record = first + i as u64;
        if let Some(j) = d.iter().position(|v| !v.is_finite()) {
            let (row, col, ch) = cell_of(j);
            return Err(DemError::input(
                model,
                format!("the model's output for record {record} of {input} is {} at row {row}, column {col}, channel {ch}", d[j]),
            ));
        }
        let row20 = RECORD_LEN - 10..RECORD_LEN;
        // Exact: the attitude is copied, never computed (a PyTorch export
        // that writes zeros there is what this catches).
        if x[row20.clone()] != d[row20] {
            att.changed += 1;
            att.first.get_or_insert(record);
            if strict {
                return Err(DemError::input(
                    model,
                    format!("--strict: the model's output for record {record} of {input} changes row 20 (the attitude), which must pass through"),
                ));
            }
        }
    }
    Ok(())
}
