//! Helpers for the tests of the dem-* tools: run the real binaries the way a
//! user does (arguments, stdin, files), find the bundled test data, and run
//! the numpy peer from the venv the Makefile makes.
#![deny(missing_docs)]

pub mod imports;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

/// Every tool of the workspace, as `make install` installs them; the
/// install test checks the list against the crates with a `main.rs` and the
/// Makefile's `TOOLS`.
pub const TOOLS: [&str; 14] = [
    "dem-apply",
    "dem-cat",
    "dem-clean-pallet",
    "dem-eval",
    "dem-fill-nans",
    "dem-filter",
    "dem-gap",
    "dem-import",
    "dem-pair",
    "dem-render",
    "dem-sensor",
    "dem-split",
    "dem-synth",
    "dem-train",
];

/// Root of the workspace.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").canonicalize().expect("workspace root")
}

/// A file under `testdata/`.
pub fn testdata(name: &str) -> PathBuf {
    workspace_root().join("testdata").join(name)
}

/// Path of a built binary of the workspace (same profile as the test).
pub fn bin(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("test exe");
    // target/<profile>/deps/test-xxxx -> target/<profile>/<name>
    let dir = exe.parent().and_then(Path::parent).expect("target dir");
    let path = dir.join(name);
    assert!(path.exists(), "{} is not built; run `cargo test --workspace` (or `make test`)", path.display());
    path
}

/// The long help of `tool` (`["dem-eval", "merge"]` for a subcommand),
/// unwrapped (`COLUMNS=1000`, as clap reads it), so each example and each
/// option stays on its line; asserts that `--help` succeeds.
pub fn help(tool: &[&str]) -> String {
    let o = Command::new(bin(tool[0])).args(&tool[1..]).arg("--help").env("COLUMNS", "1000").env("LINES", "50").output().expect("spawn");
    assert!(o.status.success(), "{tool:?} --help failed");
    String::from_utf8(o.stdout).expect("help is UTF-8")
}

/// Run binary `name` with `args`, feeding `stdin` from a thread (so large
/// inputs cannot deadlock against a full stdout pipe).
pub fn run(name: &str, args: &[&str], stdin: Option<Vec<u8>>) -> Output {
    run_cmd(Command::new(bin(name)).args(args), stdin)
}

/// Run a prepared command with optional stdin bytes.
pub fn run_cmd(cmd: &mut Command, stdin: Option<Vec<u8>>) -> Output {
    cmd.stdin(if stdin.is_some() { Stdio::piped() } else { Stdio::null() }).stdout(Stdio::piped()).stderr(Stdio::piped());
    let mut child = cmd.spawn().expect("spawn");
    let feeder = stdin.map(|bytes| {
        let mut pipe = child.stdin.take().expect("stdin");
        std::thread::spawn(move || {
            // The child may stop reading early (that is what some tests check).
            let _ = pipe.write_all(&bytes);
        })
    });
    let out = child.wait_with_output().expect("wait");
    if let Some(f) = feeder {
        f.join().expect("stdin feeder");
    }
    out
}

/// Assert success and return stdout.
pub fn ok(out: &Output) -> &[u8] {
    assert!(out.status.success(), "exit {:?}\nstderr:\n{}", out.status.code(), String::from_utf8_lossy(&out.stderr));
    &out.stdout
}

/// Stderr as text.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The Python with numpy (and later onnxruntime) that the Makefile installs
/// into `.venv`; `DEM_PYTHON` overrides. Panics with the fix when missing:
/// peer checks are part of the suite, not optional.
pub fn python() -> PathBuf {
    if let Some(p) = std::env::var_os("DEM_PYTHON") {
        return PathBuf::from(p);
    }
    let p = workspace_root().join(".venv/bin/python");
    assert!(p.exists(), "no {}: run `make venv` (make test does it) for the numpy peer", p.display());
    p
}

/// Run a Python snippet with the venv's Python in `dir`; returns stdout.
pub fn py(dir: &Path, code: &str) -> String {
    let out = Command::new(python()).arg("-c").arg(code).current_dir(dir).output().expect("python");
    assert!(out.status.success(), "python failed:\n{code}\n{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// A fresh temp dir for one test.
pub fn tempdir() -> tempfile::TempDir {
    tempfile::tempdir().expect("tempdir")
}

/// Path inside `dir` as a `String` argument.
pub fn arg(dir: &Path, name: &str) -> String {
    dir.join(name).to_string_lossy().into_owned()
}

/// A one-node ONNX model `y = OP(x)` on float32 `(N, 21, 5, 2)`, written to
/// `dir/name` with the python `onnx` package (e.g. `Identity`, `Tanh`, `Neg`,
/// `Log`): models whose every output is known. Returns its path.
pub fn onnx_one_node(dir: &Path, name: &str, op: &str) -> String {
    let path = arg(dir, name);
    py(
        dir,
        &format!(
            r#"
import onnx
from onnx import helper, TensorProto as T
x = helper.make_tensor_value_info("x", T.FLOAT, ["N", 21, 5, 2])
y = helper.make_tensor_value_info("y", T.FLOAT, ["N", 21, 5, 2])
g = helper.make_graph([helper.make_node("{op}", ["x"], ["y"])], "t", [x], [y])
m = helper.make_model(g, opset_imports=[helper.make_opsetid("", 17)])
m.ir_version = 8
onnx.save(m, "{path}")
"#
        ),
    );
    path
}

/// The onnxruntime peer: run `model` (input `dem`, output `dem_out`) with the
/// venv's onnxruntime on the records of the NPY file `input`, in batches of
/// `batch` records, and write its outputs to `dir/name`. Returns that path.
pub fn onnxruntime(dir: &Path, model: &str, input: &str, batch: usize, name: &str) -> String {
    let out = arg(dir, name);
    let said = py(
        dir,
        &format!(
            r#"
import numpy as np, onnxruntime as ort
s = ort.InferenceSession("{model}", providers=["CPUExecutionProvider"])
x = np.load("{input}")
y = np.concatenate([s.run(["dem_out"], {{"dem": x[i:i + {batch}]}})[0] for i in range(0, len(x), {batch})])
assert y.dtype == np.float32 and y.shape == x.shape, (y.dtype, y.shape)
np.save("{out}", y)
print("ok")
"#
        ),
    );
    assert_eq!(said.trim(), "ok");
    out
}
