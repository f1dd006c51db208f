//! The per-record results CSV (`--emit-records`), written a row at a time and
//! read back by `dem-eval merge`.
//!
//! A row carries everything a table row is made of: the pair error, the
//! terrain, and the pooled height and roughness measures as their exact
//! sums (metres, f64 shortest round trip) and counts. So the table of the
//! joined records of shards is, bit for bit, the table of one run:
//!
//! `sim_index,real_index,error,terrain,height_cm,` then, for each of
//! `height`, `rough_across`, `rough_along`, `real_rough_across`,
//! `real_rough_along`, `<name>_sum_m,<name>_n`.

use std::io::Write;

use crate::table::{RecordResult, Sum};
use dem_core::format::{COLS, GRID_CELLS, GRID_ROWS};
use dem_core::output::AtomicOutput;
use dem_core::DemError;
use serde::Deserialize;

/// The header of a records CSV.
pub const HEADER: &str = "sim_index,real_index,error,terrain,height_cm,\
height_sum_m,height_n,rough_across_sum_m,rough_across_n,rough_along_sum_m,rough_along_n,\
real_rough_across_sum_m,real_rough_across_n,real_rough_along_sum_m,real_rough_along_n";

/// The pooled sums of a result, in [`HEADER`] order.
fn sums(r: &RecordResult) -> [Sum; 5] {
    [r.height, r.rough_across, r.rough_along, r.real_rough_across, r.real_rough_along]
}

/// Per-record results as CSV ([`HEADER`]; terrain empty without labels;
/// height_cm, the mean abs height error against the closest real record on
/// cells valid in both, empty without such cells). By hand rather than
/// through a CSV writer, so a closed stdout stays a broken pipe (exit 0).
pub struct RecordsWriter {
    out: AtomicOutput,
    path: String,
}

impl RecordsWriter {
    /// Start writing `path` (`-` for stdout), header first.
    pub fn create(path: &str) -> anyhow::Result<Self> {
        let mut out = AtomicOutput::create(path)?;
        writeln!(out, "{HEADER}").map_err(|e| DemError::io(path, e))?;
        Ok(RecordsWriter { out, path: path.into() })
    }

    /// Append one result.
    pub fn write(&mut self, r: &RecordResult) -> anyhow::Result<()> {
        let h = r.height.mean_cm().map_or(String::new(), |h| h.to_string());
        let mut line = format!("{},{},{},{},{h}", r.sim_index, r.real_index, r.error, r.terrain.as_deref().unwrap_or(""));
        for s in sums(r) {
            line.push_str(&format!(",{},{}", s.sum, s.count));
        }
        writeln!(self.out, "{line}").map_err(|e| DemError::io(self.path.as_str(), e))?;
        Ok(())
    }

    /// Flush and move the file into place.
    pub fn finish(self) -> anyhow::Result<()> {
        Ok(self.out.commit()?)
    }
}

/// One row as read.
#[derive(Deserialize)]
struct Row {
    sim_index: u64,
    real_index: u64,
    error: f64,
    terrain: Option<String>,
    height_cm: Option<f64>,
    height_sum_m: f64,
    height_n: u64,
    rough_across_sum_m: f64,
    rough_across_n: u64,
    rough_along_sum_m: f64,
    rough_along_n: u64,
    real_rough_across_sum_m: f64,
    real_rough_across_n: u64,
    real_rough_along_sum_m: f64,
    real_rough_along_n: u64,
}

/// The largest pair error two records of the contract can give: every
/// cell's height and mask as far apart as two finite `f32` can be,
/// `(2 * f32::MAX)^2 * 2` (about 9.3e77). A larger one is not a result.
pub const MAX_ERROR: f64 = 1e78;

/// The largest sum of absolute height differences (m) a record can give:
/// 100 cells, each at most `2 * f32::MAX` (about 6.8e40).
pub const MAX_SUM_M: f64 = 1e41;

/// The most differences each sum of a record counts: the cells of the
/// grid (height), neighbours across (4 per row) and along (19 rows of 5).
const MAX_COUNTS: [u64; 5] = [
    GRID_CELLS as u64,
    (GRID_ROWS * (COLS - 1)) as u64,
    ((GRID_ROWS - 1) * COLS) as u64,
    (GRID_ROWS * (COLS - 1)) as u64,
    ((GRID_ROWS - 1) * COLS) as u64,
];

/// The sum columns of a records CSV, in [`HEADER`] order.
const SUM_NAMES: [&str; 5] = ["height", "rough_across", "rough_along", "real_rough_across", "real_rough_along"];

impl Row {
    /// The result this row holds, once every value is one a record can
    /// have: finite, not negative, within what two DEMs of the contract
    /// give, counts within the cells. Else an error naming the line and
    /// the column.
    fn result(self, path: &str, line: u64) -> Result<RecordResult, DemError> {
        let bad = |column: &str, reason: String| DemError::Table { path: path.into(), line, reason: format!("column {column}: {reason}") };
        let number = |column: &str, v: f64, max: f64| {
            if v.is_finite() && (0.0..=max).contains(&v) {
                Ok(())
            } else {
                Err(bad(column, format!("{v} is not a finite number in 0..={max:e}")))
            }
        };
        number("error", self.error, MAX_ERROR)?;
        if let Some(h) = self.height_cm {
            number("height_cm", h, 100.0 * MAX_SUM_M)?;
        }
        let raw = [
            (self.height_sum_m, self.height_n),
            (self.rough_across_sum_m, self.rough_across_n),
            (self.rough_along_sum_m, self.rough_along_n),
            (self.real_rough_across_sum_m, self.real_rough_across_n),
            (self.real_rough_along_sum_m, self.real_rough_along_n),
        ];
        let mut sums = [Sum::default(); 5];
        for (k, ((sum, count), name)) in raw.into_iter().zip(SUM_NAMES).enumerate() {
            number(&format!("{name}_sum_m"), sum, MAX_SUM_M)?;
            if count > MAX_COUNTS[k] {
                return Err(bad(&format!("{name}_n"), format!("{count} is more than the {} a record has", MAX_COUNTS[k])));
            }
            if count == 0 && sum != 0.0 {
                return Err(bad(&format!("{name}_sum_m"), format!("{sum} is a sum of no differences ({name}_n is 0)")));
            }
            sums[k] = Sum { sum, count };
        }
        let [height, rough_across, rough_along, real_rough_across, real_rough_along] = sums;
        Ok(RecordResult {
            sim_index: self.sim_index,
            real_index: self.real_index,
            error: self.error,
            terrain: self.terrain.filter(|t| !t.is_empty()),
            height,
            rough_across,
            rough_along,
            real_rough_across,
            real_rough_along,
        })
    }
}

/// Read a records CSV (`-` for stdin). A file of an older dem-eval, without
/// the sums, is refused with the reason; so is a value no record can have
/// (NaN, an infinity, a negative or out-of-range number, more differences
/// than a record has cells), naming the line and the column.
pub fn read(path: &str) -> anyhow::Result<Vec<RecordResult>> {
    let mut out = Vec::new();
    dem_core::table::for_each_row(path, &["sim_index", "real_index", "error", "terrain", "height_cm", "height_sum_m"], |line, r: Row| {
        out.push(r.result(path, line)?);
        Ok(())
    })
    .map_err(|e| match e {
        DemError::Table { line: 1, .. } => DemError::input(
            path,
            "is not a per-record results CSV of this dem-eval (its header must be that of --emit-records; \
             files of older versions lack the sums a merge needs: run the shard again)",
        ),
        e => e,
    })?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A row written and read back is the same result, every digit.
    #[test]
    fn a_record_round_trips_exactly() {
        let dir = dem_testkit::tempdir();
        let path = dir.path().join("r.csv").to_string_lossy().into_owned();
        let s = |sum: f64, count: u64| Sum { sum, count };
        let rs = vec![
            RecordResult {
                sim_index: 7,
                real_index: 3,
                error: 0.1 + 0.2,
                terrain: Some("pallet".into()),
                height: s(1.0 / 3.0, 12),
                rough_across: s(2e-9, 1),
                rough_along: s(0.0, 0),
                real_rough_across: s(123.456789012345, 80),
                real_rough_along: s(f64::MIN_POSITIVE, 95),
            },
            RecordResult {
                sim_index: 9,
                real_index: 0,
                error: 0.0,
                terrain: None,
                height: Sum::default(),
                rough_across: Sum::default(),
                rough_along: Sum::default(),
                real_rough_across: Sum::default(),
                real_rough_along: Sum::default(),
            },
        ];
        let mut w = RecordsWriter::create(&path).unwrap();
        rs.iter().for_each(|r| w.write(r).unwrap());
        w.finish().unwrap();
        assert_eq!(read(&path).unwrap(), rs);
    }

    /// The farthest apart two records of the contract can be (heights at
    /// +-f32::MAX, every neighbour apart, a raw mask at -f32::MAX) give a
    /// row the reader takes back: nothing the writer writes is refused.
    #[test]
    fn the_contract_s_extremes_are_read_back() {
        use dem_core::format::{empty_dem, DemCells};
        let (mut y, mut p) = (empty_dem(), empty_dem());
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                let s = if (r + c) % 2 == 0 { f32::MAX } else { -f32::MAX };
                y.set_valid(r, c, s);
                p.set_valid(r, c, -s);
            }
        }
        let mut q = p;
        for v in q.iter_mut().skip(1).step_by(2).take(GRID_CELLS) {
            *v = -f32::MAX;
        }
        let dir = dem_testkit::tempdir();
        let path = dir.path().join("r.csv").to_string_lossy().into_owned();
        let mut w = RecordsWriter::create(&path).unwrap();
        let mut rs = Vec::new();
        for pred in [p, q] {
            let ((rough_across, rough_along), (real_rough_across, real_rough_along)) =
                (crate::table::roughness(&pred), crate::table::roughness(&y));
            let r = RecordResult {
                sim_index: rs.len() as u64,
                real_index: 0,
                error: dem_core::metric::dem_error(&y, &pred),
                terrain: None,
                height: crate::table::height_error(&y, &pred),
                rough_across,
                rough_along,
                real_rough_across,
                real_rough_along,
            };
            assert!(r.error.is_finite() && r.error < MAX_ERROR && r.height.sum < MAX_SUM_M, "{r:?}");
            w.write(&r).unwrap();
            rs.push(r);
        }
        w.finish().unwrap();
        assert_eq!(read(&path).unwrap(), rs);
        assert_eq!(rs[0].height.count, 100);
        assert_eq!((rs[0].real_rough_across.count, rs[0].real_rough_along.count), (80, 95));
    }
}
