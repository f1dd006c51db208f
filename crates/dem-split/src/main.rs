//! dem-split: cut an NPY stream into shards for work over cores or machines.

use std::process::ExitCode;

use clap::Parser;
use dem_core::cli::{self, value};
use dem_core::table;
use dem_split::{split, Cut, SplitConfig};

/// Cut an NPY stream into shards of consecutive records, PREFIX-00000.npy,
/// PREFIX-00001.npy, ... (with PREFIX-00000_labels.csv beside each when
/// --labels is given), and print the manifest on stdout as CSV:
/// shard,first_index,records[,labels]. Give each shard's first_index to the
/// tools that draw per record (dem-sensor apply, dem-fill-nans) as
/// --first-index, and the shards joined with dem-cat equal one run on the
/// whole stream, byte for byte. A failure removes the shards written.
#[derive(Parser)]
#[command(version, after_long_help = "Examples:
  dem-split --shards 4 --out part sim.npy > shards.csv
  dem-split --records 100000 --labels sim_labels.csv --out part - < sim.npy
  # in parallel (GNU parallel reads the manifest's columns by name), then join:
  parallel --colsep , --header : dem-sensor apply --sensor s.json --seed 1 \\
      --first-index {first_index} {shard} -o {shard}.out :::: shards.csv
  dem-cat part-*.npy.out -o sim_measured.npy
  # the same with xargs:
  tail -n +2 shards.csv | tr , ' ' | xargs -P 2 -n 3 sh -c 'dem-fill-nans --first-index $1 $0 -o $0.out'")]
struct Args {
    /// Input NPY stream (`-` for stdin; a file for --shards).
    #[arg(default_value = "-")]
    input: String,
    /// Shards of this many records (the last may be shorter).
    #[arg(long, value_parser = value::at_least_one::<u64>, required_unless_present = "shards", conflicts_with = "shards")]
    records: Option<u64>,
    /// This many shards of equal size (within one record).
    #[arg(long, value_parser = value::at_least_one::<u64>)]
    shards: Option<u64>,
    /// Labels CSV of the input: split alongside, each re-indexed from 0.
    #[arg(long)]
    labels: Option<String>,
    /// Prefix of the shard files (PREFIX-00000.npy, ...).
    #[arg(short, long)]
    out: String,
}

fn main() -> ExitCode {
    cli::run(|| {
        let a: Args = cli::parse();
        let cut = match (a.records, a.shards) {
            (Some(n), _) => Cut::Records(n),
            (None, Some(k)) => Cut::Shards(k),
            (None, None) => return Err(cli::usage("give --records N or --shards K")),
        };
        let cfg = SplitConfig { input: a.input, labels: a.labels, prefix: a.out, cut };
        let shards = split(&cfg)?;
        table::write_rows("-", &shards)?;
        let records: u64 = shards.iter().map(|s| s.records).sum();
        cli::log(format_args!("{records} records in {} shards", shards.len()));
        Ok(())
    })
}
