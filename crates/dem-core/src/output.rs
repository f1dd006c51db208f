//! Output files that appear whole or not at all: data goes to a temp file in
//! the target's folder (same filesystem, so the rename is atomic) and is
//! renamed over the target on commit. Dropping without commit removes it.
//! `-` is stdout, which cannot be made atomic and is written through; so is
//! an existing target that is not a regular file (`/dev/null`, a FIFO), which
//! a rename would replace with a regular file.

use std::fs::{File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::{DemError, Result};

/// True when `path` exists (after symlinks) as something other than a
/// regular file or a folder: a device or a FIFO, written in place.
pub fn is_special(path: &str) -> bool {
    std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// Open an existing special file (see [`is_special`]) for writing, in place.
pub fn open_special(path: &str) -> Result<File> {
    OpenOptions::new().write(true).open(path).map_err(|source| DemError::Open { path: path.into(), source })
}

/// Where a file written to `path` really goes: through a symlink to its
/// target, so the rename replaces the file the link names, not the link.
pub fn resolve(path: &str) -> PathBuf {
    let p = Path::new(path);
    match std::fs::symlink_metadata(p) {
        Ok(m) if m.file_type().is_symlink() => std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf()),
        _ => p.to_path_buf(),
    }
}

/// A temp file beside `path` (beside its target, for a symlink), named
/// `.NAME.XXXX.tmp`.
pub fn temp_beside(path: &str) -> Result<tempfile::NamedTempFile> {
    let resolved = resolve(path);
    let target = resolved.as_path();
    let dir = match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let name = target.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    // 0o666 minus the umask, like any file a tool creates; tempfile's
    // default 0o600 would hide outputs from the rest of a team.
    tempfile::Builder::new()
        .permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666))
        .prefix(&format!(".{name}."))
        .suffix(".tmp")
        .tempfile_in(dir)
        .map_err(|source| DemError::Open { path: path.into(), source })
}

enum Target {
    Temp(BufWriter<tempfile::NamedTempFile>),
    /// Stdout or a special file, written through.
    Direct(BufWriter<Box<dyn Write>>),
}

/// A buffered writer to `path` (or stdout for `-`) that is atomic for files.
pub struct AtomicOutput {
    target: Target,
    path: String,
}

impl AtomicOutput {
    /// Start writing `path`.
    pub fn create(path: &str) -> Result<Self> {
        let target = if path == "-" {
            Target::Direct(BufWriter::new(Box::new(io::stdout().lock())))
        } else if is_special(path) {
            Target::Direct(BufWriter::new(Box::new(open_special(path)?)))
        } else {
            Target::Temp(BufWriter::new(temp_beside(path)?))
        };
        Ok(AtomicOutput { target, path: path.into() })
    }

    /// The path being written.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// Flush and move the file into place.
    pub fn commit(self) -> Result<()> {
        let path = self.path;
        match self.target {
            Target::Direct(mut w) => w.flush().map_err(|e| DemError::io(path, e)),
            Target::Temp(w) => {
                let temp = w.into_inner().map_err(|e| DemError::io(path.as_str(), e.into_error()))?;
                temp.persist(resolve(&path)).map_err(|e| DemError::io(path.as_str(), e.error))?;
                Ok(())
            }
        }
    }
}

impl Write for AtomicOutput {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match &mut self.target {
            Target::Temp(w) => w.write(buf),
            Target::Direct(w) => w.write(buf),
        }
    }
    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        match &mut self.target {
            Target::Temp(w) => w.write_all(buf),
            Target::Direct(w) => w.write_all(buf),
        }
    }
    fn flush(&mut self) -> io::Result<()> {
        match &mut self.target {
            Target::Temp(w) => w.flush(),
            Target::Direct(w) => w.flush(),
        }
    }
}

/// Write a whole file atomically from a closure.
pub fn write_atomic(path: &str, body: impl FnOnce(&mut AtomicOutput) -> io::Result<()>) -> Result<()> {
    let mut out = AtomicOutput::create(path)?;
    body(&mut out).map_err(|e| DemError::io(path, e))?;
    out.commit()
}

/// True when `path` names an existing file (used to refuse clobbering inputs).
pub fn exists(path: &str) -> bool {
    path != "-" && Path::new(path).exists()
}
