//! The tables dem-eval prints: a validation table, or a comparison of two,
//! as aligned text, CSV, JSON or Markdown. CSV and JSON carry every digit
//! (f64 shortest round trip), text and Markdown four decimals.

use std::io::Write;

use clap::ValueEnum;
use dem_core::eval::{Compared, RecordResult, Status, TableRow, TABLE_HEADER};
use dem_core::output::AtomicOutput;
use dem_core::DemError;
use serde::Serialize;

/// Output format of a table.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// Aligned columns for people (four decimals).
    Text,
    /// CSV, every digit: the machine-readable table `compare` reads.
    Csv,
    /// A JSON array of rows, every digit (`compare` reads it too).
    Json,
    /// A Markdown table (four decimals).
    Md,
}

/// A grid of strings: column groups (text shows them on a line of their own),
/// column names and rows.
struct Grid {
    cols: Vec<(&'static str, &'static str)>,
    rows: Vec<Vec<String>>,
}

impl Grid {
    fn name(&self, i: usize, sep: &str) -> String {
        match self.cols[i] {
            ("", n) => n.into(),
            (g, n) => format!("{g}{sep}{n}"),
        }
    }

    fn write(&self, w: &mut impl Write, f: Format) -> std::io::Result<()> {
        let n = self.cols.len();
        match f {
            Format::Csv | Format::Json => {
                let head: Vec<String> = (0..n).map(|i| self.name(i, "_")).collect();
                writeln!(w, "{}", head.join(","))?;
                for r in &self.rows {
                    writeln!(w, "{}", r.iter().map(|v| csv_field(v)).collect::<Vec<_>>().join(","))?;
                }
            }
            Format::Md => {
                let head: Vec<String> = (0..n).map(|i| self.name(i, " ")).collect();
                writeln!(w, "| {} |", head.join(" | "))?;
                writeln!(w, "|{}", "---|".repeat(n))?;
                for r in &self.rows {
                    writeln!(w, "| {} |", r.join(" | "))?;
                }
            }
            Format::Text => {
                let width: Vec<usize> = (0..n)
                    .map(|i| self.rows.iter().map(|r| r[i].len()).chain([self.cols[i].1.len()]).max().unwrap_or(0))
                    .collect();
                let line = |cells: Vec<&str>| {
                    let s: Vec<String> = cells
                        .iter()
                        .enumerate()
                        .map(|(i, c)| if i < 2 { format!("{c:<w$}", w = width[i]) } else { format!("{c:>w$}", w = width[i]) })
                        .collect();
                    s.join("  ").trim_end().to_string()
                };
                if self.cols.iter().any(|c| !c.0.is_empty()) {
                    // A group title starts over the group's first column.
                    let mut groups = Vec::new();
                    for i in 0..n {
                        let first = i == 0 || self.cols[i - 1].0 != self.cols[i].0;
                        groups.push(if first { self.cols[i].0 } else { "" });
                    }
                    let s: Vec<String> = groups.iter().enumerate().map(|(i, g)| format!("{g:<w$}", w = width[i])).collect();
                    writeln!(w, "{}", s.join("  ").trim_end())?;
                }
                writeln!(w, "{}", line(self.cols.iter().map(|c| c.1).collect()))?;
                for r in &self.rows {
                    writeln!(w, "{}", line(r.iter().map(String::as_str).collect()))?;
                }
            }
        }
        Ok(())
    }
}

fn csv_field(v: &str) -> String {
    if v.contains([',', '"', '\n']) {
        format!("\"{}\"", v.replace('"', "\"\""))
    } else {
        v.to_string()
    }
}

/// A number as the format wants it: every digit for machines, four
/// decimals for people.
fn num(v: f64, f: Format) -> String {
    match f {
        Format::Csv | Format::Json => format!("{v}"),
        Format::Text | Format::Md => format!("{v:.4}"),
    }
}

fn signed(v: f64, f: Format) -> String {
    match f {
        Format::Csv | Format::Json => format!("{v}"),
        Format::Text | Format::Md => format!("{v:+.4}"),
    }
}

/// Write `body` to `path` (`-` for stdout), atomically for files.
fn emit(path: &str, body: impl FnOnce(&mut AtomicOutput) -> std::io::Result<()>) -> anyhow::Result<()> {
    let mut out = AtomicOutput::create(path)?;
    body(&mut out).map_err(|e| DemError::io(path, e))?;
    Ok(out.commit()?)
}

/// Write a validation table.
pub fn write_table(path: &str, rows: &[TableRow], f: Format) -> anyhow::Result<()> {
    if f == Format::Csv {
        return Ok(dem_core::eval::write_table_csv(path, rows)?);
    }
    emit(path, |w| {
        if f == Format::Json {
            serde_json::to_writer_pretty(&mut *w, rows).map_err(std::io::Error::other)?;
            return writeln!(w);
        }
        let cols = TABLE_HEADER.iter().map(|&c| ("", c)).collect();
        let rows = rows
            .iter()
            .map(|r| {
                let mut v = vec![r.method.clone(), r.terrain.clone(), r.count.to_string()];
                v.extend([r.lowest, r.highest, r.mean, r.median].map(|x| num(x, f)));
                v
            })
            .collect();
        Grid { cols, rows }.write(w, f)
    })
}

/// One row of a comparison as JSON.
#[derive(Serialize)]
struct ComparedJson<'a> {
    method: &'a str,
    terrain: &'a str,
    status: Status,
    baseline: Option<&'a TableRow>,
    current: Option<&'a TableRow>,
    diff_mean: Option<f64>,
    diff_median: Option<f64>,
}

fn status_str(s: Status) -> &'static str {
    match s {
        Status::Ok => "ok",
        Status::Worse => "WORSE",
        Status::Missing => "MISSING",
        Status::New => "new",
    }
}

/// Write a comparison: baseline and current side by side, the differences
/// of mean and median (current minus baseline) and the verdict of each row.
pub fn write_comparison(path: &str, rows: &[Compared], f: Format) -> anyhow::Result<()> {
    let diff = |c: &Compared, g: fn(&TableRow) -> f64| Some(g(c.current.as_ref()?) - g(c.baseline.as_ref()?));
    emit(path, |w| {
        if f == Format::Json {
            let js: Vec<ComparedJson> = rows
                .iter()
                .map(|c| ComparedJson {
                    method: &c.method,
                    terrain: &c.terrain,
                    status: c.status,
                    baseline: c.baseline.as_ref(),
                    current: c.current.as_ref(),
                    diff_mean: diff(c, |r| r.mean),
                    diff_median: diff(c, |r| r.median),
                })
                .collect();
            serde_json::to_writer_pretty(&mut *w, &js).map_err(std::io::Error::other)?;
            return writeln!(w);
        }
        let mut cols = vec![("", "method"), ("", "terrain")];
        for g in ["baseline", "current"] {
            cols.extend(["count", "lowest", "highest", "mean", "median"].map(|c| (g, c)));
        }
        cols.extend([("diff", "mean"), ("diff", "median"), ("", "status")]);
        let side = |r: Option<&TableRow>| match r {
            Some(r) => {
                let mut v = vec![r.count.to_string()];
                v.extend([r.lowest, r.highest, r.mean, r.median].map(|x| num(x, f)));
                v
            }
            None => vec![if f == Format::Csv { String::new() } else { "-".into() }; 5],
        };
        let opt = |v: Option<f64>| v.map_or_else(|| if f == Format::Csv { String::new() } else { "-".into() }, |v| signed(v, f));
        let grid_rows = rows
            .iter()
            .map(|c| {
                let mut v = vec![c.method.clone(), c.terrain.clone()];
                v.extend(side(c.baseline.as_ref()));
                v.extend(side(c.current.as_ref()));
                v.extend([opt(diff(c, |r| r.mean)), opt(diff(c, |r| r.median))]);
                v.push(if f == Format::Csv { format!("{:?}", c.status).to_lowercase() } else { status_str(c.status).into() });
                v
            })
            .collect();
        Grid { cols, rows: grid_rows }.write(w, f)
    })
}

/// Write per-record results as CSV, `sim_index,real_index,error,terrain`
/// (terrain empty without labels). By hand rather than through
/// `table::write_rows`, so a closed stdout stays a broken pipe (exit 0).
pub fn write_records(path: &str, rows: &[RecordResult]) -> anyhow::Result<()> {
    emit(path, |w| {
        writeln!(w, "sim_index,real_index,error,terrain")?;
        for r in rows {
            writeln!(w, "{},{},{},{}", r.sim_index, r.real_index, r.error, r.terrain.as_deref().unwrap_or(""))?;
        }
        Ok(())
    })
}
