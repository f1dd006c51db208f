//! Read an NPY stream: one or more complete `.npy` arrays back to back, from a
//! file or stdin, a chunk of records at a time.
//!
//! The reader never allocates by what a header declares: it fills the
//! caller's chunk, so a lying header costs nothing and a 1 GB stream needs a
//! few MB. When the source's size is known (a file, or stdin redirected from
//! one) a header that declares more records than the bytes left is refused
//! before any payload is read.

use std::fs::File;
use std::io::{self, BufReader, Read};
use std::os::fd::AsFd;

use super::header::{parse_dict, prefix_len, ArrayHeader, Dtype, MAGIC};
use crate::error::{DemError, Result};
use crate::format::{canonicalize, Dem, RECORD_LEN};

/// Records per chunk that streaming tools hold in memory (about 3.4 MB).
pub const CHUNK_RECORDS: usize = 4096;

/// A reader over an NPY stream.
pub struct NpyReader<R> {
    src: R,
    path: String,
    /// Bytes consumed so far.
    offset: u64,
    /// Bytes in the whole stream from where reading started, when known.
    total_len: Option<u64>,
    /// Records handed out so far, over all arrays.
    records: u64,
    /// The current array and the records it still holds.
    current: Option<(Dtype, u64)>,
    /// Records that held a NaN, turned into missing cells.
    nan_records: u64,
    scratch: Vec<u8>,
}

/// Open `path` (`-` for stdin) as an NPY stream.
pub fn open(path: &str) -> Result<NpyReader<Box<dyn Read + Send>>> {
    let (src, len): (Box<dyn Read + Send>, Option<u64>) = if path == "-" {
        let stdin = io::stdin();
        let len = regular_file_len(&stdin);
        super::grow_pipe(&stdin);
        (Box::new(BufReader::with_capacity(1 << 16, stdin)), len)
    } else {
        let file = File::open(path).map_err(|source| DemError::Open { path: path.into(), source })?;
        if file.metadata().is_ok_and(|m| m.is_dir()) {
            return Err(DemError::Open { path: path.into(), source: io::Error::other("is a directory, not an NPY file") });
        }
        let len = file.metadata().ok().filter(|m| m.is_file()).map(|m| m.len());
        (Box::new(BufReader::with_capacity(1 << 16, file)), len)
    };
    Ok(NpyReader::new(src, path, len))
}

/// Read every record of `path` (`-` for stdin) into memory.
pub fn read_all(path: &str) -> Result<Vec<Dem>> {
    open(path)?.read_to_end()
}

/// Records in the NPY file at `path`, estimated from its size as one
/// array of f32 records (0 for stdin or a file that cannot be read): for a
/// progress bar's length, never for a decision.
pub fn estimate_records(path: &str) -> u64 {
    if path == "-" {
        return 0;
    }
    let (header, record) = (super::header::HEADER_LEN as u64, (RECORD_LEN * 4) as u64);
    std::fs::metadata(path).map_or(0, |m| m.len().saturating_sub(header) / record)
}

/// The records of the stream at `path` whose index `keep` accepts, by
/// index, and the number of records in the stream; memory is one chunk plus
/// the kept records.
pub fn read_selected(path: &str, keep: impl Fn(u64) -> bool) -> Result<(u64, std::collections::HashMap<u64, Dem>)> {
    let mut kept = std::collections::HashMap::new();
    let total = open(path)?.for_each_chunk(CHUNK_RECORDS, |first, chunk| {
        kept.extend(chunk.iter().enumerate().map(|(k, d)| (first + k as u64, *d)).filter(|(i, _)| keep(*i)));
        Ok::<_, DemError>(())
    })?;
    Ok((total, kept))
}

/// Bytes left in stdin when it is a regular file (`< file`), else None.
fn regular_file_len(stdin: &io::Stdin) -> Option<u64> {
    use std::io::Seek;
    let mut file = File::from(stdin.as_fd().try_clone_to_owned().ok()?);
    let meta = file.metadata().ok()?;
    if !meta.is_file() {
        return None;
    }
    let pos = file.stream_position().ok()?;
    Some(meta.len().saturating_sub(pos))
}

impl<R: Read> NpyReader<R> {
    /// Wrap a source; `total_len` is its size in bytes when known.
    pub fn new(src: R, path: impl Into<String>, total_len: Option<u64>) -> Self {
        NpyReader { src, path: path.into(), offset: 0, total_len, records: 0, current: None, nan_records: 0, scratch: Vec::new() }
    }

    /// The path this reader was opened with.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// Records read so far.
    pub fn records_read(&self) -> u64 {
        self.records
    }

    /// Records so far in which a NaN was read as a missing cell.
    pub fn nan_records(&self) -> u64 {
        self.nan_records
    }

    /// Append up to `max` records to `out`. Returns how many were appended;
    /// 0 means the stream has ended. A chunk never spans two arrays.
    pub fn read_chunk(&mut self, out: &mut Vec<Dem>, max: usize) -> Result<usize> {
        let (dtype, left) = loop {
            match self.current {
                Some((_, 0)) => self.current = None,
                Some(cur) => break cur,
                None => match self.read_header()? {
                    Some(h) => self.current = Some((h.dtype, h.records)),
                    None => return Ok(0),
                },
            }
        };
        let n = (left.min(max as u64)) as usize;
        let start = out.len();
        out.resize(start + n, [0.0; RECORD_LEN]);
        match dtype {
            Dtype::F32 => {
                let bytes: &mut [u8] = bytemuck::cast_slice_mut(&mut out[start..]);
                let got = read_full(&mut self.src, bytes).map_err(|e| self.io(e))?;
                self.check_payload(got, n, left, 4)?;
                if cfg!(target_endian = "big") {
                    for v in out[start..].iter_mut().flatten() {
                        *v = f32::from_le_bytes(v.to_ne_bytes());
                    }
                }
            }
            Dtype::F64 => {
                self.scratch.resize(n * RECORD_LEN * 8, 0);
                let got = read_full(&mut self.src, &mut self.scratch).map_err(|e| self.io(e))?;
                self.check_payload(got, n, left, 8)?;
                for (v, b) in out[start..].iter_mut().flatten().zip(self.scratch.chunks_exact(8)) {
                    *v = f64::from_le_bytes(b.try_into().expect("8 bytes")) as f32;
                }
            }
        }
        let record_bytes = (RECORD_LEN * dtype.size()) as u64;
        for (k, d) in out[start..].iter_mut().enumerate() {
            match canonicalize(d) {
                Ok(nan) => self.nan_records += u64::from(nan),
                Err(reason) => {
                    let record = self.records + k as u64;
                    return Err(self.bad_at(record, self.offset + k as u64 * record_bytes, reason));
                }
            }
        }
        self.offset += (n * RECORD_LEN * dtype.size()) as u64;
        self.records += n as u64;
        self.current = Some((dtype, left - n as u64));
        Ok(n)
    }

    /// Append up to `n` records to `out`, across arrays: fewer only at the
    /// end of the stream. Returns how many were appended.
    pub fn read_up_to(&mut self, out: &mut Vec<Dem>, n: usize) -> Result<usize> {
        let mut got = 0;
        while got < n {
            let k = self.read_chunk(out, n - got)?;
            if k == 0 {
                break;
            }
            got += k;
        }
        Ok(got)
    }

    /// Visit the rest of the stream up to `size` records at a time: `visit`
    /// gets the index of the chunk's first record in the stream and the
    /// chunk, one buffer reused for every chunk, so memory stays one chunk
    /// whatever the stream's length; it may change or drop records in it.
    /// Returns the number of records read. The chunk loop of every
    /// streaming tool.
    ///
    /// A chunk never spans two arrays ([`NpyReader::read_chunk`]): in a live
    /// pipeline whose producer writes small arrays, each array flows on as
    /// it arrives instead of waiting for a full chunk.
    pub fn for_each_chunk<E: From<DemError>>(
        &mut self,
        size: usize,
        mut visit: impl FnMut(u64, &mut Vec<Dem>) -> std::result::Result<(), E>,
    ) -> std::result::Result<u64, E> {
        let mut chunk = Vec::with_capacity(size);
        loop {
            chunk.clear();
            let first = self.records;
            if self.read_chunk(&mut chunk, size)? == 0 {
                return Ok(self.records);
            }
            visit(first, &mut chunk)?;
        }
    }

    /// Read the rest of the stream into memory.
    pub fn read_to_end(&mut self) -> Result<Vec<Dem>> {
        let mut out = Vec::new();
        while self.read_chunk(&mut out, CHUNK_RECORDS)? > 0 {}
        Ok(out)
    }

    /// Refuse a short read of `n` records out of the `left` the header still
    /// declares; the shortfall is counted against the header, not the chunk.
    fn check_payload(&self, got: usize, n: usize, left: u64, size: usize) -> Result<()> {
        let record_bytes = (RECORD_LEN * size) as u64;
        if got < n * RECORD_LEN * size {
            // Cannot overflow: read_header checked records * record_bytes.
            let missing = left * record_bytes - got as u64;
            return Err(self.bad_at(
                self.records + got as u64 / record_bytes,
                self.offset + got as u64,
                format!("truncated payload: stream ends {missing} bytes early"),
            ));
        }
        Ok(())
    }

    /// Read the next array's header; None at a clean end of stream.
    fn read_header(&mut self) -> Result<Option<ArrayHeader>> {
        let mut prefix = [0u8; 12];
        let got = read_full(&mut self.src, &mut prefix[..8]).map_err(|e| self.io(e))?;
        if got == 0 {
            return Ok(None);
        }
        if got < 8 || &prefix[..6] != MAGIC {
            let reason = if prefix[..got.min(6)] == MAGIC[..got.min(6)] {
                "truncated header".to_string()
            } else {
                "not an NPY array (no \\x93NUMPY magic)".to_string()
            };
            return Err(self.bad(reason));
        }
        let (major, minor) = (prefix[6], prefix[7]);
        let Some(plen) = prefix_len(major) else {
            return Err(self.bad(format!("unsupported NPY version {major}.{minor}")));
        };
        let got = read_full(&mut self.src, &mut prefix[8..plen]).map_err(|e| self.io(e))?;
        if got < plen - 8 {
            return Err(self.bad("truncated header".into()));
        }
        let hlen = if major == 1 {
            u16::from_le_bytes([prefix[8], prefix[9]]) as usize
        } else {
            u32::from_le_bytes(prefix[8..12].try_into().expect("4 bytes")) as usize
        };
        // A real header is a few hundred bytes; refuse absurd lengths before allocating.
        if hlen > 1 << 16 {
            return Err(self.bad(format!("header length {hlen} is not plausible")));
        }
        let mut dict = vec![0u8; hlen];
        let got = read_full(&mut self.src, &mut dict).map_err(|e| self.io(e))?;
        if got < hlen {
            return Err(self.bad("truncated header".into()));
        }
        let text = String::from_utf8_lossy(&dict);
        let header = parse_dict(&text).map_err(|reason| self.bad(reason))?;
        let start = self.offset;
        self.offset += (plen + hlen) as u64;
        let payload = header
            .records
            .checked_mul((RECORD_LEN * header.dtype.size()) as u64)
            .ok_or_else(|| self.bad_at(self.records, start, "declared shape overflows".into()))?;
        if let Some(total) = self.total_len {
            let left = total.saturating_sub(self.offset);
            if payload > left {
                return Err(self.bad_at(
                    self.records,
                    start,
                    format!("header declares {} records ({payload} bytes) but only {left} bytes follow", header.records),
                ));
            }
        }
        Ok(Some(header))
    }

    fn bad(&self, reason: String) -> DemError {
        self.bad_at(self.records, self.offset, reason)
    }

    fn bad_at(&self, record: u64, offset: u64, reason: String) -> DemError {
        DemError::Npy { path: self.path.clone(), record, offset, reason }
    }

    fn io(&self, e: io::Error) -> DemError {
        DemError::io(self.path.clone(), e)
    }
}

/// One array of a stream, as [`NpyReader::next_array`] finds it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ArrayExtent {
    /// Index of its first record in the whole stream.
    pub first: u64,
    /// Records it holds.
    pub records: u64,
    /// Byte offset of its payload in the stream.
    pub payload: u64,
    /// Its element type.
    pub dtype: Dtype,
}

impl<R: Read + std::io::Seek> NpyReader<R> {
    /// Read the next array's header and seek past its payload, without
    /// reading it: what an index of a file needs. None at the end.
    pub fn next_array(&mut self) -> Result<Option<ArrayExtent>> {
        let Some(h) = self.read_header()? else { return Ok(None) };
        let extent = ArrayExtent { first: self.records, records: h.records, payload: self.offset, dtype: h.dtype };
        // read_header refused a payload longer than the bytes left.
        let bytes = h.records * (RECORD_LEN * h.dtype.size()) as u64;
        self.src.seek(io::SeekFrom::Current(bytes as i64)).map_err(|e| self.io(e))?;
        self.offset += bytes;
        self.records += h.records;
        Ok(Some(extent))
    }
}

/// Fill `buf` as far as the source allows; returns the bytes read (fewer
/// than `buf.len()` only at the end of the source).
fn read_full(src: &mut impl Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match src.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(k) => got += k,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}
