//! MCAP files, read front to back one record at a time in bounded memory.
//!
//! An MCAP file is the magic `\x89MCAP0\r\n`, then records, each an opcode
//! (`u8`) and a length (`u64`, little-endian) followed by that many bytes,
//! and ends with a Footer record and the magic again. The records used
//! here: Schema (0x03: id, name), Channel (0x04: id, schema id, topic,
//! message encoding), Message (0x05: channel id, sequence, times, data) and
//! Chunk (0x06: times, uncompressed size and CRC, compression `""`, `zstd`
//! or `lz4`, then the compressed records, which hold Schemas, Channels and
//! Messages). Everything else (indexes, statistics, attachments, metadata,
//! the summary section) is stepped over. Channels with message encoding
//! `cdr` (ROS 2) and `ros1` are read; others are stepped over.
//!
//! Our own reader, not the `mcap` crate's `LinearReader`, so that every
//! length is checked against [`MAX_RECORD_BYTES`](super::bounded::MAX_RECORD_BYTES)
//! and against the bytes left in the file before it is allocated (that
//! reader allocates what a record declares and panics on lengths near
//! 2^64). A record that cannot be read is named by its byte offset in the
//! file; one inside a chunk by the chunk's offset and its own offset in
//! the chunk's records.

use std::collections::HashMap;
use std::fs::File;
use std::io::{self, BufReader, Read, Seek};
use std::path::Path;

use super::bounded::{self, Codec, MAX_RECORD_BYTES};
use super::{short_type, Connection, Event, StopError};
use crate::wire::Encoding;

/// The magic at the start (and end) of an MCAP file.
pub const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

const OP_FOOTER: u8 = 0x02;
const OP_SCHEMA: u8 = 0x03;
const OP_CHANNEL: u8 = 0x04;
const OP_MESSAGE: u8 = 0x05;
const OP_CHUNK: u8 = 0x06;

/// Read the MCAP file at `path`.
pub fn read(path: &Path, on_event: &mut dyn FnMut(Event<'_>), on_bytes: &mut dyn FnMut(u64)) -> Result<(), StopError> {
    let file = File::open(path)?;
    let len = file.metadata()?.len();
    read_from(BufReader::with_capacity(1 << 20, file), len, on_event, on_bytes)
}

/// A little-endian field reader over one record's bytes.
struct Fields<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> Fields<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], String> {
        let end =
            self.at.checked_add(n).filter(|&e| e <= self.b.len()).ok_or_else(|| {
                format!("{what} ({n} bytes at byte {} of the record) runs past the record's {} bytes", self.at, self.b.len())
            })?;
        let s = &self.b[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u16(&mut self, what: &str) -> Result<u16, String> {
        Ok(u16::from_le_bytes(self.take(2, what)?.try_into().expect("2 bytes")))
    }
    fn u32(&mut self, what: &str) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().expect("4 bytes")))
    }
    fn string(&mut self, what: &str) -> Result<&'a str, String> {
        let n = self.u32(what)? as usize;
        std::str::from_utf8(self.take(n, what)?).map_err(|_| format!("{what} is not UTF-8"))
    }
    fn rest(&self) -> &'a [u8] {
        &self.b[self.at..]
    }
}

#[derive(Default)]
struct State {
    schemas: HashMap<u16, String>,
    channels: HashMap<u16, Option<Connection>>,
}

impl State {
    /// One Schema, Channel or Message record (others are ignored). Err: why
    /// it cannot be used (the caller names where it is).
    fn record(&mut self, op: u8, body: &[u8], on_event: &mut dyn FnMut(Event<'_>), offset: u64) -> Result<(), String> {
        let mut f = Fields { b: body, at: 0 };
        match op {
            OP_SCHEMA => {
                let id = f.u16("schema id")?;
                let name = f.string("schema name")?;
                self.schemas.insert(id, name.to_string());
            }
            OP_CHANNEL => {
                let id = f.u16("channel id")?;
                let schema = f.u16("channel schema id")?;
                let topic = f.string("channel topic")?;
                let encoding = match f.string("channel message encoding")? {
                    "cdr" => Some(Encoding::Cdr),
                    "ros1" => Some(Encoding::Ros1),
                    // json, protobuf, ...: not a ROS message.
                    _ => None,
                };
                // The summary section repeats the channels of the data section.
                if self.channels.get(&id).is_some_and(Option::is_some) {
                    return Ok(());
                }
                let ty = self.schemas.get(&schema).map(|s| short_type(s)).unwrap_or_default();
                self.channels.insert(id, encoding.map(|encoding| Connection { topic: topic.to_string(), msg_type: ty, encoding }));
            }
            OP_MESSAGE => {
                let channel = f.u16("message channel id")?;
                f.take(4 + 8 + 8, "message sequence and times")?;
                match self.channels.get(&channel) {
                    Some(Some(conn)) => on_event(Event::Message { conn, data: f.rest() }),
                    Some(None) => {}
                    None => {
                        on_event(Event::Skipped { offset, reason: format!("a message on channel {channel}, which was never declared") })
                    }
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// The records of a decompressed chunk that starts at `offset` in the file.
    fn chunk_records(&mut self, mut body: &[u8], offset: u64, on_event: &mut dyn FnMut(Event<'_>)) {
        let total = body.len();
        while !body.is_empty() {
            let at = total - body.len();
            let here = |reason: String| Event::Skipped {
                offset,
                reason: format!("chunk, record at byte {at} of its {total} uncompressed bytes: {reason}"),
            };
            if body.len() < 9 {
                on_event(here(format!("{} bytes left, too few for a record", body.len())));
                return;
            }
            let op = body[0];
            let n = u64::from_le_bytes(body[1..9].try_into().expect("8 bytes"));
            let left = (body.len() - 9) as u64;
            if n > left {
                on_event(here(format!(
                    "record op {op:#04x} declares {n} bytes, {left} are left in the chunk: the rest of the chunk is stepped over"
                )));
                return;
            }
            let (rec, rest) = body[9..].split_at(n as usize);
            if let Err(reason) = self.record(op, rec, on_event, offset) {
                on_event(here(format!("record op {op:#04x}: {reason}")));
            }
            body = rest;
        }
    }
}

/// A chunk record's fields before its records.
struct ChunkHead {
    uncompressed_size: u64,
    uncompressed_crc: u32,
    codec: Option<Codec>,
    records_len: u64,
}

/// Read the chunk header (from `r`, inside a record of `record_len` bytes);
/// returns it and the bytes of the record read so far.
fn chunk_head(r: &mut impl Read, record_len: u64) -> Result<(ChunkHead, u64), String> {
    let mut fixed = [0u8; 32];
    if record_len < 32 {
        return Err(format!("a chunk record of {record_len} bytes, shorter than a chunk's header"));
    }
    r.read_exact(&mut fixed).map_err(|e| e.to_string())?;
    let uncompressed_size = u64::from_le_bytes(fixed[16..24].try_into().expect("8"));
    let uncompressed_crc = u32::from_le_bytes(fixed[24..28].try_into().expect("4"));
    let clen = u32::from_le_bytes(fixed[28..32].try_into().expect("4")) as u64;
    if clen > 64 || 32 + clen + 8 > record_len {
        return Err(format!("a compression name of {clen} bytes in a chunk record of {record_len} bytes"));
    }
    let mut name = [0u8; 64];
    let name = &mut name[..clen as usize];
    r.read_exact(name).map_err(|e| e.to_string())?;
    let codec = match &name[..] {
        b"" => None,
        b"zstd" => Some(Codec::Zstd),
        b"lz4" => Some(Codec::Lz4),
        other => return Err(format!("chunk compression {:?} is not zstd, lz4 or none", String::from_utf8_lossy(other))),
    };
    let mut n = [0u8; 8];
    r.read_exact(&mut n).map_err(|e| e.to_string())?;
    let records_len = u64::from_le_bytes(n);
    let used = 32 + clen + 8;
    if records_len > record_len - used {
        return Err(format!("chunk records of {records_len} bytes in a chunk record of {record_len} bytes"));
    }
    Ok((ChunkHead { uncompressed_size, uncompressed_crc, codec, records_len }, used))
}

/// Read an MCAP file of `len` bytes from `r` (positioned at its start).
pub fn read_from<R: Read + Seek>(
    mut r: R,
    len: u64,
    on_event: &mut dyn FnMut(Event<'_>),
    on_bytes: &mut dyn FnMut(u64),
) -> Result<(), StopError> {
    let mut magic = [0u8; 8];
    let got = read_up_to(&mut r, &mut magic)?;
    if got < 5 || &magic[..5] != b"\x89MCAP" {
        return Err(StopError::NotThisKind("not an MCAP file (it does not start with the MCAP magic)".into()));
    }
    if got < MAGIC.len() {
        return Err(StopError::Broken {
            offset: 0,
            reason: format!("the file ends inside the MCAP magic ({len} bytes in all): truncated"),
        });
    }
    let mut state = State::default();
    let mut buf: Vec<u8> = Vec::new();
    let mut offset = MAGIC.len() as u64;
    let io_err = |offset: u64, e: io::Error| -> StopError {
        if e.kind() == io::ErrorKind::UnexpectedEof {
            StopError::Broken { offset, reason: format!("the file ends inside a record ({len} bytes in all): truncated") }
        } else {
            StopError::Io(e)
        }
    };
    loop {
        let mut head = [0u8; 9];
        match bounded::read_or_end(&mut r, &mut head) {
            Ok(true) => {}
            // A file whose writer was killed has no footer: it ends after its last whole record.
            Ok(false) => break,
            Err(e) => return Err(io_err(offset, e)),
        }
        let op = head[0];
        let n = u64::from_le_bytes(head[1..9].try_into().expect("8 bytes"));
        let left = len.saturating_sub(offset + 9);
        if n > left {
            return Err(StopError::Broken {
                offset,
                reason: format!(
                    "record op {op:#04x} declares {n} bytes, {left} are left in the file ({len} bytes in all): truncated or damaged"
                ),
            });
        }
        let skipped = |reason: String| Event::Skipped { offset, reason };
        match op {
            OP_FOOTER => break,
            OP_SCHEMA | OP_CHANNEL | OP_MESSAGE => {
                if n > MAX_RECORD_BYTES {
                    on_event(skipped(bounded::over_limit(&format!("record op {op:#04x}"), n)));
                    bounded::skip(&mut r, n).map_err(|e| io_err(offset, e))?;
                } else {
                    let body = bounded::sized(&mut buf, n as usize);
                    r.read_exact(body).map_err(|e| io_err(offset, e))?;
                    if let Err(reason) = state.record(op, body, on_event, offset) {
                        on_event(skipped(format!("record op {op:#04x}: {reason}")));
                    }
                }
            }
            OP_CHUNK => {
                let used = chunk(&mut r, n, offset, &mut state, &mut buf, on_event).map_err(|e| io_err(offset, e))?;
                bounded::skip(&mut r, n - used).map_err(|e| io_err(offset, e))?;
            }
            _ => bounded::skip(&mut r, n).map_err(|e| io_err(offset, e))?,
        }
        offset += 9 + n;
        on_bytes(offset);
    }
    Ok(())
}

/// One chunk record of `n` bytes at `offset`: its records handed out, or a
/// warning when it cannot be read. Returns the bytes of the record read.
fn chunk<R: Read + Seek>(
    r: &mut R,
    n: u64,
    offset: u64,
    state: &mut State,
    buf: &mut Vec<u8>,
    on_event: &mut dyn FnMut(Event<'_>),
) -> io::Result<u64> {
    let mut record = Read::take(&mut *r, n);
    let mut warn = |reason: String| on_event(Event::Skipped { offset, reason: format!("chunk: {reason}") });
    let (head, _) = match chunk_head(&mut record, n) {
        Ok(h) => h,
        Err(reason) => {
            warn(reason);
            return Ok(n - record.limit());
        }
    };
    let size = head.uncompressed_size;
    if head.codec.is_none() && size != head.records_len {
        warn(format!("uncompressed, {} bytes of records, but its header says {size}", head.records_len));
        return Ok(n - record.limit());
    }
    if size > MAX_RECORD_BYTES {
        warn(bounded::over_limit("a chunk", size));
        return Ok(n - record.limit());
    }
    let out = bounded::sized(buf, size as usize);
    let mut records = (&mut record).take(head.records_len);
    let result = match head.codec {
        None => records.read_exact(out).map_err(|e| e.to_string()),
        Some(codec) => bounded::decompress_exact(codec, &mut records, out),
    };
    if let Err(reason) = result {
        warn(reason);
        return Ok(n - record.limit());
    }
    if head.uncompressed_crc != 0 {
        let crc = crc32fast::hash(out);
        if crc != head.uncompressed_crc {
            warn(format!("its records' CRC is {crc:#010x}, its header says {:#010x} (damaged)", head.uncompressed_crc));
            return Ok(n - record.limit());
        }
    }
    let used = n - record.limit();
    state.chunk_records(out, offset, on_event);
    Ok(used)
}

/// Read up to `buf.len()` bytes; how many were read (fewer only at the end).
fn read_up_to(r: &mut impl Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(k) => got += k,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}
