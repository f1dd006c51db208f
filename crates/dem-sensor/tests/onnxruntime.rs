//! `dem-sensor export` and `dem-sensor apply --emit-uniform`, run as users
//! run them: onnxruntime, fed the uniforms dem-sensor drew and the labels'
//! times, gives dem-sensor's output for every effect of the vocabulary
//! alone and for a model of several.

use dem_testkit::{arg, ok, py, run, stderr, tempdir, testdata};

fn td(name: &str) -> String {
    testdata(name).to_string_lossy().into_owned()
}

/// One model per effect (at parameters where it acts on the bundled
/// data), and one of several.
const MODELS: &[&str] = &[
    r#"{"effect": "noise", "params": {"sigma0": 0.01, "k": 0.02}}"#,
    r#"{"effect": "dropout", "params": {"p": 0.3}}"#,
    r#"{"effect": "row-dropout", "params": {"p": 0.2}}"#,
    r#"{"effect": "occlusion", "params": {"h": 0.45, "x0": 0.15}}"#,
    r#"{"effect": "fov", "params": {"x_min": -0.33, "x_max": 0.97}}"#,
    r#"{"effect": "view-top", "params": {"h": 0.3, "t": 0.3}}"#,
    r#"{"effect": "smoothing", "params": {"w": 0.4}}"#,
    r#"{"effect": "bias", "params": {"b": 0.02, "t": -0.03}}"#,
    r#"{"effect": "quantization", "params": {"q": 0.02}}"#,
    r#"{"effect": "startup", "params": {"x0": 0.4, "v": 0.3, "p": 0.4}}"#,
    r#"{"effect": "patch-dropout", "params": {"n": 3.0, "r": 0.12, "a": 0.5}}"#,
    r#"{"effect": "edge-holes", "params": {"g": 0.05, "p": 0.6}}"#,
    r#"{"effect": "rim-holes", "params": {"g": 0.05, "p": 0.6}}"#,
    r#"{"effect": "drop-holes", "params": {"p": 0.7}}"#,
    r#"{"effect": "hole-growth", "params": {"p": 0.3}}"#,
    r#"{"effect": "pit-fill", "params": {"g": 0.02, "p": 0.8}}"#,
    r#"{"effect": "drop-blend", "params": {"p": 0.6, "a": 0.8}}"#,
    r#"{"effect": "floor-lift", "params": {"x": 0.6, "p": 0.7, "a": 1.5}}"#,
    r#"{"effect": "riser-blend", "params": {"foot": 0.4, "top": -0.3}}"#,
    r#"{"effect": "mixed-cells", "params": {"up": 0.04, "down": 0.06}}"#,
    r#"{"effect": "fov", "params": {"x_min": -0.45, "x_max": 1.2}},
       {"effect": "startup", "params": {"x0": 0.3, "v": 0.25, "p": 0.3}},
       {"effect": "occlusion", "params": {"h": 0.42, "x0": 0.12}},
       {"effect": "drop-holes", "params": {"p": 0.3}},
       {"effect": "pit-fill", "params": {"g": 0.03, "p": 0.5}},
       {"effect": "mixed-cells", "params": {"up": 0.03, "down": 0.05}},
       {"effect": "riser-blend", "params": {"foot": 0.2, "top": 0.1}},
       {"effect": "smoothing", "params": {"w": 0.7}},
       {"effect": "bias", "params": {"b": 0.01, "t": 0.01}},
       {"effect": "noise", "params": {"sigma0": 0.004, "k": 0.01}},
       {"effect": "quantization", "params": {"q": 0.005}},
       {"effect": "dropout", "params": {"p": 0.05}},
       {"effect": "patch-dropout", "params": {"n": 1.0, "r": 0.08, "a": 0.3}},
       {"effect": "hole-growth", "params": {"p": 0.2}},
       {"effect": "row-dropout", "params": {"p": 0.02}}"#,
];

#[test]
fn onnxruntime_fed_dem_sensor_s_uniforms_gives_its_output_for_every_effect() {
    let dir = tempdir();
    let names: std::collections::BTreeSet<String> = MODELS[..20]
        .iter()
        .map(|m| m.split('"').nth(3).unwrap().to_string())
        .collect();
    assert_eq!(names.len(), dem_sensor::effects::NAMES.len(), "every effect of the vocabulary");
    let mut cases = Vec::new();
    for (i, effects) in MODELS.iter().enumerate() {
        let json = arg(dir.path(), &format!("m{i}.json"));
        std::fs::write(&json, format!(r#"{{"effects": [{effects}]}}"#)).unwrap();
        let (onnx, out, u) = (arg(dir.path(), &format!("m{i}.onnx")), arg(dir.path(), &format!("o{i}.npy")), arg(dir.path(), &format!("u{i}.npy")));
        let o = run("dem-sensor", &["export", "--sensor", &json, "-o", &onnx], None);
        ok(&o);
        assert!(stderr(&o).contains("tract reproduces dem-sensor"), "{}", stderr(&o));
        let args = ["apply", "--sensor", &json, "--seed", "3", "--labels", &td("sim_labels.csv"), "--emit-uniform", &u, &td("sim.npy"), "-o", &out];
        ok(&run("dem-sensor", &args, None));
        cases.push(format!("({i}, '{onnx}', '{out}', '{u}')"));
    }
    let said = py(
        dir.path(),
        &format!(
            r#"
import csv, os, numpy as np
from demstream.sensor import VirtualSensor
dem = np.load("{sim}")
t = np.array([float(r["time"]) for r in csv.DictReader(open("{labels}"))], dtype=np.float32)
for i, model, out, u in [{cases}]:
    s = VirtualSensor(model)
    uniform = np.load(u) if "uniform" in s.inputs else None
    assert np.load(u).shape == (len(dem), s.uniform_count), i
    got = s(dem, time=t, uniform=uniform)
    want = np.load(out)
    va, vb = want[:, :20, :, 1] > 0, got[:, :20, :, 1] > 0
    differ = (va != vb).mean()
    worst = np.abs(np.where(va & vb, want[:, :20, :, 0] - got[:, :20, :, 0], 0)).max()
    assert differ <= 1e-4 and worst <= 1e-5, (i, s.description, differ, worst)
    assert np.array_equal(want[:, 20], got[:, 20]), i
    assert set(np.unique(got[:, :20, :, 1])) <= {{-1.0, 1.0}}, i
    assert (got[:, :20, :, 0][~vb] == 0).all(), i
    print(i, differ, worst)
"#,
            sim = td("sim.npy"),
            labels = td("sim_labels.csv"),
            cases = cases.join(", ")
        ),
    );
    assert_eq!(said.lines().count(), MODELS.len(), "{said}");
}

#[test]
fn an_export_checks_its_inputs_and_leaves_nothing_when_refused() {
    let dir = tempdir();
    let json = arg(dir.path(), "m.json");
    std::fs::write(&json, r#"{"effects": [{"effect": "quantization", "params": {"q": 1e-310}}]}"#).unwrap();
    let onnx = arg(dir.path(), "m.onnx");
    let o = run("dem-sensor", &["export", "--sensor", &json, "-o", &onnx], None);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("q = 1e-310 must be >= 1e-4 m"), "{}", stderr(&o));
    assert!(!std::path::Path::new(&onnx).exists());
    let o = run("dem-sensor", &["export", "--sensor", &json, "-o", &json], None);
    assert_eq!(o.status.code(), Some(2), "an output never overwrites an input");
}
