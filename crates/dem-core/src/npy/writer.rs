//! Write an NPY stream to a file or stdout.
//!
//! - A named file is written to a temp file in the same folder and renamed
//!   on [`NpyWriter::finish`]: readers never see a partial file, and an error
//!   (or a panic) leaves none behind. An existing device or FIFO
//!   (`-o /dev/null`) is written in place like a pipe, never replaced.
//! - A file (named, or stdout redirected to one) holds one array, as
//!   `numpy.save` writes it, byte for byte: the header is reserved and the
//!   record count patched in when the stream ends, so `numpy.load` reads all
//!   of it.
//! - Stdout redirected to a file gets its header patched after every chunk
//!   of [`CHUNK_RECORDS`] records, so a killed run leaves a file that
//!   `numpy.load` reads up to its last complete chunk (never one whose
//!   header says 0 records with megabytes behind it).
//! - Records holding NaN or infinity are refused ([`DemError::Unwritable`]):
//!   the contract says tools never write them.
//! - A pipe gets one complete array per chunk of [`CHUNK_RECORDS`] records,
//!   which is what the contract calls a stream; memory stays one chunk.

use std::fs::File;
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::os::fd::AsFd;

use super::header::{f32_header, HEADER_LEN};
use super::reader::CHUNK_RECORDS;
use crate::error::{DemError, Result};
use crate::format::{unwritable, Dem, RECORD_LEN};
use crate::output::{is_special, open_special, resolve, temp_beside};

enum Sink {
    /// One array with a patched header; `temp` is set for a named file.
    /// `patched` is the record count the header on disk says.
    Seekable { out: BufWriter<File>, start: u64, temp: Option<tempfile::TempPath>, patched: u64 },
    /// One array per chunk, for pipes.
    Chunked { out: BufWriter<Box<dyn Write + Send>>, pending: Vec<Dem> },
}

/// A writer of DEM records; call [`NpyWriter::finish`] to complete it.
/// Dropped unfinished (an error on the way), a named file is removed and a
/// stdout redirected to a file is cut back to where it started.
pub struct NpyWriter {
    sink: Option<Sink>,
    path: String,
    records: u64,
}

impl Drop for NpyWriter {
    fn drop(&mut self) {
        if let Some(Sink::Seekable { out, start, temp: None, .. }) = self.sink.take() {
            // into_parts drops the buffer unflushed, so nothing lands after the cut.
            let (file, _) = out.into_parts();
            let _ = file.set_len(start);
        }
    }
}

/// Create `path` (`-` for stdout) as an NPY stream.
pub fn create(path: &str) -> Result<NpyWriter> {
    let io_err = |e| DemError::io(path, e);
    let sink = if path == "-" {
        if std::io::IsTerminal::is_terminal(&std::io::stdout()) {
            return Err(DemError::Usage("refusing to write binary NPY to a terminal: give -o FILE, or redirect or pipe stdout".into()));
        }
        match stdout_fd() {
            // `>>` (append mode) cannot patch a header: it gets a stream of
            // arrays, which every stream reader takes whole.
            Some(file) if file.metadata().is_ok_and(|m| m.is_file()) && !is_append(&file) => {
                let mut out = BufWriter::with_capacity(1 << 20, file);
                let start = out.stream_position().map_err(io_err)?;
                out.write_all(&f32_header(0)).map_err(io_err)?;
                Sink::Seekable { out, start, temp: None, patched: 0 }
            }
            fd => {
                let raw: Box<dyn Write + Send> = match fd {
                    Some(file) => {
                        super::grow_pipe(&file);
                        Box::new(file)
                    }
                    None => Box::new(io::stdout()),
                };
                Sink::Chunked { out: BufWriter::with_capacity(1 << 20, raw), pending: Vec::new() }
            }
        }
    } else if is_special(path) {
        let raw: Box<dyn Write + Send> = Box::new(open_special(path)?);
        Sink::Chunked { out: BufWriter::with_capacity(1 << 20, raw), pending: Vec::new() }
    } else {
        let (file, temp) = temp_beside(path)?.into_parts();
        let mut out = BufWriter::with_capacity(1 << 20, file);
        out.write_all(&f32_header(0)).map_err(io_err)?;
        Sink::Seekable { out, start: 0, temp: Some(temp), patched: 0 }
    };
    Ok(NpyWriter { sink: Some(sink), path: path.into(), records: 0 })
}

/// Write `records` to `path` (`-` for stdout) in one go.
pub fn write_all(path: &str, records: &[Dem]) -> Result<()> {
    let mut w = create(path)?;
    w.write(records)?;
    w.finish()
}

fn is_append(file: &File) -> bool {
    rustix::fs::fcntl_getfl(file).is_ok_and(|f| f.contains(rustix::fs::OFlags::APPEND))
}

/// Stdout as a `File` on a duplicate of fd 1: seekable when redirected to
/// a regular file, and for a pipe it bypasses `io::stdout()`'s `LineWriter`,
/// which scans binary data for newlines and splits writes at them.
fn stdout_fd() -> Option<File> {
    Some(File::from(io::stdout().as_fd().try_clone_to_owned().ok()?))
}

fn as_le_bytes(records: &[Dem]) -> std::borrow::Cow<'_, [u8]> {
    if cfg!(target_endian = "little") {
        std::borrow::Cow::Borrowed(bytemuck::cast_slice(records))
    } else {
        records.iter().flatten().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>().into()
    }
}

impl NpyWriter {
    /// Records written so far.
    pub fn records_written(&self) -> u64 {
        self.records
    }

    /// Append records.
    pub fn write(&mut self, records: &[Dem]) -> Result<()> {
        if let Some((k, reason)) = records.iter().enumerate().find_map(|(k, d)| unwritable(d).map(|r| (k, r))) {
            return Err(DemError::Unwritable { path: self.path.clone(), record: self.records + k as u64, reason });
        }
        let io_err = |e| DemError::io(self.path.as_str(), e);
        let total = self.records + records.len() as u64;
        match self.sink.as_mut().expect("not finished") {
            Sink::Seekable { out, start, temp, patched } => {
                out.write_all(&as_le_bytes(records)).map_err(io_err)?;
                if temp.is_none() && total - *patched >= CHUNK_RECORDS as u64 {
                    patch_header(out, *start, total).map_err(io_err)?;
                    *patched = total;
                }
            }
            Sink::Chunked { out, pending } => {
                let mut rest = records;
                while !rest.is_empty() {
                    // A whole chunk with nothing pending goes out as is, uncopied.
                    if pending.is_empty() && rest.len() >= CHUNK_RECORDS {
                        write_array(out, &rest[..CHUNK_RECORDS]).map_err(io_err)?;
                        rest = &rest[CHUNK_RECORDS..];
                        continue;
                    }
                    let take = (CHUNK_RECORDS - pending.len()).min(rest.len());
                    pending.extend_from_slice(&rest[..take]);
                    rest = &rest[take..];
                    if pending.len() == CHUNK_RECORDS {
                        write_array(out, pending).map_err(io_err)?;
                        pending.clear();
                    }
                }
            }
        }
        self.records += records.len() as u64;
        Ok(())
    }

    /// Complete the stream: patch the header or write the last chunk, flush,
    /// and move a named file into place.
    pub fn finish(mut self) -> Result<()> {
        let path = std::mem::take(&mut self.path);
        let io_err = |e| DemError::io(path.as_str(), e);
        let Some(sink) = self.sink.take() else { return Ok(()) };
        match sink {
            Sink::Chunked { mut out, pending } => {
                // An empty stream still gets one empty array, so `numpy.load`
                // of the captured output works.
                if !pending.is_empty() || self.records == 0 {
                    write_array(&mut out, &pending).map_err(io_err)?;
                }
                out.flush().map_err(io_err)?;
            }
            Sink::Seekable { mut out, start, temp, .. } => {
                let end = patch_header(&mut out, start, self.records).map_err(io_err)?;
                out.flush().map_err(io_err)?;
                let file = out.into_inner().map_err(|e| io_err(e.into_error()))?;
                // Another writer appending to the same file would break the
                // layout: catch it rather than leave a broken file.
                let len = file.metadata().map_err(io_err)?.len();
                if len != end {
                    return Err(DemError::io(path.as_str(), io::Error::other("output file changed size while writing (append mode?)")));
                }
                if let Some(temp) = temp {
                    temp.persist(resolve(&path)).map_err(|e| io_err(e.error))?;
                }
            }
        }
        Ok(())
    }
}

/// Write the header for `records` at `start` (data flushed first, so the
/// header never counts records that are not on disk) and return to the end,
/// which is returned.
fn patch_header(out: &mut BufWriter<File>, start: u64, records: u64) -> io::Result<u64> {
    let end = start + HEADER_LEN as u64 + records * (RECORD_LEN * 4) as u64;
    out.flush()?;
    out.seek(SeekFrom::Start(start))?;
    out.write_all(&f32_header(records))?;
    out.seek(SeekFrom::Start(end))?;
    Ok(end)
}

fn write_array(out: &mut impl Write, records: &[Dem]) -> io::Result<()> {
    out.write_all(&f32_header(records.len() as u64))?;
    out.write_all(&as_le_bytes(records))
}
