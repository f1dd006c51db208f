//! Run an ONNX model over batches of DEMs with tract.
//!
//! A conforming model has one input and one output, both `float32` of shape
//! `(N, 21, 5, 2)` (the file layout of `docs/format.md`, `N` the batch
//! axis). The names do not matter (an export names them `dem` and
//! `dem_out`).
//!
//! Two plans are typed, optimised and made runnable once, at load:
//! - the *batch* plan, with `N` symbolic: one call for the whole batch;
//! - the *record* plan, with `N = 1`, run once per record. tract gives a
//!   single-record 3x3 convolution its lazy im2col (the patches are gathered
//!   while the matrix product packs them), where a batch gets an eager im2col
//!   that copies 9x the activations first: on the width-32 generator the
//!   record plan runs 5x faster (1,640 against 320 records/s on one core).
//!
//! The record plan is used when it agrees with the batch plan on a probe
//! batch at load (every output within 1e-5 + 1e-5 |value|), which holds for
//! every model whose records do not see each other, as a DEM -> DEM model's
//! should; otherwise the batch plan is. Runs share the plans and each gets
//! its own state, so threads may call [`OnnxModel::run`] at the same time.
//!
//! **The native path.** A model that is a generator of `docs/network.md`
//! (dem-train's export or PyTorch's of the same network, recognised from its
//! graph and weights by [`crate::native`]) runs on dem-nn's inference
//! kernels instead ([`GeneratorInference`]: Winograd convolutions over blocks
//! of records, fused norms, no tape), when they reproduce tract on a probe
//! batch of [`NATIVE_PROBE`] records within [`NATIVE_TOLERANCE`] per value
//! (row 20 as tract gives it: the input's, or zeros for a model that writes
//! zeros there, as a PyTorch generator padding its output may).
//! Otherwise, or for any other model, tract runs it and
//! [`OnnxModel::note`] says why (the tools print it).
//!
//! ```no_run
//! # fn main() -> Result<(), dem_core::DemError> {
//! let model = dem_onnx::OnnxModel::load("model.onnx")?;
//! let input = dem_core::npy::read_all("sim.npy")?;
//! let output = model.run(&input)?; // output[i] = G(input[i]), same layout
//! # Ok(()) }
//! ```

use std::cell::RefCell;
use std::sync::Arc;

use anyhow::{bail, Context};
use dem_core::format::{CHANNELS, COLS, RECORD_LEN, ROWS};
use dem_core::{Dem, DemError};
use dem_nn::net::{GeneratorInference, InferScratch};
use prost::Message;
use tract_onnx::pb;
use tract_onnx::pb::tensor_shape_proto::dimension::Value as DimValue;
use tract_onnx::prelude::*;

/// The record shape after the batch axis: `(21, 5, 2)`.
pub const RECORD_SHAPE: [usize; 3] = [ROWS, COLS, CHANNELS];

/// Records of the probe batch on which the native path must reproduce tract.
pub const NATIVE_PROBE: usize = 32;
/// Largest `|native - tract|` per output value the native path may show on
/// the probe batch: the export's tolerance ([`crate::TOLERANCE`]); the two
/// compute in `f32` with different summation orders (~1e-6 apart).
pub const NATIVE_TOLERANCE: f32 = crate::generator::TOLERANCE;

/// What runs a model's batches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Engine {
    /// dem-nn's inference kernels (a recognised generator).
    Native,
    /// tract, record by record through the `N = 1` plan.
    TractPerRecord,
    /// tract, a batch per call.
    TractBatch,
}

/// A loaded, optimised ONNX model mapping `(N, 21, 5, 2)` to `(N, 21, 5, 2)`.
#[derive(Clone)]
pub struct OnnxModel {
    batched: Arc<TypedRunnableModel>,
    /// The `N = 1` plan, when it reproduces `batched` (see the module docs).
    single: Option<Arc<TypedRunnableModel>>,
    /// The native path, when the model is a recognised generator that
    /// reproduces tract on the probe batch.
    native: Option<Arc<GeneratorInference>>,
    /// Why the native path is not used, for the tools to print.
    note: Option<String>,
    /// The native path writes row 20 as zeros (as tract does for this
    /// model) instead of the input's.
    zero_attitude: bool,
    name: String,
    input: String,
    output: String,
}

thread_local! {
    /// Each thread's buffers for the native path (reused: a block's
    /// activations are a few MB, which a fresh allocation per call would
    /// page-fault in again).
    static SCRATCH: RefCell<InferScratch> = RefCell::new(InferScratch::default());
}

impl std::fmt::Debug for OnnxModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OnnxModel")
            .field("name", &self.name)
            .field("input", &self.input)
            .field("output", &self.output)
            .field("engine", &self.engine())
            .finish_non_exhaustive()
    }
}

fn bad(name: &str, reason: impl Into<String>) -> DemError {
    DemError::input(name, reason)
}

impl OnnxModel {
    /// Load the model file at `path`. A missing or unreadable file is
    /// [`DemError::Open`]; a file that is not ONNX, or whose input or output
    /// is not `float32 (N, 21, 5, 2)`, is [`DemError::Input`] naming `path`
    /// (both exit 2 in the tools).
    pub fn load(path: &str) -> Result<OnnxModel, DemError> {
        let bytes = std::fs::read(path).map_err(|source| DemError::Open { path: path.into(), source })?;
        Self::from_bytes(&bytes, path)
    }

    /// Load a model from the bytes of an ONNX file; `name` is used in errors.
    pub fn from_bytes(bytes: &[u8], name: &str) -> Result<OnnxModel, DemError> {
        let proto = pb::ModelProto::decode(bytes).map_err(|e| bad(name, format!("not an ONNX model (protobuf decoding failed: {e})")))?;
        // A virtual sensor's graph: its network runs here, the tail natively.
        match crate::sensor::network_part(&proto, name)? {
            Some(part) => {
                let mut m = Self::from_proto(&part.network, name)?;
                if part.sensor_alone {
                    // Its network is the identity: tract runs it, nothing to note.
                    m.note = None;
                }
                Ok(m)
            }
            None => Self::from_proto(&proto, name),
        }
    }

    /// Load a model from its protobuf message; `name` is used in errors.
    pub fn from_proto(proto: &pb::ModelProto, name: &str) -> Result<OnnxModel, DemError> {
        let (input, output) = check_signature(proto, name)?;
        let model =
            tract_onnx::onnx().model_for_proto_model(proto).map_err(|e| bad(name, format!("tract cannot read the ONNX graph: {e:#}")))?;
        let batched = plan(model.clone(), None).map_err(|e| bad(name, format!("{e:#}")))?;
        let mut m = OnnxModel { batched, single: None, native: None, note: None, zero_attitude: false, name: name.into(), input, output };
        // A model that refuses a batch of one, or that mixes records, keeps the batch plan.
        if let Ok(single) = plan(model, Some(1)) {
            let probe = probe_batch(3);
            let by_batch = m.run_batched(&probe)?;
            m.single = Some(single);
            if !m.run_per_record(&probe).is_ok_and(|by_record| agree(&by_batch, &by_record)) {
                m.single = None;
            }
        }
        match crate::native::recognise(proto) {
            Err(why) => m.note = Some(format!("{name} runs on tract: not recognised as a dem-train generator ({why})")),
            Ok(w) => {
                let native = GeneratorInference::new(&w);
                let probe = probe_batch(NATIVE_PROBE);
                let by_tract = m.run(&probe)?;
                // Row 20: the input's (an export), or zeros (what a PyTorch
                // generator that pads its output writes).
                let row20 = ROWS * COLS * CHANNELS - COLS * CHANNELS..RECORD_LEN;
                m.zero_attitude = by_tract.iter().all(|o| o[row20.clone()].iter().all(|v| *v == 0.0))
                    && probe.iter().any(|x| x[row20.clone()].iter().any(|v| *v != 0.0));
                let mut by_native = Vec::new();
                SCRATCH.with_borrow_mut(|s| native.run(&probe, s, &mut by_native));
                if m.zero_attitude {
                    by_native.iter_mut().for_each(|o| o[row20.clone()].fill(0.0));
                }
                match max_diff(&by_tract, &by_native) {
                    Some(d) if d <= NATIVE_TOLERANCE => m.native = Some(Arc::new(native)),
                    d => {
                        let by = d.map_or("a NaN".into(), |d| format!("{d:e}"));
                        m.note = Some(format!(
                            "{name} runs on tract: it looks like a {} generator of width {}, but the native path differs from tract by {by} on the probe batch (tolerance {NATIVE_TOLERANCE:e})",
                            w.arch.name(),
                            w.width
                        ));
                    }
                }
            }
        }
        Ok(m)
    }

    /// The same model with the native path switched off: tract runs every
    /// batch (to compare the two, or to rule the native path out).
    pub fn on_tract(mut self) -> OnnxModel {
        if self.native.take().is_some() {
            self.note = Some(format!("{} runs on tract: the native path was switched off", self.name));
        }
        self
    }

    /// What runs the model's batches.
    pub fn engine(&self) -> Engine {
        match (&self.native, &self.single) {
            (Some(_), _) => Engine::Native,
            (None, Some(_)) => Engine::TractPerRecord,
            (None, None) => Engine::TractBatch,
        }
    }

    /// Why a model runs on tract rather than on the native path (one line,
    /// naming the model), `None` when it runs natively.
    pub fn note(&self) -> Option<&str> {
        self.note.as_deref()
    }

    /// The engine in a few words, for a summary line: `native generator
    /// (residual, width 32)` or `tract`.
    pub fn engine_name(&self) -> String {
        match &self.native {
            Some(g) => format!("native generator ({}, width {})", g.arch().name(), g.width()),
            None => "tract".into(),
        }
    }

    /// The name given at load time (the path for [`OnnxModel::load`]).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Names of the model's input and output.
    pub fn io_names(&self) -> (&str, &str) {
        (&self.input, &self.output)
    }

    /// True when batches run record by record through the `N = 1` plan
    /// (see the module docs), false when through the batch plan.
    pub fn per_record(&self) -> bool {
        self.single.is_some()
    }

    /// Run the model on a batch of any size (0 gives an empty result):
    /// `out[i]` is the model's output for `batch[i]`, in the same layout.
    pub fn run(&self, batch: &[Dem]) -> Result<Vec<Dem>, DemError> {
        if batch.is_empty() {
            return Ok(Vec::new());
        }
        if let Some(g) = &self.native {
            let mut out = Vec::with_capacity(batch.len());
            SCRATCH.with_borrow_mut(|s| g.run(batch, s, &mut out));
            if self.zero_attitude {
                out.iter_mut().for_each(|o| o[RECORD_LEN - COLS * CHANNELS..].fill(0.0));
            }
            return Ok(out);
        }
        if self.single.is_some() {
            self.run_per_record(batch)
        } else {
            self.run_batched(batch)
        }
    }

    fn run_batched(&self, batch: &[Dem]) -> Result<Vec<Dem>, DemError> {
        let mut out = Vec::with_capacity(batch.len());
        let mut state = self.batched.spawn().map_err(|e| self.failed(batch.len(), e))?;
        self.run_one(&mut state, batch, &mut out)?;
        Ok(out)
    }

    fn run_per_record(&self, batch: &[Dem]) -> Result<Vec<Dem>, DemError> {
        let plan = self.single.as_ref().expect("a record plan");
        let mut out = Vec::with_capacity(batch.len());
        let mut state = plan.spawn().map_err(|e| self.failed(1, e))?;
        for d in batch {
            self.run_one(&mut state, std::slice::from_ref(d), &mut out)?;
        }
        Ok(out)
    }

    fn failed(&self, n: usize, e: anyhow::Error) -> DemError {
        bad(&self.name, format!("inference on a batch of {n} failed: {e:#}"))
    }

    /// One call of a plan on `batch`, outputs appended to `out`.
    fn run_one(&self, state: &mut TypedSimpleState, batch: &[Dem], out: &mut Vec<Dem>) -> Result<(), DemError> {
        let n = batch.len();
        let input = Tensor::from_shape(&[n, ROWS, COLS, CHANNELS], batch.as_flattened())
            .map_err(|e| bad(&self.name, format!("cannot make the input tensor: {e:#}")))?;
        let result = state.run(tvec![input.into_tvalue()]).map_err(|e| self.failed(n, e))?;
        let t = &result[0];
        if t.shape() != [n, ROWS, COLS, CHANNELS] {
            return Err(bad(&self.name, format!("the output of a batch of {n} has shape {:?}, not ({n}, 21, 5, 2)", t.shape())));
        }
        let view = t.try_as_plain_ram().map_err(|e| bad(&self.name, format!("cannot read the output: {e:#}")))?;
        let values = view.as_slice::<f32>().map_err(|e| bad(&self.name, format!("the output is not float32: {e:#}")))?;
        out.extend(values.chunks_exact(RECORD_LEN).map(|c| <Dem>::try_from(c).expect("210 values")));
        Ok(())
    }
}

/// `n` DEM-like records (heights within +-0.5 m, masks +-1, an attitude)
/// from a fixed sequence, to compare the plans and engines at load.
fn probe_batch(n: usize) -> Vec<Dem> {
    let mut x: u32 = 0x9e37_79b9;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        x as f32 / u32::MAX as f32 - 0.5
    };
    (0..n)
        .map(|_| {
            let mut d = [0.0; RECORD_LEN];
            for (k, v) in d.iter_mut().enumerate() {
                *v = match (k / 10, k % 2) {
                    (20, 1) => 1.0,
                    (20, _) => next(),
                    (_, 1) => next().signum(),
                    _ => next(),
                };
            }
            d
        })
        .collect()
}

/// Largest `|a - b|` over every value; `None` when some value is NaN (or the
/// lengths differ).
fn max_diff(a: &[Dem], b: &[Dem]) -> Option<f32> {
    if a.len() != b.len() {
        return None;
    }
    a.iter().flatten().zip(b.iter().flatten()).try_fold(0.0f32, |m, (x, y)| {
        let d = (x - y).abs();
        (!d.is_nan()).then_some(m.max(d))
    })
}

/// Equal within 1e-5 + 1e-5 |b| per value, NaN matching NaN.
fn agree(a: &[Dem], b: &[Dem]) -> bool {
    a.len() == b.len()
        && a.iter().flatten().zip(b.iter().flatten()).all(|(x, y)| (x.is_nan() && y.is_nan()) || (x - y).abs() <= 1e-5 + 1e-5 * y.abs())
}

/// Build the runnable plan: the input fact is `float32 (batch, 21, 5, 2)`,
/// `batch` a symbol `N` when `None`; the output must come out as the same
/// shape (checked after type inference, before optimising).
fn plan(mut model: InferenceModel, batch: Option<usize>) -> TractResult<Arc<TypedRunnableModel>> {
    let n: TDim = match batch {
        Some(k) => k.to_dim(),
        None => model.sym("N").to_dim(),
    };
    let shape: TVec<TDim> = std::iter::once(n.clone()).chain(RECORD_SHAPE.iter().map(|d| d.to_dim())).collect();
    model.set_input_fact(0, InferenceFact::dt_shape(f32::datum_type(), shape.clone()))?;
    let typed = model.into_typed().context("type and shape inference failed for input float32 (N, 21, 5, 2)")?;
    let fact = typed.output_fact(0)?;
    if fact.datum_type != f32::datum_type() || fact.shape.to_tvec() != shape {
        bail!("for an input float32 (N, 21, 5, 2) the output is {:?} {:?}, not float32 (N, 21, 5, 2)", fact.datum_type, fact.shape);
    }
    let opt = typed.into_optimized().context("optimising the graph failed")?;
    opt.into_runnable().context("making the plan failed")
}

/// Shape of a value as declared in the file: `None` for an unknown dim.
fn declared(v: &pb::ValueInfoProto) -> (Option<i32>, Option<Vec<Option<i64>>>) {
    let Some(pb::type_proto::Value::TensorType(t)) = v.r#type.as_ref().and_then(|t| t.value.as_ref()) else {
        return (None, None);
    };
    let dims = t.shape.as_ref().map(|s| {
        s.dim
            .iter()
            .map(|d| match d.value {
                Some(DimValue::DimValue(k)) => Some(k),
                _ => None,
            })
            .collect()
    });
    (Some(t.elem_type), dims)
}

/// `` `x` is float32 (N, 21, 5, 2) ``: a value as the file declares it.
fn describe(v: &pb::ValueInfoProto) -> String {
    let Some(pb::type_proto::Value::TensorType(t)) = v.r#type.as_ref().and_then(|t| t.value.as_ref()) else {
        return format!("`{}` is of undeclared type", v.name);
    };
    let dtype = match pb::tensor_proto::DataType::try_from(t.elem_type) {
        Ok(pb::tensor_proto::DataType::Float) => "float32".to_string(),
        Ok(pb::tensor_proto::DataType::Double) => "float64".to_string(),
        Ok(d) => d.as_str_name().to_lowercase(),
        Err(_) => format!("type {}", t.elem_type),
    };
    let shape = match &t.shape {
        Some(s) => {
            let dims: Vec<String> = s
                .dim
                .iter()
                .map(|d| match &d.value {
                    Some(DimValue::DimValue(k)) => k.to_string(),
                    Some(DimValue::DimParam(p)) if !p.is_empty() => p.clone(),
                    _ => "?".into(),
                })
                .collect();
            format!("({})", dims.join(", "))
        }
        None => "of undeclared shape".into(),
    };
    format!("`{}` is {dtype} {shape}", v.name)
}

/// Refuse, before tract sees it, a model whose one input or one output is
/// declared with another type or shape than `float32 (N, 21, 5, 2)` (a fixed
/// batch dim is refused too: the batch axis must be dynamic). Returns the
/// input and output names.
fn check_signature(proto: &pb::ModelProto, name: &str) -> Result<(String, String), DemError> {
    let graph = proto.graph.as_ref().ok_or_else(|| bad(name, "not an ONNX model (no graph)"))?;
    // Old exporters list the initializers among the inputs too.
    let inputs: Vec<&pb::ValueInfoProto> = graph.input.iter().filter(|i| !graph.initializer.iter().any(|t| t.name == i.name)).collect();
    let want = "float32 (N, 21, 5, 2)";
    if inputs.len() != 1 || graph.output.len() != 1 {
        return Err(bad(
            name,
            format!("the model has {} inputs and {} outputs; need one input and one output, {want}", inputs.len(), graph.output.len()),
        ));
    }
    for (what, v) in [("input", inputs[0]), ("output", &graph.output[0])] {
        let (elem, dims) = declared(v);
        let float = elem.is_none_or(|e| e == pb::tensor_proto::DataType::Float as i32);
        let shape_ok = dims.as_ref().is_none_or(|d| {
            d.len() == 4 && d[0].is_none() && d[1..].iter().zip(RECORD_SHAPE).all(|(k, want)| k.is_none_or(|k| k == want as i64))
        });
        if !float || !shape_ok {
            let fixed = dims.as_ref().is_some_and(|d| d.len() == 4 && d[0].is_some());
            let hint = if fixed && float { " (the batch axis must be dynamic)" } else { "" };
            return Err(bad(name, format!("the model's {what} {}, need {want}{hint}", describe(v))));
        }
    }
    Ok((inputs[0].name.clone(), graph.output[0].name.clone()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_model_can_be_shared_between_threads() {
        fn check<T: Send + Sync>() {}
        check::<OnnxModel>();
    }
}
