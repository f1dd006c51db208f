//! dem-apply on the bundled test data, the way users run it, against the slow
//! f64 reference forward of the exported generator (tolerance 1e-4 per
//! value, docs/network.md: tract computes in f32, the reference in f64).

use std::process::Command;

use dem_core::{npy, Dem};
use dem_nn::reference;
use dem_nn::weights::GeneratorWeights;
use dem_onnx::{export_checked, TOLERANCE};
use dem_testkit::{arg, ok, py, run, run_cmd, stderr, tempdir, testdata};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn td(name: &str) -> String {
    testdata(name).to_string_lossy().into_owned()
}

/// Sim and measured records: full grids, missing cells, attitudes.
fn records(n: usize) -> Vec<Dem> {
    let sim = npy::read_all(&td("sim.npy")).unwrap();
    let real = npy::read_all(&td("real.npy")).unwrap();
    (0..n).map(|i| if i % 2 == 0 { sim[(i * 31) % sim.len()] } else { real[(i * 17) % real.len()] }).collect()
}

/// Export a random generator of `width` to `path`; returns its weights.
fn export(width: usize, path: &str) -> GeneratorWeights {
    let w = GeneratorWeights::init(&mut ChaCha8Rng::seed_from_u64(7), width);
    let check = records(16);
    let want: Vec<Dem> = check.iter().map(|d| reference::generator(&w, d)).collect();
    export_checked(&w, &check, &want, path).unwrap();
    w
}

/// A one-node model made with the python `onnx` package.
fn python_model(dir: &std::path::Path, name: &str, op: &str, in_shape: &str, out_shape: &str) -> String {
    let path = arg(dir, name);
    py(
        dir,
        &format!(
            r#"
import onnx
from onnx import helper, TensorProto as T
x = helper.make_tensor_value_info("x", T.FLOAT, {in_shape})
y = helper.make_tensor_value_info("y", T.FLOAT, {out_shape})
g = helper.make_graph([helper.make_node("{op}", ["x"], ["y"])], "t", [x], [y])
m = helper.make_model(g, opset_imports=[helper.make_opsetid("", 17)])
m.ir_version = 8
onnx.checker.check_model(m)
onnx.save(m, "{path}")
"#
        ),
    );
    path
}

fn max_diff(a: &[Dem], b: &[Dem]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter().flatten().zip(b.iter().flatten()).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max)
}

#[test]
fn the_output_is_the_generator_of_each_record_in_order() {
    let dir = tempdir();
    let model = arg(dir.path(), "g.onnx");
    let w = export(8, &model);
    let input = records(500);
    let inp = arg(dir.path(), "in.npy");
    npy::write_all(&inp, &input).unwrap();
    let want: Vec<Dem> = input.iter().map(|d| reference::generator(&w, d)).collect();
    // A file in, a file out; odd batch, two threads.
    let out = arg(dir.path(), "out.npy");
    let o = run("dem-apply", &["--model", &model, "--batch", "7", "--threads", "2", &inp, "-o", &out], None);
    ok(&o);
    assert!(stderr(&o).contains("500 records in"), "{}", stderr(&o));
    let got = npy::read_all(&out).unwrap();
    let d = max_diff(&got, &want);
    assert!(d <= TOLERANCE, "max |dem-apply - reference| = {d}");
    // A pipe in, a pipe out, one thread, another batch: the same bytes of data.
    let o = run("dem-apply", &["-m", &model, "--threads", "1", "--batch", "100"], Some(std::fs::read(&inp).unwrap()));
    let piped = npy::NpyReader::new(ok(&o), "stdout", None).read_to_end().unwrap();
    assert!(piped == got, "the output depends on threads or batch size");
}

#[test]
fn a_closed_pipe_ends_it_quietly() {
    let dir = tempdir();
    let model = arg(dir.path(), "g.onnx");
    export(4, &model);
    let cmd = format!("{} --model {model} < {} | head -c 100 > /dev/null", dem_testkit::bin("dem-apply").display(), td("sim.npy"));
    let o = run_cmd(Command::new("sh").args(["-c", &cmd]), None);
    ok(&o);
    let err = stderr(&o);
    assert!(!err.contains("error") && !err.contains("panic"), "{err}");
}

#[test]
fn empty_input_gives_empty_output() {
    let dir = tempdir();
    let model = arg(dir.path(), "g.onnx");
    export(4, &model);
    let o = run("dem-apply", &["--model", &model], Some(Vec::new()));
    let out = npy::NpyReader::new(ok(&o), "stdout", None).read_to_end().unwrap();
    assert!(out.is_empty());
    let (empty, out) = (arg(dir.path(), "empty.npy"), arg(dir.path(), "out.npy"));
    npy::write_all(&empty, &[]).unwrap();
    ok(&run("dem-apply", &["--model", &model, &empty, "-o", &out], None));
    assert!(npy::read_all(&out).unwrap().is_empty());
}

fn refused(o: &std::process::Output, name: &str) {
    assert_eq!(o.status.code(), Some(2), "{}", stderr(o));
    let err = stderr(o);
    assert_eq!(err.lines().count(), 1, "one line: {err}");
    assert!(err.starts_with("dem-apply: error: ") && err.contains(name), "{err}");
    assert!(o.stdout.is_empty());
}

#[test]
fn a_model_of_another_shape_is_refused() {
    let dir = tempdir();
    let model = python_model(dir.path(), "rows20.onnx", "Identity", r#"["N", 20, 5, 2]"#, r#"["N", 20, 5, 2]"#);
    let o = run("dem-apply", &["--model", &model, &td("sim.npy")], None);
    refused(&o, "rows20.onnx");
    assert!(stderr(&o).contains("input `x` is float32 (N, 20, 5, 2)"), "{}", stderr(&o));
    // The right shape runs, whatever the names.
    let model = python_model(dir.path(), "id.onnx", "Identity", r#"["N", 21, 5, 2]"#, r#"["N", 21, 5, 2]"#);
    let out = arg(dir.path(), "out.npy");
    ok(&run("dem-apply", &["--model", &model, &td("real.npy"), "-o", &out], None));
    assert!(npy::read_all(&out).unwrap() == npy::read_all(&td("real.npy")).unwrap());
}

#[test]
fn missing_and_invalid_model_files_exit_2_naming_the_file() {
    let dir = tempdir();
    let missing = arg(dir.path(), "nope.onnx");
    refused(&run("dem-apply", &["--model", &missing, &td("sim.npy")], None), "nope.onnx");
    let junk = arg(dir.path(), "junk.onnx");
    std::fs::write(&junk, "not a model\n").unwrap();
    refused(&run("dem-apply", &["--model", &junk, &td("sim.npy")], None), "junk.onnx");
}

#[test]
fn a_nan_output_is_an_error_naming_the_record_and_leaves_no_file() {
    let dir = tempdir();
    // sqrt of a negative height is NaN: real.npy's first record has heights of -0.07.
    let model = python_model(dir.path(), "sqrt.onnx", "Sqrt", r#"["N", 21, 5, 2]"#, r#"["N", 21, 5, 2]"#);
    let input = records(10);
    let first_bad = input.iter().position(|d| d.iter().any(|v| *v < 0.0)).expect("a negative value");
    let inp = arg(dir.path(), "in.npy");
    npy::write_all(&inp, &input).unwrap();
    let out = arg(dir.path(), "out.npy");
    let o = run("dem-apply", &["--model", &model, &inp, "-o", &out], None);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(err.contains(&format!("record {first_bad} of")) && err.contains("NaN"), "{err}");
    assert!(!std::path::Path::new(&out).exists());
}

#[test]
fn bad_arguments_exit_2() {
    let o = run("dem-apply", &["--model", "m.onnx", "--batch", "0"], None);
    assert_eq!(o.status.code(), Some(2));
    let o = run("dem-apply", &[], None);
    assert_eq!(o.status.code(), Some(2));
}

/// A dem-train generator (residual head, width 32) runs on the native path:
/// the same bytes for any --threads and --batch, and onnxruntime's outputs
/// within 1e-4.
#[test]
fn a_generator_runs_natively_the_same_for_any_threads_and_batch() {
    use rand::Rng;
    let dir = tempdir();
    let model = arg(dir.path(), "g.onnx");
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut w = GeneratorWeights::init_arch(&mut rng, 32, dem_nn::weights::Arch::Residual);
    w.fc.weight[..100 * 210].iter_mut().for_each(|v| *v = rng.gen_range(-0.05..0.05));
    let check = records(8);
    let want: Vec<Dem> = check.iter().map(|d| reference::generator(&w, d)).collect();
    export_checked(&w, &check, &want, &model).unwrap();
    let input = records(203);
    let inp = arg(dir.path(), "in.npy");
    npy::write_all(&inp, &input).unwrap();
    let mut first: Option<Vec<u8>> = None;
    for (threads, batch) in [("2", "64"), ("1", "1"), ("2", "5"), ("1", "300"), ("2", "17")] {
        let o = run("dem-apply", &["-m", &model, "--threads", threads, "--batch", batch, &inp], None);
        ok(&o);
        let err = stderr(&o);
        assert!(err.contains("native generator (residual, width 32)") && !err.contains("runs on tract"), "{err}");
        match &first {
            None => first = Some(o.stdout.clone()),
            Some(f) => assert!(*f == o.stdout, "--threads {threads} --batch {batch} changes the output"),
        }
    }
    let got = npy::NpyReader::new(&first.unwrap()[..], "stdout", None).read_to_end().unwrap();
    assert_like_onnxruntime(dir.path(), &model, &inp, &got);
}

/// `got` (dem-apply's output of `model` on `inp`) is onnxruntime's within 1e-4.
fn assert_like_onnxruntime(dir: &std::path::Path, model: &str, inp: &str, got: &[Dem]) {
    let out = dem_testkit::onnxruntime(dir, model, inp, 4096, "ort.npy");
    let d = max_diff(got, &npy::read_all(&out).unwrap());
    assert!(d <= TOLERANCE, "max |dem-apply - onnxruntime| = {d}");
}

/// A generator built and exported by PyTorch (testdata/torch_gen_w4.onnx,
/// `scripts/peers/torch_export.py --width 4 --seed 7 --arch residual`: PyTorch's
/// own nodes, not dem-onnx's) is recognised and runs on the native path,
/// with onnxruntime's outputs within 1e-4.
#[test]
fn a_pytorch_export_runs_natively_like_onnxruntime() {
    let dir = tempdir();
    let model = td("torch_gen_w4.onnx");
    let inp = td("sim.npy");
    let o = run("dem-apply", &["--model", &model, &inp], None);
    let err = stderr(&o);
    assert!(err.contains("native generator (residual, width 4)") && !err.contains("runs on tract"), "{err}");
    let got = npy::NpyReader::new(ok(&o), "stdout", None).read_to_end().unwrap();
    assert_like_onnxruntime(dir.path(), &model, &inp, &got);
}

/// Any other conforming model runs on tract, with a note on stderr.
#[test]
fn another_model_runs_on_tract_with_a_note() {
    let dir = tempdir();
    let model = python_model(dir.path(), "neg.onnx", "Neg", "[None, 21, 5, 2]", "[None, 21, 5, 2]");
    let input = records(30);
    let inp = arg(dir.path(), "in.npy");
    npy::write_all(&inp, &input).unwrap();
    let o = run("dem-apply", &["-m", &model, "--batch", "4", &inp], None);
    let err = stderr(&o);
    assert!(err.contains("runs on tract: not recognised as a dem-train generator") && err.contains(", tract"), "{err}");
    let got = npy::NpyReader::new(ok(&o), "stdout", None).read_to_end().unwrap();
    assert!(got.iter().flatten().zip(input.iter().flatten()).all(|(y, x)| *y == -x));
}
