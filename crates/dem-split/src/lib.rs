//! Cut an NPY stream into shards of consecutive records: `PREFIX-00000.npy`,
//! `PREFIX-00001.npy`, ... (with `_labels.csv` beside each when labels are
//! given, re-indexed from 0), and a manifest, one row per shard:
//! `shard,first_index,records[,labels]`. `first_index` is what the tools that
//! draw random numbers per record take as `--first-index`, so that
//! `dem-split -> tool per shard -> dem-cat` equals one run on the whole.
//!
//! All or nothing: a failure (bad input, full disk) removes the shards
//! already written.

use dem_core::table::{self, Label, RowWriter};
use dem_core::{npy, output, Dem, DemError};

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
        (Cut::Shards(_), None) => Err(DemError::Usage("--shards needs the stream's length: give a file, or cut stdin with --records".into())),
    }
}

/// Split as `cfg` asks; returns the shards written.
pub fn split(cfg: &SplitConfig) -> Result<Vec<Shard>, DemError> {
    let mut written: Vec<Shard> = Vec::new();
    let outcome = split_into(cfg, &mut written);
    if outcome.is_err() {
        for s in &written {
            let _ = std::fs::remove_file(&s.shard);
            if let Some(l) = &s.labels {
                let _ = std::fs::remove_file(l);
            }
        }
    }
    outcome.map(|()| written)
}

fn split_into(cfg: &SplitConfig, written: &mut Vec<Shard>) -> Result<(), DemError> {
    let total = match (cfg.cut, cfg.input.as_str()) {
        (Cut::Shards(_), "-") => None,
        (Cut::Shards(_), path) => Some(npy::RecordIndex::build(path)?.len()),
        _ => None,
    };
    let size = shard_sizes(cfg.cut, total)?;
    let labels: Option<Vec<Label>> = cfg.labels.as_deref().map(table::read_labels).transpose()?;
    let mut inputs = vec![cfg.input.as_str()];
    inputs.extend(cfg.labels.as_deref());
    let mut rdr = npy::open(&cfg.input)?;
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
        let mut outs = vec![path.as_str()];
        outs.extend(lpath.as_deref());
        output::check_outputs(&inputs, &outs)?;
        let mut w = npy::create(&path)?;
        let mut got = 0u64;
        loop {
            w.write(&chunk)?;
            got += chunk.len() as u64;
            chunk.clear();
            if got == want || rdr.read_chunk(&mut chunk, (want - got).min(npy::CHUNK_RECORDS as u64) as usize)? == 0 {
                break;
            }
        }
        if let (Some(all), Some(lp)) = (&labels, &lpath) {
            let end = first + got;
            if all.len() < end as usize {
                return Err(DemError::input(cfg.labels.as_deref().unwrap_or_default(), format!("has {} rows but {} has more records ({end} so far)", all.len(), cfg.input)));
            }
            let mut lw = RowWriter::create(lp)?;
            for (n, l) in all[first as usize..end as usize].iter().enumerate() {
                lw.write(&Label { index: n as u64, ..l.clone() })?;
            }
            lw.commit()?;
        }
        w.finish()?;
        written.push(Shard { shard: path, first_index: first, records: got, labels: lpath });
        k += 1;
    }
    if let (Some(all), Some(path)) = (&labels, &cfg.labels) {
        table::check_labels_cover(path, all.len(), &cfg.input, rdr.records_read())?;
    }
    Ok(())
}
