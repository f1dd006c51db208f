//! dem-split: cut an NPY stream into shards for work over cores or machines.

use std::process::ExitCode;

use clap::Parser;
use dem_core::cli::{self, value};
use dem_core::{output, table};
use dem_split::{stage, Cut, SplitConfig};

/// Cut an NPY stream into shards of consecutive records, PREFIX-00000.npy,
/// PREFIX-00001.npy, ... (with PREFIX-00000_labels.csv beside each when
/// --labels is given), and print the manifest on stdout as CSV:
/// shard,first_index,records[,labels]. Give each shard's first_index to the
/// tools that draw per record (dem-sensor apply, dem-fill-nans) as
/// --first-index, and the shards joined with dem-cat equal one run on the
/// whole stream, byte for byte. Labels rows keep every column and byte
/// but their index. All or nothing: the shards are written to temp files
/// and renamed into place when the whole split is done, so a failed or
/// refused run leaves every file as it was; files of an earlier split to
/// the same prefix beyond the new shards are then removed (logged).
#[derive(Parser)]
#[command(
    version,
    after_long_help = "Examples:
  dem-split --shards 4 --out part sim.npy > shards.csv
  dem-split --records 100000 --labels sim_labels.csv --out chunk - < sim.npy
  # in parallel (GNU parallel reads the manifest's columns by name), then join:
  parallel --colsep , --header : dem-sensor apply --sensor s.json --seed 1 \\
      --first-index {first_index} {shard} -o {shard}.out :::: shards.csv
  dem-cat part-*.npy.out -o sim_measured.npy
  # the same with xargs:
  tail -n +2 shards.csv | tr , ' ' | xargs -P 2 -n 3 sh -c 'dem-fill-nans --first-index $1 $0 -o $0.out'"
)]
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
    #[arg(long, value_name = "CSV")]
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
        // The manifest goes to stdout: it must not be an input (`>> s.npy`).
        output::check_outputs(&cfg.inputs(), &["-"])?;
        let staged = stage(&cfg)?;
        let shards = staged.shards().to_vec();
        let manifest = || table::write_rows("-", &shards);
        if stdout_is_stream() {
            // A reader of the pipe starts on a shard as soon as it reads its
            // row: the shards are in place before the manifest names them.
            staged.commit()?;
            manifest()?;
        } else {
            // A file (or a device): the manifest first, so a full disk
            // leaves the shards that were there untouched; a failure after
            // it cuts the file back to where it started.
            let mark = StdoutMark::take();
            if let Err(e) = manifest().and_then(|()| staged.commit()) {
                if let Some(m) = mark {
                    m.cut_back();
                }
                return Err(e.into());
            }
        }
        let records: u64 = shards.iter().map(|s| s.records).sum();
        cli::log(format_args!("{records} records in {} shards", shards.len()));
        Ok(())
    })
}

/// Stdout as a `File` on a duplicate of fd 1.
fn stdout_file() -> Option<std::fs::File> {
    use std::os::fd::AsFd;
    Some(std::fs::File::from(std::io::stdout().as_fd().try_clone_to_owned().ok()?))
}

/// True when stdout is a pipe or a socket: someone reads it as it is written.
fn stdout_is_stream() -> bool {
    use std::os::unix::fs::FileTypeExt;
    stdout_file().and_then(|f| f.metadata().ok()).is_some_and(|m| m.file_type().is_fifo() || m.file_type().is_socket())
}

/// Where a stdout redirected to a regular file stood before the manifest.
struct StdoutMark {
    file: std::fs::File,
    start: u64,
}

impl StdoutMark {
    /// The mark, when stdout is a regular file.
    fn take() -> Option<StdoutMark> {
        use std::io::Seek;
        let mut file = stdout_file()?;
        let meta = file.metadata().ok().filter(std::fs::Metadata::is_file)?;
        // `>>` writes at the end whatever the offset says.
        let append = rustix::fs::fcntl_getfl(&file).is_ok_and(|f| f.contains(rustix::fs::OFlags::APPEND));
        let start = if append { meta.len() } else { file.stream_position().ok()? };
        Some(StdoutMark { file, start })
    }

    /// Cut the file back to the mark: no manifest of a split that is not in place.
    fn cut_back(self) {
        let _ = self.file.set_len(self.start);
    }
}
