//! ROS 1 bag files (format 2.0), read front to back one record at a time.
//!
//! A bag is `#ROSBAG V2.0\n` and records: `u32` header length, header
//! fields (`u32` length, `name=value`), `u32` data length, data. The ops
//! used here: 0x05 chunk (compression `none`/`bz2`/`lz4`, holding
//! connection and message records), 0x07 connection (`conn`, `topic`; data:
//! `type`, `md5sum`, `message_definition`), 0x02 message (`conn`, `time`).
//! Index records (0x04, 0x06) and the bag header (0x03) are stepped over,
//! so a bag whose recorder was killed before it wrote its index reads
//! like any other, up to its last whole record.
//!
//! Not the `rosbag` crate: it maps the whole file and slices it at the
//! header's `index_pos`, which panics on a truncated or unindexed bag (the
//! recordings a field robot leaves when its battery dies); this reader
//! holds one chunk at a time and stops at the break with its byte offset.

use std::collections::HashMap;
use std::fs::File;
use std::io::{self, BufReader, Read, Seek};
use std::path::Path;

use super::bounded::{self, Codec, MAX_RECORD_BYTES};
use super::{short_type, Connection, Event, StopError};
use crate::wire::Encoding;

const MAGIC: &[u8] = b"#ROSBAG V2.0\n";
/// No record of a sane bag has a header this large (a header holds a few
/// short fields; the connection's message definition is in its data).
pub const MAX_HEADER: u64 = 1 << 20;

/// Record header fields as `name -> value bytes`.
fn fields(header: &[u8]) -> Result<Vec<(&str, &[u8])>, String> {
    let mut out = Vec::new();
    let mut rest = header;
    while !rest.is_empty() {
        if rest.len() < 4 {
            return Err("a header field length is cut short".into());
        }
        let n = u32::from_le_bytes(rest[..4].try_into().expect("4 bytes")) as usize;
        let field = rest.get(4..4 + n).ok_or("a header field runs past its header")?;
        let eq = field.iter().position(|&b| b == b'=').ok_or("a header field without '='")?;
        let name = std::str::from_utf8(&field[..eq]).map_err(|_| "a header field name is not text")?;
        out.push((name, &field[eq + 1..]));
        rest = &rest[4 + n..];
    }
    Ok(out)
}

fn field<'a>(fields: &[(&str, &'a [u8])], name: &str) -> Option<&'a [u8]> {
    fields.iter().find(|(n, _)| *n == name).map(|(_, v)| *v)
}

fn u32_field(fields: &[(&str, &[u8])], name: &str) -> Result<u32, String> {
    let v = field(fields, name).ok_or_else(|| format!("record without its {name} field"))?;
    Ok(u32::from_le_bytes(v.try_into().map_err(|_| format!("field {name} is not 4 bytes"))?))
}

struct State {
    conns: HashMap<u32, Connection>,
}

impl State {
    /// Handle one record (op from its header); `offset` for messages.
    fn record(&mut self, header: &[u8], data: &[u8], offset: u64, on_event: &mut dyn FnMut(Event<'_>)) -> Result<(), String> {
        let f = fields(header)?;
        let op = field(&f, "op").and_then(|v| v.first().copied()).ok_or("record without an op field")?;
        match op {
            0x02 => {
                let conn = u32_field(&f, "conn")?;
                match self.conns.get(&conn) {
                    Some(c) => on_event(Event::Message { conn: c, data }),
                    None => {
                        on_event(Event::Skipped { offset, reason: format!("a message on connection {conn}, which was never declared") })
                    }
                }
            }
            0x07 => {
                let conn = u32_field(&f, "conn")?;
                // The index section repeats the connections of the chunks.
                if let std::collections::hash_map::Entry::Vacant(slot) = self.conns.entry(conn) {
                    let d = fields(data)?;
                    let text = |name: &str| field(&d, name).map(|v| String::from_utf8_lossy(v).into_owned());
                    let topic = text("topic").or_else(|| field(&f, "topic").map(|v| String::from_utf8_lossy(v).into_owned()));
                    let (Some(topic), Some(ty)) = (topic, text("type")) else {
                        return Err(format!("connection {conn} without a topic or type"));
                    };
                    slot.insert(Connection { topic, msg_type: short_type(&ty), encoding: Encoding::Ros1 });
                }
            }
            0x03 | 0x04 | 0x06 => {}
            0x05 => return Err("a chunk inside a chunk".into()),
            op => return Err(format!("unknown record op {op:#04x}")),
        }
        Ok(())
    }

    /// The records inside a decompressed chunk.
    fn chunk(&mut self, mut body: &[u8], offset: u64, on_event: &mut dyn FnMut(Event<'_>)) -> Result<(), String> {
        while !body.is_empty() {
            let (header, data, rest) = split_record(body).ok_or("a record inside the chunk is cut short")?;
            self.record(header, data, offset, on_event)?;
            body = rest;
        }
        Ok(())
    }
}

fn split_record(b: &[u8]) -> Option<(&[u8], &[u8], &[u8])> {
    let hl = u32::from_le_bytes(b.get(..4)?.try_into().ok()?) as usize;
    let header = b.get(4..4 + hl)?;
    let at = 4 + hl;
    let dl = u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?) as usize;
    let data = b.get(at + 4..at + 4 + dl)?;
    Some((header, data, &b[at + 4 + dl..]))
}

/// The compression of a chunk: None for `none`.
fn codec(compression: &[u8]) -> Result<Option<Codec>, String> {
    match compression {
        b"none" => Ok(None),
        b"bz2" => Ok(Some(Codec::Bz2)),
        b"lz4" => Ok(Some(Codec::Lz4)),
        other => Err(format!("chunk compression {:?} is not none, bz2 or lz4", String::from_utf8_lossy(other))),
    }
}

/// Read the bag at `path`.
pub fn read(path: &Path, on_event: &mut dyn FnMut(Event<'_>), on_bytes: &mut dyn FnMut(u64)) -> Result<(), StopError> {
    let file = File::open(path)?;
    let len = file.metadata()?.len();
    read_from(BufReader::with_capacity(1 << 20, file), len, on_event, on_bytes)
}

/// Read a bag of `len` bytes from `r` (positioned at its start).
///
/// Every record's header and data length is checked against the bytes
/// left in the file and against [`MAX_HEADER`] and
/// [`MAX_RECORD_BYTES`] before it is read; a compressed chunk is
/// decompressed straight from the file into a buffer of its declared size
/// (at most [`MAX_RECORD_BYTES`]), so memory is one such buffer whatever
/// the file declares or holds.
pub fn read_from<R: Read + Seek>(
    mut r: R,
    len: u64,
    on_event: &mut dyn FnMut(Event<'_>),
    on_bytes: &mut dyn FnMut(u64),
) -> Result<(), StopError> {
    let mut magic = [0u8; MAGIC.len()];
    if !bounded::read_or_end(&mut r, &mut magic).unwrap_or(false) || magic != MAGIC {
        return Err(StopError::NotThisKind("not a ROS 1 bag (it does not start with #ROSBAG V2.0)".into()));
    }
    let mut state = State { conns: HashMap::new() };
    let (mut header, mut buf) = (Vec::new(), Vec::new());
    let mut offset = MAGIC.len() as u64;
    let truncated = |offset: u64, what: &str| StopError::Broken {
        offset,
        reason: format!("the file ends inside {what} ({len} bytes in all): truncated"),
    };
    let io_err =
        |offset: u64, e: io::Error| if e.kind() == io::ErrorKind::UnexpectedEof { truncated(offset, "a record") } else { StopError::Io(e) };
    loop {
        let mut n = [0u8; 4];
        match bounded::read_or_end(&mut r, &mut n) {
            Ok(false) => break,
            Ok(true) => {}
            Err(e) => return Err(io_err(offset, e)),
        }
        let hl = u32::from_le_bytes(n) as u64;
        if hl > MAX_HEADER || offset + 4 + hl + 4 > len {
            return Err(if offset + 4 + hl + 4 > len && hl <= MAX_HEADER {
                truncated(offset, "a record header")
            } else {
                StopError::Broken {
                    offset,
                    reason: format!("a record header of {hl} bytes (at most {} in a bag): not a bag record", bounded::bytes(MAX_HEADER)),
                }
            });
        }
        header.resize(hl as usize, 0);
        r.read_exact(&mut header).map_err(|e| io_err(offset, e))?;
        r.read_exact(&mut n).map_err(|e| io_err(offset, e))?;
        let dl = u32::from_le_bytes(n) as u64;
        if offset + 8 + hl + dl > len {
            return Err(truncated(offset, "a record"));
        }
        let mut used = 0;
        let result = match fields(&header) {
            Err(reason) => Err(reason),
            Ok(f) => {
                let is_chunk = field(&f, "op") == Some(&[0x05]);
                if is_chunk {
                    match chunk_layout(&f, dl) {
                        Err(reason) => Err(reason),
                        Ok((codec, size)) => {
                            let out = bounded::sized(&mut buf, size as usize);
                            let mut data = Read::take(&mut r, dl);
                            let got = match codec {
                                // `rosbag record`'s default: read the records where they are.
                                None => data.read_exact(out).map_err(|e| io_err(offset, e)).map(|()| Ok(())),
                                Some(codec) => Ok(bounded::decompress_exact(codec, &mut data, out)),
                            };
                            used = dl - data.limit();
                            got?.and_then(|()| state.chunk(out, offset, on_event))
                        }
                    }
                } else if dl > MAX_RECORD_BYTES {
                    Err(bounded::over_limit("a record's data", dl))
                } else {
                    let data = bounded::sized(&mut buf, dl as usize);
                    r.read_exact(data).map_err(|e| io_err(offset, e))?;
                    used = dl;
                    state.record(&header, data, offset, on_event)
                }
            }
        };
        // A damaged chunk is stepped over: its length was sound, so the
        // records after it can still be read.
        if let Err(reason) = result {
            on_event(Event::Skipped { offset, reason });
        }
        bounded::skip(&mut r, dl - used).map_err(|e| io_err(offset, e))?;
        offset += 8 + hl + dl;
        on_bytes(offset);
    }
    Ok(())
}

/// A chunk's compression and uncompressed size, checked against its
/// data length and [`MAX_RECORD_BYTES`] before anything is read.
fn chunk_layout(f: &[(&str, &[u8])], dl: u64) -> Result<(Option<Codec>, u64), String> {
    let codec = codec(field(f, "compression").unwrap_or(b"none"))?;
    let size = u64::from(u32_field(f, "size")?);
    if codec.is_none() && dl != size {
        return Err(format!("chunk holds {dl} bytes, its header says {size}"));
    }
    if size > MAX_RECORD_BYTES {
        return Err(bounded::over_limit("a chunk", size));
    }
    Ok((codec, size))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rec(fields: &[(&str, &[u8])], data: &[u8]) -> Vec<u8> {
        let mut h = Vec::new();
        for (n, v) in fields {
            h.extend(((n.len() + 1 + v.len()) as u32).to_le_bytes());
            h.extend(n.as_bytes());
            h.push(b'=');
            h.extend(*v);
        }
        let mut out = (h.len() as u32).to_le_bytes().to_vec();
        out.extend(h);
        out.extend((data.len() as u32).to_le_bytes());
        out.extend(data);
        out
    }

    fn bag() -> Vec<u8> {
        // A connection record's data is a bare field list.
        let mut fields_only = Vec::new();
        for (n, v) in [("topic", &b"/x"[..]), ("type", &b"std_msgs/String"[..])] {
            fields_only.extend(((n.len() + 1 + v.len()) as u32).to_le_bytes());
            fields_only.extend(n.as_bytes());
            fields_only.push(b'=');
            fields_only.extend(v);
        }
        let mut inner = rec(&[("op", &[0x07]), ("conn", &0u32.to_le_bytes()), ("topic", b"/x")], &fields_only);
        inner.extend(rec(&[("op", &[0x02]), ("conn", &0u32.to_le_bytes()), ("time", &[0; 8])], b"hello"));
        inner.extend(rec(&[("op", &[0x02]), ("conn", &0u32.to_le_bytes()), ("time", &[0; 8])], b"world"));
        let mut b = MAGIC.to_vec();
        b.extend(rec(&[("op", &[0x03]), ("index_pos", &0u64.to_le_bytes())], &[b' '; 16]));
        b.extend(rec(&[("op", &[0x05]), ("compression", b"none"), ("size", &(inner.len() as u32).to_le_bytes())], &inner));
        b
    }

    fn read_bytes(b: &[u8]) -> (Vec<String>, Vec<String>, Result<(), StopError>) {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.bag");
        std::fs::write(&p, b).unwrap();
        let (mut msgs, mut skipped) = (Vec::new(), Vec::new());
        let r = read(
            &p,
            &mut |e| match e {
                Event::Message { conn, data } => msgs.push(format!("{}:{}", conn.topic, String::from_utf8_lossy(data))),
                Event::Skipped { reason, .. } => skipped.push(reason),
            },
            &mut |_| {},
        );
        (msgs, skipped, r)
    }

    #[test]
    fn an_unindexed_bag_reads_and_a_truncated_one_stops_at_the_break() {
        let b = bag();
        let (msgs, skipped, r) = read_bytes(&b);
        assert!(r.is_ok() && skipped.is_empty());
        assert_eq!(msgs, ["/x:hello", "/x:world"]);
        let (msgs, _, r) = read_bytes(&b[..b.len() - 3]);
        assert!(msgs.is_empty());
        let e = r.unwrap_err().to_string();
        assert!(e.contains("truncated") && e.contains("byte"), "{e}");
        let (_, _, r) = read_bytes(b"#ROSBAG V1.2\n");
        assert!(matches!(r, Err(StopError::NotThisKind(_))));
    }
}
