//! dem-render: PNG pictures of DEMs, alone in a grid or files side by side.

use std::io::IsTerminal;
use std::process::ExitCode;

use clap::Parser;
use dem_core::cli::{self, value};
use dem_render::{self as render, Captions, Pick, RenderConfig, Selection, TileStyle};

/// Draw DEMs as a PNG: jet over heights with a colour bar in metres, missing
/// cells white, the robot at the top facing down (a triangle marks its
/// centre), each record's index above it.
///
/// By default, a grid of the first 24 records of one NPY file. With
/// --compare, the input files are stacked as rows (same records in every
/// row), optionally with the error between two rows or a CSV value under
/// each column.
#[derive(Parser)]
#[command(
    version,
    after_long_help = "Examples:
  dem-synth --out run/ --runs 20 && dem-render run/sim.npy --count 12 -o sim.png
  dem-render run/real.npy --indices 130,140,150 --title 'measured, pallet' -o pallet.png
  dem-render run/real.npy --per-terrain 3 --labels run/real_labels.csv -o terrains.png   # 3 of each terrain
  dem-render run/sim.npy --index keep.csv -o kept.png      # keep.csv: header `index`
  dem-render --compare run/sim.npy run/real.npy --error-rows 2,1 -o pairs.png
  dem-render --compare in.npy closest.npy <(dem-apply --model g.onnx in.npy) --row-labels input,closest,generated -o fig.png
  dem-cat big.npy | dem-render - --start 100 --count 48 --columns 16 > page.png

--compare draws the same records from every file. Files may differ in length,
but a range that runs past the end of one file and not another is refused
(exit 2), as is an index past any file's end. With --runs equal to --real-runs
(20 by default), dem-synth's sim.npy and real.npy pair record for record."
)]
struct Args {
    /// NPY file(s); `-` is stdin (the default). Several need --compare.
    inputs: Vec<String>,
    /// Output PNG; `-` is stdout (refused when it is a terminal).
    #[arg(short, long = "out", default_value = "-")]
    output: String,
    /// Stack the input files as rows, one per file, same records in each.
    #[arg(long)]
    compare: bool,
    /// First record to draw (zero-based).
    #[arg(long, default_value_t = 0, conflicts_with_all = ["indices", "index", "per_terrain"])]
    start: u64,
    /// Records to draw from --start (fewer if the file ends first; at most 400).
    #[arg(long, default_value_t = 24, conflicts_with_all = ["indices", "index", "per_terrain"])]
    count: u64,
    /// Draw these records, in this order: zero-based, comma-separated.
    #[arg(long, value_delimiter = ',', conflicts_with = "index")]
    indices: Option<Vec<u64>>,
    /// Draw the records listed in an index CSV (header `index`).
    #[arg(long, value_name = "CSV")]
    index: Option<String>,
    /// Draw K records of each terrain, evenly spaced among its records (at
    /// 1/(K+1), 2/(K+1), ... of them), terrains in the order flat,
    /// stairs-up, stairs-down, pallet, other; needs --labels.
    #[arg(long, value_name = "K", requires = "labels", conflicts_with_all = ["indices", "index"], value_parser = value::at_least_one::<usize>)]
    per_terrain: Option<usize>,
    /// A CSV with a `terrain` column, one row per record of the (first)
    /// input in order: a labels CSV, or dem-eval's --emit-records file.
    #[arg(long, value_name = "CSV", requires = "per_terrain")]
    labels: Option<String>,
    /// Records per picture row before wrapping [default: up to 12].
    #[arg(long)]
    columns: Option<usize>,
    /// A title line at the top.
    #[arg(long)]
    title: Option<String>,
    /// Height (m) drawn dark blue [default: the lowest valid height shown].
    #[arg(long, allow_negative_numbers = true, value_parser = value::finite::<f32>)]
    vmin: Option<f32>,
    /// Height (m) drawn dark red [default: the highest valid height shown].
    #[arg(long, allow_negative_numbers = true, value_parser = value::finite::<f32>)]
    vmax: Option<f32>,
    /// With --compare: labels left of the rows, comma-separated [default: file names].
    #[arg(long, value_delimiter = ',', requires = "compare")]
    row_labels: Vec<String>,
    /// With --compare: "R,P" (1-based rows) prints under each column "e=" and
    /// the DEM error (docs/format.md) of row P's record (the prediction) against row
    /// R's (the measured DEM).
    #[arg(long, value_name = "R,P", value_delimiter = ',', requires = "compare", conflicts_with = "captions")]
    error_rows: Option<Vec<usize>>,
    /// Print a value from this CSV under each column: matched by record when
    /// the first column is `index`, else one row per drawn column in order.
    #[arg(long, value_name = "FILE")]
    captions: Option<String>,
    /// Column of --captions to print [default: the last].
    #[arg(long, value_name = "NAME", requires = "captions")]
    caption_column: Option<String>,
    /// Cell edge in pixels (a DEM is 5 x 20 cells).
    #[arg(long, default_value_t = 16)]
    cell: u32,
    /// Thin grey lines between cells.
    #[arg(long)]
    cell_lines: bool,
}

impl Args {
    fn into_config(self) -> anyhow::Result<RenderConfig> {
        if self.output == "-" && std::io::stdout().is_terminal() {
            return Err(cli::usage("refusing to write a PNG to a terminal: give -o FILE or redirect stdout"));
        }
        let pick = match (self.index, self.indices, self.per_terrain.zip(self.labels)) {
            (Some(path), _, _) => Pick::IndexCsv(path),
            (None, Some(v), _) => Pick::Direct(Selection::Indices(v)),
            (None, None, Some((k, labels))) => {
                dem_core::output::check_outputs(&[&labels], &[&self.output])?;
                Pick::Direct(Selection::Indices(render::select::per_terrain(&labels, k)?))
            }
            (None, None, None) => Pick::Direct(Selection::Range { start: self.start, count: self.count }),
        };
        let captions = match (self.error_rows, self.captions) {
            (Some(r), _) if r.len() != 2 => return Err(cli::usage("--error-rows takes two rows, as R,P")),
            (Some(r), _) => Captions::ErrorRows { measured: r[0], prediction: r[1] },
            (None, Some(path)) => Captions::Csv { path, column: self.caption_column },
            (None, None) => Captions::None,
        };
        let inputs = if self.inputs.is_empty() { vec!["-".to_string()] } else { self.inputs };
        Ok(RenderConfig {
            inputs,
            compare: self.compare,
            row_labels: self.row_labels,
            pick,
            columns: self.columns,
            title: self.title,
            vmin: self.vmin,
            vmax: self.vmax,
            captions,
            style: TileStyle { cell: self.cell, cell_lines: self.cell_lines, ..TileStyle::default() },
            output: self.output,
        })
    }
}

fn main() -> ExitCode {
    cli::run(|| {
        let cfg = cli::parse::<Args>().into_config()?;
        let mut inputs: Vec<&str> = cfg.inputs.iter().map(String::as_str).collect();
        if let Pick::IndexCsv(p) = &cfg.pick {
            inputs.push(p);
        }
        if let Captions::Csv { path, .. } = &cfg.captions {
            inputs.push(path);
        }
        dem_core::output::check_outputs(&inputs, &[&cfg.output])?;
        let s = render::render(&cfg)?;
        let target = if cfg.output == "-" { "PNG to stdout" } else { cfg.output.as_str() };
        let rows = if cfg.compare { format!("{} files x ", s.rows) } else { String::new() };
        cli::log(format_args!("wrote {target} ({rows}{} records, {}x{} px)", s.records, s.width, s.height));
        Ok(())
    })
}
