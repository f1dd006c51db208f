//! The CSV tables of the contract: labels (per-record metadata), pairs (sim
//! to real records) and index lists. Readers check the header and every row
//! and name the line that breaks; writers are atomic for files.

use serde::{de::DeserializeOwned, Deserialize, Serialize};

use crate::error::{DemError, Result};
use crate::format::Terrain;
use crate::output::AtomicOutput;

/// One row of a labels CSV: `index,terrain[,x,y,yaw,sequence,time]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Label {
    /// Zero-based record index in the NPY file the labels belong to.
    pub index: u64,
    /// Terrain class.
    #[serde(with = "terrain_serde")]
    pub terrain: Terrain,
    /// Robot position in the world, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub x: Option<f64>,
    /// Robot position in the world, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub y: Option<f64>,
    /// Robot heading in the world, radians.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub yaw: Option<f64>,
    /// Run (trajectory) the record belongs to.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sequence: Option<u64>,
    /// Time since the start of the run, seconds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time: Option<f64>,
}

/// Train or validation half of a pairs CSV (also a command-line value:
/// `train`, `val`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Split {
    /// Used for training.
    Train,
    /// Held out for validation.
    Val,
}

impl std::fmt::Display for Split {
    /// The name a pairs CSV and the `--split` flag use: `train`, `val`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Split::Train => "train",
            Split::Val => "val",
        })
    }
}

/// One row of a pairs CSV: `sim_index,real_index[,split][,distance]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Pair {
    /// Record index in the sim NPY file.
    pub sim_index: u64,
    /// Record index in the real NPY file.
    pub real_index: u64,
    /// Train or val.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub split: Option<Split>,
    /// How the pair was found (pose distance or content error).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distance: Option<f64>,
}

/// One row of an index CSV: `index[,other columns]`; extra columns are ignored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct IndexRow {
    /// Zero-based record index.
    pub index: u64,
}

mod terrain_serde {
    use crate::format::Terrain;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(t: &Terrain, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(t.as_str())
    }
    /// An empty terrain (what dem-import writes for a recording nobody
    /// labelled) reads as `other`: not one of the classes data preparation
    /// keeps.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Terrain, D::Error> {
        let s = <std::borrow::Cow<'de, str>>::deserialize(d)?;
        if s.is_empty() {
            return Ok(Terrain::Other);
        }
        s.parse().map_err(serde::de::Error::custom)
    }
}

/// Open a table for reading: the file at `path`, or stdin for `-`. The one
/// place a CSV input is opened, so every tool reads `-` the same way.
pub fn open_input(path: &str) -> Result<Box<dyn std::io::Read>> {
    if path == "-" {
        return Ok(Box::new(std::io::stdin().lock()));
    }
    let file = std::fs::File::open(path).map_err(|source| DemError::Open { path: path.into(), source })?;
    Ok(Box::new(std::io::BufReader::new(file)))
}

/// Read every row of a CSV at `path` (`-` for stdin), checking that the
/// header starts with `required` columns.
pub fn read_rows<T: DeserializeOwned>(path: &str, required: &[&str]) -> Result<Vec<T>> {
    let mut out = Vec::new();
    for_each_row(path, required, |_, row| {
        out.push(row);
        Ok(())
    })?;
    Ok(out)
}

/// Read a CSV at `path` (`-` for stdin) a row at a time, checking that the
/// header starts with `required` columns, and hand each row to `f` with its
/// line number (of the row's first line), so a caller's own checks of a
/// row's values can name the line as the reader's do.
pub fn for_each_row<T: DeserializeOwned>(path: &str, required: &[&str], mut f: impl FnMut(u64, T) -> Result<()>) -> Result<()> {
    let src = open_input(path)?;
    let mut rdr = csv::ReaderBuilder::new().trim(csv::Trim::All).from_reader(src);
    let bad = |line: u64, reason: String| DemError::Table { path: path.into(), line, reason };
    let headers = rdr.headers().map_err(|e| bad(1, e.to_string()))?.clone();
    for (i, want) in required.iter().enumerate() {
        if headers.get(i) != Some(*want) {
            return Err(bad(
                1,
                format!("header must start with {}, found {}", required.join(","), headers.iter().collect::<Vec<_>>().join(",")),
            ));
        }
    }
    let csv_err = |e: csv::Error| {
        let line = e.position().map_or(0, |p| p.line());
        let reason = match e.kind() {
            csv::ErrorKind::Deserialize { err, .. } => err.to_string(),
            _ => e.to_string(),
        };
        bad(line, reason)
    };
    let mut rec = csv::StringRecord::new();
    while rdr.read_record(&mut rec).map_err(csv_err)? {
        let line = rec.position().map_or(0, |p| p.line());
        let row: T = rec.deserialize(Some(&headers)).map_err(csv_err)?;
        f(line, row)?;
    }
    Ok(())
}

/// Write rows as CSV to `path` (`-` for stdout), atomically for files.
pub fn write_rows<T: Serialize>(path: &str, rows: &[T]) -> Result<()> {
    let mut w = RowWriter::create(path)?;
    for row in rows {
        w.write(row)?;
    }
    w.commit()
}

/// A CSV written a row at a time to `path` (`-` for stdout): memory stays
/// one row, and a named file appears, whole, on [`RowWriter::commit`] only.
pub struct RowWriter {
    w: csv::Writer<AtomicOutput>,
    path: String,
}

impl RowWriter {
    /// Start writing `path`.
    pub fn create(path: &str) -> Result<Self> {
        Ok(RowWriter { w: csv::Writer::from_writer(AtomicOutput::create(path)?), path: path.into() })
    }

    /// Append one row (the header goes before the first).
    pub fn write<T: Serialize>(&mut self, row: &T) -> Result<()> {
        self.w.serialize(row).map_err(|e| DemError::io(self.path.as_str(), csv_io(e)))
    }

    /// Flush and move the file into place.
    pub fn commit(self) -> Result<()> {
        let out = self.w.into_inner().map_err(|e| DemError::io(self.path.as_str(), e.into_error()))?;
        out.commit()
    }
}

/// The I/O error inside a CSV writer's error (so a closed pipe stays a
/// closed pipe), or the CSV error itself.
fn csv_io(e: csv::Error) -> std::io::Error {
    if matches!(e.kind(), csv::ErrorKind::Io(_)) {
        if let csv::ErrorKind::Io(io) = e.into_kind() {
            return io;
        }
        unreachable!("checked above");
    }
    std::io::Error::other(e)
}

/// Read a labels CSV; rows must be indexed 0, 1, 2, ... in order.
pub fn read_labels(path: &str) -> Result<Vec<Label>> {
    let rows: Vec<Label> = read_rows(path, &["index", "terrain"])?;
    for (i, row) in rows.iter().enumerate() {
        if row.index != i as u64 {
            return Err(DemError::Table {
                path: path.into(),
                line: i as u64 + 2,
                reason: format!("index {} out of order (expected {i})", row.index),
            });
        }
    }
    Ok(rows)
}

/// Read a pairs CSV.
pub fn read_pairs(path: &str) -> Result<Vec<Pair>> {
    read_rows(path, &["sim_index", "real_index"])
}

/// Check that a labels file of `rows` rows covers the `records` records of
/// `npy_path` exactly, one row each; else an error naming the labels file.
pub fn check_labels_cover(labels_path: &str, rows: usize, npy_path: &str, records: u64) -> Result<()> {
    if rows as u64 != records {
        return Err(DemError::input(labels_path, format!("has {rows} rows but {npy_path} has {records} records")));
    }
    Ok(())
}

/// Read a pairs CSV that is to give the pairs of `split` (all with None):
/// a `split` asked of a file without the column is an error naming it.
/// Every row is returned (a caller range-checks them all).
pub fn read_pairs_for(path: &str, split: Option<Split>) -> Result<Vec<Pair>> {
    let all = read_pairs(path)?;
    if split.is_some() && all.iter().all(|p| p.split.is_none()) {
        return Err(DemError::input(path, "has no split column for --split (dem-pair writes one)"));
    }
    Ok(all)
}

/// The error of a pairs file that holds no pair of `split` to `verb`
/// ("evaluate", "expand").
pub fn no_pairs(path: &str, split: Option<Split>, verb: &str) -> DemError {
    let which = split.map_or(String::new(), |s| format!(" of split {s}"));
    DemError::input(path, format!("holds no pairs{which} to {verb}"))
}

/// Read an index CSV.
pub fn read_index(path: &str) -> Result<Vec<u64>> {
    Ok(read_rows::<IndexRow>(path, &["index"])?.into_iter().map(|r| r.index).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_round_trip_and_bad_rows_name_the_line() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("l.csv").to_string_lossy().into_owned();
        let rows = vec![
            Label { index: 0, terrain: Terrain::Pallet, x: Some(1.5), y: Some(0.0), yaw: Some(0.1), sequence: Some(3), time: Some(0.2) },
            Label {
                index: 1,
                terrain: Terrain::StairsDown,
                x: Some(1.6),
                y: Some(0.0),
                yaw: Some(0.1),
                sequence: Some(3),
                time: Some(0.4),
            },
        ];
        write_rows(&p, &rows).unwrap();
        assert_eq!(read_labels(&p).unwrap(), rows);

        std::fs::write(&p, "index,terrain\n0,flat\n1,lava\n").unwrap();
        let e = read_labels(&p).unwrap_err().to_string();
        assert!(e.contains("line 3") && e.contains("lava"), "{e}");
        std::fs::write(&p, "index,terrain,x\n0,,1.5\n").unwrap();
        assert_eq!(read_labels(&p).unwrap()[0].terrain, Terrain::Other);
        std::fs::write(&p, "idx,terrain\n0,flat\n").unwrap();
        assert!(read_labels(&p).unwrap_err().to_string().contains("line 1"));
    }

    #[test]
    fn pairs_accept_optional_columns() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("p.csv").to_string_lossy().into_owned();
        std::fs::write(&p, "sim_index,real_index,split,distance\n3,0,val,0.1\n4,1,train,0.2\n").unwrap();
        let pairs = read_pairs(&p).unwrap();
        assert_eq!(pairs[0].split, Some(Split::Val));
        std::fs::write(&p, "sim_index,real_index\n3,0\n").unwrap();
        assert_eq!(read_pairs(&p).unwrap()[0].split, None);
        std::fs::write(&p, "sim_index,real_index\n3,-1\n").unwrap();
        assert!(read_pairs(&p).unwrap_err().to_string().contains("line 2"));
    }

    #[test]
    fn rows_come_with_the_line_they_start_on() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("i.csv").to_string_lossy().into_owned();
        std::fs::write(&p, "index,note\n4,\"two\nlines\"\n7,x\n").unwrap();
        let mut seen = Vec::new();
        for_each_row(&p, &["index"], |line, r: IndexRow| {
            seen.push((line, r.index));
            Ok(())
        })
        .unwrap();
        assert_eq!(seen, [(2, 4), (4, 7)]);
    }
}
