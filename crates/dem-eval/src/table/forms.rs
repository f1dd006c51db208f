//! The forms of a validation table and of a comparison of two: aligned
//! text, CSV, JSON and Markdown, written by one writer and read back (CSV
//! or JSON) by one reader, so every tool that prints or reads a table
//! (dem-eval and its subcommands, CI's baseline) agrees on them. CSV and JSON carry every digit
//! (f64 shortest round trip); text and Markdown four decimals for the pair
//! error, two for centimetres and three for the gap, `-` for a measure a
//! row lacks.

use std::io::Write;

use super::{check_table, read_table_csv, Compared, Measure, Status, TableRow, TABLE_HEADER};
use clap::ValueEnum;
use dem_core::error::{DemError, Result};
use dem_core::output::AtomicOutput;
use serde::Serialize;

/// Output format of a table.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// Aligned columns for people (pair error four decimals, cm two, gap three).
    Text,
    /// CSV, every digit: the machine-readable table `compare` reads.
    Csv,
    /// A JSON array of rows, every digit (`compare` reads it too).
    Json,
    /// A Markdown table (as text).
    Md,
}

/// A grid of strings: column groups (text shows them on a line of their own),
/// column names and rows.
pub struct Grid<'a> {
    /// (group, name) of each column; group "" for none.
    pub cols: Vec<(&'a str, &'a str)>,
    /// The cells, row by row.
    pub rows: Vec<Vec<String>>,
}

impl Grid<'_> {
    fn name(&self, i: usize, sep: &str) -> String {
        match self.cols[i] {
            ("", n) => n.into(),
            (g, n) => format!("{g}{sep}{n}"),
        }
    }

    /// Write the grid in form `f` (JSON writes CSV: a grid has no types).
    pub fn write(&self, w: &mut impl Write, f: Format) -> std::io::Result<()> {
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
                let width: Vec<usize> =
                    (0..n).map(|i| self.rows.iter().map(|r| r[i].len()).chain([self.cols[i].1.len()]).max().unwrap_or(0)).collect();
                // The leading names (method, terrain) to the left, numbers to the right.
                let is_name = |i: usize| i == 0 || (i == 1 && self.rows.iter().any(|r| r[1].parse::<f64>().is_err() && r[1] != "-"));
                let line = |cells: Vec<&str>| {
                    let s: Vec<String> = cells
                        .iter()
                        .enumerate()
                        .map(|(i, c)| if is_name(i) { format!("{c:<w$}", w = width[i]) } else { format!("{c:>w$}", w = width[i]) })
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

/// A measure that may be absent, with `decimals` for people (`-` when absent;
/// an empty CSV field).
pub fn opt(v: Option<f64>, decimals: usize, sign: bool, f: Format) -> String {
    match (v, f) {
        (None, Format::Csv) => String::new(),
        (None, _) => "-".into(),
        (Some(v), Format::Csv | Format::Json) => format!("{v}"),
        (Some(v), _) if sign => format!("{v:+.decimals$}"),
        (Some(v), _) => format!("{v:.decimals$}"),
    }
}

/// The height measures of a row, in [`TABLE_HEADER`] order.
fn measures(r: &TableRow, f: Format) -> Vec<String> {
    let cm = [r.height_cm, r.rough_across_cm, r.rough_along_cm, r.real_rough_across_cm, r.real_rough_along_cm];
    let mut v: Vec<String> = cm.iter().map(|&x| opt(x, 2, false, f)).collect();
    v.push(opt(r.gap, 3, false, f));
    for (dh, rcorr, flip, persist) in [
        (r.frame_dh_mm, r.frame_rcorr, r.frame_flip, r.frame_persist),
        (r.real_frame_dh_mm, r.real_frame_rcorr, r.real_frame_flip, r.real_frame_persist),
    ] {
        v.extend([opt(dh, 2, false, f), opt(rcorr, 2, false, f), opt(flip, 3, false, f), opt(persist, 3, false, f)]);
    }
    v
}

/// Decimals of measure `m` for people.
fn decimals(m: Measure) -> usize {
    match m {
        Measure::Mean | Measure::Median => 4,
        Measure::HeightCm | Measure::RoughAcross | Measure::RoughAlong => 2,
        Measure::Gap | Measure::FrameFlip | Measure::FramePersist => 3,
        Measure::FrameDh | Measure::FrameRcorr => 2,
    }
}

/// Write `body` to `path` (`-` for stdout), atomically for files.
pub fn emit(path: &str, body: impl FnOnce(&mut AtomicOutput) -> std::io::Result<()>) -> Result<()> {
    let mut out = AtomicOutput::create(path)?;
    body(&mut out).map_err(|e| DemError::io(path, e))?;
    out.commit()
}

/// Write a validation table.
pub fn write_table(path: &str, rows: &[TableRow], f: Format) -> Result<()> {
    if f == Format::Csv {
        return super::write_table_csv(path, rows);
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
                v.extend(measures(r, f));
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
    diff_height_cm: Option<f64>,
    /// Growth of |rough_across_cm - real_rough_across_cm|.
    diff_rough_across: Option<f64>,
    /// Growth of |rough_along_cm - real_rough_along_cm|.
    diff_rough_along: Option<f64>,
    diff_gap: Option<f64>,
    /// Growth of |frame_dh_mm - real_frame_dh_mm|.
    diff_frame_dh: Option<f64>,
    /// Growth of |frame_rcorr - real_frame_rcorr|.
    diff_frame_rcorr: Option<f64>,
    /// Growth of |frame_flip - real_frame_flip|.
    diff_frame_flip: Option<f64>,
    /// Growth of |frame_persist - real_frame_persist|.
    diff_frame_persist: Option<f64>,
    /// The measures that made the row worse.
    worse: &'a [Measure],
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
/// (current minus baseline) of every measure compare checks (for roughness:
/// of its distance from the real roughness, |rough - real_rough|), the
/// verdict of each row and the measures that failed.
pub fn write_comparison(path: &str, rows: &[Compared], f: Format) -> Result<()> {
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
                    diff_mean: c.diff(Measure::Mean),
                    diff_median: c.diff(Measure::Median),
                    diff_height_cm: c.diff(Measure::HeightCm),
                    diff_rough_across: c.diff(Measure::RoughAcross),
                    diff_rough_along: c.diff(Measure::RoughAlong),
                    diff_gap: c.diff(Measure::Gap),
                    diff_frame_dh: c.diff(Measure::FrameDh),
                    diff_frame_rcorr: c.diff(Measure::FrameRcorr),
                    diff_frame_flip: c.diff(Measure::FrameFlip),
                    diff_frame_persist: c.diff(Measure::FramePersist),
                    worse: &c.worse,
                })
                .collect();
            serde_json::to_writer_pretty(&mut *w, &js).map_err(std::io::Error::other)?;
            return writeln!(w);
        }
        let mut cols = vec![("", "method"), ("", "terrain")];
        for g in ["baseline", "current"] {
            cols.extend(TABLE_HEADER[2..].iter().map(|&c| (g, c)));
        }
        cols.extend(Measure::ALL.map(|m| ("diff", m.name())));
        cols.extend([("", "status"), ("", "worse")]);
        let side = |r: Option<&TableRow>| match r {
            Some(r) => {
                let mut v = vec![r.count.to_string()];
                v.extend([r.lowest, r.highest, r.mean, r.median].map(|x| num(x, f)));
                v.extend(measures(r, f));
                v
            }
            None => vec![if f == Format::Csv { String::new() } else { "-".into() }; TABLE_HEADER.len() - 2],
        };
        let grid_rows = rows
            .iter()
            .map(|c| {
                let mut v = vec![c.method.clone(), c.terrain.clone()];
                v.extend(side(c.baseline.as_ref()));
                v.extend(side(c.current.as_ref()));
                v.extend(Measure::ALL.map(|m| match c.diff(m) {
                    Some(d) if decimals(m) == 4 => signed(d, f),
                    d => opt(d, decimals(m), true, f),
                }));
                v.push(if f == Format::Csv { format!("{:?}", c.status).to_lowercase() } else { status_str(c.status).into() });
                // `;` keeps the CSV field unquoted.
                v.push(c.worse.iter().map(|m| m.name()).collect::<Vec<_>>().join(if f == Format::Csv { ";" } else { "," }));
                v
            })
            .collect();
        Grid { cols, rows: grid_rows }.write(w, f)
    })
}

/// Write `rows` as a pivot: one line per method, for each terrain a group
/// of columns, `count` and each of `measures` ([`Measure::value`]), methods
/// and terrains in the order they first appear. A method without a row for
/// a terrain has empty cells (`-` for people). JSON is written as CSV.
pub fn write_pivot(path: &str, rows: &[TableRow], measures: &[Measure], f: Format) -> Result<()> {
    let (mut methods, mut terrains): (Vec<&str>, Vec<&str>) = (Vec::new(), Vec::new());
    for r in rows {
        if !methods.contains(&r.method.as_str()) {
            methods.push(&r.method);
        }
        if !terrains.contains(&r.terrain.as_str()) {
            terrains.push(&r.terrain);
        }
    }
    let mut cols = vec![("", "method")];
    for t in &terrains {
        cols.push((*t, "count"));
        cols.extend(measures.iter().map(|m| (*t, m.name())));
    }
    let empty = || if f == Format::Csv { String::new() } else { "-".into() };
    let grid_rows = methods
        .iter()
        .map(|m| {
            let mut v = vec![m.to_string()];
            for t in &terrains {
                match rows.iter().find(|r| r.method == *m && r.terrain == *t) {
                    Some(r) => {
                        v.push(r.count.to_string());
                        v.extend(measures.iter().map(|&x| opt(x.value(r), decimals(x), false, f)));
                    }
                    None => v.extend(std::iter::repeat_with(empty).take(1 + measures.len())),
                }
            }
            v
        })
        .collect();
    emit(path, |w| Grid { cols, rows: grid_rows }.write(w, f))
}

/// Read a table written by dem-eval: JSON (one or more arrays back to back,
/// as `cat a.json b.json` makes them) when the file starts with `[`, else
/// CSV ([`read_table_csv`]: the old header too, repeated headers skipped).
pub fn read_table(path: &str) -> Result<Vec<TableRow>> {
    let text = if path == "-" { None } else { std::fs::read(path).ok() };
    if text.as_deref().is_some_and(|t| t.trim_ascii_start().starts_with(b"[")) {
        let text = text.unwrap_or_default();
        let mut rows = Vec::new();
        for v in serde_json::Deserializer::from_slice(&text).into_iter::<Vec<TableRow>>() {
            rows.extend(v.map_err(|e| DemError::Table { path: path.into(), line: e.line() as u64, reason: e.to_string() })?);
        }
        return check_table(path, rows);
    }
    read_table_csv(path)
}
