//! Cut an NPY stream into shards of consecutive records: `PREFIX-00000.npy`,
//! `PREFIX-00001.npy`, ... (with `_labels.csv` beside each when labels are
//! given, re-indexed from 0, every other byte of a row kept), and a
//! manifest, one row per shard: `shard,first_index,records[,labels]`.
//! `first_index` is what the tools that draw random numbers per record take
//! as `--first-index`, so that `dem-split -> tool per shard -> dem-cat`
//! equals one run on the whole.
//!
//! All or nothing: [`stage`] writes every shard and its labels to a temp
//! file beside it and checks the whole (labels that cover the stream);
//! [`Staged::commit`] renames them into place and removes what an earlier
//! split to the same prefix left beyond the new shards. A failure or a
//! refusal before the commit removes the temp files and leaves every file
//! that was there untouched; a killed run leaves temp files only, which the
//! next run writing beside them removes.

use std::io::Write;
use std::os::unix::fs::MetadataExt;

use dem_core::raw_labels::{self as labels, LabelsReader};
use dem_core::{cli, npy, output, Dem, DemError};

/// How to cut.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cut {
    /// Shards of this many records (the last may be shorter).
    Records(u64),
    /// This many shards of equal size (within one record); needs a file.
    Shards(u64),
}

/// A validated request.
#[derive(Clone, Debug)]
pub struct SplitConfig {
    /// Input NPY stream (`-` for stdin).
    pub input: String,
    /// Labels CSV of the input, split alongside.
    pub labels: Option<String>,
    /// Shard file names start with this.
    pub prefix: String,
    /// How to cut.
    pub cut: Cut,
}

impl SplitConfig {
    /// The files the split reads: the input and its labels.
    pub fn inputs(&self) -> Vec<&str> {
        let mut inputs = vec![self.input.as_str()];
        inputs.extend(self.labels.as_deref());
        inputs
    }
}

/// One shard written.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Shard {
    /// Its NPY path.
    pub shard: String,
    /// Index of its first record in the whole stream.
    pub first_index: u64,
    /// Records in it.
    pub records: u64,
    /// Its labels CSV, when labels were given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub labels: Option<String>,
}

/// The path of shard `k`.
pub fn shard_path(prefix: &str, k: u64) -> String {
    format!("{prefix}-{k:05}.npy")
}

fn labels_path(prefix: &str, k: u64) -> String {
    format!("{prefix}-{k:05}_labels.csv")
}

/// Records per shard for `cut` over a stream of `total` records (when known).
fn shard_sizes(cut: Cut, total: Option<u64>) -> Result<impl Fn(u64) -> u64, DemError> {
    match (cut, total) {
        (Cut::Records(n), _) => Ok(Box::new(move |_| n) as Box<dyn Fn(u64) -> u64>),
        (Cut::Shards(k), Some(total)) => Ok(Box::new(move |i| total / k + u64::from(i < total % k)) as Box<dyn Fn(u64) -> u64>),
        (Cut::Shards(_), None) => {
            Err(DemError::Usage("--shards needs the stream's length: give a file, or cut stdin with --records".into()))
        }
    }
}

/// A split written to temp files beside its shards, checked whole, not yet
/// in place. [`Staged::commit`] puts it in place; dropped, its temp files
/// are removed and nothing else has changed.
pub struct Staged {
    shards: Vec<Shard>,
    /// Each temp file and the path it becomes.
    files: Vec<(tempfile::TempPath, String)>,
    prefix: String,
    with_labels: bool,
    inputs: Vec<String>,
}

/// Split as `cfg` asks, into temp files: see [`Staged`].
pub fn stage(cfg: &SplitConfig) -> Result<Staged, DemError> {
    let inputs = cfg.inputs();
    if inputs.iter().filter(|p| **p == "-").count() > 1 {
        return Err(DemError::Usage("only one input can be `-` (stdin)".into()));
    }
    let total = match (cfg.cut, cfg.input.as_str()) {
        (Cut::Shards(_), "-") => None,
        (Cut::Shards(_), path) => Some(npy::RecordIndex::build(path)?.len()),
        _ => None,
    };
    let size = shard_sizes(cfg.cut, total)?;
    let mut labels = cfg.labels.as_deref().map(LabelsReader::open).transpose()?;
    let labels_name = cfg.labels.as_deref().unwrap_or_default();
    let mut rdr = npy::open(&cfg.input)?;
    let mut staged = Staged {
        shards: Vec::new(),
        files: Vec::new(),
        prefix: cfg.prefix.clone(),
        with_labels: labels.is_some(),
        inputs: inputs.iter().map(|s| s.to_string()).collect(),
    };
    let mut chunk: Vec<Dem> = Vec::with_capacity(npy::CHUNK_RECORDS);
    let mut k = 0u64;
    loop {
        let want = size(k);
        if want == 0 {
            break; // more shards than records: the rest would be empty
        }
        let first = rdr.records_read();
        // Read the shard's first chunk before creating its file, so no
        // empty shard is written at the end of the stream.
        chunk.clear();
        if rdr.read_chunk(&mut chunk, want.min(npy::CHUNK_RECORDS as u64) as usize)? == 0 {
            break;
        }
        let path = shard_path(&cfg.prefix, k);
        let lpath = labels.as_ref().map(|_| labels_path(&cfg.prefix, k));
        // `-` is stdout here: a shard must not replace the manifest's file.
        let mut outs = vec!["-", path.as_str()];
        outs.extend(lpath.as_deref());
        output::check_outputs(&inputs, &outs)?;
        let temp = output::temp_beside(&path)?.into_temp_path();
        let temp_name = temp.to_string_lossy().into_owned();
        let named = |e: DemError| named_as(e, &temp_name, &path);
        let mut w = npy::create(&temp_name).map_err(named)?;
        let mut got = 0u64;
        loop {
            w.write(&chunk).map_err(named)?;
            got += chunk.len() as u64;
            chunk.clear();
            if got == want || rdr.read_chunk(&mut chunk, (want - got).min(npy::CHUNK_RECORDS as u64) as usize)? == 0 {
                break;
            }
        }
        w.finish().map_err(named)?;
        staged.files.push((temp, path.clone()));
        if let (Some(rows), Some(lp)) = (&mut labels, &lpath) {
            let io = |e| DemError::io(lp.as_str(), e);
            let mut out = std::io::BufWriter::new(output::temp_beside(lp)?);
            out.write_all(&rows.header()).map_err(io)?;
            for n in 0..got {
                let Some(row) = rows.next_row()? else {
                    return Err(DemError::input(
                        labels_name,
                        format!("has {} rows but {} has more records ({} so far)", rows.rows(), cfg.input, first + got),
                    ));
                };
                labels::write_row(&mut out, &row, n).map_err(io)?;
            }
            let temp = out.into_inner().map_err(|e| io(e.into_error()))?;
            staged.files.push((temp.into_temp_path(), lp.clone()));
        }
        staged.shards.push(Shard { shard: path, first_index: first, records: got, labels: lpath });
        k += 1;
    }
    if let Some(rows) = &mut labels {
        if rows.next_row()?.is_some() {
            while rows.next_row()?.is_some() {}
            dem_core::table::check_labels_cover(labels_name, rows.rows() as usize, &cfg.input, rdr.records_read())?;
        }
    }
    Ok(staged)
}

/// An error of the writer of temp file `temp`, naming `path`, the file the
/// user asked for.
fn named_as(e: DemError, temp: &str, path: &str) -> DemError {
    match e {
        DemError::Io { path: p, source } if p == temp => DemError::Io { path: path.into(), source },
        DemError::Open { path: p, source } if p == temp => DemError::Open { path: path.into(), source },
        DemError::Unwritable { path: p, record, reason } if p == temp => DemError::Unwritable { path: path.into(), record, reason },
        e => e,
    }
}

impl Staged {
    /// The shards, as the manifest lists them.
    pub fn shards(&self) -> &[Shard] {
        &self.shards
    }

    /// Move every shard and labels file into place, then remove the files
    /// an earlier split to the same prefix left beyond these shards (each
    /// named in one log line), so `PREFIX-*.npy` is this split. An input is
    /// never removed. A rename that fails stops here: the temp files not
    /// yet renamed are removed.
    pub fn commit(self) -> Result<(), DemError> {
        for (temp, path) in self.files {
            temp.persist(output::resolve(&path)).map_err(|e| DemError::io(path.as_str(), e.error))?;
        }
        remove_stale(&self.prefix, self.shards.len() as u64, self.with_labels, &self.inputs);
        Ok(())
    }
}

/// (device, inode) of an input (`-`: stdin), after links.
fn file_id(path: &str) -> Option<(u64, u64)> {
    let meta = if path == "-" {
        use std::os::fd::AsFd;
        let fd = std::io::stdin().as_fd().try_clone_to_owned().ok()?;
        std::fs::File::from(fd).metadata().ok()?
    } else {
        std::fs::metadata(path).ok()?
    };
    Some((meta.dev(), meta.ino()))
}

/// The files named as shards (`PREFIX-NNNNN.npy`) or their labels
/// (`PREFIX-NNNNN_labels.csv`) of a split of `count` shards, `with_labels`
/// or not, that it did not write: an earlier split's. Sorted.
fn stale_files(prefix: &str, count: u64, with_labels: bool) -> Vec<String> {
    let (dir, base) = match prefix.rfind('/') {
        Some(i) => (&prefix[..=i], &prefix[i + 1..]),
        None => ("", prefix),
    };
    let Ok(entries) = std::fs::read_dir(if dir.is_empty() { "." } else { dir }) else { return Vec::new() };
    let mut stale = Vec::new();
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(rest) = name.to_str().and_then(|n| n.strip_prefix(base)).and_then(|r| r.strip_prefix('-')) else { continue };
        let (digits, is_labels) = match (rest.strip_suffix(".npy"), rest.strip_suffix("_labels.csv")) {
            (Some(d), _) => (d, false),
            (None, Some(d)) => (d, true),
            (None, None) => continue,
        };
        let Some(k) = digits.parse::<u64>().ok().filter(|k| digits.bytes().all(|b| b.is_ascii_digit()) && format!("{k:05}") == digits)
        else {
            continue;
        };
        if (k >= count || (is_labels && !with_labels)) && !entry.file_type().is_ok_and(|t| t.is_dir()) {
            stale.push(format!("{dir}{}", name.to_string_lossy()));
        }
    }
    stale.sort();
    stale
}

/// Remove an earlier split's files beyond this one (see [`stale_files`]),
/// keeping any that is an input, and say so on stderr.
fn remove_stale(prefix: &str, count: u64, with_labels: bool, inputs: &[String]) {
    let input_ids: Vec<(u64, u64)> = inputs.iter().filter_map(|i| file_id(i)).collect();
    let mut removed = Vec::new();
    for path in stale_files(prefix, count, with_labels) {
        if file_id(&path).is_some_and(|id| input_ids.contains(&id)) {
            cli::log(format_args!("kept {path}, a file of an earlier split to this prefix: it is this run's input"));
            continue;
        }
        match std::fs::remove_file(&path) {
            Ok(()) => removed.push(path),
            Err(e) => cli::log(format_args!("warning: could not remove {path}, a file of an earlier split to this prefix: {e}")),
        }
    }
    if !removed.is_empty() {
        let list = if removed.len() <= 4 {
            removed.join(", ")
        } else {
            format!("{}, {}, ..., {}", removed[0], removed[1], removed[removed.len() - 1])
        };
        cli::log(format_args!(
            "removed {} file{} an earlier split to this prefix left beyond these {count} shards: {list}",
            removed.len(),
            if removed.len() == 1 { "" } else { "s" }
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stale_files_are_the_prefix_s_shards_beyond_the_count() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().to_string_lossy().into_owned();
        for f in [
            "p-00000.npy",
            "p-00001.npy",
            "p-00002.npy",
            "p-00002_labels.csv",
            "p-00001_labels.csv",
            "p-100000.npy",
            "p-0003.npy",
            "p-00003.npy.out",
            "q-00004.npy",
            "p-x-00004.npy",
            "pp-00004.npy",
        ] {
            std::fs::write(dir.path().join(f), b"").unwrap();
        }
        std::fs::create_dir(dir.path().join("p-00005.npy")).unwrap();
        let name = |v: Vec<String>| v.into_iter().map(|p| p.rsplit('/').next().unwrap().to_string()).collect::<Vec<_>>();
        let prefix = format!("{d}/p");
        assert_eq!(name(stale_files(&prefix, 2, true)), ["p-00002.npy", "p-00002_labels.csv", "p-100000.npy"]);
        assert_eq!(name(stale_files(&prefix, 2, false)), ["p-00001_labels.csv", "p-00002.npy", "p-00002_labels.csv", "p-100000.npy"]);
        assert!(stale_files(&prefix, 200_000, true).is_empty());
    }
}
