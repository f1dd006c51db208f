//! dem-cat: join NPY streams into one, the way `cat` joins files.

use std::process::ExitCode;

use std::io::Write;

use clap::Parser;
use dem_core::raw_labels::{self, LabelsReader};
use dem_core::{cli, npy, output, table, DemError};

/// Concatenate NPY streams of DEMs into one stream.
///
/// Reads each input in order (files, or `-` for stdin; one or many arrays
/// back to back), applies the contract's input rules (float64 converted, NaN
/// heights become missing cells) and writes one stream. Written to a file (or
/// stdout redirected to one) the result is a single array `numpy.load` reads
/// whole; to a pipe it is a stream of chunks.
///
/// With --labels (one labels CSV per input, in the same order) and
/// --emit-labels, the labels are joined alongside: each input's rows are
/// re-indexed to their records' place in the joined stream, every other
/// byte kept; each labels CSV must cover its input exactly and all must
/// have the same columns.
#[derive(Parser)]
#[command(
    version,
    after_long_help = "Examples:
  dem-cat part1.npy part2.npy -o all.npy
  dem-synth --out run/ && dem-cat run/sim.npy | dem-render -o sim.png -
  python make_dems.py | dem-cat - > clean.npy      # float64/NaN -> contract
  dem-cat sim.npy real.npy --labels sim_labels.csv,real_labels.csv -o both.npy --emit-labels both_labels.csv"
)]
struct Args {
    /// Input NPY streams; `-` is stdin. None means stdin.
    inputs: Vec<String>,
    /// Output file; `-` is stdout.
    #[arg(short, long = "out", default_value = "-")]
    output: String,
    /// Labels CSV of each input, in the order of the inputs (comma-separated
    /// or repeated); needs --emit-labels.
    #[arg(long, value_name = "CSV", value_delimiter = ',', requires = "emit_labels")]
    labels: Vec<String>,
    /// Write the joined labels, re-indexed to the joined stream, to this CSV.
    #[arg(long, value_name = "CSV", requires = "labels")]
    emit_labels: Option<String>,
}

fn main() -> ExitCode {
    cli::run(|| {
        let args: Args = cli::parse();
        let inputs = if args.inputs.is_empty() { vec!["-".to_string()] } else { args.inputs };
        if args.emit_labels.is_some() && args.labels.len() != inputs.len() {
            return Err(cli::usage(format!(
                "--labels names {} CSV(s) for {} input(s): give one per input, in order",
                args.labels.len(),
                inputs.len()
            )));
        }
        let reads: Vec<&str> = inputs.iter().chain(&args.labels).map(String::as_str).collect();
        let writes: Vec<&str> = [Some(&args.output), args.emit_labels.as_ref()].into_iter().flatten().map(String::as_str).collect();
        output::check_outputs(&reads, &writes)?;
        let mut labels_out = args.emit_labels.as_deref().map(output::AtomicOutput::create).transpose()?;
        let mut columns: Option<(String, Vec<String>)> = None;
        let mut out = npy::create(&args.output)?;
        let (mut total, mut nans) = (0, 0);
        for (k, path) in inputs.iter().enumerate() {
            let mut rdr = npy::open(path)?;
            let n = rdr.for_each_chunk(npy::CHUNK_RECORDS, |_, chunk| out.write(chunk))?;
            nans += rdr.nan_records();
            if let Some(w) = labels_out.as_mut() {
                join_labels(&args.labels[k], path, n, total, w, &mut columns)?;
            }
            total += n;
        }
        out.finish()?;
        if let Some(w) = labels_out {
            w.commit()?;
        }
        cli::log(format_args!("{total} records from {} input(s); {nans} had NaN heights (now missing)", inputs.len()));
        Ok(())
    })
}

/// Append the rows of `labels` (the labels of `npy`, `records` records) to
/// `out` with indices from `first`; the first file's header goes first, and
/// every later file must have its columns.
fn join_labels(
    labels: &str,
    npy: &str,
    records: u64,
    first: u64,
    out: &mut output::AtomicOutput,
    columns: &mut Option<(String, Vec<String>)>,
) -> anyhow::Result<()> {
    let mut rdr = LabelsReader::open(labels)?;
    let these: Vec<String> = rdr.columns().into_iter().map(String::from).collect();
    match columns {
        None => {
            out.write_all(&rdr.header()).map_err(|e| DemError::io(out.path(), e))?;
            *columns = Some((labels.to_string(), these));
        }
        Some((name, cols)) if *cols != these => {
            return Err(DemError::input(
                labels,
                format!("has the columns {} but {name} has {}: joined labels need the same columns", these.join(","), cols.join(",")),
            )
            .into());
        }
        Some(_) => {}
    }
    while let Some(row) = rdr.next_row()? {
        raw_labels::write_row(out, &row, first + rdr.rows() - 1).map_err(|e| DemError::io(out.path(), e))?;
    }
    table::check_labels_cover(labels, rdr.rows() as usize, npy, records)?;
    Ok(())
}
