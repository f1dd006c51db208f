//! Export a generator, or a whole virtual sensor, to an ONNX file checked
//! against the trainer's forward pass before it is written; the graph is
//! [`crate::generator`]'s.

use dem_core::format::{GRID_CELLS, GRID_LEN};
use dem_core::output::write_atomic;
use dem_core::{Dem, DemError};
use dem_nn::weights::GeneratorWeights;
use prost::Message;
use std::io::Write;
use tract_onnx::pb;

use crate::generator::{generator_model, TOLERANCE};
use crate::model::OnnxModel;
use crate::sensor::Stored;

/// What [`export_checked`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportReport {
    /// The file written.
    pub path: String,
    /// Its size in bytes.
    pub bytes: usize,
    /// Records the check ran.
    pub records: usize,
    /// Largest `|tract - expected|` over every value of every check record.
    pub max_abs_diff: f32,
    /// The check of the whole graph, for a virtual sensor.
    pub tail: Option<TailCheck>,
}
/// Export generator `w` to `path`, only if it reproduces `expected`.
///
/// Encodes [`generator_model`], reloads the bytes with tract
/// ([`OnnxModel::from_bytes`]), runs `check_inputs` and compares with
/// `expected` (the trainer's own forward pass on the same records, computed
/// by the caller). Refuses, writing nothing, unless every output value is
/// within [`TOLERANCE`] of its expected value (a NaN anywhere fails);
/// otherwise writes the file atomically (temp file + rename) and reports the
/// largest difference.
pub fn export_checked(w: &GeneratorWeights, check_inputs: &[Dem], expected: &[Dem], path: &str) -> Result<ExportReport, DemError> {
    export_checked_with(w, check_inputs, expected, path, &[])
}

/// [`export_checked`], with `metadata` stored as the model's
/// `metadata_props` (key, value): what it was trained on and how, so the
/// file says what it is (`dem-apply --info`).
pub fn export_checked_with(
    w: &GeneratorWeights,
    check_inputs: &[Dem],
    expected: &[Dem],
    path: &str,
    metadata: &[(String, String)],
) -> Result<ExportReport, DemError> {
    export_sensor_checked(w, &Stored::default(), check_inputs, expected, path, metadata)
}

/// [`export_checked_with`] for a virtual sensor: generator `w` and the tail
/// `stored` describes as one graph ([`crate::sensor`]), when it has one.
/// Checked twice before anything is written: tract's network against
/// `expected` (within [`TOLERANCE`]), then tract's whole graph against the
/// native tail ([`Stored::finish`]) on the trainer's outputs, fed the same
/// uniforms and times (a fifth of them unknown): at most [`TAIL_VALIDITY`]
/// of the cells may be decided differently (their validity, or their
/// height by more than [`TOLERANCE`]), row 20 not at all.
pub fn export_sensor_checked(
    w: &GeneratorWeights,
    stored: &Stored,
    check_inputs: &[Dem],
    expected: &[Dem],
    path: &str,
    metadata: &[(String, String)],
) -> Result<ExportReport, DemError> {
    if check_inputs.is_empty() || check_inputs.len() != expected.len() {
        return Err(DemError::Usage(format!(
            "export to {path}: need check records and as many expected outputs (got {} and {})",
            check_inputs.len(),
            expected.len()
        )));
    }
    let name = std::path::Path::new(path).file_stem().map_or("generator".into(), |s| s.to_string_lossy().into_owned());
    let network = generator_model(w, &name);
    // tract, not the native path: the file must be right for any runtime.
    let model = OnnxModel::from_proto(&network, path)?.on_tract();
    let max_abs_diff = check_network(&model, check_inputs, expected, path)?;
    let (mut proto, tail) = if stored.has_tail() {
        let proto = crate::sensor::sensor_model(w, &name, stored);
        let tail = check_tail(&proto, stored, check_inputs, expected, path)?;
        (proto, Some(tail))
    } else {
        (network, None)
    };
    let extra = if stored.has_tail() { stored.metadata() } else { Vec::new() };
    proto.metadata_props =
        metadata.iter().chain(&extra).map(|(key, value)| pb::StringStringEntryProto { key: key.clone(), value: value.clone() }).collect();
    let bytes = proto.encode_to_vec();
    write_atomic(path, |f| f.write_all(&bytes))?;
    Ok(ExportReport { path: path.into(), bytes: bytes.len(), records: check_inputs.len(), max_abs_diff, tail })
}

/// Largest share of cells the whole graph and the native tail may decide
/// differently in the export check. The network's output differs between
/// runtimes by float rounding (about 5e-6 m), so a mask within that of 0
/// falls either side, and so does a step within that of an effect's
/// threshold (a drop that one runtime blends and the other does not): such
/// a cell differs in validity, or in height by part of the step.
pub const TAIL_VALIDITY: f64 = 1e-3;

/// What the check of a virtual sensor's whole graph found.
#[derive(Clone, Debug, PartialEq)]
pub struct TailCheck {
    /// Share of cells whose validity differs.
    pub validity_differ: f64,
    /// Share of cells valid in both whose heights differ by more than
    /// [`TOLERANCE`]: a threshold decided the other way.
    pub height_differ: f64,
    /// Largest height difference over the other cells valid in both.
    pub max_height_diff: f32,
}

/// The largest `|tract - expected|` of the network, or the refusal.
fn check_network(model: &OnnxModel, check_inputs: &[Dem], expected: &[Dem], path: &str) -> Result<f32, DemError> {
    let mut max_abs_diff = 0.0f32;
    let mut worst = (0, 0);
    let mut nan = None;
    for (k, (inputs, want)) in check_inputs.chunks(256).zip(expected.chunks(256)).enumerate() {
        let got = model.run(inputs)?;
        for (i, (g, e)) in got.iter().zip(want).enumerate() {
            for (j, (a, b)) in g.iter().zip(e).enumerate() {
                let d = (a - b).abs();
                if d.is_nan() {
                    nan = nan.or(Some((k * 256 + i, j)));
                } else if d > max_abs_diff {
                    max_abs_diff = d;
                    worst = (k * 256 + i, j);
                }
            }
        }
    }
    if nan.is_some() || max_abs_diff > TOLERANCE {
        let what = if nan.is_some() { "a NaN".to_string() } else { format!("{max_abs_diff:e}") };
        let (rec, j) = nan.unwrap_or(worst);
        let (row, col, ch) = (j / 10, j % 10 / 2, j % 2);
        return Err(DemError::input(
            path,
            format!(
                "export check failed, nothing written: tract's output differs from the expected output by \
                 {what} (tolerance {TOLERANCE:e}) at check record {rec}, row {row}, column {col}, channel {ch}"
            ),
        ));
    }
    Ok(max_abs_diff)
}

/// Run the whole graph `proto` with tract and the native tail on the
/// trainer's outputs; refuse beyond the tolerances of [`export_sensor_checked`].
fn check_tail(proto: &pb::ModelProto, stored: &Stored, check_inputs: &[Dem], expected: &[Dem], path: &str) -> Result<TailCheck, DemError> {
    let model = stored.residual_or_empty();
    let k = model.draws();
    let n = check_inputs.len();
    let uniform = model.uniforms_of(0, 0, n, None);
    let times: Vec<f32> = (0..n).map(|i| if i % 5 == 0 { f32::NAN } else { 0.1 * (i % 40) as f32 }).collect();
    let mut native = expected.to_vec();
    for (i, (x, y)) in check_inputs.iter().zip(native.iter_mut()).enumerate() {
        stored.finish(x, y, &uniform[i * k..(i + 1) * k], Some(f64::from(times[i])).filter(|t| t.is_finite()));
    }
    let got = dem_sensor::graph::run_tract(proto, &model, check_inputs, &uniform, &times)
        .map_err(|e| DemError::input(path, format!("export check failed, nothing written: tract cannot run the whole graph: {e:#}")))?;
    let (mut differ, mut moved, mut worst) = (0usize, 0usize, 0.0f32);
    for (i, (a, b)) in native.iter().zip(&got).enumerate() {
        if a[GRID_LEN..] != b[GRID_LEN..] {
            return Err(DemError::input(
                path,
                format!("export check failed, nothing written: the whole graph changes row 20 of check record {i}"),
            ));
        }
        for j in 0..GRID_CELLS {
            let (va, vb) = (a[2 * j + 1] > 0.0, b[2 * j + 1] > 0.0);
            if va != vb {
                differ += 1;
            } else if va {
                let d = (a[2 * j] - b[2 * j]).abs();
                if d.is_nan() {
                    return Err(DemError::input(
                        path,
                        format!("export check failed, nothing written: a NaN height in check record {i}, cell {j}"),
                    ));
                } else if d > TOLERANCE {
                    moved += 1;
                } else {
                    worst = worst.max(d);
                }
            }
        }
    }
    let cells = (n * GRID_CELLS) as f64;
    let (validity_differ, height_differ) = (differ as f64 / cells, moved as f64 / cells);
    if validity_differ + height_differ > TAIL_VALIDITY {
        return Err(DemError::input(
            path,
            format!(
                "export check failed, nothing written: tract's whole graph decides {:.3} % of the cells differently from \
                 dem-apply's tail (tolerance {:.3} %): {:.3} % in validity, {:.3} % in height by more than {TOLERANCE:e} m",
                100.0 * (validity_differ + height_differ),
                100.0 * TAIL_VALIDITY,
                100.0 * validity_differ,
                100.0 * height_differ
            ),
        ));
    }
    Ok(TailCheck { validity_differ, height_differ, max_height_diff: worst })
}
