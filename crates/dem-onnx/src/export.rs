//! Export a generator (`docs/network.md`) to ONNX, built from tract's
//! protobuf types and encoded with `prost`.
//!
//! The graph, opset [`OPSET`], `N` the dynamic batch axis:
//!
//! ```text
//! dem (N,21,5,2) -Transpose[0,3,1,2]-> (N,2,21,5) -+-Slice rows 0..20-> img (N,2,20,5)
//!                                                  +-Slice row 20----> att (N,2,1,5)
//! img -> 3 x [Conv 3x3 pad 1 -> InstanceNormalization(eps 1e-5) -> LeakyRelu(0.2)]    2 -> w -> 2w -> 2w
//!     -> 3 x [h + IN(Conv(Relu(IN(Conv(h)))))]                                       residual blocks at 2w
//!     -> Conv -> IN -> LeakyRelu -> Conv -> IN -> LeakyRelu -> Conv                  2w -> 2w -> w -> 2
//!     -> Flatten (N,200), feature c*100 + r*5 + col
//! Concat(that, Flatten(att) (N,10), feature 200 + c*5 + col) (N,210)
//!     -> Gemm(transB = 1) 210 -> 200 -> [heights 0..100 | Tanh(masks 100..200)]
//!     -> residual head only: heights = (Flatten(img channel 0) + 0.1 heights) * Sigmoid(20 masks_raw)
//!     -> Reshape (N,2,20,5) -> Concat(., att, axis rows) (N,2,21,5)
//!     -> Transpose[0,2,3,1] -> dem_out (N,21,5,2)
//! ```
//!
//! Row 20 of the output is the input's row 20, untouched.

use dem_core::format::{GRID_CELLS, GRID_LEN, RECORD_LEN};
use dem_core::output::write_atomic;
use dem_core::{Dem, DemError};
use dem_graph::{attr_float, attr_int, attr_ints, Builder};
use dem_nn::weights::{Arch, Conv2d, GeneratorWeights, InstanceNorm, CORRECTION_SCALE, GATE_SHARPNESS, LEAK, NORM_EPS};
use prost::Message;
use std::io::Write;
use tract_onnx::pb;

use crate::model::OnnxModel;
use crate::sensor::Stored;

pub use dem_graph::{IR_VERSION, OPSET};
/// Name of the model's input.
pub const INPUT: &str = "dem";
/// Name of the model's output.
pub const OUTPUT: &str = "dem_out";
pub use dem_graph::BATCH_AXIS;
/// Largest absolute difference, per output value, between the exported
/// model and the trainer's forward pass that [`export_checked`] accepts.
/// Both compute in `f32`; over ~15 layers with instance norms their rounding
/// differs by ~1e-6 for values of order 1, so 1e-4 leaves room for that and
/// nothing else (`docs/network.md` fixes this number).
pub const TOLERANCE: f32 = 1e-4;

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

/// Generator layers on a [`Builder`].
trait Layers {
    fn conv(&mut self, x: &str, c: &Conv2d, name: &str) -> String;
    fn norm(&mut self, x: &str, n: &InstanceNorm, name: &str) -> String;
    fn leaky(&mut self, x: &str, name: &str) -> String;
}

impl Layers for Builder {
    /// 3x3 conv, stride 1, pad 1: `(N, c_in, 20, 5) -> (N, c_out, 20, 5)`.
    fn conv(&mut self, x: &str, c: &Conv2d, name: &str) -> String {
        assert_eq!((c.k, c.stride), (3, 1), "{name}: the generator's convs are 3x3 stride 1");
        let w = self.f32s(&format!("{name}.weight"), &[c.c_out, c.c_in, c.k, c.k], &c.weight);
        let b = self.f32s(&format!("{name}.bias"), &[c.c_out], &c.bias);
        let attrs = vec![attr_ints("kernel_shape", &[3, 3]), attr_ints("pads", &[1, 1, 1, 1]), attr_ints("strides", &[1, 1])];
        self.node("Conv", &[x, &w, &b], attrs, name)
    }

    /// Affine instance norm over the 20x5 positions of each sample and channel.
    fn norm(&mut self, x: &str, n: &InstanceNorm, name: &str) -> String {
        let g = self.f32s(&format!("{name}.gamma"), &[n.gamma.len()], &n.gamma);
        let b = self.f32s(&format!("{name}.beta"), &[n.beta.len()], &n.beta);
        self.node("InstanceNormalization", &[x, &g, &b], vec![attr_float("epsilon", NORM_EPS)], name)
    }

    fn leaky(&mut self, x: &str, name: &str) -> String {
        self.node("LeakyRelu", &[x], vec![attr_float("alpha", LEAK)], name)
    }
}

/// The ONNX model of generator `w`, named `name`: input [`INPUT`] and output
/// [`OUTPUT`], both `float32 (N, 21, 5, 2)`, `N` dynamic; see the module docs
/// for the graph. Panics if `w` is not shaped as `GeneratorWeights::init`
/// makes it (3 encoder, 3 residual, 3 decoder 3x3 convs, a 210 -> 200 head).
pub fn generator_model(w: &GeneratorWeights, name: &str) -> pb::ModelProto {
    let mut g = Builder::new();
    generator_nodes(&mut g, w, OUTPUT);
    let doc = format!(
        "Generator of docs/network.md, {} head, width {}: {INPUT} float32 (N,21,5,2) -> {OUTPUT} float32 (N,21,5,2), \
         row 20 (attitude) passed through",
        w.arch.name(),
        w.width
    );
    model_proto(g, name, doc, vec![dem_graph::batch_value(INPUT, &[21, 5, 2])])
}

/// A model of graph `g` with output [`OUTPUT`] `(N, 21, 5, 2)`.
pub(crate) fn model_proto(g: Builder, name: &str, doc: String, inputs: Vec<pb::ValueInfoProto>) -> pb::ModelProto {
    let mut m = g.model(name, inputs, vec![dem_graph::batch_value(OUTPUT, &[21, 5, 2])], doc, &[]);
    m.producer_name = "dem-onnx".into();
    m
}

/// The generator's nodes on `g`, from the graph input [`INPUT`] to the
/// tensor named `out` (`(N, 21, 5, 2)`); names are fixed (no fresh names),
/// so what follows in `g` is named as in a graph of its own.
pub fn generator_nodes(g: &mut Builder, w: &GeneratorWeights, out: &str) -> String {
    assert!(
        w.enc.len() == 3 && w.enc_norm.len() == 3 && w.dec.len() == 3 && w.dec_norm.len() == 2,
        "a generator has 3 encoder and 3 decoder convs"
    );
    assert_eq!((w.fc.n_in, w.fc.n_out), (RECORD_LEN, GRID_LEN), "the generator head is 210 -> 200");
    let nchw = g.node("Transpose", &[INPUT], vec![attr_ints("perm", &[0, 3, 1, 2])], "nchw");
    let img = g.slice(&nchw, 2, 0, 20, "grid");
    let att = g.slice(&nchw, 2, 20, 21, "attitude");
    let mut h = img.clone();
    for (i, (c, n)) in w.enc.iter().zip(&w.enc_norm).enumerate() {
        let x = g.conv(&h, c, &format!("enc{i}"));
        let x = g.norm(&x, n, &format!("enc{i}.norm"));
        h = g.leaky(&x, &format!("enc{i}.act"));
    }
    for (i, r) in w.res.iter().enumerate() {
        let p = format!("res{i}");
        let x = g.conv(&h, &r.a, &format!("{p}.a"));
        let x = g.norm(&x, &r.na, &format!("{p}.na"));
        let x = g.node("Relu", &[&x], vec![], &format!("{p}.relu"));
        let x = g.conv(&x, &r.b, &format!("{p}.b"));
        let x = g.norm(&x, &r.nb, &format!("{p}.nb"));
        h = g.node("Add", &[&h, &x], vec![], &format!("{p}.out"));
    }
    for (i, c) in w.dec.iter().enumerate() {
        h = g.conv(&h, c, &format!("dec{i}"));
        if i < 2 {
            let x = g.norm(&h, &w.dec_norm[i], &format!("dec{i}.norm"));
            h = g.leaky(&x, &format!("dec{i}.act"));
        }
    }
    let flat = g.node("Flatten", &[&h], vec![attr_int("axis", 1)], "grid_features");
    let att_flat = g.node("Flatten", &[&att], vec![attr_int("axis", 1)], "attitude_features");
    let feat = g.node("Concat", &[&flat, &att_flat], vec![attr_int("axis", 1)], "features");
    let fw = g.f32s("fc.weight", &[GRID_LEN, RECORD_LEN], &w.fc.weight);
    let fb = g.f32s("fc.bias", &[GRID_LEN], &w.fc.bias);
    let o = g.node("Gemm", &[&feat, &fw, &fb], vec![attr_int("transB", 1)], "fc");
    // The head's output: the 100 heights, then the 100 raw masks.
    let (cells, values) = (GRID_CELLS as i64, GRID_LEN as i64);
    let heights = g.slice(&o, 1, 0, cells, "heights");
    let masks_raw = g.slice(&o, 1, cells, values, "masks_raw");
    let masks = g.node("Tanh", &[&masks_raw], vec![], "masks");
    let heights = match w.arch {
        Arch::Thesis => heights,
        Arch::Residual => {
            // (x_h + o_h) * (1 + m) / 2, x_h the input's height channel.
            let xh = g.slice(&img, 1, 0, 1, "input_heights");
            let xh = g.node("Flatten", &[&xh], vec![attr_int("axis", 1)], "input_heights_flat");
            let scale = g.f32s("correction.scale", &[1], &[CORRECTION_SCALE]);
            let c = g.node("Mul", &[&heights, &scale], vec![], "correction");
            let a = g.node("Add", &[&c, &xh], vec![], "heights_ungated");
            let k = g.f32s("gate.sharpness", &[1], &[GATE_SHARPNESS]);
            let gate = g.node("Mul", &[&masks_raw, &k], vec![], "gate_logit");
            let gate = g.node("Sigmoid", &[&gate], vec![], "gate");
            g.node("Mul", &[&a, &gate], vec![], "heights_gated")
        }
    };
    let o = g.node("Concat", &[&heights, &masks], vec![attr_int("axis", 1)], "head");
    let shape = g.i64s("head.shape", &[-1, 2, 20, 5]);
    let o = g.node("Reshape", &[&o, &shape], vec![], "head_nchw");
    let o = g.node("Concat", &[&o, &att], vec![attr_int("axis", 2)], "out_nchw");
    g.node("Transpose", &[&o], vec![attr_ints("perm", &[0, 2, 3, 1])], out)
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
/// uniforms and times (a fifth of them unknown): validity may differ on at
/// most [`TAIL_VALIDITY`] of the cells (masks within rounding of 0), heights
/// by [`TOLERANCE`] where both are valid, row 20 not at all.
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

/// Largest share of cells whose validity the whole graph and the native
/// tail may disagree on in the export check: a network mask within float
/// rounding of 0 can fall either side, and the effects after it follow.
pub const TAIL_VALIDITY: f64 = 1e-3;

/// What the check of a virtual sensor's whole graph found.
#[derive(Clone, Debug, PartialEq)]
pub struct TailCheck {
    /// Share of cells whose validity differs.
    pub validity_differ: f64,
    /// Largest height difference where both are valid.
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
    let uniform = model.uniforms_of(0, 0, n);
    let times: Vec<f32> = (0..n).map(|i| if i % 5 == 0 { f32::NAN } else { 0.1 * (i % 40) as f32 }).collect();
    let mut native = expected.to_vec();
    for (i, (x, y)) in check_inputs.iter().zip(native.iter_mut()).enumerate() {
        stored.finish(x, y, &uniform[i * k..(i + 1) * k], Some(f64::from(times[i])).filter(|t| t.is_finite()));
    }
    let got = dem_sensor::graph::run_tract(proto, &model, check_inputs, &uniform, &times)
        .map_err(|e| DemError::input(path, format!("export check failed, nothing written: tract cannot run the whole graph: {e:#}")))?;
    let (mut differ, mut worst) = (0usize, 0.0f32);
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
                worst = if d.is_nan() { f32::INFINITY } else { worst.max(d) };
            }
        }
    }
    let validity_differ = differ as f64 / (n * GRID_CELLS) as f64;
    if validity_differ > TAIL_VALIDITY || worst > TOLERANCE {
        return Err(DemError::input(
            path,
            format!(
                "export check failed, nothing written: tract's whole graph differs from dem-apply's tail on {:.3} % of the cells' \
                 validity (tolerance {:.3} %) and by {worst:e} m in height (tolerance {TOLERANCE:e})",
                100.0 * validity_differ,
                100.0 * TAIL_VALIDITY
            ),
        ));
    }
    Ok(TailCheck { validity_differ, max_height_diff: worst })
}

/// The `metadata_props` key of a generator's residual sensor model: the
/// JSON of a dem-sensor model that dem-gap fitted between the network's
/// output and measured DEMs, which `dem-apply` applies after the network
/// (`dem-train export --residual`).
pub const RESIDUAL_KEY: &str = "dem.residual";

/// What an ONNX file says about itself: producer, description and the
/// `metadata_props` an export stored ([`export_checked_with`]), in file order.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelInfo {
    /// `producer_name producer_version`.
    pub producer: String,
    /// The model's `doc_string`.
    pub description: String,
    /// The ONNX operator set imported from the default domain.
    pub opset: Option<i64>,
    /// `metadata_props`, key and value.
    pub metadata: Vec<(String, String)>,
}

impl ModelInfo {
    /// `dem-apply --info`'s lines for the model at `path` run by `engine`:
    /// one `key: value` each; a multi-line value (the validation table)
    /// follows its key, indented.
    pub fn lines(&self, path: &str, engine: &str) -> Vec<String> {
        let mut lines = vec![
            format!("model: {path}"),
            format!("producer: {}", self.producer),
            format!("opset: {}", self.opset.map_or("none".into(), |o| o.to_string())),
            format!("description: {}", self.description),
            format!("engine: {engine}"),
        ];
        if self.metadata.is_empty() {
            lines.push("metadata: none (not exported by dem-train, or by a version before models carried it)".into());
        }
        for (k, v) in &self.metadata {
            if v.contains('\n') {
                lines.push(format!("{k}:"));
                lines.extend(v.lines().map(|l| format!("  {l}")));
            } else {
                lines.push(format!("{k}: {v}"));
            }
        }
        lines
    }
}

/// Read [`ModelInfo`] from the ONNX file at `path` (the graph is not built).
pub fn read_info(path: &str) -> Result<ModelInfo, DemError> {
    let bytes = std::fs::read(path).map_err(|e| DemError::input(path, format!("cannot read: {e}")))?;
    let m = pb::ModelProto::decode(&bytes[..]).map_err(|e| DemError::input(path, format!("not an ONNX model: {e}")))?;
    Ok(ModelInfo::of(&m))
}

impl ModelInfo {
    /// What model `m` says about itself.
    pub fn of(m: &pb::ModelProto) -> ModelInfo {
        ModelInfo {
            producer: format!("{} {}", m.producer_name, m.producer_version).trim().to_string(),
            description: m.doc_string.clone(),
            opset: m.opset_import.iter().find(|o| o.domain.is_empty() || o.domain == "ai.onnx").map(|o| o.version),
            metadata: m.metadata_props.iter().map(|e| (e.key.clone(), e.value.clone())).collect(),
        }
    }
}
