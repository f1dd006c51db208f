//! Recognise a generator of `docs/network.md` in an ONNX graph and read its
//! weights back, so [`crate::OnnxModel`] can run it on dem-nn's inference
//! kernels ([`dem_nn::net::GeneratorInference`]) instead of tract.
//!
//! A graph is recognised when it is made only of the operators a generator
//! export needs (ours, [`crate::generator_model`], or PyTorch's of the same
//! network) and holds exactly the generator's weighted layers, in execution
//! order:
//!
//! ```text
//! 12 x Conv 3x3, stride 1, pad 1, group 1     channels 2 -> w -> 2w -> 2w, 6 x (2w -> 2w), 2w -> 2w -> w -> 2
//! 11 x InstanceNormalization, epsilon 1e-5    after every conv but the last
//!  5 x LeakyRelu(0.2), 3 x Relu, 1 x Tanh     encoder and decoder, residual blocks, the mask
//!  1 x Gemm 210 -> 200                        the head (alpha = beta = 1, transA = 0)
//!  0 or 1 x Sigmoid                           thesis or residual head
//! ```
//!
//! Weights come from the graph's initializers or `Constant` nodes. Whether the
//! wiring between those layers is the generator's is not proved here: the
//! caller runs the recognised network and tract on a probe batch and keeps
//! the native path only when they agree (see [`crate::model`]); every operator
//! allowed is continuous, so a different wiring shows on random records.

use std::collections::HashMap;

use dem_core::format::{GRID_LEN, RECORD_LEN};
use dem_nn::weights::{Arch, Conv2d, GeneratorWeights, InstanceNorm, Linear, ResBlock, LEAK, NORM_EPS};
use tract_onnx::pb;
use tract_onnx::pb::tensor_proto::DataType;

/// Operators a generator's graph may hold (the weighted ones and the glue
/// exporters write around them: layout, slicing, shapes).
const ALLOWED: &[&str] = &[
    "Conv",
    "InstanceNormalization",
    "LeakyRelu",
    "Relu",
    "Tanh",
    "Sigmoid",
    "Gemm",
    "Add",
    "Mul",
    "Transpose",
    "Slice",
    "Flatten",
    "Reshape",
    "Concat",
    "Constant",
    "Identity",
    "Shape",
    "Gather",
    "Unsqueeze",
    "Squeeze",
    "Cast",
    "Split",
    "ConstantOfShape",
    "Expand",
];

/// The generator weights of `proto`'s graph, or why it is not recognised as
/// a generator (one phrase, for the note the tools print).
pub fn recognise(proto: &pb::ModelProto) -> Result<GeneratorWeights, String> {
    let graph = proto.graph.as_ref().ok_or("no graph")?;
    let mut tensors: HashMap<&str, &pb::TensorProto> = graph.initializer.iter().map(|t| (t.name.as_str(), t)).collect();
    for n in &graph.node {
        if !n.domain.is_empty() && n.domain != "ai.onnx" {
            return Err(format!("it has an operator of domain {}", n.domain));
        }
        if !ALLOWED.contains(&n.op_type.as_str()) {
            return Err(format!("it has a {} node", n.op_type));
        }
        if n.op_type == "Constant" {
            if let (Some(out), Some(t)) = (n.output.first(), n.attribute.iter().find(|a| a.name == "value").and_then(|a| a.t.as_ref())) {
                tensors.insert(out.as_str(), t);
            }
        }
    }
    let count = |op: &str| graph.node.iter().filter(|n| n.op_type == op).count();
    let want = [
        ("Conv", 12, 12),
        ("InstanceNormalization", 11, 11),
        ("LeakyRelu", 5, 5),
        ("Relu", 3, 3),
        ("Tanh", 1, 1),
        ("Gemm", 1, 1),
        ("Sigmoid", 0, 1),
    ];
    for (op, lo, hi) in want {
        let k = count(op);
        if k < lo || k > hi {
            return Err(format!("it has {k} {op} nodes, a generator {lo}"));
        }
    }
    let weights = |n: &pb::NodeProto, i: usize| -> Result<(Vec<i64>, Vec<f32>), String> {
        let name = n.input.get(i).filter(|s| !s.is_empty()).ok_or_else(|| format!("{} `{}` lacks input {i}", n.op_type, n.name))?;
        let t = tensors.get(name.as_str()).ok_or_else(|| format!("{} `{}` takes `{name}`, not a constant", n.op_type, n.name))?;
        Ok((t.dims.clone(), floats(t).ok_or_else(|| format!("`{name}` is not float32 data stored in the file"))?))
    };
    let ints = |n: &pb::NodeProto, a: &str| n.attribute.iter().find(|x| x.name == a).map(|x| x.ints.clone());
    let int = |n: &pb::NodeProto, a: &str, default: i64| n.attribute.iter().find(|x| x.name == a).map_or(default, |x| x.i);
    let float = |n: &pb::NodeProto, a: &str, default: f32| n.attribute.iter().find(|x| x.name == a).map_or(default, |x| x.f);

    let mut convs = Vec::new();
    let mut norms = Vec::new();
    let mut fc = None;
    for n in &graph.node {
        match n.op_type.as_str() {
            "Conv" => {
                let (dims, weight) = weights(n, 1)?;
                let ones = |a: &str| ints(n, a).is_none_or(|v| v.iter().all(|&k| k == 1));
                let geometry = dims.len() == 4
                    && dims[2..] == [3, 3]
                    && ints(n, "kernel_shape").is_none_or(|k| k == [3, 3])
                    && ints(n, "pads").is_some_and(|p| p == [1, 1, 1, 1])
                    && ones("strides")
                    && ones("dilations")
                    && int(n, "group", 1) == 1;
                if !geometry {
                    return Err(format!("Conv `{}` is not 3x3, stride 1, pad 1", n.name));
                }
                let (c_out, c_in) = (dims[0] as usize, dims[1] as usize);
                let bias = if n.input.len() > 2 && !n.input[2].is_empty() { weights(n, 2)?.1 } else { vec![0.0; c_out] };
                if bias.len() != c_out || weight.len() != c_out * c_in * 9 {
                    return Err(format!("Conv `{}` has weights of the wrong size", n.name));
                }
                convs.push(Conv2d { c_out, c_in, k: 3, stride: 1, weight, bias });
            }
            "InstanceNormalization" => {
                if (float(n, "epsilon", 1e-5) - NORM_EPS).abs() > 1e-9 {
                    return Err(format!("InstanceNormalization `{}` has epsilon {}, not {NORM_EPS}", n.name, float(n, "epsilon", 1e-5)));
                }
                norms.push(InstanceNorm { gamma: weights(n, 1)?.1, beta: weights(n, 2)?.1 });
            }
            "LeakyRelu" if (float(n, "alpha", 0.01) - LEAK).abs() > 1e-7 => {
                return Err(format!("LeakyRelu `{}` has slope {}, not {LEAK}", n.name, float(n, "alpha", 0.01)));
            }
            "Gemm" => {
                let plain = int(n, "transA", 0) == 0 && float(n, "alpha", 1.0) == 1.0 && float(n, "beta", 1.0) == 1.0;
                let (dims, w) = weights(n, 1)?;
                let bias = if n.input.len() > 2 { weights(n, 2)?.1 } else { Vec::new() };
                // The head of docs/network.md: the record (210 values) in, the grid (200) out.
                const IN: i64 = RECORD_LEN as i64;
                const OUT: i64 = GRID_LEN as i64;
                let weight = match (int(n, "transB", 0), dims.as_slice()) {
                    (1, [OUT, IN]) => w,
                    (0, [IN, OUT]) => (0..GRID_LEN * RECORD_LEN).map(|k| w[(k % RECORD_LEN) * GRID_LEN + k / RECORD_LEN]).collect(),
                    _ => return Err(format!("Gemm `{}` is not {RECORD_LEN} -> {GRID_LEN}", n.name)),
                };
                if !plain || bias.len() != GRID_LEN {
                    return Err(format!("Gemm `{}` is not x W^T + b", n.name));
                }
                fc = Some(Linear { n_out: GRID_LEN, n_in: RECORD_LEN, weight, bias });
            }
            _ => {}
        }
    }
    let w = convs[0].c_out;
    let chain = [(2, w), (w, 2 * w), (2 * w, 2 * w)].into_iter().chain(std::iter::repeat_n((2 * w, 2 * w), 7)).chain([(2 * w, w), (w, 2)]);
    let norm_ch = chain.clone().take(11).map(|(_, co)| co);
    if !convs.iter().zip(chain).all(|(c, (ci, co))| (c.c_in, c.c_out) == (ci, co))
        || !norms.iter().zip(norm_ch).all(|(n, c)| n.gamma.len() == c && n.beta.len() == c)
    {
        return Err(format!("its convs and norms are not a width-{w} generator's channels"));
    }
    let arch = if count("Sigmoid") == 1 { Arch::Residual } else { Arch::Thesis };
    let mut convs = convs.into_iter();
    let mut norms = norms.into_iter();
    let mut next = || (convs.next().expect("12 convs"), norms.next());
    let (mut enc, mut enc_norm) = (Vec::new(), Vec::new());
    for _ in 0..3 {
        let (c, n) = next();
        enc.push(c);
        enc_norm.push(n.expect("a norm"));
    }
    let res = (0..3)
        .map(|_| {
            let ((a, na), (b, nb)) = (next(), next());
            ResBlock { a, na: na.expect("a norm"), b, nb: nb.expect("a norm") }
        })
        .collect();
    let (mut dec, mut dec_norm) = (Vec::new(), Vec::new());
    for _ in 0..3 {
        let (c, n) = next();
        dec.push(c);
        dec_norm.extend(n);
    }
    let fc = fc.expect("one Gemm");
    Ok(GeneratorWeights { width: w, arch, enc, enc_norm, res, dec, dec_norm, fc })
}

/// The values of a float32 tensor stored in the file (`float_data` or
/// little-endian `raw_data`); `None` for another type or external data.
fn floats(t: &pb::TensorProto) -> Option<Vec<f32>> {
    if t.data_type != DataType::Float as i32 || t.data_location == Some(1) {
        return None;
    }
    let len: i64 = t.dims.iter().product();
    let v: Vec<f32> = if t.raw_data.is_empty() {
        t.float_data.clone()
    } else {
        t.raw_data.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
    };
    (v.len() as i64 == len).then_some(v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn an_export_gives_its_weights_back() {
        for arch in [Arch::Thesis, Arch::Residual] {
            let w = GeneratorWeights::init_arch(&mut ChaCha8Rng::seed_from_u64(2), 4, arch);
            let proto = crate::generator_model(&w, "g");
            assert_eq!(recognise(&proto), Ok(w));
        }
    }

    #[test]
    fn other_graphs_are_named_not_recognised() {
        let w = GeneratorWeights::init_arch(&mut ChaCha8Rng::seed_from_u64(2), 4, Arch::Thesis);
        let mut proto = crate::generator_model(&w, "g");
        let g = proto.graph.as_mut().unwrap();
        let k = g.node.iter().position(|n| n.op_type == "Tanh").unwrap();
        g.node[k].op_type = "Softsign".into();
        assert_eq!(recognise(&proto).unwrap_err(), "it has a Softsign node");
        let mut proto = crate::generator_model(&w, "g");
        let g = proto.graph.as_mut().unwrap();
        let k = g.node.iter().position(|n| n.op_type == "LeakyRelu").unwrap();
        g.node[k].attribute[0].f = 0.1;
        assert!(recognise(&proto).unwrap_err().contains("slope"));
    }
}
