//! Typed errors of the library. Each names the file, and where it applies the
//! record or line and the byte offset, so a user can find the bad spot. The
//! binaries print them once, at their edge ([`crate::cli`]).

use std::io;

/// Everything the library can refuse or fail at.
#[derive(Debug, thiserror::Error)]
pub enum DemError {
    /// An input could not be opened or read (missing file, permissions).
    #[error("failed to open {path}")]
    Open {
        /// The path as the user gave it (`-` is stdin).
        path: String,
        /// What the OS said.
        #[source]
        source: io::Error,
    },
    /// Reading or writing failed after the file was opened.
    #[error("I/O error on {path}")]
    Io {
        /// The path as the user gave it (`-` is stdin/stdout).
        path: String,
        /// What the OS said.
        #[source]
        source: io::Error,
    },
    /// An NPY stream breaks the contract.
    #[error("{path}: record {record}, byte {offset}: {reason}")]
    Npy {
        /// The path as the user gave it.
        path: String,
        /// Zero-based index of the record (over the whole stream) where it broke.
        record: u64,
        /// Byte offset in the stream where it broke.
        offset: u64,
        /// What is wrong.
        reason: String,
    },
    /// A CSV table breaks the contract.
    #[error("{path}: line {line}: {reason}")]
    Table {
        /// The path as the user gave it.
        path: String,
        /// One-based line number in the file.
        line: u64,
        /// What is wrong.
        reason: String,
    },
    /// An input is well formed but unusable (empty where data is needed,
    /// indices past the data, ...).
    #[error("{path}: {reason}")]
    Input {
        /// The path as the user gave it.
        path: String,
        /// What is wrong.
        reason: String,
    },
    /// Arguments that make no sense together.
    #[error("{0}")]
    Usage(String),
    /// A record about to be written breaks the contract (a NaN or an
    /// infinity): a defect of the tool or of a model it ran, never written.
    #[error("{path}: record {record} not written: {reason}")]
    Unwritable {
        /// The output path as the user gave it.
        path: String,
        /// Zero-based index of the record in the output.
        record: u64,
        /// What is wrong.
        reason: String,
    },
}

impl DemError {
    /// Exit status for this error: 2 for bad input or usage, 1 for an
    /// internal or I/O failure.
    pub fn exit_code(&self) -> u8 {
        match self {
            DemError::Io { .. } | DemError::Unwritable { .. } => 1,
            _ => 2,
        }
    }

    /// Wrap an I/O error on `path`.
    pub fn io(path: impl Into<String>, source: io::Error) -> Self {
        DemError::Io { path: path.into(), source }
    }

    /// A bad input that is not tied to one record or line.
    pub fn input(path: impl Into<String>, reason: impl Into<String>) -> Self {
        DemError::Input { path: path.into(), reason: reason.into() }
    }
}

/// Result with a [`DemError`].
pub type Result<T, E = DemError> = std::result::Result<T, E>;
