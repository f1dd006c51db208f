//! Validation tables of the pair error (the thesis's tables 7.x) and their
//! comparison against a baseline.
//!
//! For every sim record of a selection (the sim side of a pairs CSV, often
//! its `val` split) a prediction p is scored by its pair error, the smallest
//! equation 7.1 error against the real records paired with it
//! ([`dem_core::metric::pair_error`]). A [`TableRow`] summarises a method over
//! those records: count, lowest, highest, mean and median (numpy's median:
//! the mean of the two middle values for an even count), all in f64.
//!
//! ```
//! use dem_eval::table::ErrorSummary;
//! let s = ErrorSummary::of(&[0.4, 0.1, 0.3, 0.2]).unwrap();
//! assert_eq!((s.count, s.lowest, s.highest), (4, 0.1, 0.4));
//! assert!((s.mean - 0.25).abs() < 1e-15 && (s.median - 0.25).abs() < 1e-15);
//! ```
//!
//! Equation 7.1 barely sees heights (a 10 cm error costs 0.0001, a wrong
//! mask 0.04), so every row also carries measures that do, pooled over the
//! row's records ([`Sum`]: a sum and a count per record, so `--by terrain`
//! pools per terrain):
//!
//! - `height_cm`: mean |p_h - y_h| (cm) between the prediction p and the
//!   closest paired real record y (the one of the pair error), over the cells
//!   of rows 0..19 valid in both (p_m > 0 and y_m > 0);
//! - `rough_across_cm`, `rough_along_cm`: the prediction's roughness, mean
//!   |h(r,c) - h(r,c+1)| (across the robot) and |h(r,c) - h(r+1,c)| (along
//!   it) over neighbour pairs of rows 0..19 both valid; `real_rough_*_cm`
//!   the same of the closest real records;
//! - `gap`: [`dem_core::distribution::gap`] of the row's predictions against its
//!   real set (the unique real records paired with the row's sim records),
//!   unpaired; computed by the caller, which holds the records ([`table_with`]);
//! - `frame_dh_mm`, `frame_rcorr`, `frame_flip`, `frame_persist`: how the
//!   predictions of consecutive frames of a run move ([`dem_core::temporal`]:
//!   mean |h(t+1) - h(t)| in mm over the same ground, the correlation of the
//!   error against the sim input at t and t+1, the share of cells changing
//!   validity, P(missing at t+1 | missing at t)), over the steps whose both
//!   frames are scored; `real_frame_*` the same of the real records of the
//!   row's pairs, in their own runs (`--real-labels`), their error against
//!   their sim partner where each has exactly one. Computed by the caller,
//!   which holds the runs.
//!
//! ```
//! use dem_eval::table::Sum;
//! let s = Sum { sum: 0.03, count: 2 } + Sum { sum: 0.01, count: 2 };
//! assert!((s.mean_cm().unwrap() - 1.0).abs() < 1e-12);
//! assert_eq!(Sum::default().mean_cm(), None);
//! ```
//!
//! Tables are written as CSV, `method,terrain,count,lowest,highest,mean,median,`
//! `height_cm,rough_across_cm,rough_along_cm,real_rough_across_cm,real_rough_along_cm,gap,`
//! then the eight frame columns (the `terrain` of a row over every record
//! is `all`; a measure without cells is an empty field), and read back by
//! [`read_table_csv`], which also reads the older seven- and 13-column
//! tables and skips repeated header lines so tables join with `cat`. [`compare`] matches two tables by (method,
//! terrain) and marks a row worse when its mean or median grew by more than
//! an absolute tolerance, or one of the height measures did ([`Tolerances`]).
//! [`forms`] writes a table or a comparison as text, CSV, JSON or Markdown
//! and reads a table back from CSV or JSON.

pub mod forms;

use std::collections::{BTreeMap, HashMap};

use serde::{Deserialize, Serialize};

use dem_core::error::{DemError, Result};
use dem_core::format::{Dem, DemCells, Terrain, COLS, GRID_ROWS};
use dem_core::metric::dem_error;
use dem_core::table::{Pair, Split};
use dem_core::temporal::FrameStats;

/// The `terrain` value of a row over all records.
pub const ALL: &str = "all";

/// The sim records to score and, for each, the real records it is paired with
/// (sorted by sim index; real indices in file order of the pairs CSV).
pub type Selection = BTreeMap<u64, Vec<u64>>;

/// The pairs to score, keeping only the rows of `split` when given, as
/// (sim, real) sorted by sim index, each sim's reals in file order without
/// repeats: 16 bytes a pair, which is all an evaluation keeps of them.
pub fn select(pairs: &[Pair], split: Option<Split>) -> Vec<(u64, u64)> {
    let mut sorted: Vec<(u64, u64)> =
        pairs.iter().filter(|p| split.is_none() || p.split == split).map(|p| (p.sim_index, p.real_index)).collect();
    sorted.sort_by_key(|p| p.0); // stable: each sim's reals stay in file order
    let mut kept: Vec<(u64, u64)> = Vec::with_capacity(sorted.len());
    let mut group_start = 0;
    for p in sorted {
        if kept.last().is_none_or(|l| l.0 != p.0) {
            group_start = kept.len();
        }
        if !kept[group_start..].contains(&p) {
            kept.push(p);
        }
    }
    kept
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
    /// |p_h - y_h| (m) against that real record, cells valid in both.
    #[serde(default)]
    pub height: Sum,
    /// The prediction's |h(r,c) - h(r,c+1)| (m), pairs both valid.
    #[serde(default)]
    pub rough_across: Sum,
    /// The prediction's |h(r,c) - h(r+1,c)| (m), pairs both valid.
    #[serde(default)]
    pub rough_along: Sum,
    /// The same across the robot of that real record.
    #[serde(default)]
    pub real_rough_across: Sum,
    /// The same along the robot of that real record.
    #[serde(default)]
    pub real_rough_along: Sum,
}

/// A sum of absolute differences (m) and their number, pooled by adding.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Sum {
    /// Sum of the absolute differences, in metres (f64).
    pub sum: f64,
    /// Number of differences.
    pub count: u64,
}

impl std::ops::Add for Sum {
    type Output = Sum;
    fn add(self, o: Sum) -> Sum {
        Sum { sum: self.sum + o.sum, count: self.count + o.count }
    }
}

impl std::iter::Sum for Sum {
    fn sum<I: Iterator<Item = Sum>>(it: I) -> Sum {
        it.fold(Sum::default(), |a, b| a + b)
    }
}

impl Sum {
    /// The mean in centimetres; None without differences.
    pub fn mean_cm(&self) -> Option<f64> {
        (self.count > 0).then(|| 100.0 * self.sum / self.count as f64)
    }

    fn push(&mut self, a: f32, b: f32) {
        self.sum += (a as f64 - b as f64).abs();
        self.count += 1;
    }
}

/// |p_h - y_h| over the cells of rows 0..19 valid in both `p` and `y`.
pub fn height_error(y: &Dem, p: &Dem) -> Sum {
    let mut s = Sum::default();
    for r in 0..GRID_ROWS {
        for c in (0..COLS).filter(|&c| p.is_valid(r, c) && y.is_valid(r, c)) {
            s.push(p.height(r, c), y.height(r, c));
        }
    }
    s
}

/// Roughness of `d`: (across, along) sums of |h(r,c) - h(r,c+1)| and
/// |h(r,c) - h(r+1,c)| over neighbour pairs of rows 0..19 both valid.
pub fn roughness(d: &Dem) -> (Sum, Sum) {
    let (mut across, mut along) = (Sum::default(), Sum::default());
    for r in 0..GRID_ROWS {
        for c in (0..COLS).filter(|&c| d.is_valid(r, c)) {
            if c + 1 < COLS && d.is_valid(r, c + 1) {
                across.push(d.height(r, c), d.height(r, c + 1));
            }
            if r + 1 < GRID_ROWS && d.is_valid(r + 1, c) {
                along.push(d.height(r, c), d.height(r + 1, c));
            }
        }
    }
    (across, along)
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
            let y = real(best);
            let ((rough_across, rough_along), (real_rough_across, real_rough_along)) = (roughness(p), roughness(y));
            RecordResult {
                sim_index: s,
                real_index: best,
                error,
                terrain: terrain(s).map(|t| t.to_string()),
                height: height_error(y, p),
                rough_across,
                rough_along,
                real_rough_across,
                real_rough_along,
            }
        })
        .collect()
}

/// Summary of a set of pair errors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorSummary {
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

impl ErrorSummary {
    /// Summarise `errors`; None when empty.
    pub fn of(errors: &[f64]) -> Option<ErrorSummary> {
        if errors.is_empty() {
            return None;
        }
        let mut sorted = errors.to_vec();
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len();
        let median = if n % 2 == 1 { sorted[n / 2] } else { (sorted[n / 2 - 1] + sorted[n / 2]) / 2.0 };
        Some(ErrorSummary {
            count: n as u64,
            lowest: sorted[0],
            highest: sorted[n - 1],
            mean: errors.iter().sum::<f64>() / n as f64,
            median,
        })
    }
}

/// One row of a validation table.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
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
    /// Mean abs height error (cm) against the closest real record, cells
    /// valid in both, pooled over the row's records; None without such cells
    /// (or in a table of an older dem-eval).
    #[serde(default)]
    pub height_cm: Option<f64>,
    /// The predictions' mean |h(r,c) - h(r,c+1)| (cm), pairs both valid.
    #[serde(default)]
    pub rough_across_cm: Option<f64>,
    /// The predictions' mean |h(r,c) - h(r+1,c)| (cm), pairs both valid.
    #[serde(default)]
    pub rough_along_cm: Option<f64>,
    /// `rough_across_cm` of the closest real records.
    #[serde(default)]
    pub real_rough_across_cm: Option<f64>,
    /// `rough_along_cm` of the closest real records.
    #[serde(default)]
    pub real_rough_along_cm: Option<f64>,
    /// Distribution gap (dem-gap's measure, unpaired) of the predictions
    /// against the row's real set.
    #[serde(default)]
    pub gap: Option<f64>,
    /// The predictions' mean |h(t+1) - h(t)| over the same ground of
    /// consecutive frames (mm).
    #[serde(default)]
    pub frame_dh_mm: Option<f64>,
    /// Correlation of the predictions' error against sim at t and t+1.
    #[serde(default)]
    pub frame_rcorr: Option<f64>,
    /// Share of the predictions' cells changing validity from frame to frame.
    #[serde(default)]
    pub frame_flip: Option<f64>,
    /// P(missing at t+1 | missing at t) of the predictions.
    #[serde(default)]
    pub frame_persist: Option<f64>,
    /// `frame_dh_mm` of the real records of the row's pairs.
    #[serde(default)]
    pub real_frame_dh_mm: Option<f64>,
    /// `frame_rcorr` of the real records (against their one sim partner).
    #[serde(default)]
    pub real_frame_rcorr: Option<f64>,
    /// `frame_flip` of the real records.
    #[serde(default)]
    pub real_frame_flip: Option<f64>,
    /// `frame_persist` of the real records.
    #[serde(default)]
    pub real_frame_persist: Option<f64>,
}

impl TableRow {
    /// |rough - real_rough| (cm), across and along: how far the
    /// predictions' roughness is from the real one's.
    pub fn rough_offsets(&self) -> [Option<f64>; 2] {
        let off = |a: Option<f64>, b: Option<f64>| Some((a? - b?).abs());
        [off(self.rough_across_cm, self.real_rough_across_cm), off(self.rough_along_cm, self.real_rough_along_cm)]
    }

    /// |frame - real_frame| of dh (mm), rcorr, flip and persist: how far
    /// the predictions move from frame to frame unlike the real records.
    pub fn frame_offsets(&self) -> [Option<f64>; 4] {
        let off = |a: Option<f64>, b: Option<f64>| Some((a? - b?).abs());
        [
            off(self.frame_dh_mm, self.real_frame_dh_mm),
            off(self.frame_rcorr, self.real_frame_rcorr),
            off(self.frame_flip, self.real_frame_flip),
            off(self.frame_persist, self.real_frame_persist),
        ]
    }

    /// The row with its frame columns: `pred` of the predictions, `real` of
    /// the real records.
    pub fn with_frames(self, pred: Option<&FrameStats>, real: Option<&FrameStats>) -> TableRow {
        let mm = |s: Option<&FrameStats>| s.and_then(|s| s.dh).map(|v| 1000.0 * v);
        TableRow {
            frame_dh_mm: mm(pred),
            frame_rcorr: pred.and_then(|s| s.rcorr),
            frame_flip: pred.and_then(|s| s.flip),
            frame_persist: pred.and_then(|s| s.persist),
            real_frame_dh_mm: mm(real),
            real_frame_rcorr: real.and_then(|s| s.rcorr),
            real_frame_flip: real.and_then(|s| s.flip),
            real_frame_persist: real.and_then(|s| s.persist),
            ..self
        }
    }
}

/// One table row accumulated record by record: the pair errors (kept, 8
/// bytes a record, for the exact median) and the pooled height and roughness
/// sums. Adding a row's records in index order gives the same row, bit for
/// bit, as [`table_with`] over those records.
#[derive(Debug, Clone, Default)]
pub struct RowAcc {
    errors: Vec<f64>,
    height: Sum,
    rough_across: Sum,
    rough_along: Sum,
    real_rough_across: Sum,
    real_rough_along: Sum,
}

impl RowAcc {
    /// Add one record's result.
    pub fn add(&mut self, r: &RecordResult) {
        self.errors.push(r.error);
        self.height = self.height + r.height;
        self.rough_across = self.rough_across + r.rough_across;
        self.rough_along = self.rough_along + r.rough_along;
        self.real_rough_across = self.real_rough_across + r.real_rough_across;
        self.real_rough_along = self.real_rough_along + r.real_rough_along;
    }

    /// Records added.
    pub fn len(&self) -> usize {
        self.errors.len()
    }

    /// True when no record was added.
    pub fn is_empty(&self) -> bool {
        self.errors.is_empty()
    }

    /// The row; None when no record was added.
    pub fn row(&self, method: &str, terrain: &str, gap: Option<f64>) -> Option<TableRow> {
        let s = ErrorSummary::of(&self.errors)?;
        Some(TableRow {
            method: method.into(),
            terrain: terrain.into(),
            count: s.count,
            lowest: s.lowest,
            highest: s.highest,
            mean: s.mean,
            median: s.median,
            height_cm: self.height.mean_cm(),
            rough_across_cm: self.rough_across.mean_cm(),
            rough_along_cm: self.rough_along.mean_cm(),
            real_rough_across_cm: self.real_rough_across.mean_cm(),
            real_rough_along_cm: self.real_rough_along.mean_cm(),
            gap,
            ..TableRow::default()
        })
    }
}

/// The table of `method` over `results`: one row over all records and, with
/// `by_terrain`, one per terrain present, in label order (`flat`,
/// `stairs-up`, `stairs-down`, `pallet`, `other`). Empty when `results` is.
/// The rows have no `gap` (see [`table_with`]).
pub fn table(method: &str, results: &[RecordResult], by_terrain: bool) -> Vec<TableRow> {
    table_with(method, results, by_terrain, |_| None)
}

/// [`table`], with `gap(records)` the gap of the predictions of a row's
/// records against their real set.
pub fn table_with(
    method: &str,
    results: &[RecordResult],
    by_terrain: bool,
    gap: impl Fn(&[&RecordResult]) -> Option<f64>,
) -> Vec<TableRow> {
    let row = |terrain: &str, group: Vec<&RecordResult>| {
        let mut acc = RowAcc::default();
        group.iter().for_each(|r| acc.add(r));
        acc.row(method, terrain, gap(&group))
    };
    let mut rows: Vec<TableRow> = row(ALL, results.iter().collect()).into_iter().collect();
    if by_terrain {
        for t in Terrain::ALL {
            rows.extend(row(t.as_str(), results.iter().filter(|r| r.terrain.as_deref() == Some(t.as_str())).collect()));
        }
    }
    rows
}

/// The CSV header of a table.
pub const TABLE_HEADER: [&str; 21] = [
    "method",
    "terrain",
    "count",
    "lowest",
    "highest",
    "mean",
    "median",
    "height_cm",
    "rough_across_cm",
    "rough_along_cm",
    "real_rough_across_cm",
    "real_rough_along_cm",
    "gap",
    "frame_dh_mm",
    "frame_rcorr",
    "frame_flip",
    "frame_persist",
    "real_frame_dh_mm",
    "real_frame_rcorr",
    "real_frame_flip",
    "real_frame_persist",
];

/// The header of the tables of dem-eval before the height measures (still read).
pub const OLD_TABLE_HEADER: [&str; 7] = ["method", "terrain", "count", "lowest", "highest", "mean", "median"];

/// The headers a table CSV may have: [`TABLE_HEADER`], its first 13 columns
/// (before the frame columns) and [`OLD_TABLE_HEADER`] (still read).
fn headers() -> [csv::StringRecord; 3] {
    [
        csv::StringRecord::from(TABLE_HEADER.to_vec()),
        csv::StringRecord::from(TABLE_HEADER[..13].to_vec()),
        csv::StringRecord::from(OLD_TABLE_HEADER.to_vec()),
    ]
}

/// Read a table CSV (`-` for stdin), with [`TABLE_HEADER`] or an older
/// header ([`headers`]: the rows lack the later measures). Header lines
/// later in the file are skipped and switch the columns, so `cat a.csv
/// b.csv` is a table, old and new alike; a (method, terrain) key may appear once.
pub fn read_table_csv(path: &str) -> Result<Vec<TableRow>> {
    let src = dem_core::table::open_input(path)?;
    let bad = |line: u64, reason: String| DemError::Table { path: path.into(), line, reason };
    let mut rdr = csv::ReaderBuilder::new().has_headers(false).flexible(true).trim(csv::Trim::All).from_reader(src);
    let known = headers();
    let mut header = &known[0];
    let mut rows = Vec::new();
    for (n, rec) in rdr.records().enumerate() {
        let rec = rec.map_err(|e| bad(e.position().map_or(0, |p| p.line()), e.to_string()))?;
        let line = rec.position().map_or(n as u64 + 1, |p| p.line());
        if let Some(h) = known.iter().find(|h| **h == rec) {
            header = h;
            continue;
        }
        if n == 0 {
            return Err(bad(1, format!("header must be {} (or its first seven columns)", TABLE_HEADER.join(","))));
        }
        if rec.len() != header.len() {
            return Err(bad(line, format!("{} fields where the header has {}", rec.len(), header.len())));
        }
        let row: TableRow = rec.deserialize(Some(header)).map_err(|e| bad(line, e.to_string()))?;
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
        let measures = [r.height_cm, r.rough_across_cm, r.rough_along_cm, r.real_rough_across_cm, r.real_rough_along_cm, r.gap];
        if measures.iter().flatten().any(|v| !v.is_finite() || *v < 0.0) {
            return Err(DemError::input(path, format!("row {}/{}: height measures and gap must be numbers >= 0", r.method, r.terrain)));
        }
        let shares = [r.frame_dh_mm, r.frame_flip, r.frame_persist, r.real_frame_dh_mm, r.real_frame_flip, r.real_frame_persist];
        if shares.iter().flatten().any(|v| !v.is_finite() || *v < 0.0)
            || [r.frame_rcorr, r.real_frame_rcorr].iter().flatten().any(|v| !(-1.0..=1.0).contains(v))
        {
            return Err(DemError::input(
                path,
                format!("row {}/{}: frame measures must be numbers >= 0 (correlations in [-1, 1])", r.method, r.terrain),
            ));
        }
    }
    Ok(rows)
}

/// Write a table as CSV (`-` for stdout), atomically for files.
pub fn write_table_csv(path: &str, rows: &[TableRow]) -> Result<()> {
    dem_core::table::write_rows(path, rows)
}

/// How a row of the current table stands against the baseline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Every measure within its tolerance (or better).
    Ok,
    /// Some measure worse than the baseline by more than its tolerance.
    Worse,
    /// In the baseline, not in the current table (counts as a failure).
    Missing,
    /// In the current table only.
    New,
}

/// A measure [`compare`] checks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Measure {
    /// Mean pair error (equation 7.1).
    Mean,
    /// Median pair error (equation 7.1).
    Median,
    /// `height_cm`.
    HeightCm,
    /// |rough_across_cm - real_rough_across_cm|.
    RoughAcross,
    /// |rough_along_cm - real_rough_along_cm|.
    RoughAlong,
    /// `gap`.
    Gap,
    /// |frame_dh_mm - real_frame_dh_mm|.
    FrameDh,
    /// |frame_rcorr - real_frame_rcorr|.
    FrameRcorr,
    /// |frame_flip - real_frame_flip|.
    FrameFlip,
    /// |frame_persist - real_frame_persist|.
    FramePersist,
}

impl Measure {
    /// Every measure, in table order.
    pub const ALL: [Measure; 10] = [
        Measure::Mean,
        Measure::Median,
        Measure::HeightCm,
        Measure::RoughAcross,
        Measure::RoughAlong,
        Measure::Gap,
        Measure::FrameDh,
        Measure::FrameRcorr,
        Measure::FrameFlip,
        Measure::FramePersist,
    ];

    /// Its name in tables and messages.
    pub fn name(self) -> &'static str {
        match self {
            Measure::Mean => "mean",
            Measure::Median => "median",
            Measure::HeightCm => "height_cm",
            Measure::RoughAcross => "rough_across",
            Measure::RoughAlong => "rough_along",
            Measure::Gap => "gap",
            Measure::FrameDh => "frame_dh",
            Measure::FrameRcorr => "frame_rcorr",
            Measure::FrameFlip => "frame_flip",
            Measure::FramePersist => "frame_persist",
        }
    }

    /// The value of `row` this measure compares (lower is better): the
    /// error, the height error, the roughness's distance from the real one,
    /// the gap. None when the row lacks it.
    pub fn value(self, row: &TableRow) -> Option<f64> {
        match self {
            Measure::Mean => Some(row.mean),
            Measure::Median => Some(row.median),
            Measure::HeightCm => row.height_cm,
            Measure::RoughAcross => row.rough_offsets()[0],
            Measure::RoughAlong => row.rough_offsets()[1],
            Measure::Gap => row.gap,
            Measure::FrameDh => row.frame_offsets()[0],
            Measure::FrameRcorr => row.frame_offsets()[1],
            Measure::FrameFlip => row.frame_offsets()[2],
            Measure::FramePersist => row.frame_offsets()[3],
        }
    }
}

/// The largest allowed growth of each measure (absolute).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerances {
    /// Mean and median pair error, equation 7.1 units.
    pub pair: f64,
    /// `height_cm`, cm.
    pub height_cm: f64,
    /// |rough - real_rough| across and along, cm.
    pub rough_cm: f64,
    /// The gap.
    pub gap: f64,
    /// |frame_dh - real_frame_dh|, mm.
    pub frame_dh_mm: f64,
    /// |frame - real_frame| of the correlation, the flip share and the
    /// persistence.
    pub frame: f64,
}

impl Default for Tolerances {
    /// The defaults of `dem-eval compare`.
    fn default() -> Self {
        Tolerances { pair: 0.02, height_cm: 0.5, rough_cm: 0.5, gap: DEFAULT_GAP_TOLERANCE, frame_dh_mm: 1.0, frame: 0.05 }
    }
}

/// Default growth of the gap `compare` allows (see docs/dem-eval.md).
pub const DEFAULT_GAP_TOLERANCE: f64 = 2.0;

impl Tolerances {
    /// The tolerance of `m`.
    pub fn of(&self, m: Measure) -> f64 {
        match m {
            Measure::Mean | Measure::Median => self.pair,
            Measure::HeightCm => self.height_cm,
            Measure::RoughAcross | Measure::RoughAlong => self.rough_cm,
            Measure::Gap => self.gap,
            Measure::FrameDh => self.frame_dh_mm,
            Measure::FrameRcorr | Measure::FrameFlip | Measure::FramePersist => self.frame,
        }
    }

    /// The measures of `current` worse than `baseline`'s by more than their
    /// tolerance. A measure the baseline lacks is not checked; one the
    /// baseline has and `current` lacks (no valid cells left) is worse.
    pub fn worse(&self, baseline: &TableRow, current: &TableRow) -> Vec<Measure> {
        Measure::ALL
            .into_iter()
            .filter(|&m| match (m.value(baseline), m.value(current)) {
                (None, _) => false,
                (Some(_), None) => true,
                (Some(b), Some(c)) => c > b + self.of(m),
            })
            .collect()
    }
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
    /// The measures that made it [`Status::Worse`] (empty otherwise).
    pub worse: Vec<Measure>,
}

impl Compared {
    /// True when this row fails the comparison (worse or missing).
    pub fn fails(&self) -> bool {
        matches!(self.status, Status::Worse | Status::Missing)
    }

    /// Current minus baseline of measure `m`, when both rows have it.
    pub fn diff(&self, m: Measure) -> Option<f64> {
        Some(m.value(self.current.as_ref()?)? - m.value(self.baseline.as_ref()?)?)
    }
}

/// Match `current` against `baseline` by (method, terrain): baseline rows
/// first in their order, then rows new in `current`. A row is
/// [`Status::Worse`] when one of its measures grew by more than its
/// tolerance ([`Tolerances::worse`]): mean or median pair error (equation
/// 7.1 units), height error (cm), roughness's distance from the real one,
/// across or along (cm), gap.
pub fn compare(baseline: &[TableRow], current: &[TableRow], tol: &Tolerances) -> Vec<Compared> {
    let cur: HashMap<(&str, &str), &TableRow> = current.iter().map(|r| ((r.method.as_str(), r.terrain.as_str()), r)).collect();
    let base: HashMap<(&str, &str), &TableRow> = baseline.iter().map(|r| ((r.method.as_str(), r.terrain.as_str()), r)).collect();
    let mut out: Vec<Compared> = baseline
        .iter()
        .map(|b| {
            let c = cur.get(&(b.method.as_str(), b.terrain.as_str())).copied();
            let worse = c.map(|c| tol.worse(b, c)).unwrap_or_default();
            let status = match c {
                None => Status::Missing,
                Some(_) if !worse.is_empty() => Status::Worse,
                Some(_) => Status::Ok,
            };
            Compared { method: b.method.clone(), terrain: b.terrain.clone(), baseline: Some(b.clone()), current: c.cloned(), status, worse }
        })
        .collect();
    out.extend(current.iter().filter(|c| !base.contains_key(&(c.method.as_str(), c.terrain.as_str()))).map(|c| Compared {
        method: c.method.clone(),
        terrain: c.terrain.clone(),
        baseline: None,
        current: Some(c.clone()),
        status: Status::New,
        worse: Vec::new(),
    }));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::format::{at, empty_dem, level_dem, DemCells, FLAT_GROUND};

    fn row(method: &str, mean: f64, median: f64) -> TableRow {
        TableRow {
            method: method.into(),
            terrain: ALL.into(),
            count: 3,
            lowest: 0.0,
            highest: 1.0,
            mean,
            median,
            height_cm: None,
            rough_across_cm: None,
            rough_along_cm: None,
            real_rough_across_cm: None,
            real_rough_along_cm: None,
            gap: None,
            ..TableRow::default()
        }
    }

    /// A row with every height measure: height 1.5 cm, roughness 0.1 / 0.2
    /// against real 0.3 / 0.4, gap 2.
    fn full(method: &str) -> TableRow {
        TableRow {
            height_cm: Some(1.5),
            rough_across_cm: Some(0.1),
            rough_along_cm: Some(0.2),
            real_rough_across_cm: Some(0.3),
            real_rough_along_cm: Some(0.4),
            gap: Some(2.0),
            ..row(method, 0.4, 0.3)
        }
    }

    fn result(error: f64, terrain: &str) -> RecordResult {
        RecordResult {
            sim_index: 0,
            real_index: 0,
            error,
            terrain: Some(terrain.into()),
            height: Sum::default(),
            rough_across: Sum::default(),
            rough_along: Sum::default(),
            real_rough_across: Sum::default(),
            real_rough_along: Sum::default(),
        }
    }

    fn close(a: Option<f64>, b: f64) -> bool {
        a.is_some_and(|a| (a - b).abs() < 1e-9)
    }

    #[test]
    fn median_is_numpys() {
        assert_eq!(ErrorSummary::of(&[3.0, 1.0, 2.0]).unwrap().median, 2.0);
        assert_eq!(ErrorSummary::of(&[4.0, 1.0, 2.0, 3.0]).unwrap().median, 2.5);
        assert_eq!(ErrorSummary::of(&[0.7]).unwrap(), ErrorSummary { count: 1, lowest: 0.7, highest: 0.7, mean: 0.7, median: 0.7 });
        assert!(ErrorSummary::of(&[]).is_none());
    }

    #[test]
    fn select_keeps_the_split_and_drops_repeats() {
        let p = |s, r, split| Pair { sim_index: s, real_index: r, split, distance: None };
        let pairs = [p(5, 1, Some(Split::Val)), p(5, 2, Some(Split::Val)), p(5, 1, Some(Split::Val)), p(3, 0, Some(Split::Train))];
        assert_eq!(select(&pairs, Some(Split::Val)), vec![(5, 1), (5, 2)]);
        assert_eq!(select(&pairs, None), vec![(3, 0), (5, 1), (5, 2)]);
    }

    // The worked checks of docs/format.md through evaluate: the best of
    // the paired real records is taken, before any mask threshold.
    #[test]
    fn evaluate_takes_the_best_pair_and_the_raw_mask() {
        let y = level_dem(FLAT_GROUND);
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
        let res = [result(0.1, "pallet"), result(0.3, "flat"), result(0.5, "pallet")];
        let t = table("m", &res, true);
        let keys: Vec<_> = t.iter().map(|r| (r.terrain.as_str(), r.count)).collect();
        assert_eq!(keys, vec![("all", 3), ("flat", 1), ("pallet", 2)]);
        assert!((t[2].mean - 0.3).abs() < 1e-15);
        assert_eq!(table("m", &res, false).len(), 1);
        assert!(table("m", &[], true).is_empty());
    }

    #[test]
    fn a_row_accumulated_record_by_record_is_the_table_row_bit_for_bit() {
        let res: Vec<RecordResult> = (0..7)
            .map(|i| RecordResult {
                height: Sum { sum: 0.013 * i as f64, count: 3 + i },
                rough_across: Sum { sum: 0.1 / (i + 1) as f64, count: 4 },
                real_rough_along: Sum { sum: 1.0 / 3.0, count: i },
                ..result(0.1 + 0.37 * ((i * 5) % 7) as f64, "flat")
            })
            .collect();
        let mut acc = RowAcc::default();
        res.iter().for_each(|r| acc.add(r));
        assert_eq!(acc.row("m", ALL, Some(1.5)).unwrap(), table_with("m", &res, false, |_| Some(1.5))[0]);
        assert!(RowAcc::default().row("m", ALL, None).is_none());
    }

    #[test]
    fn compare_marks_worse_missing_and_new() {
        let base = [row("a", 0.5, 0.2), row("b", 0.5, 0.2)];
        let cur = [row("a", 0.52, 0.2), row("c", 9.0, 9.0)];
        let tol = |pair| Tolerances { pair, ..Tolerances::default() };
        let c = compare(&base, &cur, &tol(0.02 + 1e-12));
        let st: Vec<_> = c.iter().map(|c| (c.method.as_str(), c.status)).collect();
        assert_eq!(st, vec![("a", Status::Ok), ("b", Status::Missing), ("c", Status::New)]);
        let c = compare(&base, &[row("a", 0.5, 0.23), row("b", 0.4, 0.1)], &tol(0.02));
        assert_eq!((c[0].status, c[0].worse.as_slice()), (Status::Worse, &[Measure::Median][..]));
        assert_eq!(c[1].status, Status::Ok);
        assert!(compare(&base, &base, &tol(0.0)).iter().all(|c| !c.fails()));
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

    // Hand-computed: y flat at -0.07 with (0,0) missing; p valid everywhere
    // but (0,1), 2 cm higher at (0,0) (missing in y: not counted), 3 cm at
    // (5,2), 1 cm lower at (7,4): (0.03 + 0.01) / 98 cells.
    #[test]
    fn height_error_counts_only_cells_valid_in_both() {
        let mut y = level_dem(FLAT_GROUND);
        y.set_missing(0, 0);
        let mut p = level_dem(FLAT_GROUND);
        p.set_missing(0, 1);
        p.set_valid(0, 0, -0.05);
        p.set_valid(5, 2, -0.04);
        p.set_valid(7, 4, -0.08);
        p[at(20, 0, 0)] = 9.0; // row 20 is not a grid row
        let h = height_error(&y, &p);
        assert_eq!(h.count, 98);
        assert!((h.sum - 0.04).abs() < 1e-7, "{h:?}");
        assert!((h.mean_cm().unwrap() - 4.0 / 98.0).abs() < 1e-5);
        assert_eq!(height_error(&empty_dem(), &p), Sum::default());
        assert_eq!(height_error(&empty_dem(), &p).mean_cm(), None);
    }

    // A step of 10 cm between rows 9 and 10 and a 4 cm bump at (3,2):
    // across pairs 20 * 4 = 80, along 19 * 5 = 95 when all valid.
    #[test]
    fn roughness_across_and_along() {
        let mut d = level_dem(FLAT_GROUND);
        for r in 10..20 {
            for c in 0..5 {
                d.set_valid(r, c, FLAT_GROUND + 0.1);
            }
        }
        d.set_valid(3, 2, FLAT_GROUND + 0.04);
        let (across, along) = roughness(&d);
        assert_eq!((across.count, along.count), (80, 95));
        // Across: the bump against its two neighbours; along: the step (5
        // columns) and the bump against rows 2 and 4.
        assert!((across.sum - 0.08).abs() < 1e-6, "{across:?}");
        assert!((along.sum - (0.5 + 0.08)).abs() < 1e-6, "{along:?}");
        // A missing cell takes its pairs out: (3,2) missing leaves 78 and 93.
        d.set_missing(3, 2);
        let (across, along) = roughness(&d);
        assert_eq!((across.count, along.count), (78, 93));
        assert!(across.sum.abs() < 1e-6 && (along.sum - 0.5).abs() < 1e-6);
        assert_eq!(roughness(&empty_dem()), (Sum::default(), Sum::default()));
    }

    // evaluate measures against the closest real record, and the table pools
    // sums and counts (not means of records) per terrain.
    #[test]
    fn evaluate_measures_heights_against_the_closest_real_record_and_pools() {
        let y = level_dem(FLAT_GROUND);
        let mut far = level_dem(FLAT_GROUND);
        far.set_missing(0, 0); // a worse pair: the mask term of one cell
        for c in 0..5 {
            far.set_valid(12, c, FLAT_GROUND + 0.5);
        }
        let mut p = level_dem(FLAT_GROUND);
        p.set_valid(2, 2, FLAT_GROUND + 0.02); // 2 cm off in one cell
        let mut q = level_dem(FLAT_GROUND);
        for r in 0..20 {
            q.set_valid(r, 0, FLAT_GROUND + 0.01); // 1 cm off in 20 cells
        }
        q.set_missing(19, 4);
        let preds = [p, q, p];
        let reals = [far, y];
        let sel: Selection = [(0, vec![0, 1]), (1, vec![1]), (2, vec![0])].into();
        let terr = [Terrain::Flat, Terrain::StairsUp, Terrain::Flat];
        let res = evaluate(&sel, |i| &preds[i as usize], |j| &reals[j as usize], |i| Some(terr[i as usize]));
        assert_eq!(res.iter().map(|r| r.real_index).collect::<Vec<_>>(), vec![1, 1, 0]);
        assert_eq!((res[0].height.count, res[1].height.count, res[2].height.count), (100, 99, 99));
        assert!((res[0].height.sum - 0.02).abs() < 1e-6 && (res[1].height.sum - 0.2).abs() < 1e-6);
        // Record 2 against `far`: 2 cm at (2,2) and 50 cm in row 12.
        assert!((res[2].height.sum - (0.02 + 2.5)).abs() < 1e-5);
        // Roughness: p's 2 cm bump against its 2 neighbours each way.
        assert!((res[0].rough_across.sum - 0.04).abs() < 1e-6 && (res[0].rough_along.sum - 0.04).abs() < 1e-6);
        assert_eq!((res[0].rough_across.count, res[0].rough_along.count), (80, 95));
        assert_eq!((res[0].real_rough_across.sum, res[0].real_rough_along.sum), (0.0, 0.0));
        // far: row 12 is 50 cm above rows 11 and 13 (5 columns, twice).
        assert!((res[2].real_rough_along.sum - 5.0).abs() < 1e-5 && res[2].real_rough_across.sum.abs() < 1e-9);
        assert_eq!((res[2].real_rough_across.count, res[2].real_rough_along.count), (79, 94));

        let t = table("m", &res, true);
        assert_eq!(t.iter().map(|r| r.terrain.as_str()).collect::<Vec<_>>(), vec!["all", "flat", "stairs-up"]);
        // Pooled: (0.02 + 0.2 + 2.52) / 298 cells over all; flat (0.02 + 2.52) / 199.
        assert!((t[0].height_cm.unwrap() - 274.0 / 298.0).abs() < 1e-4);
        assert!((t[1].height_cm.unwrap() - 254.0 / 199.0).abs() < 1e-4);
        assert!((t[2].height_cm.unwrap() - 20.0 / 99.0).abs() < 1e-4);
        assert!((t[1].real_rough_along_cm.unwrap() - 500.0 / 189.0).abs() < 1e-4);
        assert!((t[1].rough_across_cm.unwrap() - 8.0 / 160.0).abs() < 1e-4);
        assert!(t.iter().all(|r| r.gap.is_none()));
        // The gap closure sees each row's records.
        let t = table_with("m", &res, true, |g| Some(g.len() as f64));
        assert_eq!(t.iter().map(|r| r.gap).collect::<Vec<_>>(), vec![Some(3.0), Some(2.0), Some(1.0)]);
        // No valid cell in both: no height error, but still a row.
        let preds = [empty_dem()];
        let sel: Selection = [(0, vec![1])].into();
        let res = evaluate(&sel, |i| &preds[i as usize], |j| &reals[j as usize], |_| None);
        let t = table("m", &res, false);
        assert_eq!((t[0].height_cm, t[0].rough_across_cm), (None, None));
        assert!(close(t[0].real_rough_across_cm, 0.0));
    }

    #[test]
    fn tables_read_with_the_old_and_the_new_header() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.csv").to_string_lossy().into_owned();
        let rows = vec![full("a"), TableRow { gap: None, height_cm: None, ..full("b") }];
        write_table_csv(&p, &rows).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.starts_with(&TABLE_HEADER.join(",")), "{text}");
        assert!(text.contains(",0.4,0.3,,0.1,0.2,0.3,0.4,,,,,,,,,\n"), "{text}");
        assert_eq!(read_table_csv(&p).unwrap(), rows);
        // The 13 columns before the frame columns: those are None.
        let mid: String = text.lines().map(|l| l.split(',').take(13).collect::<Vec<_>>().join(",") + "\n").collect();
        std::fs::write(&p, &mid).unwrap();
        assert_eq!(read_table_csv(&p).unwrap(), rows);
        // Frame columns round-trip; a correlation outside [-1, 1] is refused.
        let framed = vec![TableRow { frame_dh_mm: Some(5.1), frame_rcorr: Some(-0.2), real_frame_persist: Some(0.92), ..full("f") }];
        write_table_csv(&p, &framed).unwrap();
        assert_eq!(read_table_csv(&p).unwrap(), framed);
        write_table_csv(&p, &[TableRow { frame_rcorr: Some(1.5), ..full("f") }]).unwrap();
        assert!(read_table_csv(&p).unwrap_err().to_string().contains("correlations in [-1, 1]"));
        // The old header: the measures are None.
        let old = format!("{}\nold,all,56,0.005,2.6,0.548,0.13\n", OLD_TABLE_HEADER.join(","));
        let q = dir.path().join("old.csv").to_string_lossy().into_owned();
        std::fs::write(&q, &old).unwrap();
        assert_eq!(read_table_csv(&q).unwrap(), vec![TableRow { count: 56, lowest: 0.005, highest: 2.6, ..row("old", 0.548, 0.13) }]);
        // Joined with cat, either order.
        std::fs::write(&q, format!("{old}{text}")).unwrap();
        assert_eq!(read_table_csv(&q).unwrap().len(), 3);
        std::fs::write(&q, format!("{text}{old}")).unwrap();
        let joined = read_table_csv(&q).unwrap();
        assert_eq!((joined.len(), joined[2].method.as_str(), joined[2].gap), (3, "old", None));
        // A row of the wrong width, a negative measure: refused with the line.
        std::fs::write(&q, format!("{old}x,all,1,0,0,0,0,1\n")).unwrap();
        assert!(read_table_csv(&q).unwrap_err().to_string().contains("line 3"));
        std::fs::write(&q, text.replace(",0.3,0.4,2.0,", ",0.3,-0.4,2.0,")).unwrap();
        assert!(read_table_csv(&q).unwrap_err().to_string().contains(">= 0"));
        // JSON of an old table: the measures default to None.
        let js: Vec<TableRow> =
            serde_json::from_str(r#"[{"method":"a","terrain":"all","count":3,"lowest":0,"highest":1,"mean":0.4,"median":0.3}]"#).unwrap();
        assert_eq!(js, vec![row("a", 0.4, 0.3)]);
    }

    #[test]
    fn compare_fails_on_each_height_measure() {
        let base = [full("a")];
        let tol = Tolerances { pair: 0.02, height_cm: 0.5, rough_cm: 0.5, gap: 0.3, ..Tolerances::default() };
        let worse = |cur: TableRow| {
            let c = compare(&base, &[cur], &tol);
            assert_eq!(c[0].status == Status::Worse, !c[0].worse.is_empty());
            c[0].worse.clone()
        };
        assert!(worse(full("a")).is_empty());
        assert_eq!(worse(TableRow { height_cm: Some(2.0), ..full("a") }), Vec::<Measure>::new()); // +0.5: within
        assert_eq!(worse(TableRow { height_cm: Some(2.01), ..full("a") }), vec![Measure::HeightCm]);
        assert_eq!(worse(TableRow { height_cm: Some(0.1), ..full("a") }), Vec::<Measure>::new()); // better
                                                                                                  // Roughness: the distance from the real one counts, either side.
                                                                                                  // Across 0.1 vs real 0.3 (distance 0.2): 0.75 (distance 0.45, +0.25)
                                                                                                  // passes, 1.05 (0.75, +0.55) fails; so does the real side moving
                                                                                                  // away: real 0.9 (distance 0.8, +0.6).
        assert_eq!(worse(TableRow { rough_across_cm: Some(0.75), ..full("a") }), Vec::<Measure>::new());
        assert_eq!(worse(TableRow { rough_across_cm: Some(1.05), ..full("a") }), vec![Measure::RoughAcross]);
        assert_eq!(worse(TableRow { real_rough_across_cm: Some(0.9), ..full("a") }), vec![Measure::RoughAcross]);
        assert_eq!(worse(TableRow { rough_along_cm: Some(0.4), ..full("a") }), Vec::<Measure>::new()); // exactly real
        assert_eq!(worse(TableRow { rough_along_cm: Some(1.2), ..full("a") }), vec![Measure::RoughAlong]);
        assert_eq!(worse(TableRow { gap: Some(2.29), ..full("a") }), Vec::<Measure>::new());
        assert_eq!(worse(TableRow { gap: Some(2.31), ..full("a") }), vec![Measure::Gap]);
        assert_eq!(
            worse(TableRow { mean: 0.5, gap: Some(9.0), height_cm: Some(9.0), ..full("a") }),
            vec![Measure::Mean, Measure::HeightCm, Measure::Gap]
        );
        // A current row without a measure the baseline has: worse.
        assert_eq!(worse(TableRow { height_cm: None, ..full("a") }), vec![Measure::HeightCm]);
        // A baseline without the measures (an old table): only mean and median are checked.
        let c = compare(&[row("a", 0.4, 0.3)], &[TableRow { gap: Some(99.0), height_cm: Some(99.0), ..full("a") }], &tol);
        assert_eq!(c[0].status, Status::Ok);
        let c = compare(&[row("a", 0.4, 0.3)], &[row("a", 0.4, 0.3)], &tol);
        assert_eq!((c[0].status, c[0].diff(Measure::Gap), c[0].diff(Measure::Mean)), (Status::Ok, None, Some(0.0)));
        let c = compare(&base, &[TableRow { gap: Some(2.5), ..full("a") }], &tol);
        assert!((c[0].diff(Measure::Gap).unwrap() - 0.5).abs() < 1e-12);
        assert_eq!(Tolerances::default().gap, DEFAULT_GAP_TOLERANCE);
    }
}
