//! dem-fill-nans: fill the large missing areas of startup frames.

use std::collections::HashSet;
use std::process::ExitCode;

use clap::Parser;
use dem_core::cli::{self, value};
use dem_core::npy::transform;
use dem_core::output;
use dem_fill_nans::{fill_from_own_heights, is_large, keep_exactly, record_uniform};

/// Fill the missing cells of records with a large missing area (the thesis's
/// NaN removal): such records (a run's first frames, before the map has seen
/// the rows behind the robot) are kept as they are for --keep of them, and
/// in the others every missing cell gets a height drawn at random from the
/// same record's valid cells and is marked valid. Records with a smaller
/// missing area pass bit-identical.
///
/// Which records are kept and which heights are drawn depend only on --seed
/// and the record index.
#[derive(Parser)]
#[command(
    version,
    after_long_help = "Examples:
  dem-fill-nans --min-missing 0.3 --keep-fraction 0.2 --seed 1 real.npy -o real_filled.npy
  dem-fill-nans --keep 50 real.npy -o real_filled.npy       # exactly 50 kept (needs a file)
  dem-synth --out run/ && dem-fill-nans run/real.npy | dem-render - -o filled.png"
)]
struct Args {
    /// Input NPY stream (`-` for stdin; a file for --keep).
    #[arg(default_value = "-")]
    input: String,
    /// Output NPY stream (`-` for stdout).
    #[arg(short, long = "out", default_value = "-")]
    output: String,
    /// A record has a large missing area when at least this fraction of its
    /// 100 grid cells is missing.
    #[arg(long, default_value_t = 0.3, value_parser = value::fraction::<f64>)]
    min_missing: f64,
    /// Keep this fraction of the large-missing records unfilled (chosen at random).
    #[arg(long, default_value_t = 0.2, conflicts_with = "keep", value_parser = value::fraction::<f64>)]
    keep_fraction: f64,
    /// Keep exactly this many large-missing records unfilled (chosen at
    /// random; reads the input twice, so it must be a file).
    #[arg(long)]
    keep: Option<u64>,
    /// Seed of the choices and draws.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Index of the input's first record in the whole data set, when the
    /// input is a shard (`dem-split` prints it): choices and draws follow the
    /// index in the whole, so joined shards equal one run on the whole.
    #[arg(long, default_value_t = 0, conflicts_with = "keep")]
    first_index: u64,
}

fn main() -> ExitCode {
    cli::run(|| {
        let a: Args = cli::parse();
        output::check_outputs(&[&a.input], &[&a.output])?;
        let large = |d: &dem_core::Dem| is_large(d, a.min_missing);
        let kept_set: Option<HashSet<u64>> = match a.keep {
            None => None,
            Some(_) if a.input == "-" => {
                return Err(cli::usage("--keep N reads the input twice: give a file, or use --keep-fraction"));
            }
            Some(n) => Some(keep_exactly(&a.input, n, a.seed, a.min_missing)?),
        };
        let (mut found, mut kept, mut filled, mut cells, mut empty) = (0u64, 0u64, 0u64, 0u64, 0u64);
        let (read, _) = transform(&a.input, &a.output, |first, chunk| {
            for (k, d) in chunk.iter_mut().enumerate().filter(|(_, d)| large(d)) {
                let i = a.first_index + first + k as u64;
                found += 1;
                let keep = match &kept_set {
                    Some(set) => set.contains(&i),
                    None => record_uniform(a.seed, i) < a.keep_fraction,
                };
                if keep {
                    kept += 1;
                    continue;
                }
                let missing = dem_core::format::GRID_CELLS as u64 - dem_core::DemCells::valid_cells(d) as u64;
                if fill_from_own_heights(d, a.seed, i) {
                    filled += 1;
                    cells += missing;
                } else {
                    empty += 1;
                }
            }
            Ok(())
        })?;
        cli::log(format_args!(
            "{found} of {read} records have >= {:.0}% missing: kept {kept}, filled {filled} ({cells} cells), {empty} without any valid cell left as they are",
            a.min_missing * 100.0
        ));
        Ok(())
    })
}
