//! Which records a picture shows, read from NPY streams without holding the
//! whole file, and the per-column captions read from a CSV.
//!
//! Every file is read to its end (a chunk at a time), so a truncated or
//! malformed stream is refused even when the records asked for come first,
//! and the record count is known for the messages and for `--compare`'s
//! same-length check.

use std::collections::HashMap;

use dem_core::error::{DemError, Result};
use dem_core::format::{Dem, Terrain};
use dem_core::npy;

/// Most records one picture may show; more makes an unreadable picture
/// (and a huge PNG). Split larger sets with `--start`.
pub const MAX_RECORDS: usize = 400;

/// The records to draw, by zero-based index.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Selection {
    /// `count` records from `start`, clipped to the data like `head`.
    Range {
        /// First record.
        start: u64,
        /// How many.
        count: u64,
    },
    /// These records, in this order (repeats allowed).
    Indices(Vec<u64>),
}

impl Selection {
    /// Check the size against [`MAX_RECORDS`] and emptiness.
    pub fn validate(&self) -> Result<()> {
        let n = match self {
            Selection::Range { count, .. } => *count,
            Selection::Indices(v) => v.len() as u64,
        };
        if n == 0 {
            return Err(DemError::Usage("nothing to draw: the selection is empty".into()));
        }
        if n > MAX_RECORDS as u64 {
            return Err(DemError::Usage(format!(
                "{n} records asked for; one picture shows at most {MAX_RECORDS} (split with --start/--count)"
            )));
        }
        Ok(())
    }
}

/// Records of one file picked by a [`Selection`].
#[derive(Debug, Clone)]
pub struct Picked {
    /// The index of each picked record, in drawing order.
    pub indices: Vec<u64>,
    /// The records, in drawing order.
    pub records: Vec<Dem>,
    /// Records in the whole file.
    pub total: u64,
}

/// Read `path` (`-` is stdin) to its end and keep the selected records.
/// Errors name the file: missing, malformed, empty, or an index past its end.
pub fn read_selected(path: &str, selection: &Selection) -> Result<Picked> {
    let (total, kept) = match selection {
        Selection::Range { start, count } => npy::read_selected(path, |i| i >= *start && i - start < *count)?,
        Selection::Indices(v) => {
            let wanted: std::collections::HashSet<u64> = v.iter().copied().collect();
            npy::read_selected(path, |i| wanted.contains(&i))?
        }
    };
    if total == 0 {
        return Err(DemError::input(path, "holds no records; nothing to draw"));
    }
    let indices: Vec<u64> = match selection {
        Selection::Range { start, .. } if *start >= total => {
            return Err(DemError::input(path, format!("--start {start} is past the last record ({} records, 0..={})", total, total - 1)));
        }
        Selection::Range { start, count } => (*start..(start + count).min(total)).collect(),
        Selection::Indices(v) => v.clone(),
    };
    let mut records = Vec::with_capacity(indices.len());
    for &i in &indices {
        match kept.get(&i) {
            Some(d) => records.push(*d),
            None => {
                return Err(DemError::input(path, format!("record {i} asked for, but the file holds {total} records (0..={})", total - 1)))
            }
        }
    }
    Ok(Picked { indices, records, total })
}

/// `--per-terrain K`: for each terrain, in [`Terrain::ALL`] order, the
/// records at K evenly spaced places among that terrain's records (the
/// j-th of n at j = floor(n k / (K + 1)), k = 1..K, each once), from the
/// `terrain` column of the CSV at `path`, whose rows are the input's
/// records in order (a labels CSV, or dem-eval's `--emit-records` file).
/// Terrains without records are skipped.
pub fn per_terrain(path: &str, k: usize) -> Result<Vec<u64>> {
    let mut rdr = csv::ReaderBuilder::new().trim(csv::Trim::All).from_reader(dem_core::table::open_input(path)?);
    let bad = |line: u64, reason: String| DemError::Table { path: path.into(), line, reason };
    let headers = rdr.headers().map_err(|e| bad(1, e.to_string()))?.clone();
    let col = headers
        .iter()
        .position(|h| h == "terrain")
        .ok_or_else(|| bad(1, format!("no terrain column (columns: {})", headers.iter().collect::<Vec<_>>().join(","))))?;
    let mut of: HashMap<Terrain, Vec<u64>> = HashMap::new();
    for (i, rec) in rdr.records().enumerate() {
        let line = i as u64 + 2;
        let rec = rec.map_err(|e| bad(e.position().map_or(line, |p| p.line()), e.to_string()))?;
        let t: Terrain = rec.get(col).unwrap_or("").parse().map_err(|e: String| bad(line, e))?;
        of.entry(t).or_default().push(i as u64);
    }
    let mut picked = Vec::new();
    for t in Terrain::ALL {
        let Some(rows) = of.get(&t) else { continue };
        let n = rows.len();
        let mut at: Vec<usize> = (1..=k).map(|j| n * j / (k + 1)).collect();
        at.dedup();
        picked.extend(at.into_iter().map(|j| rows[j]));
    }
    Ok(picked)
}

/// One caption per drawn column from column `column` (default: the last)
/// of the CSV at `path`. When the CSV's first column is `index`, rows are
/// matched to records by that index; otherwise row k (after the header)
/// captions the k-th drawn column and the row count must match. Numbers
/// are shown with 3 decimals (integers as they are), text as it is.
/// Returns the column's name and the captions.
pub fn read_captions(path: &str, column: Option<&str>, indices: &[u64]) -> Result<(String, Vec<String>)> {
    let src = dem_core::table::open_input(path)?;
    let mut rdr = csv::ReaderBuilder::new().trim(csv::Trim::All).from_reader(src);
    let bad = |line: u64, reason: String| DemError::Table { path: path.into(), line, reason };
    let headers = rdr.headers().map_err(|e| bad(1, e.to_string()))?.clone();
    let names: Vec<&str> = headers.iter().collect();
    let col = match column {
        Some(name) => {
            names.iter().position(|h| *h == name).ok_or_else(|| bad(1, format!("no column {name:?} (columns: {})", names.join(","))))?
        }
        None if names.is_empty() => return Err(bad(1, "no columns".into())),
        None => names.len() - 1,
    };
    let by_index = names.first() == Some(&"index");
    let name = names[col].to_string();
    let mut rows: Vec<(u64, String)> = Vec::new();
    for (k, rec) in rdr.records().enumerate() {
        let line = k as u64 + 2;
        let rec = rec.map_err(|e| bad(e.position().map_or(line, |p| p.line()), e.to_string()))?;
        let value = rec.get(col).ok_or_else(|| bad(line, format!("no value in column {}", names[col])))?;
        let key = if by_index {
            rec[0].parse::<u64>().map_err(|_| bad(line, format!("index {:?} is not a record number", &rec[0])))?
        } else {
            k as u64
        };
        rows.push((key, format_caption(value)));
    }
    if by_index {
        let map: HashMap<u64, String> = rows.into_iter().collect();
        let captions = indices
            .iter()
            .map(|i| map.get(i).cloned().ok_or_else(|| DemError::input(path, format!("no row for record {i}"))))
            .collect::<Result<_>>()?;
        Ok((name, captions))
    } else if rows.len() != indices.len() {
        Err(DemError::input(
            path,
            format!(
                "{} caption rows for {} drawn columns (give one row per column, or an `index` first column)",
                rows.len(),
                indices.len()
            ),
        ))
    } else {
        Ok((name, rows.into_iter().map(|r| r.1).collect()))
    }
}

/// A CSV cell as a caption: integers as they are, other numbers with 3
/// decimals, text unchanged.
pub fn format_caption(value: &str) -> String {
    if value.parse::<i64>().is_ok() {
        return value.to_string();
    }
    match value.parse::<f64>() {
        Ok(v) if v.is_finite() => format!("{v:.3}"),
        _ => value.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::format::{empty_dem, DemCells};

    fn file(dir: &tempfile::TempDir, n: usize) -> String {
        let p = dir.path().join("d.npy").to_string_lossy().into_owned();
        let recs: Vec<Dem> = (0..n)
            .map(|i| {
                let mut d = empty_dem();
                d.set_valid(0, 0, i as f32);
                d
            })
            .collect();
        npy::write_all(&p, &recs).unwrap();
        p
    }

    #[test]
    fn picks_ranges_and_indices_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let p = file(&dir, 10);
        let got = read_selected(&p, &Selection::Range { start: 7, count: 24 }).unwrap();
        assert_eq!((got.indices, got.total), (vec![7, 8, 9], 10));
        let got = read_selected(&p, &Selection::Indices(vec![9, 2, 2])).unwrap();
        let heights: Vec<f32> = got.records.iter().map(|d| d.height(0, 0)).collect();
        assert_eq!(heights, [9.0, 2.0, 2.0]);
    }

    #[test]
    fn refuses_indices_past_the_end_naming_file_and_record() {
        let dir = tempfile::tempdir().unwrap();
        let p = file(&dir, 10);
        let e = read_selected(&p, &Selection::Indices(vec![3, 10])).unwrap_err().to_string();
        assert!(e.contains(&p) && e.contains("record 10") && e.contains("10 records"), "{e}");
        let e = read_selected(&p, &Selection::Range { start: 10, count: 1 }).unwrap_err().to_string();
        assert!(e.contains("--start 10"), "{e}");
        assert!(Selection::Range { start: 0, count: 401 }.validate().is_err());
        assert!(Selection::Indices(vec![]).validate().is_err());
    }

    #[test]
    fn captions_by_index_or_by_row() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.csv").to_string_lossy().into_owned();
        std::fs::write(&p, "index,terrain,error\n4,flat,0.12345\n7,pallet,2\n").unwrap();
        let (name, got) = read_captions(&p, None, &[7, 4]).unwrap();
        assert_eq!((name.as_str(), got), ("error", vec!["2".to_string(), "0.123".to_string()]));
        assert_eq!(read_captions(&p, Some("terrain"), &[4]).unwrap().1, ["flat"]);
        assert!(read_captions(&p, None, &[5]).unwrap_err().to_string().contains("record 5"));
        assert!(read_captions(&p, Some("nope"), &[4]).unwrap_err().to_string().contains("\"nope\""));
        std::fs::write(&p, "sim_index,real_index,distance\n4,0,0.5\n7,1,0.25\n").unwrap();
        assert_eq!(read_captions(&p, None, &[0, 1]).unwrap().1, ["0.500", "0.250"]);
        assert!(read_captions(&p, None, &[0]).unwrap_err().to_string().contains("2 caption rows"));
    }
}
