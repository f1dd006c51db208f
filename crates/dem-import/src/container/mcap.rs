//! MCAP files, read front to back with the `mcap` crate's sans-io
//! `LinearReader` (chunks decompressed one at a time, zstd or lz4), so
//! memory is one chunk, not the file. Channels with message encoding `cdr`
//! (ROS 2) and `ros1` are read; others are stepped over.

use std::collections::HashMap;
use std::fs::File;
use std::io::Read;
use std::path::Path;

use mcap::records::Record;
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader};

use super::{short_type, Connection, Event, StopError};
use crate::wire::Encoding;

/// Read the MCAP file at `path`.
pub fn read(path: &Path, on_event: &mut dyn FnMut(Event<'_>), on_bytes: &mut dyn FnMut(u64)) -> Result<(), StopError> {
    let mut file = File::open(path)?;
    let mut magic = [0u8; 8];
    let got = file.read(&mut magic)?;
    if got < 5 || &magic[..5] != b"\x89MCAP" {
        return Err(StopError::NotThisKind("not an MCAP file (it does not start with the MCAP magic)".into()));
    }
    drop(file);
    let mut file = File::open(path)?;
    let mut reader = LinearReader::new();
    let mut schemas: HashMap<u16, String> = HashMap::new();
    let mut channels: HashMap<u16, Option<Connection>> = HashMap::new();
    let mut bytes = 0u64;
    while let Some(event) = reader.next_event() {
        let event = event.map_err(|e| StopError::Broken {
            offset: bytes,
            reason: match e {
                mcap::McapError::UnexpectedEof => "the file ends inside a record: truncated".to_string(),
                e => e.to_string(),
            },
        })?;
        match event {
            LinearReadEvent::ReadRequest(need) => {
                let n = file.read(reader.insert(need))?;
                reader.notify_read(n);
                bytes += n as u64;
                on_bytes(bytes);
            }
            LinearReadEvent::Record { data, opcode } => {
                let record = match mcap::parse_record(opcode, data) {
                    Ok(r) => r,
                    Err(e) => {
                        on_event(Event::Skipped { offset: bytes, reason: format!("record op {opcode:#04x}: {e}") });
                        continue;
                    }
                };
                match record {
                    Record::Schema { header, .. } => {
                        schemas.insert(header.id, header.name);
                    }
                    Record::Channel(c) => {
                        let encoding = match c.message_encoding.as_str() {
                            "cdr" => Some(Encoding::Cdr),
                            "ros1" => Some(Encoding::Ros1),
                            // json, protobuf, ...: not a ROS message.
                            _ => None,
                        };
                        let ty = schemas.get(&c.schema_id).map(|s| short_type(s)).unwrap_or_default();
                        channels.insert(c.id, encoding.map(|encoding| Connection { topic: c.topic, msg_type: ty, encoding }));
                    }
                    Record::Message { header, data } => match channels.get(&header.channel_id) {
                        Some(Some(conn)) => on_event(Event::Message { conn, data: &data }),
                        Some(None) => {}
                        None => on_event(Event::Skipped {
                            offset: bytes,
                            reason: format!("a message on channel {}, which was never declared", header.channel_id),
                        }),
                    },
                    _ => {}
                }
            }
        }
    }
    Ok(())
}
