//! The virtual sensor as one ONNX file behaves the same in every runtime:
//! dem-apply (native network, native tail) and onnxruntime (the whole graph,
//! through `demstream.sensor.VirtualSensor`) fed the uniforms dem-apply drew
//! (`--emit-uniform`) and the labels' times give the same DEMs.

use dem_core::{npy, Dem};
use dem_nn::reference;
use dem_nn::weights::GeneratorWeights;
use dem_onnx::export::export_sensor_checked;
use dem_onnx::sensor::Stored;
use dem_onnx::Heights;
use dem_sensor::SensorModel;
use dem_testkit::{arg, ok, py, run, stderr, tempdir, testdata};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn td(name: &str) -> String {
    testdata(name).to_string_lossy().into_owned()
}

/// A residual of several effects, startup by time among them.
const RESIDUAL: &str = r#"{"effects": [
    {"effect": "startup", "params": {"x0": 0.35, "v": 0.3, "p": 0.2}},
    {"effect": "occlusion", "params": {"h": 0.45, "x0": 0.15}},
    {"effect": "drop-blend", "params": {"p": 0.5, "a": 0.6}},
    {"effect": "floor-lift", "params": {"x": 1.45, "p": 0.4, "a": 1.3}},
    {"effect": "noise", "params": {"sigma0": 0.003, "k": 0.01}},
    {"effect": "patch-dropout", "params": {"n": 1.5, "r": 0.09, "a": 0.5}},
    {"effect": "hole-growth", "params": {"p": 0.15}}
]}"#;

/// Export a random width-4 generator with `stored`'s tail to `path`.
fn export(path: &str, stored: &Stored) {
    let w = GeneratorWeights::init(&mut ChaCha8Rng::seed_from_u64(7), 4);
    let sim = npy::read_all(&td("sim.npy")).unwrap();
    let check: Vec<Dem> = sim.iter().step_by(97).copied().collect();
    let want: Vec<Dem> = check.iter().map(|d| reference::generator(&w, d)).collect();
    let report = export_sensor_checked(&w, stored, &check, &want, path, &[]).unwrap();
    assert!(report.tail.is_some() == stored.has_tail());
}

/// dem-apply's output and onnxruntime's on the same uniforms: (share of
/// cells whose validity differs, largest height difference where both are
/// valid, row 20 equal).
fn compare_with_onnxruntime(dir: &std::path::Path, model: &str, out: &str, uniform: Option<&str>) -> (f64, f64, bool) {
    let uniform = uniform.map_or("None".to_string(), |u| format!("np.load('{u}')"));
    let said = py(
        dir,
        &format!(
            r#"
import csv, numpy as np
from demstream.sensor import VirtualSensor
s = VirtualSensor("{model}")
dem = np.load("{sim}")
t = np.array([float(r["time"]) for r in csv.DictReader(open("{labels}"))], dtype=np.float32)
got = np.concatenate([s(dem[i:i + 1000], time=t[i:i + 1000], uniform=None if {uniform} is None else {uniform}[i:i + 1000]) for i in range(0, len(dem), 1000)])
want = np.load("{out}")
va, vb = want[:, :20, :, 1] > 0, got[:, :20, :, 1] > 0
both = va & vb
print((va != vb).mean(), np.abs(np.where(both, want[:, :20, :, 0] - got[:, :20, :, 0], 0)).max(), np.array_equal(want[:, 20], got[:, 20]))
"#,
            sim = td("sim.npy"),
            labels = td("sim_labels.csv"),
        ),
    );
    let v: Vec<&str> = said.split_whitespace().collect();
    (v[0].parse().unwrap(), v[1].parse().unwrap(), v[2] == "True")
}

#[test]
fn the_whole_graph_in_onnxruntime_gives_dem_apply_s_output() {
    let dir = tempdir();
    let residual = SensorModel::from_json(RESIDUAL).unwrap();
    for heights in [Heights::Input, Heights::Network] {
        let model = arg(dir.path(), &format!("gy-{heights}.onnx"));
        export(&model, &Stored { residual: Some(residual.clone()), heights });
        let (out, u) = (arg(dir.path(), "out.npy"), arg(dir.path(), "u.npy"));
        let o = run(
            "dem-apply",
            &["--model", &model, "--labels", &td("sim_labels.csv"), "--seed", "5", "--emit-uniform", &u, &td("sim.npy"), "-o", &out],
            None,
        );
        ok(&o);
        let k: usize = residual.draws();
        assert_eq!(npy_shape(dir.path(), &u), format!("(3025, {k})"));
        let (differ, worst, row20) = compare_with_onnxruntime(dir.path(), &model, &out, Some(&u));
        assert!(differ <= 1e-4, "{heights}: {:.4} % of cells differ in validity", 100.0 * differ);
        assert!(worst <= 1e-5, "{heights}: heights differ by {worst:e} m");
        assert!(row20, "{heights}: row 20 untouched");
        // What the file says about itself.
        let info = String::from_utf8(ok(&run("dem-apply", &["--model", &model, "--info"], None)).to_vec()).unwrap();
        assert!(info.contains(&format!("in another runtime: the whole virtual sensor, as dem-apply runs it; inputs: dem float32 (N,21,5,2); uniform float32 (N,{k})")), "{info}");
        assert!(info.contains("dem.graph: network+sensor") && info.contains(&format!("dem.uniform_count: {k}")), "{info}");
        assert!(info.contains("description: dem-tools virtual sensor, one graph: G_Y"), "{info}");
    }
}

fn npy_shape(dir: &std::path::Path, path: &str) -> String {
    py(dir, &format!("import numpy as np; print(np.load('{path}').shape)")).trim().replace(' ', "").replace(",", ", ")
}

/// `model` written to `out` with `from` replaced by `to` in its
/// `dem.residual` metadata (the graph left as it is).
fn residual_replaced(dir: &std::path::Path, model: &str, out: &str, from: &str, to: &str) {
    py(
        dir,
        &format!(
            r#"
import onnx
m = onnx.load("{model}")
for p in m.metadata_props:
    if p.key == "dem.residual":
        p.value = p.value.replace('{from}', '{to}')
onnx.save(m, "{out}")
"#
        ),
    );
}

#[test]
fn a_changed_tail_is_refused_and_a_network_alone_says_so() {
    let dir = tempdir();
    let model = arg(dir.path(), "gy.onnx");
    let residual = SensorModel::from_json(RESIDUAL).unwrap();
    export(&model, &Stored { residual: Some(residual), heights: Heights::Input });
    // The metadata says one model, the graph holds another.
    let tampered = arg(dir.path(), "tampered.onnx");
    residual_replaced(dir.path(), &model, &tampered, r#""p":0.15"#, r#""p":0.5"#);
    let o = run("dem-apply", &["--model", &tampered, &td("sim.npy")], None);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(err.contains("not what its metadata") && err.contains("tampered.onnx"), "{err}");
    // A key twice: which residual runs would be a guess.
    let twice = arg(dir.path(), "twice.onnx");
    py(
        dir.path(),
        &format!(
            r#"
import onnx
m = onnx.load("{model}")
r = [p for p in m.metadata_props if p.key == "dem.residual"][0]
e = m.metadata_props.add(); e.key = r.key; e.value = r.value
onnx.save(m, "{twice}")
"#
        ),
    );
    let o = run("dem-apply", &["--model", &twice, &td("sim.npy")], None);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("dem.residual twice"), "{}", stderr(&o));
    // A residual outside its effects' physical boxes, as dem-sensor and
    // dem-train export refuse it: the limit is in the message, nothing written.
    let outside = arg(dir.path(), "outside.onnx");
    residual_replaced(dir.path(), &model, &outside, r#""x":1.45"#, r#""x":2.0"#);
    let written = arg(dir.path(), "outside.npy");
    let o = run("dem-apply", &["--model", &outside, &td("sim.npy"), "-o", &written], None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("x = 2 is outside its physical box -0.6..=1.45"), "{}", stderr(&o));
    assert!(!std::path::Path::new(&written).exists(), "nothing written");
    // --info never appends to the model (`>> model`).
    let o = dem_testkit::run_cmd(
        std::process::Command::new("bash")
            .args(["-c", &format!("{} --model {model} --info >> {model}", dem_testkit::bin("dem-apply").display())]),
        None,
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    // A network alone says what another runtime gets.
    let plain = arg(dir.path(), "g.onnx");
    export(&plain, &Stored::default());
    let info = String::from_utf8(ok(&run("dem-apply", &["--model", &plain, "--info"], None)).to_vec()).unwrap();
    assert!(info.contains("in another runtime: the network alone, as dem-apply runs it"), "{info}");
    // --emit-uniform with a tail other than the file's is refused.
    let o = run("dem-apply", &["--model", &model, "--network-only", "--emit-uniform", &arg(dir.path(), "u.npy"), &td("sim.npy")], None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    // Labels one row longer than the stream: refused, no output.
    let labels = arg(dir.path(), "labels.csv");
    let mut text = std::fs::read_to_string(td("sim_labels.csv")).unwrap();
    text.push_str("3025,flat,0,0,0,999,1.0\n");
    std::fs::write(&labels, text).unwrap();
    let out = arg(dir.path(), "o.npy");
    let o = run("dem-apply", &["--model", &model, "--labels", &labels, &td("sim.npy"), "-o", &out], None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("3026 labels for a stream of 3025 records"), "{}", stderr(&o));
    assert!(!std::path::Path::new(&out).exists());
}

/// With its own draws (numpy's), onnxruntime's output is dem-apply's in
/// distribution: their gap is below the sampling floor dem-gap reports for
/// that many records (two halves of dem-apply's output, scaled to the
/// sizes compared), paired against the same sim records and unpaired.
#[test]
fn with_other_draws_onnxruntime_and_dem_apply_differ_less_than_sampling_does() {
    use dem_core::distribution::{gap, stats};
    let dir = tempdir();
    let model = arg(dir.path(), "gy.onnx");
    let residual = SensorModel::from_json(RESIDUAL).unwrap();
    export(&model, &Stored { residual: Some(residual), heights: Heights::Input });
    let (apply_out, ort_out) = (arg(dir.path(), "apply.npy"), arg(dir.path(), "ort.npy"));
    ok(&run("dem-apply", &["--model", &model, "--labels", &td("sim_labels.csv"), "--seed", "5", &td("sim.npy"), "-o", &apply_out], None));
    py(
        dir.path(),
        &format!(
            r#"
import csv, numpy as np
from demstream.sensor import VirtualSensor
s = VirtualSensor("{model}")
dem = np.load("{sim}")
t = np.array([float(r["time"]) for r in csv.DictReader(open("{labels}"))], dtype=np.float32)
np.save("{ort_out}", s(dem, time=t, rng=np.random.default_rng(11)))
"#,
            sim = td("sim.npy"),
            labels = td("sim_labels.csv"),
        ),
    );
    let sim = npy::read_all(&td("sim.npy")).unwrap();
    let a = npy::read_all(&apply_out).unwrap();
    let b = npy::read_all(&ort_out).unwrap();
    assert!(a != b, "other draws, other DEMs");
    let n = a.len() as f64;
    let [h0, h1] = dem_gap::halves(a.len(), None, None);
    let pick = |v: &[Dem], idx: &[usize]| idx.iter().map(|&i| v[i]).collect::<Vec<_>>();
    for paired in [true, false] {
        let side = |out: &[Dem], idx: Option<&[usize]>| {
            let (o, s) = match idx {
                Some(i) => (pick(out, i), pick(&sim, i)),
                None => (out.to_vec(), sim.clone()),
            };
            stats(&o, paired.then_some(&s[..]))
        };
        let draws = gap(&side(&b, None), &side(&a, None));
        let split = gap(&side(&a, Some(&h0)), &side(&a, Some(&h1)));
        let floor = split * (1.0 / n + 1.0 / n) / (4.0 / n);
        eprintln!("paired {paired}: onnxruntime against dem-apply {draws:.4}, sampling floor {floor:.4}");
        assert!(draws < floor, "paired {paired}: onnxruntime against dem-apply {draws:.4}, sampling floor {floor:.4}");
    }
}

/// The example training loop runs the exported file on a batch every step.
#[test]
fn the_example_training_loop_applies_the_sensor_every_step() {
    let dir = tempdir();
    let model = arg(dir.path(), "gy.onnx");
    let residual = SensorModel::from_json(RESIDUAL).unwrap();
    export(&model, &Stored { residual: Some(residual), heights: Heights::Input });
    let script = dem_testkit::workspace_root().join("python/examples/policy_loop.py");
    let out = std::process::Command::new(dem_testkit::python())
        .args([script.to_str().unwrap(), &model, &td("sim.npy"), &td("sim_labels.csv"), "--envs", "32", "--steps", "30", "--seed", "2"])
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{said}\n{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(said.lines().count(), 3, "{said}");
    for line in said.lines() {
        // Valid cells per DEM, and the rows behind missing in the first second
        // (the residual's startup: x0 = 0.35 m receding at 0.3 m/s).
        let v: Vec<f64> = line.split_whitespace().filter_map(|w| w.trim_end_matches(',').parse().ok()).collect();
        assert!(v[0] > 10.0 && v[0] < 100.0, "{line}");
        assert!(v[1] > 0.9, "{line}");
    }
}

/// A sensor model alone (`dem-sensor export`) runs in dem-apply as it does
/// in dem-sensor: the same bytes and the same uniforms.
#[test]
fn a_sensor_model_alone_runs_in_dem_apply_as_in_dem_sensor() {
    let dir = tempdir();
    let json = arg(dir.path(), "s.json");
    std::fs::write(&json, RESIDUAL).unwrap();
    let onnx = arg(dir.path(), "s.onnx");
    ok(&run("dem-sensor", &["export", "--sensor", &json, "-o", &onnx], None));
    let files: Vec<String> = ["a.npy", "ua.npy", "b.npy", "ub.npy"].iter().map(|f| arg(dir.path(), f)).collect();
    let labels = td("sim_labels.csv");
    let o = run(
        "dem-apply",
        &["--model", &onnx, "--labels", &labels, "--seed", "4", "--emit-uniform", &files[1], &td("sim.npy"), "-o", &files[0]],
        None,
    );
    ok(&o);
    assert!(!stderr(&o).contains("runs on tract"), "{}", stderr(&o));
    let args =
        ["apply", "--sensor", &json, "--labels", &labels, "--seed", "4", "--emit-uniform", &files[3], &td("sim.npy"), "-o", &files[2]];
    ok(&run("dem-sensor", &args, None));
    for (a, b) in [(0, 2), (1, 3)] {
        assert!(std::fs::read(&files[a]).unwrap() == std::fs::read(&files[b]).unwrap(), "{} and {} differ", files[a], files[b]);
    }
}

/// In the loop the contract holds as in the tools: an infinite height (or
/// time) is refused naming the environment and the cell, where it would
/// reach the policy as an infinite output; a NaN height is a missing cell.
#[test]
fn the_virtual_sensor_refuses_an_infinite_height_naming_the_environment() {
    let dir = tempdir();
    let model = arg(dir.path(), "gy.onnx");
    export(&model, &Stored { residual: Some(SensorModel::from_json(RESIDUAL).unwrap()), heights: Heights::Input });
    let said = py(
        dir.path(),
        &format!(
            r#"
import numpy as np
from demstream.sensor import VirtualSensor
s = VirtualSensor("{model}")
dem = np.load("{sim}")[:8].copy()
for where, value, time in [((5, 3, 2, 0), np.inf, None), ((2, 7, 0, 1), np.nan, None), ((0, 0, 0, 0), 0.0, np.array([0, 0, np.inf, 0, 0, 0, 0, 0]))]:
    d = dem.copy(); d[where] = value
    try:
        s(d, time=time, rng=np.random.default_rng(0)); print("passed")
    except ValueError as e:
        print(e)
d = dem.copy(); d[4, 6, 1, 0] = np.nan
out = s(d, rng=np.random.default_rng(0))
print(bool(np.isfinite(out).all()))
"#,
            sim = td("sim.npy"),
        ),
    );
    let lines: Vec<&str> = said.lines().collect();
    assert_eq!(
        lines[0],
        "environment 5: inf in the height at row 3, column 2, channel 0 (the contract allows no infinite value, and NaN only as a height)"
    );
    assert!(lines[1].starts_with("environment 2: nan in the mask at row 7, column 0"), "{said}");
    assert!(lines[2].starts_with("environment 2: time inf"), "{said}");
    assert_eq!(lines[3], "True", "a NaN height is a missing cell, not a NaN output: {said}");
}

/// A residual with a map's memory: dem-apply steps each run of the labels in
/// stream order, and onnxruntime stepping the whole graph through the same
/// runs (`VirtualSensor.over_runs`, fed dem-apply's uniforms) gives its
/// output; `VirtualSensor` keeps each environment's map, `reset(ids)`
/// starts those runs again while the others keep theirs, and it refuses a
/// motion or height that is not finite, naming the environment. A run out
/// of time order is refused naming the record, and nothing is written.
#[test]
fn a_map_s_memory_steps_each_run_alike_in_dem_apply_and_onnxruntime() {
    let dir = tempdir();
    let json = RESIDUAL.replace(
        r#"{"effect": "hole-growth", "params": {"p": 0.15}}"#,
        r#"{"effect": "hole-growth", "params": {"p": 0.15}}, {"effect": "map-memory", "params": {"tau": 0.6, "keep": 3.0}}"#,
    );
    let residual = SensorModel::from_json(&json).unwrap();
    assert!(residual.map_memory().is_some());
    let model = arg(dir.path(), "gy-memory.onnx");
    export(&model, &Stored { residual: Some(residual.clone()), heights: Heights::Input });
    let (out, u) = (arg(dir.path(), "out.npy"), arg(dir.path(), "u.npy"));
    let args = ["--model", &model, "--labels", &td("sim_labels.csv"), "--seed", "5", "--emit-uniform", &u, &td("sim.npy"), "-o", &out];
    ok(&run("dem-apply", &args, None));
    let said = py(
        dir.path(),
        &format!(
            r#"
import csv, numpy as np
from demstream.sensor import VirtualSensor, motion_between
s = VirtualSensor("{model}")
assert s.stateful and s.inputs == ["dem", "uniform", "time", "state", "motion", "reset"], s.inputs
dem, u, want = np.load("{sim}"), np.load("{u}"), np.load("{out}")
rows = list(csv.DictReader(open("{labels}")))
t = np.array([float(r["time"]) for r in rows], dtype=np.float32)
run = np.array([int(r["sequence"]) for r in rows])
pose = np.array([[float(r[k]) for k in ("x", "y", "yaw")] for r in rows])
got = s.over_runs(dem, run, pose, time=t, uniform=u)
va, vb = want[:, :20, :, 1] > 0, got[:, :20, :, 1] > 0
worst = np.abs(np.where(va & vb, want[:, :20, :, 0] - got[:, :20, :, 0], 0)).max()
print("alike", (va != vb).mean(), worst, np.array_equal(want[:, 20], got[:, 20]))
# Three environments, each on its own run; environment 1 starts again at the fourth step.
runs = [np.flatnonzero(run == r)[:4] for r in np.unique(run)[:3]]
steps = [np.array([r[k] for r in runs]) for k in range(4)]
s, outs = VirtualSensor("{model}"), []
for k, idx in enumerate(steps):
    if k == 3:
        s.reset([1])
    motion = None if k == 0 else motion_between(pose[steps[k - 1]], pose[idx], t[idx] - t[steps[k - 1]])
    outs.append(s(dem[idx], time=t[idx], uniform=u[idx], motion=motion))
idx = steps[3]
first = VirtualSensor("{model}")(dem[idx[1:2]], time=t[idx[1:2]], uniform=u[idx[1:2]])
kept = VirtualSensor("{model}").over_runs(dem[runs[0]], run=[0] * 4, pose=pose[runs[0]], time=t[runs[0]], uniform=u[runs[0]])
frame = VirtualSensor("{model}")(dem[idx[:1]], time=t[idx[:1]], uniform=u[idx[:1]])
print("reset", np.array_equal(outs[3][1], first[0]), np.abs(outs[3][0] - kept[3]).max() < 1e-6, not np.array_equal(outs[3][0], frame[0]))
for bad, what in [("motion", "environment 2: motion"), ("dem", "environment 0: inf in the height")]:
    m = np.zeros((3, 4), np.float32)
    m[:, 3] = 0.4
    d = dem[idx].copy()
    if bad == "motion":
        m[2, 0] = np.nan
    else:
        d[0, 4, 2, 0] = np.inf
    try:
        s(d, time=t[idx], motion=m)
        print("accepted", bad)
    except ValueError as e:
        print("refused", what in str(e), e)
"#,
            sim = td("sim.npy"),
            labels = td("sim_labels.csv"),
        ),
    );
    let alike: Vec<&str> = said.lines().find(|l| l.starts_with("alike")).unwrap().split_whitespace().collect();
    let (differ, worst): (f64, f64) = (alike[1].parse().unwrap(), alike[2].parse().unwrap());
    assert!(differ <= 1e-4 && worst <= 1e-5 && alike[3] == "True", "{said}");
    assert!(said.contains("reset True True True"), "the reset environment starts again, the others keep their maps: {said}");
    assert_eq!(said.matches("refused True").count(), 2, "{said}");
    // A run out of time order: record 2 of run 0 before record 1.
    let text = std::fs::read_to_string(td("sim_labels.csv")).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let mut row: Vec<String> = lines[2].split(',').map(String::from).collect();
    *row.last_mut().unwrap() = "9.5".into();
    lines[2] = row.join(",");
    let labels = arg(dir.path(), "late.csv");
    std::fs::write(&labels, lines.join("\n") + "\n").unwrap();
    let late = arg(dir.path(), "late.npy");
    let o = run("dem-apply", &["--model", &model, "--labels", &labels, &td("sim.npy"), "-o", &late], None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("late.csv") && stderr(&o).contains("record 2 (run 0) is at 0.8 s"), "{}", stderr(&o));
    assert!(!std::path::Path::new(&late).exists(), "nothing written");
}
