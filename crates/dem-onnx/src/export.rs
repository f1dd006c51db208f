//! Export a generator (`spec/network.md`) to ONNX, built from tract's
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
use dem_nn::weights::{Arch, CORRECTION_SCALE, GATE_SHARPNESS, Conv2d, GeneratorWeights, InstanceNorm, LEAK, NORM_EPS};
use prost::Message;
use std::io::Write;
use tract_onnx::pb;
use tract_onnx::pb::attribute_proto::AttributeType;
use tract_onnx::pb::tensor_proto::DataType;
use tract_onnx::pb::tensor_shape_proto::{dimension, Dimension};

use crate::run::OnnxModel;

/// The ONNX operator set the export declares.
pub const OPSET: i64 = 17;
/// The ONNX IR version the export declares (IR 8 goes with opsets 13..=17).
pub const IR_VERSION: i64 = 8;
/// Name of the model's input.
pub const INPUT: &str = "dem";
/// Name of the model's output.
pub const OUTPUT: &str = "dem_out";
/// Name of the batch axis (a `dim_param`).
pub const BATCH_AXIS: &str = "N";
/// Largest absolute difference, per output value, between the exported
/// model and the trainer's forward pass that [`export_checked`] accepts.
/// Both compute in `f32`; over ~15 layers with instance norms their rounding
/// differs by ~1e-6 for values of order 1, so 1e-4 leaves room for that and
/// nothing else (`spec/network.md` fixes this number).
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
}

/// A graph under construction: nodes in order, initializers, fresh names.
struct Builder {
    nodes: Vec<pb::NodeProto>,
    inits: Vec<pb::TensorProto>,
}

fn attr_int(name: &str, i: i64) -> pb::AttributeProto {
    pb::AttributeProto { name: name.into(), r#type: AttributeType::Int as i32, i, ..Default::default() }
}

fn attr_ints(name: &str, ints: &[i64]) -> pb::AttributeProto {
    pb::AttributeProto { name: name.into(), r#type: AttributeType::Ints as i32, ints: ints.to_vec(), ..Default::default() }
}

fn attr_float(name: &str, f: f32) -> pb::AttributeProto {
    pb::AttributeProto { name: name.into(), r#type: AttributeType::Float as i32, f, ..Default::default() }
}

/// `float32 (N, 21, 5, 2)` with `N` a named dynamic axis.
fn dem_value(name: &str) -> pb::ValueInfoProto {
    let dim = |v| Dimension { value: Some(v), ..Default::default() };
    let mut dims = vec![dim(dimension::Value::DimParam(BATCH_AXIS.into()))];
    dims.extend([21, 5, 2].map(|k| dim(dimension::Value::DimValue(k))));
    pb::ValueInfoProto {
        name: name.into(),
        r#type: Some(pb::TypeProto {
            value: Some(pb::type_proto::Value::TensorType(pb::type_proto::Tensor {
                elem_type: DataType::Float as i32,
                shape: Some(pb::TensorShapeProto { dim: dims }),
            })),
            ..Default::default()
        }),
        ..Default::default()
    }
}

impl Builder {
    fn f32s(&mut self, name: &str, dims: &[usize], data: &[f32]) -> String {
        assert_eq!(dims.iter().product::<usize>(), data.len(), "{name}: shape and data disagree");
        self.inits.push(pb::TensorProto {
            name: name.into(),
            dims: dims.iter().map(|&d| d as i64).collect(),
            data_type: DataType::Float as i32,
            float_data: data.to_vec(),
            ..Default::default()
        });
        name.into()
    }

    fn i64s(&mut self, name: &str, data: &[i64]) -> String {
        self.inits.push(pb::TensorProto {
            name: name.into(),
            dims: vec![data.len() as i64],
            data_type: DataType::Int64 as i32,
            int64_data: data.to_vec(),
            ..Default::default()
        });
        name.into()
    }

    /// Append a node whose single output is named `out`.
    fn node(&mut self, op: &str, inputs: &[&str], attrs: Vec<pb::AttributeProto>, out: &str) -> String {
        self.nodes.push(pb::NodeProto {
            input: inputs.iter().map(|s| s.to_string()).collect(),
            output: vec![out.into()],
            name: out.into(),
            op_type: op.into(),
            attribute: attrs,
            ..Default::default()
        });
        out.into()
    }

    /// `Slice(x)[start..end]` on `axis`.
    fn slice(&mut self, x: &str, axis: i64, start: i64, end: i64, out: &str) -> String {
        let s = self.i64s(&format!("{out}.starts"), &[start]);
        let e = self.i64s(&format!("{out}.ends"), &[end]);
        let a = self.i64s(&format!("{out}.axes"), &[axis]);
        self.node("Slice", &[x, &s, &e, &a], vec![], out)
    }

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
    assert!(
        w.enc.len() == 3 && w.enc_norm.len() == 3 && w.dec.len() == 3 && w.dec_norm.len() == 2,
        "a generator has 3 encoder and 3 decoder convs"
    );
    assert_eq!((w.fc.n_in, w.fc.n_out), (RECORD_LEN, GRID_LEN), "the generator head is 210 -> 200");
    let mut g = Builder { nodes: Vec::new(), inits: Vec::new() };
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
    g.node("Transpose", &[&o], vec![attr_ints("perm", &[0, 2, 3, 1])], OUTPUT);
    pb::ModelProto {
        ir_version: IR_VERSION,
        opset_import: vec![pb::OperatorSetIdProto { domain: String::new(), version: OPSET }],
        producer_name: "dem-onnx".into(),
        producer_version: env!("CARGO_PKG_VERSION").into(),
        doc_string: format!(
            "Generator of spec/network.md, {} head, width {}: {INPUT} float32 (N,21,5,2) -> {OUTPUT} float32 (N,21,5,2), \
             row 20 (attitude) passed through",
            w.arch.name(),
            w.width
        ),
        graph: Some(pb::GraphProto {
            node: g.nodes,
            name: name.into(),
            initializer: g.inits,
            input: vec![dem_value(INPUT)],
            output: vec![dem_value(OUTPUT)],
            ..Default::default()
        }),
        ..Default::default()
    }
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
pub fn export_checked(
    w: &GeneratorWeights,
    check_inputs: &[Dem],
    expected: &[Dem],
    path: &str,
) -> Result<ExportReport, DemError> {
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
    if check_inputs.is_empty() || check_inputs.len() != expected.len() {
        return Err(DemError::Usage(format!(
            "export to {path}: need check records and as many expected outputs (got {} and {})",
            check_inputs.len(),
            expected.len()
        )));
    }
    let name = std::path::Path::new(path).file_stem().map_or("generator".into(), |s| s.to_string_lossy().into_owned());
    let mut proto = generator_model(w, &name);
    proto.metadata_props =
        metadata.iter().map(|(key, value)| pb::StringStringEntryProto { key: key.clone(), value: value.clone() }).collect();
    let bytes = proto.encode_to_vec();
    // tract, not the native path: the file must be right for any runtime.
    let model = OnnxModel::from_bytes(&bytes, path)?.on_tract();
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
    write_atomic(path, |f| f.write_all(&bytes))?;
    Ok(ExportReport { path: path.into(), bytes: bytes.len(), records: check_inputs.len(), max_abs_diff })
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
    Ok(ModelInfo {
        producer: format!("{} {}", m.producer_name, m.producer_version).trim().to_string(),
        description: m.doc_string,
        opset: m.opset_import.iter().find(|o| o.domain.is_empty() || o.domain == "ai.onnx").map(|o| o.version),
        metadata: m.metadata_props.into_iter().map(|e| (e.key, e.value)).collect(),
    })
}
