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
//! A residual with a map's memory (`map-memory`) steps each run's records
//! in stream order, from the labels' runs, times and poses, carrying each
//! run's map from batch to batch ([`Runs`]); a record earlier in its run
//! than the one before it is refused.
//!
//! A generator exported with `--heights input` keeps the input's heights
//! under its holes ([`Heights::Input`]): the network decides which cells are
//! missing, the sim's heights stay, and its residual model (fitted on that
//! output) draws the measured heights' effects.

use dem_core::format::Dem;
use dem_core::npy::F32ArrayWriter;
use dem_core::{table, DemError};
use dem_onnx::apply::{apply, After, ApplyStats, MaskSampling};
use dem_onnx::sensor::Stored;
use dem_onnx::{Heights, OnnxModel};
use dem_sensor::fusion::{memory_draws, Runs};
use rayon::prelude::*;

pub use dem_onnx::generator::RESIDUAL_KEY;

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
    /// Write each record's uniforms here (float32 `(N, K)`), the
    /// `uniform` input of the model's graph.
    pub emit_uniform: Option<String>,
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

/// The residual model and heights source stored in the ONNX file at
/// `path`, from one read of its metadata.
pub fn stored(path: &str) -> Result<Stored, DemError> {
    Stored::from_info(&dem_onnx::read_info(path)?, path)
}

/// Run `model` (loaded from `c.model`) over `c.input` into `c.output`: the
/// network, then holes drawn (`sample_masks`), then the tail the model
/// carries ([`Stored::finish`]: masks thresholded, the heights chosen, the
/// residual sensor model unless `network_only`), each record with its
/// uniforms drawn from the seed and its index in the whole data set.
/// `progress` gets the records done so far.
pub fn run(c: &Config, model: &OnnxModel, progress: impl FnMut(u64)) -> Result<Report, DemError> {
    let file = stored(&c.model)?;
    let tail = Stored { residual: if c.network_only { None } else { file.residual.clone() }, heights: c.heights.unwrap_or(file.heights) };
    let moments = match &c.labels {
        Some(p) => Some((p.as_str(), dem_sensor::moments(&table::read_labels(p)?))),
        None => None,
    };
    let mut notes = Vec::new();
    if let Some(r) = &tail.residual {
        if moments.is_none() && r.uses_time() {
            notes.push(
                "note: the model's residual has `startup` but no --labels gave the records' times: \
                 startup frames are drawn at its rate p instead of by time"
                    .to_string(),
            );
        }
        if let Some(why) = dem_sensor::runs_unknown(r, moments.as_ref().map(|(_, m)| m.as_slice())) {
            notes.push(format!("note: the model's residual: {why}"));
        }
    }
    if c.emit_uniform.is_some() && (c.sample_masks || tail != file) {
        return Err(DemError::Usage(
            "--emit-uniform gives the uniforms of the model's own graph: it does not combine with --sample-masks, \
             --network-only or a --heights other than the model's"
                .into(),
        ));
    }
    let k = tail.draws();
    let emit = match &c.emit_uniform {
        Some(path) => Some(std::sync::Mutex::new(F32ArrayWriter::create(path, &[k as u64])?)),
        None => None,
    };
    let sample = c.sample_masks.then_some(MaskSampling { seed: c.seed, first_index: c.first_index });
    let residual = tail.residual_or_empty();
    // A map's memory steps each run's records in stream order, batch after batch.
    let runs =
        residual.map_memory().zip(moments.as_ref()).map(|(m, (path, _))| (std::sync::Mutex::new(Runs::new(m, c.first_index)), *path));
    let finish = |inp: &[Dem], out: &mut [Dem], first: u64| -> Result<(), DemError> {
        if let Some(s) = &sample {
            s.draw(inp, out, first);
        }
        let m = dem_sensor::chunk_moments(moments.as_ref().map(|(p, m)| (*p, m.as_slice())), first, out.len())?;
        let u = residual.uniforms_of(c.seed, c.first_index + first, out.len(), m);
        out.par_iter_mut().zip(inp).enumerate().for_each(|(i, (y, x))| {
            tail.finish(x, y, &u[i * k..(i + 1) * k], dem_sensor::moment_at(m, i).known_time());
        });
        if let (Some((runs, path)), Some(m)) = (&runs, m) {
            let memory = |i: usize| memory_draws(&u[i * k..(i + 1) * k]).to_vec();
            runs.lock().expect("one stream").step_chunk(path, first, out, inp, m, memory)?;
        }
        if let Some(w) = &emit {
            let mut w = w.lock().expect("one writer");
            if k > 0 {
                w.write(&u)?;
            } else {
                w.write_empty(out.len() as u64);
            }
        }
        Ok(())
    };
    let labels_cover = |records: u64| dem_sensor::labels_cover(moments.as_ref().map(|(p, m)| (*p, m.len())), records);
    let any = sample.is_some() || tail.has_tail();
    let after = After { finish: any.then_some(&finish as _), at_end: Some(&labels_cover) };
    let stats = apply(model, &c.input, &c.output, c.batch, c.strict, after, progress)?;
    if let Some(w) = emit {
        w.into_inner().expect("one writer").finish()?;
    }
    Ok(Report { stats, residual: tail.residual.map(|r| r.summary()), heights: tail.heights, notes })
}

/// `--info`'s line on what another runtime (onnxruntime, PyTorch) gets from
/// the file at `path`, and its inputs.
pub fn runtime_line(path: &str, info: &dem_onnx::ModelInfo) -> Result<String, DemError> {
    let stored = Stored::from_info(info, path)?;
    use dem_onnx::sensor::{GRAPH_KEY, GRAPH_SENSOR, GRAPH_SENSOR_ONLY};
    let whole = info.metadata.iter().any(|(k, v)| k == GRAPH_KEY && (v == GRAPH_SENSOR || v == GRAPH_SENSOR_ONLY));
    let model = stored.residual_or_empty();
    Ok(if whole {
        format!("in another runtime: the whole virtual sensor, as dem-apply runs it; inputs: {}", dem_sensor::graph::input_list(&model))
    } else if stored.has_tail() {
        "in another runtime: the network alone (raw masks, the network's heights); what dem-apply adds after it \
         (dem.residual, dem.heights) is only in the metadata: re-export with dem-train export for one graph"
            .to_string()
    } else {
        "in another runtime: the network alone, as dem-apply runs it (input dem float32 (N,21,5,2))".to_string()
    })
}
