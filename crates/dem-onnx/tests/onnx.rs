//! The export and the tract runner against the slow f64 reference forward
//! (`dem_nn::reference::generator`) and onnxruntime, on the bundled records.
//!
//! Tolerance: 1e-4 absolute per value (docs/network.md). tract and
//! onnxruntime compute in f32, the reference in f64; for random generators
//! of PyTorch's initialisation the outputs are of order 1 and the f32
//! rounding over the ~20 layers stays around 1e-6.

use dem_core::format::{at, ATTITUDE_ROW};
use dem_core::Dem;
use dem_nn::reference;
use dem_nn::weights::{Arch, GeneratorWeights};
use dem_onnx::{export_checked, generator_model, pb, Engine, OnnxModel, TOLERANCE};
use dem_testkit::{arg, py, tempdir, testdata};
use prost::Message;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn generator(width: usize, seed: u64) -> GeneratorWeights {
    GeneratorWeights::init(&mut ChaCha8Rng::seed_from_u64(seed), width)
}

/// A residual-head generator whose height correction is not zero (a fresh
/// one starts at zero, which would hide a wrong correction path).
fn residual(width: usize, seed: u64) -> GeneratorWeights {
    use rand::Rng;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut w = GeneratorWeights::init_arch(&mut rng, width, Arch::Residual);
    w.fc.weight[..100 * 210].iter_mut().for_each(|v| *v = rng.gen_range(-0.05..0.05));
    w.fc.bias[..100].iter_mut().for_each(|v| *v = rng.gen_range(-0.05..0.05));
    w
}

/// `n` records: sim records (full grids) and measured ones (missing cells),
/// every one with a non-zero attitude (the bundled sim data has some, the
/// others get a made-up pitch and flippers).
fn records(n: usize) -> Vec<Dem> {
    let sim = dem_core::npy::read_all(testdata("sim.npy").to_str().unwrap()).unwrap();
    let real = dem_core::npy::read_all(testdata("real.npy").to_str().unwrap()).unwrap();
    let mut out: Vec<Dem> = Vec::new();
    for i in 0..n {
        let mut d = if i % 2 == 0 { sim[(i * 37) % sim.len()] } else { real[(i * 53) % real.len()] };
        if (0..5).all(|c| d[at(ATTITUDE_ROW, c, 0)] == 0.0) {
            for c in 0..5 {
                d[at(ATTITUDE_ROW, c, 0)] = 0.1 * (c as f32 - 2.0) + 0.01 * (i % 7) as f32;
            }
        }
        out.push(d);
    }
    let missing = out.iter().filter(|d| (0..100).any(|k| d[2 * k + 1] < 0.0)).count();
    assert!(missing >= n / 4, "want records with missing cells, have {missing} of {n}");
    out
}

fn max_diff(a: &[Dem], b: &[Dem]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter().flatten().zip(b.iter().flatten()).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max)
}

fn reference_outputs(w: &GeneratorWeights, input: &[Dem]) -> Vec<Dem> {
    input.iter().map(|d| reference::generator(w, d)).collect()
}

/// The export of `w` on tract (the native path switched off).
fn tract_model(w: &GeneratorWeights) -> OnnxModel {
    native_model(w).on_tract()
}

/// The export of `w` as the tools load it: a generator runs natively.
fn native_model(w: &GeneratorWeights) -> OnnxModel {
    OnnxModel::from_bytes(&generator_model(w, "g").encode_to_vec(), "g.onnx").unwrap()
}

#[test]
fn tract_matches_the_reference_at_width_4() {
    let w = generator(4, 1);
    let input = records(40);
    let got = tract_model(&w).run(&input).unwrap();
    let d = max_diff(&got, &reference_outputs(&w, &input));
    assert!(d <= TOLERANCE, "max |tract - reference| = {d}");
}

#[test]
fn tract_matches_the_reference_at_width_32() {
    let w = generator(32, 2);
    let input = records(12);
    let got = tract_model(&w).run(&input).unwrap();
    let d = max_diff(&got, &reference_outputs(&w, &input));
    assert!(d <= TOLERANCE, "max |tract - reference| = {d}");
}

#[test]
fn tract_matches_the_reference_with_the_residual_head() {
    for (width, n) in [(4, 40), (32, 12)] {
        let w = residual(width, 20 + width as u64);
        let input = records(n);
        let got = tract_model(&w).run(&input).unwrap();
        let d = max_diff(&got, &reference_outputs(&w, &input));
        assert!(d <= TOLERANCE, "width {width}: max |tract - reference| = {d}");
        // Where the output mask says missing, the gate writes a height near 0.
        for o in &got {
            for k in 0..100 {
                if o[2 * k + 1] < -0.5 {
                    assert!(o[2 * k].abs() < 1e-2, "a missing cell keeps height {}", o[2 * k]);
                }
            }
        }
    }
}

#[test]
fn the_attitude_row_passes_through_and_masks_stay_in_range() {
    let w = generator(8, 3);
    let input = records(10);
    let got = tract_model(&w).run(&input).unwrap();
    for (g, x) in got.iter().zip(&input) {
        assert_eq!(g[at(ATTITUDE_ROW, 0, 0)..], x[at(ATTITUDE_ROW, 0, 0)..]);
        assert!((0..100).all(|k| (-1.0..=1.0).contains(&g[2 * k + 1])));
    }
}

#[test]
fn the_batch_axis_is_dynamic() {
    let w = generator(4, 4);
    let model = tract_model(&w);
    let input = records(300);
    let want = reference_outputs(&w, &input);
    for n in [1, 7, 300] {
        let got = model.run(&input[..n]).unwrap();
        assert_eq!(got.len(), n);
        let d = max_diff(&got, &want[..n]);
        assert!(d <= TOLERANCE, "batch {n}: max |tract - reference| = {d}");
    }
    assert!(model.run(&[]).unwrap().is_empty());
}

#[test]
fn threads_can_share_one_model() {
    let w = generator(4, 5);
    let model = tract_model(&w);
    let input = records(64);
    let want = model.run(&input).unwrap();
    std::thread::scope(|s| {
        let handles: Vec<_> = input.chunks(16).map(|chunk| s.spawn(|| model.run(chunk).unwrap())).collect();
        let got: Vec<Dem> = handles.into_iter().flat_map(|h| h.join().unwrap()).collect();
        assert_eq!(got, want);
    });
}

/// The exported file through onnxruntime and `onnx.checker` in Python.
#[test]
fn onnxruntime_and_the_onnx_checker_accept_the_export() {
    let dir = tempdir();
    for (width, arch) in [(4, Arch::Thesis), (32, Arch::Thesis), (8, Arch::Residual)] {
        let w = if arch == Arch::Thesis { generator(width, 10 + width as u64) } else { residual(width, 30) };
        let input = records(if width == 32 { 12 } else { 60 });
        let want = reference_outputs(&w, &input);
        let model = arg(dir.path(), &format!("g{width}.onnx"));
        let report = export_checked(&w, &input, &want, &model).unwrap();
        assert!(report.max_abs_diff <= TOLERANCE && report.records == input.len());
        let inp = arg(dir.path(), "in.npy");
        dem_core::npy::write_all(&inp, &input).unwrap();
        let said = py(
            dir.path(),
            &format!(
                r#"
import onnx
m = onnx.load("{model}")
onnx.checker.check_model(m, full_check=True)
assert [i.name for i in m.graph.input] == ["dem"] and [o.name for o in m.graph.output] == ["dem_out"]
for v in (m.graph.input[0], m.graph.output[0]):
    d = v.type.tensor_type.shape.dim
    assert d[0].dim_param == "N" and [x.dim_value for x in d[1:]] == [21, 5, 2], d
assert v.type.tensor_type.elem_type == onnx.TensorProto.FLOAT
assert m.opset_import[0].version >= 13
print("ok")
"#
            ),
        );
        assert_eq!(said.trim(), "ok");
        // Batches of 7: the batch axis is dynamic.
        let out = dem_testkit::onnxruntime(dir.path(), &model, &inp, 7, "out.npy");
        let got = dem_core::npy::read_all(&out).unwrap();
        let d = max_diff(&got, &want);
        assert!(d <= TOLERANCE, "width {width} {arch:?}: max |onnxruntime - reference| = {d}");
    }
}

#[test]
fn export_checked_refuses_a_wrong_expectation_and_writes_nothing() {
    let dir = tempdir();
    let w = generator(4, 6);
    let input = records(8);
    let mut want = reference_outputs(&w, &input);
    want[5][at(3, 2, 0)] += 1e-3;
    let path = arg(dir.path(), "g.onnx");
    let err = export_checked(&w, &input, &want, &path).unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains("g.onnx") && msg.contains("nothing written") && msg.contains("record 5"), "{msg}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "a file was left behind");
    // A NaN expectation is refused too, and a mismatched count.
    want[5][at(3, 2, 0)] = f32::NAN;
    assert!(export_checked(&w, &input, &want, &path).is_err());
    assert!(export_checked(&w, &input, &want[..3], &path).is_err());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    // And the right one is written.
    let want = reference_outputs(&w, &input);
    let r = export_checked(&w, &input, &want, &path).unwrap();
    assert_eq!(std::fs::metadata(&path).unwrap().len() as usize, r.bytes);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    let reloaded = OnnxModel::load(&path).unwrap();
    assert_eq!(reloaded.io_names(), ("dem", "dem_out"));
}

/// A one-node model `Identity` (or `op`) with the given input and output
/// types: shape dims < 0 are the dynamic batch axis.
fn tiny_model(op: &str, in_type: i32, in_shape: &[i64], out_shape: &[i64]) -> Vec<u8> {
    use pb::tensor_shape_proto::{dimension::Value, Dimension};
    let value = |name: &str, elem: i32, shape: &[i64]| pb::ValueInfoProto {
        name: name.into(),
        r#type: Some(pb::TypeProto {
            value: Some(pb::type_proto::Value::TensorType(pb::type_proto::Tensor {
                elem_type: elem,
                shape: Some(pb::TensorShapeProto {
                    dim: shape
                        .iter()
                        .map(|&d| Dimension {
                            value: Some(if d < 0 { Value::DimParam("N".into()) } else { Value::DimValue(d) }),
                            ..Default::default()
                        })
                        .collect(),
                }),
            })),
            ..Default::default()
        }),
        ..Default::default()
    };
    pb::ModelProto {
        ir_version: 8,
        opset_import: vec![pb::OperatorSetIdProto { domain: String::new(), version: 17 }],
        graph: Some(pb::GraphProto {
            node: vec![pb::NodeProto { input: vec!["x".into()], output: vec!["y".into()], op_type: op.into(), ..Default::default() }],
            input: vec![value("x", in_type, in_shape)],
            output: vec![value("y", in_type, out_shape)],
            ..Default::default()
        }),
        ..Default::default()
    }
    .encode_to_vec()
}

#[test]
fn any_single_input_single_output_model_of_the_shape_runs() {
    let m = OnnxModel::from_bytes(&tiny_model("Identity", 1, &[-1, 21, 5, 2], &[-1, 21, 5, 2]), "id.onnx").unwrap();
    assert_eq!(m.io_names(), ("x", "y"));
    let input = records(9);
    assert_eq!(m.run(&input).unwrap(), input);
}

#[test]
fn models_of_another_shape_or_type_are_refused_naming_the_file() {
    let float = 1;
    let cases: [(Vec<u8>, &str); 5] = [
        (tiny_model("Identity", float, &[-1, 20, 5, 2], &[-1, 20, 5, 2]), "input `x` is float32 (N, 20, 5, 2), need float32 (N, 21, 5, 2)"),
        (tiny_model("Identity", 7, &[-1, 21, 5, 2], &[-1, 21, 5, 2]), "input `x` is int64 (N, 21, 5, 2)"),
        (tiny_model("Identity", float, &[1, 21, 5, 2], &[1, 21, 5, 2]), "batch axis must be dynamic"),
        (tiny_model("Identity", float, &[-1, 21, 5, 2], &[-1, 210]), "output `y` is float32 (N, 210)"),
        // Declared right, but the graph makes another shape: caught by tract's inference.
        (tiny_model("Flatten", float, &[-1, 21, 5, 2], &[-1, 21, 5, 2]), "output is"),
    ];
    for (bytes, want) in cases {
        let err = OnnxModel::from_bytes(&bytes, "bad.onnx").unwrap_err().to_string();
        assert!(err.starts_with("bad.onnx: ") && err.contains(want), "{err}\nwanted: {want}");
    }
}

#[test]
fn unreadable_and_invalid_files_are_errors_naming_the_file() {
    let dir = tempdir();
    let missing = arg(dir.path(), "missing.onnx");
    let err = OnnxModel::load(&missing).unwrap_err();
    assert!(matches!(err, dem_core::DemError::Open { .. }) && err.to_string().contains("missing.onnx"), "{err}");
    assert_eq!(err.exit_code(), 2);
    let junk = arg(dir.path(), "junk.onnx");
    std::fs::write(&junk, b"this is not a protobuf \xff\xff\xff").unwrap();
    let err = OnnxModel::load(&junk).unwrap_err();
    assert!(err.to_string().starts_with(&format!("{junk}: ")), "{err}");
    assert_eq!(err.exit_code(), 2);
    // A valid protobuf that is an empty model.
    std::fs::write(&junk, b"").unwrap();
    let err = OnnxModel::load(&junk).unwrap_err();
    assert!(err.to_string().contains("junk.onnx"), "{err}");
}

#[test]
fn a_model_that_mixes_records_runs_as_one_batch() {
    // Softmax over the batch axis: each output depends on every record.
    let mut m = pb::ModelProto::decode(&tiny_model("Softmax", 1, &[-1, 21, 5, 2], &[-1, 21, 5, 2])[..]).unwrap();
    m.graph.as_mut().unwrap().node[0].attribute.push(pb::AttributeProto {
        name: "axis".into(),
        r#type: pb::attribute_proto::AttributeType::Int as i32,
        i: 0,
        ..Default::default()
    });
    let model = OnnxModel::from_proto(&m, "softmax.onnx").unwrap();
    assert!(!model.per_record());
    let input = records(5);
    let got = model.run(&input).unwrap();
    for k in 0..210 {
        let z: f32 = input.iter().map(|d| d[k].exp()).sum();
        for (g, x) in got.iter().zip(&input) {
            assert!((g[k] - x[k].exp() / z).abs() < 1e-5);
        }
    }
    // The generator's records are independent: it runs record by record.
    assert!(tract_model(&generator(4, 9)).per_record());
}

/// dem-train's generators (both heads) run on the native path, which equals
/// tract, the f64 reference and onnxruntime within 1e-4 per value.
#[test]
fn generators_run_natively_and_equal_tract_the_reference_and_onnxruntime() {
    let dir = tempdir();
    for (width, arch) in [(32, Arch::Thesis), (32, Arch::Residual), (8, Arch::Residual)] {
        let w = if arch == Arch::Thesis { generator(width, 40) } else { residual(width, 41) };
        let input = records(if width == 32 { 24 } else { 60 });
        let want = reference_outputs(&w, &input);
        let path = arg(dir.path(), &format!("native{width}{}.onnx", arch.name()));
        export_checked(&w, &input, &want, &path).unwrap();
        let model = OnnxModel::load(&path).unwrap();
        assert_eq!(model.engine(), Engine::Native, "{:?}", model.note());
        assert!(model.note().is_none());
        let got = model.run(&input).unwrap();
        let by_tract = model.clone().on_tract().run(&input).unwrap();
        let d = max_diff(&got, &by_tract);
        assert!(d <= TOLERANCE, "width {width} {arch:?}: max |native - tract| = {d}");
        let d = max_diff(&got, &want);
        assert!(d <= TOLERANCE, "width {width} {arch:?}: max |native - reference| = {d}");
        for (g, x) in got.iter().zip(&input) {
            assert_eq!(g[at(ATTITUDE_ROW, 0, 0)..], x[at(ATTITUDE_ROW, 0, 0)..], "row 20 passes through");
        }
        let inp = arg(dir.path(), "in.npy");
        dem_core::npy::write_all(&inp, &input).unwrap();
        let out = dem_testkit::onnxruntime(dir.path(), &path, &inp, 4096, "out.npy");
        let d = max_diff(&got, &dem_core::npy::read_all(&out).unwrap());
        assert!(d <= TOLERANCE, "width {width} {arch:?}: max |native - onnxruntime| = {d}");
    }
}

/// Weights stored as `raw_data` (as PyTorch's exporter writes them) are read too.
#[test]
fn a_graph_with_raw_data_weights_runs_natively() {
    let w = residual(8, 42);
    let mut m = generator_model(&w, "g");
    for t in &mut m.graph.as_mut().unwrap().initializer {
        t.raw_data = t.float_data.iter().flat_map(|v| v.to_le_bytes()).collect();
        t.float_data.clear();
    }
    let model = OnnxModel::from_proto(&m, "raw.onnx").unwrap();
    assert_eq!(model.engine(), Engine::Native, "{:?}", model.note());
    let input = records(20);
    let d = max_diff(&model.run(&input).unwrap(), &reference_outputs(&w, &input));
    assert!(d <= TOLERANCE, "max |native - reference| = {d}");
}

/// A model that is not a generator runs on tract, and says so.
#[test]
fn an_unrecognised_model_runs_on_tract_with_a_note() {
    let model = OnnxModel::from_bytes(&tiny_model("Neg", 1, &[-1, 21, 5, 2], &[-1, 21, 5, 2]), "neg.onnx").unwrap();
    assert_eq!(model.engine(), Engine::TractPerRecord);
    let note = model.note().unwrap();
    assert!(note.starts_with("neg.onnx runs on tract: not recognised") && note.contains("Neg"), "{note}");
    let input = records(9);
    let got = model.run(&input).unwrap();
    assert!(got.iter().flatten().zip(input.iter().flatten()).all(|(y, x)| *y == -x));
}

/// A graph with a generator's layers that computes something else (here the
/// residual head's correction scale doubled) fails the probe against tract
/// and runs on tract, with a note.
#[test]
fn a_lookalike_that_differs_from_tract_runs_on_tract() {
    let w = residual(8, 43);
    let mut m = generator_model(&w, "g");
    let scale = m.graph.as_mut().unwrap().initializer.iter_mut().find(|t| t.name == "correction.scale").unwrap();
    scale.float_data[0] *= 2.0;
    let model = OnnxModel::from_proto(&m, "lookalike.onnx").unwrap();
    assert_eq!(model.engine(), Engine::TractPerRecord);
    let note = model.note().unwrap();
    assert!(note.contains("residual generator of width 8") && note.contains("differs from tract"), "{note}");
    // And what runs is the file's model, not the recognised one.
    let input = records(10);
    let d = max_diff(&model.run(&input).unwrap(), &reference_outputs(&w, &input));
    assert!(d > 1e-3, "the doubled correction shows ({d})");
}

/// A generator that writes zeros in row 20 (as PyTorch's reference generator
/// pads its output) runs natively too, and writes zeros there as tract does.
#[test]
fn a_generator_writing_zeros_in_row_20_runs_natively() {
    let w = generator(8, 44);
    let mut m = generator_model(&w, "g");
    let g = m.graph.as_mut().unwrap();
    g.initializer.push(pb::TensorProto {
        name: "zero".into(),
        dims: vec![1],
        data_type: pb::tensor_proto::DataType::Float as i32,
        float_data: vec![0.0],
        ..Default::default()
    });
    let k = g.node.iter().position(|n| n.name == "out_nchw").unwrap();
    g.node[k].input[1] = "attitude_zero".into();
    g.node.insert(
        k,
        pb::NodeProto {
            input: vec!["attitude".into(), "zero".into()],
            output: vec!["attitude_zero".into()],
            name: "attitude_zero".into(),
            op_type: "Mul".into(),
            ..Default::default()
        },
    );
    let model = OnnxModel::from_proto(&m, "zeros.onnx").unwrap();
    assert_eq!(model.engine(), Engine::Native, "{:?}", model.note());
    let input = records(20);
    let got = model.run(&input).unwrap();
    let by_tract = model.clone().on_tract().run(&input).unwrap();
    assert!(max_diff(&got, &by_tract) <= TOLERANCE);
    assert!(got.iter().all(|o| o[at(ATTITUDE_ROW, 0, 0)..].iter().all(|v| *v == 0.0)));
}
