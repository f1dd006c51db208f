//! dem-filter: keep DEM records by terrain, index, valid cells and uniqueness.

use std::process::ExitCode;

use clap::Parser;

use dem_core::cli::{self, value};
use dem_core::table;
use dem_core::{output, Terrain};
use dem_filter::{filter_stream, FilterFiles, FilterRules, RowRule};

/// Keep the records of an NPY stream that pass every rule given, in order.
///
/// Rules: terrain (from a labels CSV), an index CSV (or its complement),
/// a minimum fraction of valid cells, fully valid rows in a region (e.g.
/// ahead of the robot), and uniqueness. --emit-index and --emit-labels write
/// what was kept, so labels and other files can follow the records.
#[derive(Parser)]
#[command(
    version,
    after_long_help = "Examples:
  dem-filter --labels l.csv --terrain stairs-up,pallet < sim.npy | dem-render - -o stairs.png
  dem-filter --labels real_labels.csv --max-time 0 real.npy -o first_frames.npy   # each run's first frame
  dem-filter --labels real_labels.csv --min-time 6 real.npy -o settled.npy --emit-labels settled_labels.csv   # past startup
  dem-filter --labels sim_labels.csv --drop-other --unique --emit-index keep.csv sim.npy -o sim_clean.npy
  dem-filter --index keep.csv --invert sim.npy -o rest.npy     # the complement
  dem-filter --labels real_labels.csv --runs 3,4,5 real.npy -o test.npy --emit-labels test_labels.csv   # held-out runs
  dem-filter --labels real_labels.csv --except-runs 3,4,5 real.npy -o train.npy                      # all other runs
  dem-filter --rows 6..20 --min-valid 0.5 real.npy -o seen_ahead.npy"
)]
struct Args {
    /// Input NPY stream (`-` for stdin).
    #[arg(default_value = "-")]
    input: String,
    /// Output NPY stream (`-` for stdout).
    #[arg(short, long = "out", default_value = "-")]
    output: String,
    /// Labels CSV of the input (index,terrain,...), for the terrain rules.
    #[arg(long, value_name = "CSV")]
    labels: Option<String>,
    /// Keep only these terrains (comma-separated).
    #[arg(long, value_delimiter = ',')]
    terrain: Option<Vec<Terrain>>,
    /// Drop records labelled `other` (ramps, rubble: not flat, stairs or pallet).
    #[arg(long)]
    drop_other: bool,
    /// Keep records at most this many seconds into their run (the labels'
    /// `time`): `--max-time 0` keeps the first frame of every run.
    #[arg(long, value_parser = value::non_negative::<f64>)]
    max_time: Option<f64>,
    /// Keep records at least this many seconds into their run (the labels'
    /// `time`): `--min-time 6` leaves out the startup frames of runs whose
    /// map needs 6 s to see behind the robot.
    #[arg(long, value_parser = value::non_negative::<f64>)]
    min_time: Option<f64>,
    /// Keep only the records of these runs (the labels' `sequence`;
    /// comma-separated numbers).
    #[arg(long, value_delimiter = ',')]
    runs: Option<Vec<u64>>,
    /// Keep the records of all runs but these (comma-separated).
    #[arg(long, value_delimiter = ',', conflicts_with = "runs")]
    except_runs: Option<Vec<u64>>,
    /// Keep only the records listed in this index CSV (header `index`).
    #[arg(long, value_name = "CSV")]
    index: Option<String>,
    /// With --index: keep the records NOT listed.
    #[arg(long, requires = "index")]
    invert: bool,
    /// Keep records with at least this fraction (0..1) of grid cells valid.
    #[arg(long, value_parser = value::fraction::<f64>)]
    min_valid: Option<f64>,
    /// Region of grid rows A..B (0-based, B excluded) for --min-rows.
    #[arg(long, value_parser = parse_rows)]
    rows: Option<std::ops::Range<usize>>,
    /// Fully valid rows needed in --rows (default: all of them).
    #[arg(long, requires = "rows")]
    min_rows: Option<usize>,
    /// Drop records identical to an earlier one.
    #[arg(long)]
    unique: bool,
    /// Write the input indices of kept records to this CSV.
    #[arg(long)]
    emit_index: Option<String>,
    /// Write the labels of kept records (re-indexed from 0) to this CSV.
    #[arg(long, value_name = "CSV", requires = "labels")]
    emit_labels: Option<String>,
}

fn parse_rows(s: &str) -> Result<std::ops::Range<usize>, String> {
    let (a, b) = s.split_once("..").ok_or("expected A..B, e.g. 6..20")?;
    let (a, b): (usize, usize) = (a.parse().map_err(|_| "bad start")?, b.parse().map_err(|_| "bad end")?);
    if a >= b || b > 20 {
        return Err(format!("{s}: need 0 <= A < B <= 20"));
    }
    Ok(a..b)
}

fn main() -> ExitCode {
    cli::run(|| {
        let a: Args = cli::parse();
        let runs_rule = a.runs.is_some() || a.except_runs.is_some();
        if (a.terrain.is_some() || a.drop_other || a.max_time.is_some() || a.min_time.is_some() || runs_rule) && a.labels.is_none() {
            return Err(cli::usage("--terrain, --drop-other, --max-time, --min-time, --runs and --except-runs need --labels"));
        }
        let inputs: Vec<&str> = [Some(&a.input), a.labels.as_ref(), a.index.as_ref()].into_iter().flatten().map(String::as_str).collect();
        let outputs: Vec<&str> =
            [Some(&a.output), a.emit_index.as_ref(), a.emit_labels.as_ref()].into_iter().flatten().map(String::as_str).collect();
        output::check_outputs(&inputs, &outputs)?;
        let labels = a.labels.as_deref().map(|p| table::read_labels(p).map(|l| (p.to_string(), l))).transpose()?;
        let rows = a.rows.map(|rows| RowRule { min_rows: a.min_rows.unwrap_or(rows.len()), rows });
        if rows.as_ref().is_some_and(|r| r.min_rows > r.rows.len()) {
            return Err(cli::usage("--min-rows is larger than the --rows region"));
        }
        let index = a.index.as_deref().map(|p| table::read_index(p).map(|rows| (p.to_string(), rows))).transpose()?;
        let rules = FilterRules {
            labels,
            terrains: a.terrain,
            drop_other: a.drop_other,
            max_time: a.max_time,
            min_time: a.min_time,
            except_runs: a.except_runs.is_some(),
            runs: a.runs.or(a.except_runs),
            index,
            invert_index: a.invert,
            min_valid: a.min_valid,
            rows,
            unique: a.unique,
        };
        let files = FilterFiles { input: a.input, output: a.output, emit_index: a.emit_index, emit_labels: a.emit_labels };
        let c = filter_stream(rules, &files)?;
        cli::log(format_args!(
            "kept {} of {} records (dropped: {} terrain, {} time, {} run, {} index, {} valid cells, {} rows, {} duplicates)",
            c.kept, c.read, c.terrain, c.time, c.run, c.index, c.valid, c.rows, c.duplicate
        ));
        Ok(())
    })
}
