//! `dem-eval join`: tables (CSV or JSON, as dem-eval writes them) as one
//! table in any form, e.g. the rows of several runs into one CSV with one
//! header, a CSV table as Markdown for a report, or a pivot of methods by
//! terrain.

use clap::Args;
use dem_core::cli;
use dem_core::eval::forms::{read_table, write_pivot, write_table, Format};
use dem_core::eval::{check_table, Measure, TableRow};
use dem_core::output;

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
    #[arg(short, long = "out", alias = "output", default_value = "-")]
    pub output: String,
}

/// Read every table, refuse a (method, terrain) row that appears twice, and
/// write the rows in order.
pub fn run(a: JoinArgs) -> anyhow::Result<()> {
    output::check_outputs(&a.tables.iter().map(String::as_str).collect::<Vec<_>>(), &[&a.output])?;
    let mut rows: Vec<TableRow> = Vec::new();
    for t in &a.tables {
        rows.extend(read_table(t)?);
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

fn measure(s: &str) -> Result<Measure, String> {
    Measure::ALL.into_iter().find(|m| m.name() == s).ok_or_else(|| {
        format!("no measure {s:?} (one of: {})", Measure::ALL.map(Measure::name).join(", "))
    })
}
