//! Recording containers, read front to back in bounded memory: ROS 1 bags
//! ([`ros1`]), MCAP files ([`mcap`], also the `.mcap` files of a ROS 2
//! bag folder) and ROS 2 SQLite bags ([`sqlite`], `.db3` files, in
//! timestamp order). All give the same events: each message with its
//! connection, or a part of the file that had to be skipped.

pub mod bounded;
pub mod mcap;
pub mod ros1;
pub mod sqlite;

use std::path::{Path, PathBuf};

use crate::wire::Encoding;

/// A topic as the recording declares it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Connection {
    /// Topic name.
    pub topic: String,
    /// Message type as `package/Name` (ROS 2's `package/msg/Name` shortened).
    pub msg_type: String,
    /// Serialization of its messages.
    pub encoding: Encoding,
}

/// `package/msg/Name` -> `package/Name`; ROS 1 names pass unchanged.
pub fn short_type(name: &str) -> String {
    name.replacen("/msg/", "/", 1)
}

/// What a reader hands out, in file order.
pub enum Event<'a> {
    /// One message: its connection, the time it was recorded (ns) and its bytes.
    Message {
        /// The connection it came on.
        conn: &'a Connection,
        /// Its serialized bytes.
        data: &'a [u8],
    },
    /// A part of the file that could not be read and was stepped over.
    Skipped {
        /// Where it starts (bytes into the file).
        offset: u64,
        /// What was wrong.
        reason: String,
    },
}

/// A reader that had to stop: the file is not this kind of recording, or it
/// ends or breaks where more was due (messages before that were handed out).
#[derive(Debug, thiserror::Error)]
pub enum StopError {
    /// The file could not be opened or read.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// Not a recording of this kind (bad magic).
    #[error("{0}")]
    NotThisKind(String),
    /// Broken at a byte offset: truncated, or a record that cannot be followed.
    #[error("byte {offset}: {reason}")]
    Broken {
        /// Bytes into the file.
        offset: u64,
        /// What is wrong.
        reason: String,
    },
}

/// The kinds of recording dem-import reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A ROS 1 `.bag` file.
    Ros1Bag,
    /// One `.mcap` file.
    Mcap,
    /// One `.db3` file (rosbag2's SQLite storage).
    Sqlite,
}

/// The files of a recording given on the command line: a `.bag`, `.mcap`
/// or `.db3` file, or a ROS 2 bag folder (its `.mcap` or `.db3` files in
/// split order).
pub fn files_of(path: &Path) -> Result<Vec<(Kind, PathBuf)>, String> {
    if path.is_dir() {
        let mut parts = Vec::new();
        let entries = std::fs::read_dir(path).map_err(|e| format!("cannot list the folder: {e}"))?;
        for e in entries.flatten() {
            let p = e.path();
            match p.extension().and_then(|x| x.to_str()) {
                Some("mcap") => parts.push((Kind::Mcap, p)),
                Some("db3") => parts.push((Kind::Sqlite, p)),
                _ => {}
            }
        }
        if parts.is_empty() {
            return Err(
                "a folder without .mcap or .db3 files (a ROS 2 bag folder holds metadata.yaml and NAME_0.mcap or NAME_0.db3, ...)".into()
            );
        }
        // rosbag2 splits as NAME_0.mcap, NAME_1.mcap, ..., NAME_10.mcap: by number.
        let split_no =
            |p: &PathBuf| p.file_stem().and_then(|s| s.to_str()).and_then(|s| s.rsplit('_').next()).and_then(|n| n.parse::<u64>().ok());
        parts.sort_by(|a, b| split_no(&a.1).cmp(&split_no(&b.1)).then_with(|| a.1.cmp(&b.1)));
        return Ok(parts);
    }
    match path.extension().and_then(|x| x.to_str()) {
        Some("bag") => Ok(vec![(Kind::Ros1Bag, path.to_path_buf())]),
        Some("mcap") => Ok(vec![(Kind::Mcap, path.to_path_buf())]),
        Some("db3") => Ok(vec![(Kind::Sqlite, path.to_path_buf())]),
        _ => Err("not a recording dem-import reads (a ROS 1 .bag, a .mcap or .db3, or a ROS 2 bag folder of them)".into()),
    }
}

/// Read one file of `kind`, calling `on_event` for each message or skipped
/// part and `on_bytes` with the bytes read so far.
pub fn read(kind: Kind, path: &Path, on_event: &mut dyn FnMut(Event<'_>), on_bytes: &mut dyn FnMut(u64)) -> Result<(), StopError> {
    match kind {
        Kind::Ros1Bag => ros1::read(path, on_event, on_bytes),
        Kind::Mcap => mcap::read(path, on_event, on_bytes),
        Kind::Sqlite => sqlite::read(path, on_event, on_bytes),
    }
}
