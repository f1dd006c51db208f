//! The generator (`docs/network.md`) as an ONNX graph, built from tract's
//! protobuf types, and the metadata an exported model carries.
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
use dem_core::DemError;
use dem_graph::{attr_float, attr_int, attr_ints, Builder};
use dem_nn::weights::{Arch, Conv2d, GeneratorWeights, InstanceNorm, CORRECTION_SCALE, GATE_SHARPNESS, LEAK, NORM_EPS};
use prost::Message;
use tract_onnx::pb;

pub use dem_graph::{IR_VERSION, OPSET};
/// Name of the model's input.
pub const INPUT: &str = "dem";
/// Name of the model's output.
pub const OUTPUT: &str = "dem_out";
pub use dem_graph::BATCH_AXIS;
/// Largest absolute difference, per output value, between the exported
/// model and the trainer's forward pass that [`crate::export::export_checked`] accepts.
/// Both compute in `f32`; over ~15 layers with instance norms their rounding
/// differs by ~1e-6 for values of order 1, so 1e-4 leaves room for that and
/// nothing else (`docs/network.md` fixes this number).
pub const TOLERANCE: f32 = 1e-4;
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
    model_proto(g, name, doc, vec![dem_graph::batch_value(INPUT, &[21, 5, 2])], vec![dem_graph::batch_value(OUTPUT, &[21, 5, 2])])
}

/// A model of graph `g` with output [`OUTPUT`] `(N, 21, 5, 2)`.
pub(crate) fn model_proto(
    g: Builder,
    name: &str,
    doc: String,
    inputs: Vec<pb::ValueInfoProto>,
    outputs: Vec<pb::ValueInfoProto>,
) -> pb::ModelProto {
    let mut m = g.model(name, inputs, outputs, doc, &[]);
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

/// The `metadata_props` key of a generator's residual sensor model: the
/// JSON of a dem-sensor model that dem-gap fitted between the network's
/// output and measured DEMs, which `dem-apply` applies after the network
/// (`dem-train export --residual`).
pub const RESIDUAL_KEY: &str = "dem.residual";

/// What an ONNX file says about itself: producer, description and the
/// `metadata_props` an export stored ([`crate::export::export_checked_with`]), in file order.
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
