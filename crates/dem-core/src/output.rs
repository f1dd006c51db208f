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
/// `.NAME.HOST-PID.XXXXXX.tmp`. Temp files of that naming left by a killed
/// run of this host (their process is gone) are removed first, with a log
/// line: a `kill -9` costs no disk for longer than the next run.
pub fn temp_beside(path: &str) -> Result<tempfile::NamedTempFile> {
    let resolved = resolve(path);
    let target = resolved.as_path();
    let dir = match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let name = target.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    remove_stale_temps(dir);
    // 0o666 minus the umask, like any file a tool creates; tempfile's
    // default 0o600 would hide outputs from the rest of a team.
    tempfile::Builder::new()
        .permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666))
        .prefix(&format!(".{name}.{}-{}.", host(), std::process::id()))
        .suffix(".tmp")
        .tempfile_in(dir)
        .map_err(|source| DemError::Open { path: path.into(), source })
}

/// This machine's name, so a folder shared over the network never loses a
/// temp file another machine is still writing.
fn host() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().replace(['/', '.'], "_"))
        .ok()
        .filter(|h| !h.is_empty())
        .unwrap_or_else(|| "host".into())
}

/// The pid in a temp file name of ours (`.NAME.HOST-PID.XXXXXX.tmp`) written
/// by `host`; `name`, when given, must be the output's name.
fn temp_owner(file: &str, name: Option<&str>, host: &str) -> Option<u32> {
    let rest = file.strip_prefix('.')?.strip_suffix(".tmp")?;
    let (head, _random) = rest.rsplit_once('.')?;
    let (out_name, owner) = head.rsplit_once('.')?;
    if name.is_some_and(|n| n != out_name) {
        return None;
    }
    let (h, pid) = owner.rsplit_once('-')?;
    (h == host).then(|| pid.parse().ok()).flatten()
}

/// Remove this host's temp files of ours in `dir` whose process is gone.
/// Once per folder in a process: a tool writing many files into one folder
/// (dem-split's shards) scans it once.
fn remove_stale_temps(dir: &Path) {
    static SCANNED: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());
    {
        let mut seen = SCANNED.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if seen.iter().any(|d| d == dir) {
            return;
        }
        seen.push(dir.to_path_buf());
    }
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    let host = host();
    for entry in entries.flatten() {
        let file = entry.file_name().to_string_lossy().into_owned();
        let Some(pid) = temp_owner(&file, None, &host) else { continue };
        // Without /proc we cannot tell a live writer from a dead one: keep it.
        if !Path::new("/proc/self").exists() || Path::new(&format!("/proc/{pid}")).exists() {
            continue;
        }
        if std::fs::remove_file(entry.path()).is_ok() {
            crate::cli::log(format_args!("removed {}, a temp file left by a killed run (pid {pid})", entry.path().display()));
        }
    }
}

/// Check, before any work, the outputs a tool is about to write: each can be
/// created (its folder exists and takes files, it is not a folder), none is
/// one of the inputs (also through a link, or as a redirected stdout: `-`
/// stands for stdin among inputs and stdout among outputs), and no two are
/// the same file. Refusals are usage errors (exit 2), naming both paths.
pub fn check_outputs(inputs: &[&str], outputs: &[&str]) -> Result<()> {
    use std::os::unix::fs::MetadataExt;
    let id = |path: &str, is_output: bool| -> Option<(u64, u64)> {
        let meta = if path == "-" {
            let fd = if is_output { std_fd(1) } else { std_fd(0) }?;
            fd.metadata().ok()?
        } else {
            std::fs::metadata(path).ok()?
        };
        // Devices and FIFOs (`/dev/null`) are written in place, never replaced.
        meta.is_file().then(|| (meta.dev(), meta.ino()))
    };
    let name = |path: &str, is_output: bool| match (path, is_output) {
        ("-", true) => "stdout".to_string(),
        ("-", false) => "stdin".to_string(),
        (p, _) => p.to_string(),
    };
    for (k, &out) in outputs.iter().enumerate() {
        if out != "-" {
            if Path::new(out).is_dir() {
                return Err(DemError::Usage(format!("output {out} is a folder, not a file")));
            }
            if !is_special(out) {
                drop(temp_beside(out)?);
            }
        }
        let Some(out_id) = id(out, true) else { continue };
        if let Some(i) = inputs.iter().find(|&&i| id(i, false) == Some(out_id)) {
            return Err(DemError::Usage(format!("output {} would overwrite the input {}", name(out, true), name(i, false))));
        }
        if let Some(o) = outputs[..k].iter().find(|&&o| id(o, true) == Some(out_id) || (o == out && o != "-")) {
            return Err(DemError::Usage(format!("two outputs are the same file: {} and {out}", name(o, true))));
        }
    }
    // Outputs that do not exist yet can still collide by name.
    for (k, &out) in outputs.iter().enumerate() {
        if out != "-" && outputs[..k].contains(&out) {
            return Err(DemError::Usage(format!("the output {out} is given twice")));
        }
    }
    Ok(())
}

/// A duplicate of stdin (0) or stdout (1) as a `File`, for its metadata.
fn std_fd(fd: i32) -> Option<std::fs::File> {
    use std::os::fd::AsFd;
    let owned = match fd {
        0 => io::stdin().as_fd().try_clone_to_owned().ok()?,
        _ => io::stdout().as_fd().try_clone_to_owned().ok()?,
    };
    Some(std::fs::File::from(owned))
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

/// A folder of outputs, made when missing: a run that fails (or a probe
/// that only checks it) removes it again on drop when it made it and it is
/// still empty, so a refused input leaves no folder behind. [`keep`] it once
/// the run has written into it.
///
/// [`keep`]: OutputFolder::keep
pub struct OutputFolder {
    path: PathBuf,
    made: bool,
}

impl OutputFolder {
    /// Make `dir` (and its parents) when missing.
    pub fn create(dir: &str) -> Result<Self> {
        let made = !Path::new(dir).exists();
        std::fs::create_dir_all(dir).map_err(|source| DemError::Open { path: dir.to_string(), source })?;
        Ok(OutputFolder { path: PathBuf::from(dir), made })
    }

    /// The outputs `names` in the folder, as [`check_outputs`] checks them
    /// against `inputs`.
    pub fn check(&self, inputs: &[&str], names: &[&str]) -> Result<()> {
        let outputs: Vec<String> = names.iter().map(|n| self.path.join(n).to_string_lossy().into_owned()).collect();
        check_outputs(inputs, &outputs.iter().map(String::as_str).collect::<Vec<_>>())
    }

    /// Leave the folder in place.
    pub fn keep(mut self) {
        self.made = false;
    }
}

impl Drop for OutputFolder {
    fn drop(&mut self) {
        if self.made {
            // Only an empty folder goes: remove_dir refuses any other.
            let _ = std::fs::remove_dir(&self.path);
        }
    }
}

/// True when `path` names an existing file (used to refuse clobbering inputs).
pub fn exists(path: &str) -> bool {
    path != "-" && Path::new(path).exists()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_output_folder_made_for_a_probe_or_a_failed_run_is_removed_a_kept_one_stays() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("a/b").to_string_lossy().into_owned();
        let folder = OutputFolder::create(&out).unwrap();
        folder.check(&[], &["x.npy", "y.csv"]).unwrap();
        drop(folder);
        assert!(!Path::new(&out).exists(), "a probe leaves no folder");
        OutputFolder::create(&out).unwrap().keep();
        assert!(Path::new(&out).is_dir(), "a kept folder stays");
        // Existing, it is never removed, empty or not.
        drop(OutputFolder::create(&out).unwrap());
        assert!(Path::new(&out).is_dir());
        let made = OutputFolder::create(&dir.path().join("c").to_string_lossy()).unwrap();
        let err = made.check(&[], &["x.npy", "x.npy"]).unwrap_err();
        assert!(err.to_string().contains("is given twice"), "{err}");
        drop(made);
        assert!(!dir.path().join("c").exists());
    }

    #[test]
    fn temp_names_carry_host_and_pid_and_parse_back() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("x.npy").to_string_lossy().into_owned();
        let t = temp_beside(&out).unwrap();
        let file = t.path().file_name().unwrap().to_string_lossy().into_owned();
        assert_eq!(temp_owner(&file, Some("x.npy"), &host()), Some(std::process::id()));
        assert_eq!(temp_owner(&file, Some("y.npy"), &host()), None);
        assert_eq!(temp_owner(&file, Some("x.npy"), "elsewhere"), None);
        assert_eq!(temp_owner(&file, None, &host()), Some(std::process::id()));
        assert_eq!(temp_owner(".notes.txt", None, &host()), None);
    }

    #[test]
    fn stale_temps_of_dead_processes_go_live_ones_stay() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("x.npy").to_string_lossy().into_owned();
        // pid 4194304 is above Linux's pid_max, so never alive.
        let dead = dir.path().join(format!(".x.npy.{}-4194304.abc123.tmp", host()));
        let alive = dir.path().join(format!(".x.npy.{}-{}.def456.tmp", host(), std::process::id()));
        let other_host = dir.path().join(".x.npy.far_away-4194304.ghi789.tmp");
        for p in [&dead, &alive, &other_host] {
            std::fs::write(p, b"partial").unwrap();
        }
        drop(temp_beside(&out).unwrap());
        assert!(!dead.exists());
        assert!(alive.exists() && other_host.exists());
    }

    #[test]
    fn outputs_never_name_an_input_or_each_other() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.npy").to_string_lossy().into_owned();
        let b = dir.path().join("b.npy").to_string_lossy().into_owned();
        std::fs::write(&a, b"x").unwrap();
        let link = dir.path().join("l.npy");
        std::os::unix::fs::symlink(&a, &link).unwrap();
        let link = link.to_string_lossy().into_owned();
        assert!(check_outputs(&[&a], &[&b]).is_ok());
        assert!(check_outputs(&[&a], &[&a]).unwrap_err().to_string().contains("would overwrite the input"));
        assert!(check_outputs(&[&a], &[&link]).is_err());
        assert!(check_outputs(&[], &[&b, &b]).unwrap_err().to_string().contains("twice"));
        let d = dir.path().to_string_lossy().into_owned();
        assert!(check_outputs(&[], &[&d]).unwrap_err().to_string().contains("folder"));
        let missing = dir.path().join("no/such/x.npy").to_string_lossy().into_owned();
        assert_eq!(check_outputs(&[], &[&missing]).unwrap_err().exit_code(), 2);
    }
}
