//! The per-record results CSV (`--records`), written a row at a time and
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

use dem_core::eval::{RecordResult, Sum};
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

/// Read a records CSV (`-` for stdin). A file of an older dem-eval, without
/// the sums, is refused with the reason.
pub fn read(path: &str) -> anyhow::Result<Vec<RecordResult>> {
    let rows: Vec<Row> = dem_core::table::read_rows(path, &["sim_index", "real_index", "error", "terrain", "height_cm", "height_sum_m"])
        .map_err(|e| match e {
            DemError::Table { line: 1, .. } => DemError::input(
                path,
                "is not a per-record results CSV of this dem-eval (its header must be that of --records; \
                 files of older versions lack the sums a merge needs: run the shard again)",
            ),
            e => e,
        })?;
    let sum = |sum: f64, count: u64| Sum { sum, count };
    Ok(rows
        .into_iter()
        .map(|r| RecordResult {
            sim_index: r.sim_index,
            real_index: r.real_index,
            error: r.error,
            terrain: r.terrain.filter(|t| !t.is_empty()),
            height: sum(r.height_sum_m, r.height_n),
            rough_across: sum(r.rough_across_sum_m, r.rough_across_n),
            rough_along: sum(r.rough_along_sum_m, r.rough_along_n),
            real_rough_across: sum(r.real_rough_across_sum_m, r.real_rough_across_n),
            real_rough_along: sum(r.real_rough_along_sum_m, r.real_rough_along_n),
        })
        .collect())
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
}
