//! `dem-eval join`: tables (CSV or JSON, as dem-eval writes them) as one
//! table in any form, e.g. the rows of several runs into one CSV with one
//! header, a CSV table as Markdown for a report, or a pivot of methods by
//! terrain.

use crate::table::forms::{read_table, write_pivot, write_table, Format};
use crate::table::{check_table, Measure, TableRow};
use clap::Args;
use dem_core::cli;
use dem_core::{output, DemError};

/// Arguments of `dem-eval join`.
#[derive(Args)]
pub struct JoinArgs {
    /// Tables to join, in order (CSV or JSON written by dem-eval; `-` for stdin).
    #[arg(required = true)]
    pub tables: Vec<String>,
    /// Output format.
    #[arg(long, value_enum, default_value = "csv")]
    pub format: Format,
    /// Keep only the rows of this terrain (e.g. `all`, `stairs-up`).
    #[arg(long)]
    pub terrain: Option<String>,
    /// Write a pivot instead: one line per method, per terrain the count and
    /// these measures (comma-separated: mean, median, height_cm,
    /// rough_across, rough_along, gap; roughness as its distance from the
    /// real DEMs').
    #[arg(long, value_delimiter = ',', value_parser = measure)]
    pub pivot: Vec<Measure>,
    /// Output file (`-` for stdout).
    #[arg(short, long = "out", default_value = "-")]
    pub output: String,
}

/// Read every table, refuse a (method, terrain) row that appears twice, and
/// write the rows in order.
pub fn run(a: JoinArgs) -> anyhow::Result<()> {
    output::check_outputs(&a.tables.iter().map(String::as_str).collect::<Vec<_>>(), &[&a.output])?;
    let mut rows: Vec<TableRow> = Vec::new();
    for t in &a.tables {
        let table = read_table(t)?;
        check_finite(t, &table)?;
        rows.extend(table);
    }
    let mut rows = check_table(&a.tables.join(" + "), rows)?;
    if let Some(t) = &a.terrain {
        rows.retain(|r| r.terrain == *t);
        if rows.is_empty() {
            return Err(cli::usage(format!("--terrain {t}: no row of that terrain in {}", a.tables.join(", "))));
        }
    }
    if a.pivot.is_empty() {
        Ok(write_table(&a.output, &rows, a.format)?)
    } else {
        Ok(write_pivot(&a.output, &rows, &a.pivot, a.format)?)
    }
}

/// Refuse a table row whose pair errors are not finite (the table reader
/// refuses NaN, negative numbers and non-finite measures; this adds an
/// infinity, which no evaluation writes), naming the file, the row's line
/// (when the file can be read again: not on stdin) and the column.
pub fn check_finite(path: &str, rows: &[TableRow]) -> Result<(), DemError> {
    for r in rows {
        let errors = [("lowest", r.lowest), ("highest", r.highest), ("mean", r.mean), ("median", r.median)];
        if let Some((column, v)) = errors.iter().find(|(_, v)| !v.is_finite()) {
            let reason = format!("column {column}: {v} is not a finite number (row {}/{})", r.method, r.terrain);
            return Err(match line_of(path, &r.method, &r.terrain) {
                Some(line) => DemError::Table { path: path.into(), line, reason },
                None => DemError::input(path, reason),
            });
        }
    }
    Ok(())
}

/// The line of a CSV table that holds the row (method, terrain).
fn line_of(path: &str, method: &str, terrain: &str) -> Option<u64> {
    if path == "-" {
        return None;
    }
    let text = std::fs::read_to_string(path).ok()?;
    let at = text.lines().position(|l| {
        let mut f = l.split(',').map(|f| f.trim().trim_matches('"'));
        f.next() == Some(method) && f.next() == Some(terrain)
    })?;
    Some(at as u64 + 1)
}

fn measure(s: &str) -> Result<Measure, String> {
    Measure::ALL
        .into_iter()
        .find(|m| m.name() == s)
        .ok_or_else(|| format!("no measure {s:?} (one of: {})", Measure::ALL.map(Measure::name).join(", ")))
}
