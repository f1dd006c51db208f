//! dem-cat: join NPY streams into one, the way `cat` joins files.

use std::process::ExitCode;

use clap::Parser;
use dem_core::{cli, npy, output};

/// Concatenate NPY streams of DEMs into one stream.
///
/// Reads each input in order (files, or `-` for stdin; one or many arrays
/// back to back), applies the contract's input rules (float64 converted, NaN
/// heights become missing cells) and writes one stream. Written to a file (or
/// stdout redirected to one) the result is a single array `numpy.load` reads
/// whole; to a pipe it is a stream of chunks.
#[derive(Parser)]
#[command(version, after_long_help = "Examples:
  dem-cat part1.npy part2.npy -o all.npy
  dem-synth --out run/ && dem-cat run/sim.npy | dem-render -o sim.png -
  python make_dems.py | dem-cat - > clean.npy      # float64/NaN -> contract")]
struct Args {
    /// Input NPY streams; `-` is stdin. None means stdin.
    inputs: Vec<String>,
    /// Output file; `-` is stdout.
    #[arg(short, long = "out", alias = "output", default_value = "-")]
    output: String,
}

fn main() -> ExitCode {
    cli::run(|| {
        let args: Args = cli::parse();
        let inputs = if args.inputs.is_empty() { vec!["-".to_string()] } else { args.inputs };
        output::check_outputs(&inputs.iter().map(String::as_str).collect::<Vec<_>>(), &[&args.output])?;
        let mut out = npy::create(&args.output)?;
        let (mut total, mut nans) = (0, 0);
        for path in &inputs {
            let mut rdr = npy::open(path)?;
            total += rdr.for_each_chunk(npy::CHUNK_RECORDS, |_, chunk| out.write(chunk))?;
            nans += rdr.nan_records();
        }
        out.finish()?;
        cli::log(format_args!("{total} records from {} input(s); {nans} had NaN heights (now missing)", inputs.len()));
        Ok(())
    })
}
