//! PNG pictures of DEMs, the way the thesis's figures show them: colormap
//! `jet` over heights with a colour bar in metres, missing cells white, the
//! robot at the top facing down (row 0 at the top), the record index above
//! each DEM.
//!
//! Two layouts, one engine ([`layout::Figure`]):
//! - a **grid** of records of one file, wrapped into rows of columns;
//! - a **comparison**: several files stacked as rows (input / closest real /
//!   generated), the same records in every row, with a number under each
//!   column: the equation 7.1 error between two of the rows, or a value
//!   from a CSV.
//!
//! Modules: [`colormap`] (jet, height range, ticks), [`font`] (8x8 bitmap
//! text), [`canvas`] (RGB image, shapes, PNG), [`tile`] (one DEM, the robot
//! marker, the colour bar), [`layout`] (the page), [`select`] (which
//! records, captions). [`render`] runs a whole [`RenderConfig`].

pub mod canvas;
pub mod colormap;
pub mod font;
pub mod layout;
pub mod plot;
pub mod select;
pub mod tile;

use std::path::Path;

use colormap::HeightRange;
use dem_core::error::{DemError, Result};
use dem_core::format::{DemCells, COLS, GRID_ROWS};
use dem_core::{metric, output, table};
use layout::{Column, Figure};
pub use select::{Selection, MAX_RECORDS};
pub use tile::TileStyle;

/// Columns per band when `--columns` is not given (fewer when fewer records).
pub const DEFAULT_COLUMNS: usize = 12;

/// What goes under each column.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum Captions {
    /// Nothing.
    #[default]
    None,
    /// `e=...`: equation 7.1 error of figure row `prediction` against
    /// figure row `measured` (both 1-based, as the user counts rows).
    ErrorRows {
        /// Row holding y, the measured DEM.
        measured: usize,
        /// Row holding p, the prediction.
        prediction: usize,
    },
    /// One value per column from a CSV (see [`select::read_captions`]).
    Csv {
        /// The CSV (`-` is stdin).
        path: String,
        /// Column to show; None is the last.
        column: Option<String>,
    },
}

/// Which records to draw: a selection, or an index CSV that lists them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Pick {
    /// A [`Selection`] given directly.
    Direct(Selection),
    /// The records listed in an index CSV (header `index`).
    IndexCsv(String),
}

/// Everything one picture needs.
#[derive(Debug, Clone)]
pub struct RenderConfig {
    /// NPY files (`-` is stdin): one for a grid, one per row for a comparison.
    pub inputs: Vec<String>,
    /// Stack the inputs as rows.
    pub compare: bool,
    /// Labels left of the rows of a comparison; empty means the file names.
    pub row_labels: Vec<String>,
    /// Which records.
    pub pick: Pick,
    /// Columns per band; None is up to [`DEFAULT_COLUMNS`].
    pub columns: Option<usize>,
    /// Title line at the top.
    pub title: Option<String>,
    /// Height drawn dark blue; None is the lowest valid height shown.
    pub vmin: Option<f32>,
    /// Height drawn dark red; None is the highest valid height shown.
    pub vmax: Option<f32>,
    /// Text under each column.
    pub captions: Captions,
    /// Tile and text sizes.
    pub style: TileStyle,
    /// The PNG to write (`-` is stdout); files appear whole or not at all.
    pub output: String,
}

/// What [`render`] drew.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Summary {
    /// Records per row (columns drawn).
    pub records: usize,
    /// Rows (files) stacked; 1 for a grid.
    pub rows: usize,
    /// Picture width in pixels.
    pub width: u32,
    /// Picture height in pixels.
    pub height: u32,
}

fn usage(msg: impl Into<String>) -> DemError {
    DemError::Usage(msg.into())
}

impl RenderConfig {
    /// Refuse combinations that make no sense, before reading anything.
    pub fn validate(&self) -> Result<()> {
        let n = self.inputs.len();
        if n == 0 {
            return Err(usage("no input given"));
        }
        if !self.compare && n > 1 {
            return Err(usage(format!("{n} inputs given; several files are drawn with --compare (one row per file)")));
        }
        if !self.row_labels.is_empty() && self.row_labels.len() != n {
            return Err(usage(format!("{} row labels for {n} input files", self.row_labels.len())));
        }
        if let Captions::ErrorRows { measured, prediction } = self.captions {
            if !self.compare {
                return Err(usage("--error-rows compares rows of --compare"));
            }
            for r in [measured, prediction] {
                if r == 0 || r > n {
                    return Err(usage(format!("--error-rows: row {r} does not exist (rows are 1..={n})")));
                }
            }
            if measured == prediction {
                return Err(usage("--error-rows needs two different rows"));
            }
        }
        if self.columns == Some(0) {
            return Err(usage("--columns must be at least 1"));
        }
        if !(4..=64).contains(&self.style.cell) {
            return Err(usage(format!("--cell {} is outside 4..=64 pixels", self.style.cell)));
        }
        let mut stdin_users = self.inputs.iter().filter(|p| *p == "-").count();
        stdin_users += usize::from(matches!(&self.pick, Pick::IndexCsv(p) if p == "-"));
        stdin_users += usize::from(matches!(&self.captions, Captions::Csv { path, .. } if path == "-"));
        if stdin_users > 1 {
            return Err(usage("stdin (`-`) can feed only one input"));
        }
        if self.output != "-" {
            let out = Path::new(&self.output);
            if let Some(i) = self.inputs.iter().find(|i| *i != "-" && same_file(Path::new(i), out)) {
                return Err(usage(format!("-o {} would overwrite the input {i}", self.output)));
            }
        }
        if let Pick::Direct(sel) = &self.pick {
            sel.validate()?;
        }
        Ok(())
    }
}

fn same_file(a: &Path, b: &Path) -> bool {
    a == b || matches!((a.canonicalize(), b.canonicalize()), (Ok(x), Ok(y)) if x == y)
}

/// The error for the first index of the CSV at `csv` past the end of the
/// NPY at `npy` (line numbers count the header as line 1).
fn index_past_end(csv: &str, indices: &[u64], npy: &str) -> Option<DemError> {
    if npy == "-" {
        return None;
    }
    let total = dem_core::npy::open(npy).ok()?.for_each_chunk(dem_core::npy::CHUNK_RECORDS, |_, _| Ok::<_, DemError>(())).ok()?;
    let k = indices.iter().position(|&i| i >= total)?;
    Some(DemError::Table {
        path: csv.into(),
        line: k as u64 + 2,
        reason: format!("index {} is past the end of {npy} ({total} records)", indices[k]),
    })
}

/// The name a file gets as a row label: its stem (`run/sim.npy` -> `sim`).
pub fn default_label(path: &str) -> String {
    if path == "-" {
        return "stdin".into();
    }
    Path::new(path).file_stem().map_or_else(|| path.to_string(), |s| s.to_string_lossy().into_owned())
}

/// Read the inputs and lay out the picture `cfg` asks for.
pub fn build_figure(cfg: &RenderConfig) -> Result<Figure> {
    cfg.validate()?;
    let selection = match &cfg.pick {
        Pick::Direct(s) => s.clone(),
        Pick::IndexCsv(path) => {
            let s = Selection::Indices(table::read_index(path)?);
            s.validate().map_err(|e| DemError::input(path, e.to_string()))?;
            s
        }
    };
    let mut picked: Vec<select::Picked> = Vec::with_capacity(cfg.inputs.len());
    for path in &cfg.inputs {
        let p = select::read_selected(path, &selection).map_err(|e| match (&cfg.pick, &selection, &e) {
            // An index CSV past the end is the CSV's fault: name its line.
            (Pick::IndexCsv(csv), Selection::Indices(v), DemError::Input { .. }) => index_past_end(csv, v, path).unwrap_or(e),
            _ => e,
        })?;
        picked.push(p);
    }
    // Files may differ in length (a sim file often begins with the records
    // paired with a shorter real file), but every file holds every record
    // drawn: explicit indices are refused past a file's end when read, and a
    // range that one file cuts shorter than another is refused here (a range
    // past the end of files of equal length is cut, as for one file).
    let drawn = |k: usize| picked[k].indices.len();
    let short = (0..picked.len()).min_by_key(|&k| drawn(k)).unwrap_or(0);
    let long = (0..picked.len()).max_by_key(|&k| drawn(k)).unwrap_or(0);
    let name = |k: usize| if cfg.inputs[k] == "-" { "stdin" } else { cfg.inputs[k].as_str() };
    if drawn(short) != drawn(long) {
        let range = match &selection {
            Selection::Range { start, count } => format!("--start {start} --count {count}"),
            Selection::Indices(_) => "the records asked for".into(),
        };
        return Err(usage(format!(
            "--compare draws the same records from every file, but {} holds {} records and {} holds {}: {range} runs past the end of {}",
            name(short),
            picked[short].total,
            name(long),
            picked[long].total,
            name(short)
        )));
    }
    let indices = picked[0].indices.clone();
    let mut caption_label = None;
    let captions: Vec<Option<String>> = match &cfg.captions {
        Captions::None => vec![None; indices.len()],
        Captions::ErrorRows { measured, prediction } => (0..indices.len())
            .map(|k| {
                let e = metric::dem_error(&picked[measured - 1].records[k], &picked[prediction - 1].records[k]);
                caption_label = Some("error".to_string());
                Some(format!("e={e:.3}"))
            })
            .collect(),
        Captions::Csv { path, column } => {
            let (name, values) = select::read_captions(path, column.as_deref(), &indices)?;
            caption_label = Some(name);
            values.into_iter().map(Some).collect()
        }
    };
    let heights = picked
        .iter()
        .flat_map(|p| p.records.iter())
        .flat_map(|d| (0..GRID_ROWS).flat_map(move |r| (0..COLS).filter(move |&c| d.is_valid(r, c)).map(move |c| d.height(r, c))));
    let range = HeightRange::resolve(cfg.vmin, cfg.vmax, heights).map_err(usage)?;
    let columns = indices
        .iter()
        .zip(captions)
        .enumerate()
        .map(|(k, (i, caption))| Column { header: format!("#{i}"), dems: picked.iter().map(|p| p.records[k]).collect(), caption })
        .collect::<Vec<_>>();
    let row_labels = match (cfg.compare, cfg.row_labels.is_empty()) {
        (false, _) => vec![],
        (true, true) => cfg.inputs.iter().map(|p| default_label(p)).collect(),
        (true, false) => cfg.row_labels.clone(),
    };
    // A plain grid has no label column; its captions speak for themselves.
    let caption_label = caption_label.filter(|_| cfg.compare);
    let per_band = cfg.columns.unwrap_or(DEFAULT_COLUMNS.min(columns.len()));
    Ok(Figure { title: cfg.title.clone(), row_labels, caption_label, columns, per_band, range, style: cfg.style })
}

/// Draw the picture of `cfg` and write it as PNG to `cfg.output`
/// atomically (stdout for `-`).
pub fn render(cfg: &RenderConfig) -> Result<Summary> {
    let figure = build_figure(cfg)?;
    let canvas = figure.draw();
    output::write_atomic(&cfg.output, |w| canvas.write_png(w))?;
    Ok(Summary {
        records: figure.columns.len(),
        rows: figure.columns.first().map_or(0, |c| c.dems.len()),
        width: canvas.width(),
        height: canvas.height(),
    })
}
