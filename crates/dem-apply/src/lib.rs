//! dem-apply: run an ONNX generator over an NPY stream, then what its
//! network cannot write: holes drawn at the rate its masks predict, and the
//! residual sensor model the generator carries.
//!
//! A generator trained on sim DEMs is deterministic and sees no time: it
//! writes the *expected* measured DEM of a sim DEM. What a measured DEM
//! has on top (per-record noise, the rows behind the robot missing in a
//! run's first frames) is drawn by a sensor model that dem-gap fits between
//! the network's output and the measured DEMs; `dem-train export
//! --residual` stores that model in the ONNX file (`dem.residual`), and
//! [`run`] applies it after the network, with each record's time from its
//! labels. The result equals `dem-apply --network-only | dem-sensor apply`
//! with the same seed, byte for byte.
//!
//! A generator exported with `--heights input` keeps the input's heights
//! under its holes ([`Heights::Input`]): the network decides which cells are
//! missing, the sim's heights stay, and its residual model (fitted on that
//! output) draws the measured heights' effects.

use dem_core::format::Dem;
use dem_core::{table, DemError};
use dem_onnx::apply::{apply, ApplyStats, MaskSampling};
use dem_onnx::{Heights, OnnxModel, HEIGHTS_KEY};
use dem_sensor::SensorModel;

pub use dem_onnx::export::RESIDUAL_KEY;

/// What to run, validated from the command line.
#[derive(Clone, Debug)]
pub struct Config {
    /// The ONNX model.
    pub model: String,
    /// Input NPY stream (`-` for stdin).
    pub input: String,
    /// Output NPY stream (`-` for stdout).
    pub output: String,
    /// Records per model call.
    pub batch: usize,
    /// Refuse a model that changes row 20.
    pub strict: bool,
    /// Draw the holes from the raw masks.
    pub sample_masks: bool,
    /// Run the network only, without the residual sensor model it carries.
    pub network_only: bool,
    /// Where valid cells take their heights from; `None`: what the model
    /// says (`dem-train export --heights`), else the network's.
    pub heights: Option<Heights>,
    /// Labels of the input's records (their `time` drives `startup`).
    pub labels: Option<String>,
    /// Seed of every draw (holes, the residual model).
    pub seed: u64,
    /// Index of the input's first record in the whole data set (shards).
    pub first_index: u64,
}

/// What [`run`] did.
#[derive(Clone, Debug)]
pub struct Report {
    /// Records, and what the model did to row 20.
    pub stats: ApplyStats,
    /// The residual sensor model applied, if any (its one-line summary).
    pub residual: Option<String>,
    /// Where the valid cells' heights came from.
    pub heights: Heights,
    /// Said once after the run (e.g. no times for a time effect).
    pub notes: Vec<String>,
}

/// What an exported generator says dem-apply runs around its network.
#[derive(Clone, Debug)]
pub struct Stored {
    /// The residual sensor model (`dem-train export --residual`), if any.
    pub residual: Option<SensorModel>,
    /// Where its valid cells take their heights from (`dem-train export
    /// --heights`; a model without the key: the network's).
    pub heights: Heights,
}

/// The residual model and heights source stored in the ONNX file at
/// `path`, from one read of its metadata.
pub fn stored(path: &str) -> Result<Stored, DemError> {
    let info = dem_onnx::read_info(path)?;
    let value = |key: &str| info.metadata.iter().find(|(k, _)| k == key).map(|(_, v)| v);
    let residual = value(RESIDUAL_KEY)
        .map(|json| SensorModel::from_json(json).map_err(|e| DemError::input(path, format!("its residual sensor model ({RESIDUAL_KEY}) is not valid: {e}"))))
        .transpose()?;
    let heights = match value(HEIGHTS_KEY) {
        None => Heights::Network,
        Some(v) => v.parse().map_err(|e| DemError::input(path, format!("its {HEIGHTS_KEY} is not valid: {e}")))?,
    };
    Ok(Stored { residual, heights })
}

/// Run `model` (loaded from `c.model`) over `c.input` into `c.output`: the
/// network, then holes drawn (`sample_masks`), then the input's heights
/// under the holes (`heights`), then the residual sensor model unless
/// `network_only`. `progress` gets the records done so far.
pub fn run(c: &Config, model: &OnnxModel, progress: impl FnMut(u64)) -> Result<Report, DemError> {
    let stored = stored(&c.model)?;
    let residual = if c.network_only { None } else { stored.residual };
    let heights = c.heights.unwrap_or(stored.heights);
    let times = match &c.labels {
        Some(p) => Some((p.as_str(), table::times(&table::read_labels(p)?))),
        None => None,
    };
    let mut notes = Vec::new();
    if let Some(r) = &residual {
        if times.is_none() && r.uses_time() {
            notes.push(
                "note: the model's residual has `startup` but no --labels gave the records' times: \
                 startup frames are drawn at its rate p instead of by time"
                    .to_string(),
            );
        }
    }
    let sample = c.sample_masks.then_some(MaskSampling { seed: c.seed, first_index: c.first_index });
    let finish = |inp: &[Dem], out: &mut [Dem], first: u64| -> Result<(), DemError> {
        if let Some(s) = &sample {
            s.draw(inp, out, first);
        }
        inp.iter().zip(out.iter_mut()).for_each(|(x, y)| heights.apply(x, y));
        if let Some(r) = &residual {
            r.apply_chunk(out, c.seed, c.first_index, first, times.as_ref().map(|(p, t)| (*p, t.as_slice())))?;
        }
        Ok(())
    };
    let any = sample.is_some() || residual.is_some() || heights == Heights::Input;
    let stats = apply(model, &c.input, &c.output, c.batch, c.strict, any.then_some(&finish as _), progress)?;
    Ok(Report { stats, residual: residual.map(|r| r.summary()), heights, notes })
}
