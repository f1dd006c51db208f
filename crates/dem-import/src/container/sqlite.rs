//! ROS 2 bags in SQLite storage (`.db3`, rosbag2's default before Iron),
//! read with `rusqlite` (SQLite's own C library, bundled), read-only.
//!
//! rosbag2's schema: `topics(id, name, type, serialization_format, ...)`
//! and `messages(id, topic_id, timestamp, data)`; `data` is the message as
//! serialized on the wire (CDR), the same bytes an MCAP channel with
//! encoding `cdr` holds, so the decoders are the MCAP path's.
//!
//! Messages are handed out in timestamp order (ties by row id, which is the
//! order they were written), one row at a time: the sorted walk reads only
//! (row id, topic, timestamp, size), through rosbag2's `timestamp_idx` when
//! the file has it (else SQLite sorts those small rows, spilling to its temp
//! files), and each message's bytes are then fetched by row id. Only the
//! messages of the types dem-import decodes are loaded; the others (camera
//! images, point clouds) are handed out without their bytes.
//!
//! A file that is not rosbag2's SQLite (no SQLite magic, tables or columns
//! missing or of the wrong type), that is cut short (SQLite pages are not in
//! recording order, so a cut file holds an arbitrary subset of the
//! recording, not its beginning), that SQLite finds damaged, or that holds a
//! message larger than [`MAX_MESSAGE_BYTES`] is not imported.

use std::fs::File;
use std::io::Read;
use std::path::Path;

use rusqlite::types::ValueRef;
use rusqlite::{Connection as Db, OpenFlags};

use super::{short_type, Connection, Event, StopError};
use crate::wire::Encoding;

/// The largest message loaded (bytes): a 1000 x 1000 map of 16 float layers.
pub const MAX_MESSAGE_BYTES: i64 = 64 << 20;

/// The message types dem-import decodes; messages of other types are handed
/// out with empty bytes (their topic is listed, their bytes never loaded).
const DECODED_TYPES: [&str; 3] = ["grid_map_msgs/GridMap", "tf2_msgs/TFMessage", "sensor_msgs/JointState"];

const MAGIC: &[u8; 16] = b"SQLite format 3\0";

fn refused(why: impl std::fmt::Display) -> StopError {
    StopError::NotThisKind(format!("not a readable ROS 2 SQLite bag: {why}"))
}

/// The header's page size and, when SQLite would trust it, page count: the
/// file must hold that many whole pages.
fn check_header(path: &Path) -> Result<(), StopError> {
    let mut file = File::open(path)?;
    let len = file.metadata()?.len();
    let mut h = [0u8; 100];
    let mut got = 0;
    while got < h.len() {
        match file.read(&mut h[got..])? {
            0 => break,
            n => got += n,
        }
    }
    if got < 16 || &h[..16] != MAGIC {
        return Err(StopError::NotThisKind("not a SQLite database (it does not start with the SQLite magic)".into()));
    }
    if got < 100 {
        return Err(refused(format!("truncated: {len} bytes, less than the 100-byte SQLite header")));
    }
    let page = match u16::from_be_bytes([h[16], h[17]]) {
        1 => 65536u64,
        p if p >= 512 && p.is_power_of_two() => u64::from(p),
        p => return Err(refused(format!("byte 16: page size {p} is not SQLite's"))),
    };
    let u32_at = |at: usize| u32::from_be_bytes(h[at..at + 4].try_into().expect("4 bytes"));
    let pages = u64::from(u32_at(28));
    // SQLite trusts the header's page count only when the change counter
    // matches the version-valid-for number; else it goes by the file size.
    let declared = if pages > 0 && u32_at(24) == u32_at(92) { pages * page } else { len.div_ceil(page) * page };
    if len < declared || len % page != 0 {
        return Err(refused(format!("truncated: {len} bytes, the header declares {declared} ({} pages of {page} bytes)", declared / page)));
    }
    Ok(())
}

/// The declared type of each column of `table` (empty when there is no such table).
fn columns(db: &Db, table: &str) -> rusqlite::Result<Vec<(String, String)>> {
    let mut st = db.prepare(&format!("PRAGMA table_info({table})"))?;
    let rows = st.query_map([], |r| Ok((r.get::<_, String>(1)?, r.get::<_, String>(2)?)))?;
    rows.collect()
}

/// Refuse tables whose needed columns are missing or declared with another
/// type than rosbag2's (`INTEGER`, `TEXT`, `BLOB`).
fn check_schema(db: &Db) -> Result<(), StopError> {
    let want: [(&str, &[(&str, &str)]); 2] = [
        ("topics", &[("id", "INT"), ("name", "TEXT"), ("type", "TEXT"), ("serialization_format", "TEXT")]),
        ("messages", &[("id", "INT"), ("topic_id", "INT"), ("timestamp", "INT"), ("data", "BLOB")]),
    ];
    for (table, cols) in want {
        let have = columns(db, table).map_err(refused)?;
        if have.is_empty() {
            return Err(refused(format!("no table {table} (a rosbag2 database has tables topics and messages)")));
        }
        for (col, ty) in cols {
            match have.iter().find(|(c, _)| c == col) {
                None => return Err(refused(format!("table {table} has no column {col}"))),
                Some((_, t)) if !t.to_ascii_uppercase().contains(ty) => {
                    return Err(refused(format!("column {table}.{col} is declared {t:?}, not {ty} as rosbag2's")));
                }
                Some(_) => {}
            }
        }
    }
    Ok(())
}

/// The topics by id: a connection when the serialization is one dem-import
/// reads (`cdr`, `ros1`), else None.
fn topics(db: &Db) -> Result<Vec<(i64, Option<Connection>)>, StopError> {
    let mut st = db.prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id").map_err(refused)?;
    let mut rows = st.query([]).map_err(refused)?;
    let mut out = Vec::new();
    while let Some(r) = rows.next().map_err(refused)? {
        let text = |k: usize, what: &str| -> Result<String, StopError> {
            match r.get_ref(k).map_err(refused)? {
                ValueRef::Text(t) => Ok(String::from_utf8_lossy(t).into_owned()),
                v => Err(refused(format!("topics.{what} holds {:?}, not text", v.data_type()))),
            }
        };
        let id = match r.get_ref(0).map_err(refused)? {
            ValueRef::Integer(id) => id,
            v => return Err(refused(format!("topics.id holds {:?}, not an integer", v.data_type()))),
        };
        let (name, ty, format) = (text(1, "name")?, text(2, "type")?, text(3, "serialization_format")?);
        let encoding = match format.as_str() {
            "cdr" => Some(Encoding::Cdr),
            "ros1" => Some(Encoding::Ros1),
            _ => None,
        };
        out.push((id, encoding.map(|encoding| Connection { topic: name, msg_type: short_type(&ty), encoding })));
    }
    Ok(out)
}

/// Read the `.db3` file at `path`.
pub fn read(path: &Path, on_event: &mut dyn FnMut(Event<'_>), on_bytes: &mut dyn FnMut(u64)) -> Result<(), StopError> {
    check_header(path)?;
    let size = std::fs::metadata(path)?.len();
    let db = Db::open_with_flags(path, OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX).map_err(refused)?;
    check_schema(&db)?;
    let topics = topics(&db)?;
    let conn_of = |id: i64| topics.iter().find(|(k, _)| *k == id).map(|(_, c)| c);
    // Rows are numbered about 1..=max(rowid): the progress estimate.
    let last_row: i64 = db.query_row("SELECT ifnull(max(rowid), 0) FROM messages", [], |r| r.get(0)).map_err(refused)?;
    let mut walk =
        db.prepare("SELECT rowid, topic_id, typeof(data), length(data) FROM messages ORDER BY timestamp, rowid").map_err(refused)?;
    let mut fetch = db.prepare("SELECT data FROM messages WHERE rowid = ?1").map_err(refused)?;
    let mut rows = walk.query([]).map_err(refused)?;
    let mut seen = 0u64;
    while let Some(r) = rows.next().map_err(refused)? {
        seen += 1;
        if seen.is_multiple_of(1024) {
            on_bytes((size as u128 * u128::from(seen) / (last_row.max(1) as u128)).min(u128::from(size)) as u64);
        }
        let int = |k: usize, what: &str| match r.get_ref(k) {
            Ok(ValueRef::Integer(v)) => Ok(v),
            Ok(v) => Err(refused(format!("message row {}: {what} holds {:?}, not an integer", seen, v.data_type()))),
            Err(e) => Err(refused(e)),
        };
        let (rowid, topic_id) = (int(0, "rowid")?, int(1, "topic_id")?);
        let at = || format!("message row {rowid}");
        let conn = match conn_of(topic_id) {
            Some(Some(c)) => c,
            // A serialization dem-import does not read (json, ...).
            Some(None) => continue,
            None => return Err(refused(format!("{}: topic_id {topic_id}, which the topics table does not declare", at()))),
        };
        if !DECODED_TYPES.contains(&conn.msg_type.as_str()) {
            on_event(Event::Message { conn, data: &[] });
            continue;
        }
        let kind = match r.get_ref(2).map_err(refused)? {
            ValueRef::Text(t) => String::from_utf8_lossy(t).into_owned(),
            _ => String::new(),
        };
        if kind != "blob" {
            return Err(refused(format!("{} on {}: data holds {kind}, not a blob", at(), conn.topic)));
        }
        let len = int(3, "length(data)")?;
        if len > MAX_MESSAGE_BYTES {
            return Err(refused(format!(
                "{} on {}: a message of {len} bytes, more than the {MAX_MESSAGE_BYTES} a message may have",
                at(),
                conn.topic
            )));
        }
        let mut one = fetch.query([rowid]).map_err(refused)?;
        let row = one.next().map_err(refused)?.ok_or_else(|| refused(format!("{}: gone while reading", at())))?;
        match row.get_ref(0).map_err(refused)? {
            ValueRef::Blob(data) => on_event(Event::Message { conn, data }),
            v => return Err(refused(format!("{} on {}: data holds {:?}, not a blob", at(), conn.topic, v.data_type()))),
        }
    }
    on_bytes(size);
    Ok(())
}
