//! ONNX graphs for the dem-* tools, built from tract's protobuf types
//! (`tract_onnx::pb`) and encoded with `prost`, and run with tract to check
//! them before a file is written.
//!
//! - [`Builder`]: nodes in order, initializers, fresh names; one method per
//!   operator pattern the exports use (slices, shifts along an axis,
//!   comparisons, selections).
//! - [`run`]: a model's outputs for named float32 inputs of concrete shapes.
//!
//! The operators are the plain ones every runtime has (onnxruntime,
//! tract, PyTorch through onnx2torch): arithmetic, `Where`, comparisons,
//! `And`/`Or`/`Not`, `Cast`, `Slice`, `Pad`, `Concat`, `Reshape`,
//! `Reduce*` with an `axes` attribute (opset [`OPSET`]), `Gather`,
//! `GatherElements`, `Conv`,
//! `Floor`, `Sqrt`, `Log`, `Cos`, `Sin` (no `LessOrEqual`: onnx2torch has none).

use prost::Message;
use tract_onnx::pb;
use tract_onnx::pb::attribute_proto::AttributeType;
use tract_onnx::pb::tensor_proto::DataType;
use tract_onnx::pb::tensor_shape_proto::{dimension, Dimension};
use tract_onnx::prelude::*;

pub use tract_onnx::pb as proto;

/// The ONNX operator set the exports declare.
pub const OPSET: i64 = 17;
/// The ONNX IR version the exports declare (IR 8 goes with opsets 13..=17).
pub const IR_VERSION: i64 = 8;
/// Name of the batch axis (a `dim_param`).
pub const BATCH_AXIS: &str = "N";

/// An integer attribute.
pub fn attr_int(name: &str, i: i64) -> pb::AttributeProto {
    pb::AttributeProto { name: name.into(), r#type: AttributeType::Int as i32, i, ..Default::default() }
}

/// A list-of-integers attribute.
pub fn attr_ints(name: &str, ints: &[i64]) -> pb::AttributeProto {
    pb::AttributeProto { name: name.into(), r#type: AttributeType::Ints as i32, ints: ints.to_vec(), ..Default::default() }
}

/// A float attribute.
pub fn attr_float(name: &str, f: f32) -> pb::AttributeProto {
    pb::AttributeProto { name: name.into(), r#type: AttributeType::Float as i32, f, ..Default::default() }
}

/// `float32 (N, dims...)` with `N` the named dynamic batch axis.
pub fn batch_value(name: &str, dims: &[i64]) -> pb::ValueInfoProto {
    let dim = |v| Dimension { value: Some(v), ..Default::default() };
    let mut all = vec![dim(dimension::Value::DimParam(BATCH_AXIS.into()))];
    all.extend(dims.iter().map(|&k| dim(dimension::Value::DimValue(k))));
    pb::ValueInfoProto {
        name: name.into(),
        r#type: Some(pb::TypeProto {
            value: Some(pb::type_proto::Value::TensorType(pb::type_proto::Tensor {
                elem_type: DataType::Float as i32,
                shape: Some(pb::TensorShapeProto { dim: all }),
            })),
            ..Default::default()
        }),
        ..Default::default()
    }
}

/// A graph under construction: nodes in order, initializers, and a counter
/// for fresh names under a prefix.
#[derive(Default)]
pub struct Builder {
    /// The nodes, in topological order.
    pub nodes: Vec<pb::NodeProto>,
    /// The constant tensors.
    pub inits: Vec<pb::TensorProto>,
    prefix: String,
    fresh: usize,
}

impl Builder {
    /// An empty graph.
    pub fn new() -> Self {
        Self::default()
    }

    /// Name the nodes that follow `prefix.N` (a readable graph: one prefix
    /// per layer or effect).
    pub fn set_prefix(&mut self, prefix: &str) {
        self.prefix = prefix.into();
    }

    /// The current prefix.
    pub fn prefix(&self) -> &str {
        &self.prefix
    }

    /// A fresh name under the current prefix.
    pub fn fresh(&mut self, what: &str) -> String {
        self.fresh += 1;
        if self.prefix.is_empty() {
            format!("{what}.{}", self.fresh)
        } else {
            format!("{}.{what}.{}", self.prefix, self.fresh)
        }
    }

    /// A float32 constant of shape `dims` named `name`.
    pub fn f32s(&mut self, name: &str, dims: &[usize], data: &[f32]) -> String {
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

    /// A float32 constant of shape `dims` under a fresh name.
    pub fn constant(&mut self, dims: &[usize], data: &[f32]) -> String {
        let name = self.fresh("const");
        self.f32s(&name, dims, data)
    }

    /// A float32 scalar (shape `[]`: broadcasts against anything).
    pub fn scalar(&mut self, v: f32) -> String {
        self.constant(&[], &[v])
    }

    /// A 1-D int64 constant named `name`.
    pub fn i64s(&mut self, name: &str, data: &[i64]) -> String {
        self.inits.push(pb::TensorProto {
            name: name.into(),
            dims: vec![data.len() as i64],
            data_type: DataType::Int64 as i32,
            int64_data: data.to_vec(),
            ..Default::default()
        });
        name.into()
    }

    /// A 1-D int64 constant under a fresh name.
    pub fn ints(&mut self, data: &[i64]) -> String {
        let name = self.fresh("ints");
        self.i64s(&name, data)
    }

    /// Append a node whose single output is named `out`.
    pub fn node(&mut self, op: &str, inputs: &[&str], attrs: Vec<pb::AttributeProto>, out: &str) -> String {
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

    /// Append a node with a fresh output name.
    pub fn op(&mut self, op: &str, inputs: &[&str], attrs: Vec<pb::AttributeProto>) -> String {
        let out = self.fresh(&op.to_lowercase());
        self.node(op, inputs, attrs, &out)
    }

    /// `Slice(x)[start..end]` on `axis`, output named `out`.
    pub fn slice(&mut self, x: &str, axis: i64, start: i64, end: i64, out: &str) -> String {
        let s = self.i64s(&format!("{out}.starts"), &[start]);
        let e = self.i64s(&format!("{out}.ends"), &[end]);
        let a = self.i64s(&format!("{out}.axes"), &[axis]);
        self.node("Slice", &[x, &s, &e, &a], vec![], out)
    }

    /// `x[.., start..end, ..]` on `axis`, under a fresh name.
    pub fn take(&mut self, x: &str, axis: i64, start: i64, end: i64) -> String {
        let out = self.fresh("slice");
        self.slice(x, axis, start, end, &out)
    }

    /// `Reshape(x, shape)` (`-1` for the batch axis).
    pub fn reshape(&mut self, x: &str, shape: &[i64]) -> String {
        let s = self.ints(shape);
        self.op("Reshape", &[x, &s], vec![])
    }

    /// `y[.., i, ..] = x[.., i + by, ..]` on `axis` of length `len`, `fill`
    /// where `i + by` falls outside (`by` = 1: each cell sees its neighbour
    /// ahead; -1: behind). Float tensors only.
    pub fn shift(&mut self, x: &str, axis: usize, rank: usize, len: i64, by: i64, fill: f32) -> String {
        assert!(by != 0 && by.abs() < len && axis < rank);
        let kept = if by > 0 { self.take(x, axis as i64, by, len) } else { self.take(x, axis as i64, 0, len + by) };
        let mut pads = vec![0i64; 2 * rank];
        if by > 0 {
            pads[rank + axis] = by;
        } else {
            pads[axis] = -by;
        }
        let pads = self.ints(&pads);
        let fill = self.scalar(fill);
        self.op("Pad", &[&kept, &pads, &fill], vec![])
    }

    /// `Concat` along `axis`.
    pub fn concat(&mut self, xs: &[&str], axis: i64) -> String {
        self.op("Concat", xs, vec![attr_int("axis", axis)])
    }

    /// A binary operator (`Add`, `Sub`, `Mul`, `Div`, `Min`, `Max`,
    /// `Greater`, `Less`, `Equal`, `And`, `Or`, `Pow`).
    pub fn bin(&mut self, op: &str, a: &str, b: &str) -> String {
        self.op(op, &[a, b], vec![])
    }

    /// A unary operator (`Neg`, `Abs`, `Floor`, `Sqrt`, `Log`, `Cos`,
    /// `Sin`, `Not`).
    pub fn un(&mut self, op: &str, a: &str) -> String {
        self.op(op, &[a], vec![])
    }

    /// `Where(cond, a, b)`.
    pub fn select(&mut self, cond: &str, a: &str, b: &str) -> String {
        self.op("Where", &[cond, a, b], vec![])
    }

    /// A boolean tensor as float32 (1 or 0).
    pub fn to_float(&mut self, b: &str) -> String {
        self.op("Cast", &[b], vec![attr_int("to", DataType::Float as i64)])
    }

    /// `x > c` for a float constant `c`.
    pub fn gt_const(&mut self, x: &str, c: f32) -> String {
        let c = self.scalar(c);
        self.bin("Greater", x, &c)
    }

    /// `x < c` for a float constant `c`.
    pub fn lt_const(&mut self, x: &str, c: f32) -> String {
        let c = self.scalar(c);
        self.bin("Less", x, &c)
    }

    /// `x * c` for a float constant `c`.
    pub fn mul_const(&mut self, x: &str, c: f32) -> String {
        let c = self.scalar(c);
        self.bin("Mul", x, &c)
    }

    /// `x + c` for a float constant `c`.
    pub fn add_const(&mut self, x: &str, c: f32) -> String {
        let c = self.scalar(c);
        self.bin("Add", x, &c)
    }

    /// The conjunction of boolean tensors (at least one).
    pub fn all(&mut self, xs: &[&str]) -> String {
        let mut acc = xs[0].to_string();
        for x in &xs[1..] {
            acc = self.bin("And", &acc, x);
        }
        acc
    }

    /// The disjunction of boolean tensors (at least one).
    pub fn any(&mut self, xs: &[&str]) -> String {
        let mut acc = xs[0].to_string();
        for x in &xs[1..] {
            acc = self.bin("Or", &acc, x);
        }
        acc
    }

    /// `Reduce{Max,Sum,Min}` over `axes`, kept as axes of length 1 (a
    /// `Reshape` after it drops them: onnx2torch keeps reduced axes of a
    /// `ReduceSum` whatever `keepdims` says). At opset 17, `ReduceSum` takes
    /// its axes as an input, the others as an attribute.
    pub fn reduce(&mut self, op: &str, x: &str, axes: &[i64]) -> String {
        if op == "ReduceSum" {
            let a = self.ints(axes);
            self.op(op, &[x, &a], vec![attr_int("keepdims", 1)])
        } else {
            self.op(op, &[x], vec![attr_ints("axes", axes), attr_int("keepdims", 1)])
        }
    }

    /// A model of this graph: `inputs` and `outputs` as value infos.
    pub fn model(
        self,
        name: &str,
        inputs: Vec<pb::ValueInfoProto>,
        outputs: Vec<pb::ValueInfoProto>,
        doc: String,
        metadata: &[(String, String)],
    ) -> pb::ModelProto {
        pb::ModelProto {
            ir_version: IR_VERSION,
            opset_import: vec![pb::OperatorSetIdProto { domain: String::new(), version: OPSET }],
            producer_name: "dem-tools".into(),
            producer_version: env!("CARGO_PKG_VERSION").into(),
            doc_string: doc,
            metadata_props: metadata
                .iter()
                .map(|(key, value)| pb::StringStringEntryProto { key: key.clone(), value: value.clone() })
                .collect(),
            graph: Some(pb::GraphProto {
                node: self.nodes,
                name: name.into(),
                initializer: self.inits,
                input: inputs,
                output: outputs,
                ..Default::default()
            }),
            ..Default::default()
        }
    }
}

/// The bytes of an ONNX file holding `model`.
pub fn encode(model: &pb::ModelProto) -> Vec<u8> {
    model.encode_to_vec()
}

/// One named float32 input of a concrete shape.
pub struct Input<'a> {
    /// The graph input's name.
    pub name: &'a str,
    /// Its shape, batch axis first.
    pub shape: Vec<usize>,
    /// Its values, row-major.
    pub data: &'a [f32],
}

/// Run `model` with tract on `inputs` (given in the graph's input order)
/// and return its first output's values, row-major.
pub fn run(model: &pb::ModelProto, inputs: &[Input]) -> anyhow::Result<Vec<f32>> {
    Ok(run_all(model, inputs)?.swap_remove(0))
}

/// [`run`], returning every output's values, row-major, in the graph's
/// output order.
pub fn run_all(model: &pb::ModelProto, inputs: &[Input]) -> anyhow::Result<Vec<Vec<f32>>> {
    let bytes = model.encode_to_vec();
    let mut m = tract_onnx::onnx().model_for_read(&mut &bytes[..])?;
    for (i, x) in inputs.iter().enumerate() {
        m.set_input_fact(i, f32::fact(&x.shape).into())?;
    }
    let plan = m.into_optimized()?.into_runnable()?;
    let tensors: TVec<TValue> = inputs
        .iter()
        .map(|x| Ok(tract_ndarray::ArrayD::from_shape_vec(x.shape.clone(), x.data.to_vec())?.into_tensor().into_tvalue()))
        .collect::<anyhow::Result<_>>()?;
    let out = plan.run(tensors)?;
    out.iter().map(|o| Ok(o.try_as_plain_ram()?.as_slice::<f32>()?.to_vec())).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shift_moves_along_an_axis_and_fills() {
        let mut b = Builder::new();
        let ahead = b.shift("x", 1, 2, 4, 1, -9.0);
        let behind = b.shift(&ahead, 1, 2, 4, -2, 7.0);
        b.node("Identity", &[&behind], vec![], "y");
        let m = b.model("t", vec![batch_value("x", &[4])], vec![batch_value("y", &[4])], String::new(), &[]);
        let y = run(&m, &[Input { name: "x", shape: vec![1, 4], data: &[1.0, 2.0, 3.0, 4.0] }]).unwrap();
        // ahead: [2, 3, 4, -9]; behind by 2: [7, 7, 2, 3]
        assert_eq!(y, [7.0, 7.0, 2.0, 3.0]);
    }
}
