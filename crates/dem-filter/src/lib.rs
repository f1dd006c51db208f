//! Keep records by terrain, index, valid cells, valid rows in a region, and
//! uniqueness (the thesis's chapter 5: unique sim keys, no `other` terrain).

use std::collections::HashSet;
use std::hash::{Hash, Hasher};
use std::ops::Range;

use dem_core::error::{DemError, Result};
use dem_core::format::{Dem, DemCells, Terrain, COLS, GRID_CELLS};
use dem_core::npy::transform_checked;
use dem_core::table::{IndexRow, Label, RowWriter};

/// Rows that must be valid: keep a record when at least `min_rows` rows of
/// `rows` have every cell valid.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RowRule {
    /// Grid rows looked at (0 is 0.6 m behind C; 6.. is ahead of C).
    pub rows: Range<usize>,
    /// How many of them must be fully valid.
    pub min_rows: usize,
}

/// What to keep; every rule given must hold.
#[derive(Debug, Clone, Default)]
pub struct FilterRules {
    /// Per-record labels (needed by the terrain rules).
    pub labels: Option<(String, Vec<Label>)>,
    /// Keep only these terrains.
    pub terrains: Option<Vec<Terrain>>,
    /// Drop records labelled `other`.
    pub drop_other: bool,
    /// Keep records at most this many seconds into their run (the labels'
    /// `time`; 0 keeps the first frame of every run).
    pub max_time: Option<f64>,
    /// Keep records at least this many seconds into their run (past a
    /// run's startup frames).
    pub min_time: Option<f64>,
    /// Keep records of these runs (the labels' `sequence`), or with
    /// `except_runs` all other runs'.
    pub runs: Option<Vec<u64>>,
    /// Invert the runs rule: drop the records of `runs`.
    pub except_runs: bool,
    /// Keep only these indices (or all but these, with `invert_index`): the
    /// index CSV's path and its rows in file order.
    pub index: Option<(String, Vec<u64>)>,
    /// Invert the index rule.
    pub invert_index: bool,
    /// Keep records with at least this fraction of the 100 grid cells valid.
    pub min_valid: Option<f64>,
    /// Keep records with enough fully valid rows in a region.
    pub rows: Option<RowRule>,
    /// Drop records identical (bit for bit) to an earlier one.
    pub unique: bool,
}

/// Why records were dropped, counted per rule (the first failing rule).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FilterCounts {
    /// Records read.
    pub read: u64,
    /// Records kept.
    pub kept: u64,
    /// Dropped by terrain (including `other`).
    pub terrain: u64,
    /// Dropped by time in the run.
    pub time: u64,
    /// Dropped by run (the labels' `sequence`).
    pub run: u64,
    /// Dropped by the index rule.
    pub index: u64,
    /// Dropped for too few valid cells.
    pub valid: u64,
    /// Dropped for too few valid rows in the region.
    pub rows: u64,
    /// Dropped as duplicates.
    pub duplicate: u64,
}

/// A running filter: rules plus what it has seen.
pub struct Filter {
    rules: FilterRules,
    index: Option<HashSet<u64>>,
    seen: HashSet<u128>,
    /// Counts so far.
    pub counts: FilterCounts,
}

impl Filter {
    /// A filter over `rules`.
    pub fn new(rules: FilterRules) -> Self {
        let index = rules.index.as_ref().map(|(_, rows)| rows.iter().copied().collect());
        Filter { rules, index, seen: HashSet::new(), counts: FilterCounts::default() }
    }

    /// The labels the terrain rules read, when given.
    pub fn labels(&self) -> Option<&[Label]> {
        self.rules.labels.as_ref().map(|(_, l)| l.as_slice())
    }

    /// Decide on record `index` of the stream named `input`.
    pub fn keep(&mut self, input: &str, index: u64, d: &Dem) -> Result<bool> {
        self.counts.read += 1;
        let r = &self.rules;
        // Labels, when given, cover the stream whatever the rules: a kept
        // record's label is written out (`--emit-labels`).
        if let Some((path, labels)) = &r.labels {
            if labels.len() as u64 <= index {
                return Err(DemError::input(
                    path.as_str(),
                    format!("has {} rows but {input} has more records (record {index})", labels.len()),
                ));
            }
        }
        if r.terrains.is_some() || r.drop_other || r.max_time.is_some() || r.min_time.is_some() || r.runs.is_some() {
            let (path, labels) = r.labels.as_ref().ok_or_else(|| DemError::Usage("terrain, time and run rules need --labels".into()))?;
            let label = &labels[index as usize];
            let wanted = r.terrains.as_ref().is_none_or(|ts| ts.contains(&label.terrain));
            if !wanted || (r.drop_other && label.terrain == Terrain::Other) {
                self.counts.terrain += 1;
                return Ok(false);
            }
            if r.max_time.is_some() || r.min_time.is_some() {
                let t = label.time.ok_or_else(|| DemError::Table {
                    path: path.clone(),
                    line: index + 2,
                    reason: format!("record {index} has no time, which the time rule reads"),
                })?;
                if r.max_time.is_some_and(|max| t > max) || r.min_time.is_some_and(|min| t < min) {
                    self.counts.time += 1;
                    return Ok(false);
                }
            }
            if let Some(runs) = &r.runs {
                let run = label.sequence.ok_or_else(|| DemError::Table {
                    path: path.clone(),
                    line: index + 2,
                    reason: format!("record {index} has no sequence, which the run rule reads"),
                })?;
                if runs.contains(&run) == r.except_runs {
                    self.counts.run += 1;
                    return Ok(false);
                }
            }
        }
        if let Some(set) = &self.index {
            if set.contains(&index) == r.invert_index {
                self.counts.index += 1;
                return Ok(false);
            }
        }
        if let Some(min) = r.min_valid {
            if (d.valid_cells() as f64) < min * GRID_CELLS as f64 - 1e-9 {
                self.counts.valid += 1;
                return Ok(false);
            }
        }
        if let Some(rule) = &r.rows {
            let full = rule.rows.clone().filter(|&row| (0..COLS).all(|c| d.is_valid(row, c))).count();
            if full < rule.min_rows {
                self.counts.rows += 1;
                return Ok(false);
            }
        }
        if r.unique && !self.seen.insert(record_hash(d)) {
            self.counts.duplicate += 1;
            return Ok(false);
        }
        self.counts.kept += 1;
        Ok(true)
    }

    /// Check at the end of the stream that labels covered it exactly and
    /// that every index of the index CSV named a record.
    pub fn finish(&self, input: &str) -> Result<()> {
        if let Some((path, rows)) = &self.rules.index {
            if let Some(k) = rows.iter().position(|&i| i >= self.counts.read) {
                return Err(DemError::Table {
                    path: path.clone(),
                    line: k as u64 + 2,
                    reason: format!("index {} is past the end of {input} ({} records)", rows[k], self.counts.read),
                });
            }
        }
        if let Some((path, labels)) = &self.rules.labels {
            dem_core::table::check_labels_cover(path, labels.len(), input, self.counts.read)?;
        }
        Ok(())
    }
}

/// The files a filter run reads and writes.
#[derive(Debug, Clone, Default)]
pub struct FilterFiles {
    /// Input NPY stream (`-` for stdin).
    pub input: String,
    /// Output NPY stream (`-` for stdout).
    pub output: String,
    /// Write the input index of every kept record to this CSV.
    pub emit_index: Option<String>,
    /// Write the labels of the kept records (re-indexed from 0) to this CSV.
    pub emit_labels: Option<String>,
}

/// Stream `files.input` to `files.output`, keeping the records `rules`
/// keep. Kept indices and labels are written as they are decided, so memory
/// does not grow with the stream; every output appears only on success.
/// Returns the counts of kept and dropped records.
pub fn filter_stream(rules: FilterRules, files: &FilterFiles) -> Result<FilterCounts> {
    let mut emit_index = files.emit_index.as_deref().map(RowWriter::create).transpose()?;
    let mut emit_labels = files.emit_labels.as_deref().map(RowWriter::create).transpose()?;
    // Borrowed by the chunk loop and by the end-of-stream check.
    let filter = std::cell::RefCell::new(Filter::new(rules));
    let mut kept = 0u64;
    transform_checked(
        &files.input,
        &files.output,
        |first, chunk| {
            let mut i = first;
            let mut err = None;
            chunk.retain(|d| {
                let mut filter = filter.borrow_mut();
                let keep = err.is_none()
                    && filter
                        .keep(&files.input, i, d)
                        .and_then(|keep| {
                            if keep {
                                if let Some(w) = &mut emit_index {
                                    w.write(&IndexRow { index: i })?;
                                }
                                if let (Some(w), Some(all)) = (&mut emit_labels, filter.labels()) {
                                    w.write(&Label { index: kept, ..all[i as usize].clone() })?;
                                }
                                kept += 1;
                            }
                            Ok(keep)
                        })
                        .unwrap_or_else(|e| {
                            err = Some(e);
                            false
                        });
                i += 1;
                keep
            });
            err.map_or(Ok(()), Err)
        },
        |_| filter.borrow().finish(&files.input),
    )?;
    for w in [emit_index, emit_labels].into_iter().flatten() {
        w.commit()?;
    }
    Ok(filter.into_inner().counts)
}

/// 128-bit hash of a record's bits: two independent SipHash passes, so a
/// false duplicate among a billion records has odds of about 1e-20.
fn record_hash(d: &Dem) -> u128 {
    let bits: &[u32] = bytemuck::cast_slice(d.as_slice());
    let mut a = std::hash::DefaultHasher::new();
    bits.hash(&mut a);
    let mut b = std::hash::DefaultHasher::new();
    SALT.hash(&mut b);
    bits.hash(&mut b);
    (u128::from(a.finish()) << 64) | u128::from(b.finish())
}

/// Salt of the second hash pass (the golden ratio's bits).
const SALT: u64 = 0x9e37_79b9_7f4a_7c15;

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::format::empty_dem;
    use dem_core::{npy, table};

    #[test]
    fn filter_stream_writes_the_kept_records_their_indices_and_relabelled_labels() {
        let dir = dem_testkit::tempdir();
        let path = |n: &str| dem_testkit::arg(dir.path(), n);
        // Five records: heights 0..4; terrains alternate flat / pallet.
        let records: Vec<Dem> = (0..5)
            .map(|k| {
                let mut d = empty_dem();
                (0..GRID_CELLS).for_each(|i| d.set_valid(i / COLS, i % COLS, k as f32));
                d
            })
            .collect();
        npy::write_all(&path("in.npy"), &records).unwrap();
        let terrain = |k: u64| if k.is_multiple_of(2) { Terrain::Flat } else { Terrain::Pallet };
        let labels: Vec<Label> = (0..5)
            .map(|k| Label { index: k, terrain: terrain(k), x: None, y: None, yaw: None, sequence: Some(7), time: Some(k as f64) })
            .collect();
        let rules = FilterRules { labels: Some((path("l.csv"), labels)), terrains: Some(vec![Terrain::Pallet]), ..FilterRules::default() };
        let files = FilterFiles {
            input: path("in.npy"),
            output: path("out.npy"),
            emit_index: Some(path("index.csv")),
            emit_labels: Some(path("labels.csv")),
        };
        let counts = filter_stream(rules, &files).unwrap();
        assert_eq!((counts.read, counts.kept, counts.terrain), (5, 2, 3));
        let kept = npy::read_all(&path("out.npy")).unwrap();
        assert_eq!(kept, vec![records[1], records[3]]);
        assert_eq!(table::read_index(&path("index.csv")).unwrap(), vec![1, 3]);
        let relabelled = table::read_labels(&path("labels.csv")).unwrap();
        assert_eq!(relabelled.iter().map(|l| (l.index, l.time)).collect::<Vec<_>>(), vec![(0, Some(1.0)), (1, Some(3.0))]);

        // Runs: records 0..4 are runs 0, 1, 2, 0, 1 (sequence = k % 3).
        let labels: Vec<Label> = (0..5)
            .map(|k| Label { index: k, terrain: Terrain::Flat, x: None, y: None, yaw: None, sequence: Some(k % 3), time: None })
            .collect();
        for (except, want) in [(false, vec![1, 2, 4]), (true, vec![0, 3])] {
            let rules = FilterRules {
                labels: Some((path("r.csv"), labels.clone())),
                runs: Some(vec![1, 2]),
                except_runs: except,
                ..FilterRules::default()
            };
            let files =
                FilterFiles { input: path("in.npy"), output: path("runs.npy"), emit_index: Some(path("runs.csv")), emit_labels: None };
            let counts = filter_stream(rules, &files).unwrap();
            assert_eq!((counts.kept, counts.run), (want.len() as u64, 5 - want.len() as u64));
            assert_eq!(table::read_index(&path("runs.csv")).unwrap(), want);
        }

        // Labels that do not cover the stream: an error, and no output appears.
        let short = vec![Label { index: 0, terrain: Terrain::Flat, x: None, y: None, yaw: None, sequence: None, time: None }];
        let files = FilterFiles { output: path("out2.npy"), emit_index: Some(path("index2.csv")), ..files };
        let e = filter_stream(FilterRules { labels: Some((path("short.csv"), short)), ..FilterRules::default() }, &files).unwrap_err();
        assert!(e.to_string().contains("short.csv"), "{e}");
        assert!(!std::path::Path::new(&path("out2.npy")).exists() && !std::path::Path::new(&path("index2.csv")).exists());
    }
}
