//! Validation tables of the pair error (the thesis's tables 7.x) and their
//! comparison against a baseline.
//!
//! For every sim record of a selection (the sim side of a pairs CSV, often
//! its `val` split) a prediction p is scored by its pair error, the smallest
//! equation 7.1 error against the real records paired with it
//! ([`crate::metric::pair_error`]). A [`TableRow`] summarises a method over
//! those records: count, lowest, highest, mean and median (numpy's median:
//! the mean of the two middle values for an even count), all in f64.
//!
//! ```
//! use dem_core::eval::Stats;
//! let s = Stats::of(&[0.4, 0.1, 0.3, 0.2]).unwrap();
//! assert_eq!((s.count, s.lowest, s.highest), (4, 0.1, 0.4));
//! assert!((s.mean - 0.25).abs() < 1e-15 && (s.median - 0.25).abs() < 1e-15);
//! ```
//!
//! Tables are written as CSV, `method,terrain,count,lowest,highest,mean,median`
//! (the `terrain` of a row over every record is `all`), and read back by
//! [`read_table_csv`], which skips repeated header lines so tables join with
//! `cat`. [`compare`] matches two tables by (method, terrain) and marks a row
//! worse when its mean or median grew by more than an absolute tolerance.

use std::collections::{BTreeMap, HashMap};

use serde::{Deserialize, Serialize};

use crate::error::{DemError, Result};
use crate::format::{Dem, Terrain};
use crate::metric::dem_error;
use crate::table::{Pair, Split};

/// The `terrain` value of a row over all records.
pub const ALL: &str = "all";

/// The sim records to score and, for each, the real records it is paired with
/// (sorted by sim index; real indices in file order of the pairs CSV).
pub type Selection = BTreeMap<u64, Vec<u64>>;

/// Group `pairs` by sim record, keeping only the rows of `split` when given.
pub fn select(pairs: &[Pair], split: Option<Split>) -> Selection {
    let mut sel = Selection::new();
    for p in pairs.iter().filter(|p| split.is_none() || p.split == split) {
        let reals = sel.entry(p.sim_index).or_default();
        if !reals.contains(&p.real_index) {
            reals.push(p.real_index);
        }
    }
    sel
}

/// The score of one sim record: its pair error and the real record that
/// gives it (the first of equal ones).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordResult {
    /// Index of the sim record.
    pub sim_index: u64,
    /// Index of the closest real record among its pairs.
    pub real_index: u64,
    /// Pair error: equation 7.1 against that real record.
    pub error: f64,
    /// Terrain of the sim record, when labels were given.
    pub terrain: Option<String>,
}

/// Score `pred(i)` for every sim record `i` of `sel` against `real(j)` for
/// its paired real records `j`. Both lookups must cover the selection.
pub fn evaluate<'a>(
    sel: &Selection,
    pred: impl Fn(u64) -> &'a Dem,
    real: impl Fn(u64) -> &'a Dem,
    terrain: impl Fn(u64) -> Option<Terrain>,
) -> Vec<RecordResult> {
    sel.iter()
        .map(|(&s, reals)| {
            let p = pred(s);
            let (best, error) = reals
                .iter()
                .map(|&r| (r, dem_error(real(r), p)))
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .expect("every selected sim record has a pair");
            RecordResult { sim_index: s, real_index: best, error, terrain: terrain(s).map(|t| t.to_string()) }
        })
        .collect()
}

/// Summary of a set of pair errors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stats {
    /// Number of records.
    pub count: u64,
    /// Smallest error.
    pub lowest: f64,
    /// Largest error.
    pub highest: f64,
    /// Mean error (f64 sum in record order, divided by the count).
    pub mean: f64,
    /// Median error; for an even count, the mean of the two middle values.
    pub median: f64,
}

impl Stats {
    /// Summarise `errors`; None when empty.
    pub fn of(errors: &[f64]) -> Option<Stats> {
        if errors.is_empty() {
            return None;
        }
        let mut sorted = errors.to_vec();
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len();
        let median = if n % 2 == 1 { sorted[n / 2] } else { (sorted[n / 2 - 1] + sorted[n / 2]) / 2.0 };
        Some(Stats {
            count: n as u64,
            lowest: sorted[0],
            highest: sorted[n - 1],
            mean: errors.iter().sum::<f64>() / n as f64,
            median,
        })
    }
}

/// One row of a validation table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TableRow {
    /// Method or model name (`identity`, a model's file stem, `--name`).
    pub method: String,
    /// Terrain of the records summarised, or [`ALL`].
    pub terrain: String,
    /// Number of sim records.
    pub count: u64,
    /// Lowest pair error.
    pub lowest: f64,
    /// Highest pair error.
    pub highest: f64,
    /// Mean pair error.
    pub mean: f64,
    /// Median pair error.
    pub median: f64,
}

impl TableRow {
    fn new(method: &str, terrain: &str, s: Stats) -> Self {
        TableRow {
            method: method.into(),
            terrain: terrain.into(),
            count: s.count,
            lowest: s.lowest,
            highest: s.highest,
            mean: s.mean,
            median: s.median,
        }
    }
}

/// The table of `method` over `results`: one row over all records and, with
/// `by_terrain`, one per terrain present, in label order (`flat`,
/// `stairs-up`, `stairs-down`, `pallet`, `other`). Empty when `results` is.
pub fn table(method: &str, results: &[RecordResult], by_terrain: bool) -> Vec<TableRow> {
    let all: Vec<f64> = results.iter().map(|r| r.error).collect();
    let mut rows: Vec<TableRow> = Stats::of(&all).map(|s| TableRow::new(method, ALL, s)).into_iter().collect();
    if by_terrain {
        for t in Terrain::ALL {
            let e: Vec<f64> = results.iter().filter(|r| r.terrain.as_deref() == Some(t.as_str())).map(|r| r.error).collect();
            rows.extend(Stats::of(&e).map(|s| TableRow::new(method, t.as_str(), s)));
        }
    }
    rows
}

/// The CSV header of a table.
pub const TABLE_HEADER: [&str; 7] = ["method", "terrain", "count", "lowest", "highest", "mean", "median"];

/// Read a table CSV (`-` for stdin). Lines repeating the header are skipped,
/// so `cat a.csv b.csv` is a table; a (method, terrain) key may appear once.
pub fn read_table_csv(path: &str) -> Result<Vec<TableRow>> {
    let src: Box<dyn std::io::Read> = if path == "-" {
        Box::new(std::io::stdin().lock())
    } else {
        Box::new(std::fs::File::open(path).map_err(|source| DemError::Open { path: path.into(), source })?)
    };
    let bad = |line: u64, reason: String| DemError::Table { path: path.into(), line, reason };
    let mut rdr = csv::ReaderBuilder::new().has_headers(false).trim(csv::Trim::All).from_reader(src);
    let header = csv::StringRecord::from(TABLE_HEADER.to_vec());
    let mut rows = Vec::new();
    for (n, rec) in rdr.records().enumerate() {
        let rec = rec.map_err(|e| bad(e.position().map_or(0, |p| p.line()), e.to_string()))?;
        let line = rec.position().map_or(n as u64 + 1, |p| p.line());
        if rec == header {
            continue;
        }
        if n == 0 {
            return Err(bad(1, format!("header must be {}", TABLE_HEADER.join(","))));
        }
        let row: TableRow = rec.deserialize(Some(&header)).map_err(|e| bad(line, e.to_string()))?;
        rows.push(row);
    }
    check_table(path, rows)
}

/// Refuse a table that is empty, repeats a (method, terrain) key or holds a
/// negative or NaN error; returns it unchanged otherwise.
pub fn check_table(path: &str, rows: Vec<TableRow>) -> Result<Vec<TableRow>> {
    if rows.is_empty() {
        return Err(DemError::input(path, "holds no table rows"));
    }
    let mut seen = std::collections::HashSet::new();
    for r in &rows {
        if !seen.insert((r.method.as_str(), r.terrain.as_str())) {
            return Err(DemError::input(path, format!("row {}/{} appears twice", r.method, r.terrain)));
        }
        if [r.lowest, r.highest, r.mean, r.median].iter().any(|v| v.is_nan() || *v < 0.0) {
            return Err(DemError::input(path, format!("row {}/{}: errors must be numbers >= 0", r.method, r.terrain)));
        }
    }
    Ok(rows)
}

/// Write a table as CSV (`-` for stdout), atomically for files.
pub fn write_table_csv(path: &str, rows: &[TableRow]) -> Result<()> {
    crate::table::write_rows(path, rows)
}

/// How a row of the current table stands against the baseline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Mean and median within the tolerance (or better).
    Ok,
    /// Mean or median worse than the baseline by more than the tolerance.
    Worse,
    /// In the baseline, not in the current table (counts as a failure).
    Missing,
    /// In the current table only.
    New,
}

/// One row of a comparison: the baseline and current rows of one key.
#[derive(Debug, Clone, PartialEq)]
pub struct Compared {
    /// Method name.
    pub method: String,
    /// Terrain or [`ALL`].
    pub terrain: String,
    /// The baseline's row.
    pub baseline: Option<TableRow>,
    /// The current row.
    pub current: Option<TableRow>,
    /// The verdict.
    pub status: Status,
}

impl Compared {
    /// True when this row fails the comparison (worse or missing).
    pub fn fails(&self) -> bool {
        matches!(self.status, Status::Worse | Status::Missing)
    }
}

/// Match `current` against `baseline` by (method, terrain): baseline rows
/// first in their order, then rows new in `current`. A row is
/// [`Status::Worse`] when `current.mean > baseline.mean + tolerance` or
/// `current.median > baseline.median + tolerance` (absolute, in units of
/// equation 7.1).
pub fn compare(baseline: &[TableRow], current: &[TableRow], tolerance: f64) -> Vec<Compared> {
    let cur: HashMap<(&str, &str), &TableRow> = current.iter().map(|r| ((r.method.as_str(), r.terrain.as_str()), r)).collect();
    let base: HashMap<(&str, &str), &TableRow> = baseline.iter().map(|r| ((r.method.as_str(), r.terrain.as_str()), r)).collect();
    let mut out: Vec<Compared> = baseline
        .iter()
        .map(|b| {
            let c = cur.get(&(b.method.as_str(), b.terrain.as_str())).copied();
            let status = match c {
                None => Status::Missing,
                Some(c) if c.mean > b.mean + tolerance || c.median > b.median + tolerance => Status::Worse,
                Some(_) => Status::Ok,
            };
            Compared { method: b.method.clone(), terrain: b.terrain.clone(), baseline: Some(b.clone()), current: c.cloned(), status }
        })
        .collect();
    out.extend(current.iter().filter(|c| !base.contains_key(&(c.method.as_str(), c.terrain.as_str()))).map(|c| Compared {
        method: c.method.clone(),
        terrain: c.terrain.clone(),
        baseline: None,
        current: Some(c.clone()),
        status: Status::New,
    }));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::{at, empty_dem, DemCells, FLAT_GROUND};

    fn flat() -> Dem {
        let mut d = empty_dem();
        for r in 0..20 {
            for c in 0..5 {
                d.set_valid(r, c, FLAT_GROUND);
            }
        }
        d
    }

    fn row(method: &str, mean: f64, median: f64) -> TableRow {
        TableRow { method: method.into(), terrain: ALL.into(), count: 3, lowest: 0.0, highest: 1.0, mean, median }
    }

    #[test]
    fn median_is_numpys() {
        assert_eq!(Stats::of(&[3.0, 1.0, 2.0]).unwrap().median, 2.0);
        assert_eq!(Stats::of(&[4.0, 1.0, 2.0, 3.0]).unwrap().median, 2.5);
        assert_eq!(Stats::of(&[0.7]).unwrap(), Stats { count: 1, lowest: 0.7, highest: 0.7, mean: 0.7, median: 0.7 });
        assert!(Stats::of(&[]).is_none());
    }

    #[test]
    fn select_keeps_the_split_and_drops_repeats() {
        let p = |s, r, split| Pair { sim_index: s, real_index: r, split, distance: None };
        let pairs = [p(5, 1, Some(Split::Val)), p(5, 2, Some(Split::Val)), p(5, 1, Some(Split::Val)), p(3, 0, Some(Split::Train))];
        let val = select(&pairs, Some(Split::Val));
        assert_eq!(val.into_iter().collect::<Vec<_>>(), vec![(5, vec![1, 2])]);
        assert_eq!(select(&pairs, None).keys().copied().collect::<Vec<_>>(), vec![3, 5]);
    }

    // The worked checks of spec/dem-format.md through evaluate: the best of
    // the paired real records is taken, before any mask threshold.
    #[test]
    fn evaluate_takes_the_best_pair_and_the_raw_mask() {
        let y = flat();
        let mut p = y;
        p[at(4, 2, 1)] = 0.5; // 0.0025 against the valid y
        let missing = empty_dem(); // against an all-missing y: mask term only
        let preds = [p];
        let reals = [missing, y];
        let sel: Selection = [(0, vec![0, 1])].into();
        let res = evaluate(&sel, |i| &preds[i as usize], |j| &reals[j as usize], |_| Some(Terrain::Pallet));
        assert_eq!(res.len(), 1);
        assert_eq!((res[0].real_index, res[0].terrain.as_deref()), (1, Some("pallet")));
        assert!((res[0].error - 0.0025).abs() < 1e-12);

        let mut q = empty_dem();
        q[at(7, 1, 1)] = 0.5; // 0.0225 against all missing
        let preds = [q];
        let res = evaluate(&sel, |i| &preds[i as usize], |j| &reals[j as usize], |_| None);
        assert_eq!(res[0].real_index, 0);
        assert!((res[0].error - 0.0225).abs() < 1e-12);
    }

    #[test]
    fn table_by_terrain_follows_label_order() {
        let r = |e, t: &str| RecordResult { sim_index: 0, real_index: 0, error: e, terrain: Some(t.into()) };
        let res = [r(0.1, "pallet"), r(0.3, "flat"), r(0.5, "pallet")];
        let t = table("m", &res, true);
        let keys: Vec<_> = t.iter().map(|r| (r.terrain.as_str(), r.count)).collect();
        assert_eq!(keys, vec![("all", 3), ("flat", 1), ("pallet", 2)]);
        assert!((t[2].mean - 0.3).abs() < 1e-15);
        assert_eq!(table("m", &res, false).len(), 1);
        assert!(table("m", &[], true).is_empty());
    }

    #[test]
    fn compare_marks_worse_missing_and_new() {
        let base = [row("a", 0.5, 0.2), row("b", 0.5, 0.2)];
        let cur = [row("a", 0.52, 0.2), row("c", 9.0, 9.0)];
        let c = compare(&base, &cur, 0.02 + 1e-12);
        let st: Vec<_> = c.iter().map(|c| (c.method.as_str(), c.status)).collect();
        assert_eq!(st, vec![("a", Status::Ok), ("b", Status::Missing), ("c", Status::New)]);
        let c = compare(&base, &[row("a", 0.5, 0.23), row("b", 0.4, 0.1)], 0.02);
        assert_eq!(c[0].status, Status::Worse);
        assert_eq!(c[1].status, Status::Ok);
        assert!(compare(&base, &base, 0.0).iter().all(|c| !c.fails()));
    }

    #[test]
    fn table_csv_round_trips_and_joins_with_cat() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.csv").to_string_lossy().into_owned();
        let rows = vec![row("a", 0.1 + 0.2, 1.0 / 3.0)];
        write_table_csv(&p, &rows).unwrap();
        assert_eq!(read_table_csv(&p).unwrap(), rows);
        let text = std::fs::read_to_string(&p).unwrap();
        std::fs::write(&p, format!("{text}{}", text.replace("\na,", "\nb,"))).unwrap();
        assert_eq!(read_table_csv(&p).unwrap().len(), 2);
        std::fs::write(&p, format!("{text}{text}")).unwrap();
        assert!(read_table_csv(&p).unwrap_err().to_string().contains("twice"));
        std::fs::write(&p, "method,terrain,count\na,all,3\n").unwrap();
        assert!(read_table_csv(&p).unwrap_err().to_string().contains("line 1"));
        std::fs::write(&p, format!("{}\na,all,x,0,0,0,0\n", TABLE_HEADER.join(","))).unwrap();
        assert!(read_table_csv(&p).unwrap_err().to_string().contains("line 2"));
    }
}
