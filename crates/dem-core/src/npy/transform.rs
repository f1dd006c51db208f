//! The loop every streaming tool shares: read a chunk, work on it, write
//! what is kept, so memory stays one chunk whatever the stream's length.

use crate::error::Result;
use crate::format::Dem;
use crate::npy;

/// Stream `input` to `output` (`-` for stdin/stdout) a chunk at a time.
/// `work` gets the index of the chunk's first record in the whole stream and
/// the chunk; it may change, drop or keep records in place. Returns the
/// number of records read and written.
pub fn transform(input: &str, output: &str, work: impl FnMut(u64, &mut Vec<Dem>) -> Result<()>) -> Result<(u64, u64)> {
    transform_checked(input, output, work, |_| Ok(()))
}

/// [`transform`], with a last check that needs the whole stream (labels that
/// cover it exactly, indices inside it): `at_end` gets the number of records
/// read, and when it refuses, a named output file is not written.
pub fn transform_checked(
    input: &str,
    output: &str,
    mut work: impl FnMut(u64, &mut Vec<Dem>) -> Result<()>,
    at_end: impl FnOnce(u64) -> Result<()>,
) -> Result<(u64, u64)> {
    let mut reader = npy::open(input)?;
    let mut writer = npy::create(output)?;
    let read = reader.for_each_chunk(npy::CHUNK_RECORDS, |first, chunk| {
        work(first, chunk)?;
        writer.write(chunk)
    })?;
    at_end(read)?;
    let written = writer.records_written();
    writer.finish()?;
    Ok((read, written))
}
