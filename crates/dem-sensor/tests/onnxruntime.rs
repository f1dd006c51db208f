//! `dem-sensor export` and `dem-sensor apply --emit-uniform`, run as users
//! run them: onnxruntime, fed the uniforms dem-sensor drew and the labels'
//! times, gives dem-sensor's output for every effect of the vocabulary
//! alone and for a model of several; a map's memory stepped through the
//! labels' runs with the motion their poses give.

use dem_sensor::SensorModel;
use dem_testkit::{arg, ok, py, run, stderr, tempdir, testdata};

fn td(name: &str) -> String {
    testdata(name).to_string_lossy().into_owned()
}

/// One model per effect (at parameters where it acts on the bundled
/// data), then one of several: `testdata/effects.json`, which the PyTorch
/// check (`scripts/torch_sensor_check.sh`) reads too.
fn models() -> Vec<String> {
    let text = std::fs::read_to_string(td("effects.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mut out: Vec<String> = v["every_effect"].as_array().unwrap().iter().map(|e| format!(r#"{{"effects": [{e}]}}"#)).collect();
    out.push(format!(r#"{{"effects": {}}}"#, v["several"]));
    out
}

#[test]
fn onnxruntime_fed_dem_sensor_s_uniforms_gives_its_output_for_every_effect() {
    let dir = tempdir();
    let models = models();
    let names: std::collections::BTreeSet<String> =
        models[..models.len() - 1].iter().map(|m| SensorModel::from_json(m).unwrap().effects[0].name().to_string()).collect();
    assert_eq!(names.len(), dem_sensor::effects::NAMES.len(), "every effect of the vocabulary");
    let mut cases = Vec::new();
    for (i, model) in models.iter().enumerate() {
        let json = arg(dir.path(), &format!("m{i}.json"));
        std::fs::write(&json, model).unwrap();
        let (onnx, out, u) =
            (arg(dir.path(), &format!("m{i}.onnx")), arg(dir.path(), &format!("o{i}.npy")), arg(dir.path(), &format!("u{i}.npy")));
        let o = run("dem-sensor", &["export", "--sensor", &json, "-o", &onnx], None);
        ok(&o);
        assert!(stderr(&o).contains("tract reproduces dem-sensor"), "{}", stderr(&o));
        let args = [
            "apply",
            "--sensor",
            &json,
            "--seed",
            "3",
            "--labels",
            &td("sim_labels.csv"),
            "--emit-uniform",
            &u,
            &td("sim.npy"),
            "-o",
            &out,
        ];
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
rows = list(csv.DictReader(open("{labels}")))
t = np.array([float(r["time"]) for r in rows], dtype=np.float32)
run = np.array([int(r["sequence"]) for r in rows])
pose = np.array([[float(r[k]) for k in ("x", "y", "yaw")] for r in rows])
for i, model, out, u in [{cases}]:
    s = VirtualSensor(model)
    uniform = np.load(u) if "uniform" in s.inputs else None
    assert np.load(u).shape == (len(dem), s.uniform_count), i
    # A map's memory: the runs stepped side by side, as dem-sensor steps them.
    got = s.over_runs(dem, run, pose, time=t, uniform=uniform)
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
    assert_eq!(said.lines().count(), models.len(), "{said}");
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
