//! python/demstream reads what every NPY-writing tool writes, to a file and
//! to a pipe (where numpy.load sees only the first 4,096 records), and what
//! it writes every tool reads. Run with the venv's Python (`make venv`
//! installs the module with `pip install ./python`).

use std::fs;

use dem_testkit::{arg, ok, py, run, tempdir, testdata};

fn td(name: &str) -> String {
    testdata(name).to_string_lossy().into_owned()
}

#[test]
fn demstream_reads_every_tool_output_file_and_pipe() {
    let dir = tempdir();
    let d = |n: &str| arg(dir.path(), n);
    let (sim, real) = (td("sim.npy"), td("real.npy"));
    // A stream longer than one pipe chunk: 2 x 3,025 records.
    let m = d("m.json");
    fs::write(&m, r#"{"effects":[{"effect":"dropout","params":{"p":0.1}}]}"#).unwrap();
    let onnx = dem_testkit::onnx_one_node(dir.path(), "id.onnx", "Identity");
    let cases: Vec<(&str, Vec<String>)> = vec![
        ("dem-cat", vec![sim.clone(), sim.clone()]),
        ("dem-filter", vec![sim.clone(), sim.clone()].into_iter().take(1).collect()),
        ("dem-sensor", vec!["apply".into(), "--sensor".into(), m.clone(), sim.clone()]),
        ("dem-fill-nans", vec![real.clone()]),
        ("dem-clean-pallet", vec![sim.clone()]),
        ("dem-apply", vec!["--model".into(), onnx.clone(), sim.clone()]),
    ];
    for (k, (tool, args)) in cases.iter().enumerate() {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        // To a pipe: the captured bytes hold one array per 4,096 records.
        let piped = d(&format!("pipe{k}.npy"));
        fs::write(&piped, ok(&run(tool, &a, None))).unwrap();
        // To a file: one array.
        let file = d(&format!("file{k}.npy"));
        let mut fa = a.clone();
        fa.extend(["-o", &file]);
        ok(&run(tool, &fa, None));
        let out = py(
            dir.path(),
            &format!(
                r#"
import numpy as np, demstream, subprocess, sys
a, b = demstream.read("pipe{k}.npy"), demstream.read("file{k}.npy")
assert a.dtype == np.float32 and a.shape[1:] == (21, 5, 2), a.shape
assert np.array_equal(a, b), "{tool}: pipe and file differ"
assert np.array_equal(b, np.load("file{k}.npy")), "{tool}: not numpy's array"
chunks = [len(c) for c in demstream.iter_chunks(open("pipe{k}.npy", "rb"))]
assert sum(chunks) == len(a)
print(len(a), len(np.load("pipe{k}.npy")), len(chunks))
"#
            ),
        );
        let v: Vec<usize> = out.split_whitespace().map(|x| x.parse().unwrap()).collect();
        if v[0] > 4096 {
            assert_eq!(v[1], 4096, "{tool}: numpy.load reads only the first array of a pipe's bytes");
            assert!(v[2] > 1);
        }
    }
    // From stdin (a pipe), and what demstream writes every tool reads.
    let out = py(
        dir.path(),
        r#"
import subprocess, sys, numpy as np, demstream
p = subprocess.run([sys.executable, "-c", "import sys, demstream; print(len(demstream.read(sys.stdin.buffer)))"],
                   input=open("pipe0.npy", "rb").read(), capture_output=True, check=True)
print(p.stdout.decode().strip())
demstream.write("w.npy", demstream.read("pipe0.npy"))
"#,
    );
    assert_eq!(out.trim(), "6050");
    ok(&run("dem-cat", &[&d("w.npy"), "-o", &d("w2.npy")], None));
    assert_eq!(fs::read(d("w.npy")).unwrap(), fs::read(d("w2.npy")).unwrap(), "numpy.save's bytes, as our writer's");
    // The contract's refusals, naming the record.
    let out = py(
        dir.path(),
        r#"
import numpy as np, demstream
a = demstream.read("file0.npy")[:10].copy()
a[7, 3, 2, 0] = np.inf
np.save("inf.npy", a)
try:
    demstream.read("inf.npy"); print("accepted")
except ValueError as e:
    print(e)
b = demstream.read("file0.npy")[:3].copy(); b[1, 2, 2, 0] = np.nan
np.save("nan.npy", b)
c = demstream.read("nan.npy")
print(c[1, 2, 2].tolist())
try:
    demstream.write("x.npy", b); print("wrote")
except ValueError as e:
    print(e)
"#,
    );
    let lines: Vec<&str> = out.lines().collect();
    assert!(lines[0].contains("record 7") && lines[0].contains("inf"), "{out}");
    assert_eq!(lines[1], "[0.0, -1.0]");
    assert!(lines[2].contains("record 1"), "{out}");
}
