//! dem-clean-pallet: fill the gaps between pallet boards in sim DEMs.

use std::process::ExitCode;

use clap::Parser;
use dem_clean_pallet::{fill_gaps, gap_cells, looks_like_pallet, StripeRule};
use dem_core::cli::{self, value};
use dem_core::npy::transform_checked;
use dem_core::{output, table, DemError, Terrain};

/// Make sim pallets solid (the thesis's pallet cleaning): a simulated pallet
/// sampled at cell centres shows the gaps between its top boards as stripes
/// of low cells, which a real depth sensor never shows. Each gap cell (lower
/// than the two level boards before and after it along x) is filled with
/// the boards' mean height.
///
/// Pallets are the records labelled `pallet` when --labels is given, else
/// the records that show a stripe of at least --min-row-cells gap cells in
/// one row. Every other record passes bit-identical.
#[derive(Parser)]
#[command(
    version,
    after_long_help = "Examples:
  dem-clean-pallet --labels sim_labels.csv sim.npy -o sim_clean.npy
  dem-filter --labels l.csv --terrain pallet sim.npy | dem-clean-pallet | dem-render - -o solid.png"
)]
struct Args {
    /// Input NPY stream (`-` for stdin).
    #[arg(default_value = "-")]
    input: String,
    /// Output NPY stream (`-` for stdout).
    #[arg(short, long = "out", default_value = "-")]
    output: String,
    /// Labels CSV of the input: clean the records labelled `pallet`.
    #[arg(long, value_name = "CSV")]
    labels: Option<String>,
    /// Boards either side of a gap differ by at most this (m).
    #[arg(long, default_value_t = 0.02, value_parser = value::non_negative::<f32>)]
    level_tol: f32,
    /// A gap is at least this much below the boards (m).
    #[arg(long, default_value_t = 0.05, value_parser = value::positive::<f32>)]
    min_depth: f32,
    /// ... and at most this much (m).
    #[arg(long, default_value_t = 0.2, value_parser = value::positive::<f32>)]
    max_depth: f32,
    /// Without --labels: gap cells in one row that make a record a pallet.
    #[arg(long, default_value_t = 3)]
    min_row_cells: usize,
}

fn main() -> ExitCode {
    cli::run(|| {
        let a: Args = cli::parse();
        let inputs: Vec<&str> = [Some(&a.input), a.labels.as_ref()].into_iter().flatten().map(String::as_str).collect();
        output::check_outputs(&inputs, &[&a.output])?;
        let rule = StripeRule { level_tol: a.level_tol, min_depth: a.min_depth, max_depth: a.max_depth, min_row_cells: a.min_row_cells };
        if !(rule.min_depth > 0.0 && rule.min_depth <= rule.max_depth && rule.level_tol >= 0.0) || rule.min_row_cells > 5 {
            return Err(cli::usage("need 0 < --min-depth <= --max-depth, --level-tol >= 0, --min-row-cells <= 5"));
        }
        let labels = a.labels.as_deref().map(table::read_labels).transpose()?;
        let (mut pallets, mut changed, mut cells) = (0u64, 0u64, 0u64);
        let (read, _) = transform_checked(
            &a.input,
            &a.output,
            |first, chunk| {
                for (k, d) in chunk.iter_mut().enumerate() {
                    let index = first + k as u64;
                    let gaps = gap_cells(d, &rule);
                    let is_pallet = match (&labels, a.labels.as_deref()) {
                        (Some(l), Some(path)) => {
                            let label = l.get(index as usize).ok_or_else(|| {
                                DemError::input(path, format!("has {} rows but {} has more records (record {index})", l.len(), a.input))
                            })?;
                            label.terrain == Terrain::Pallet
                        }
                        _ => looks_like_pallet(&gaps, &rule),
                    };
                    if is_pallet {
                        pallets += 1;
                        let n = fill_gaps(d, &gaps);
                        changed += u64::from(n > 0);
                        cells += n as u64;
                    }
                }
                Ok(())
            },
            |read| match (&labels, &a.labels) {
                (Some(l), Some(path)) => Ok(dem_core::table::check_labels_cover(path, l.len(), &a.input, read)?),
                _ => Ok(()),
            },
        )?;
        let how = if labels.is_some() { "labelled" } else { "found by shape" };
        cli::log(format_args!("{pallets} of {read} records are pallets ({how}); cleaned {changed}, filling {cells} gap cells"));
        Ok(())
    })
}
