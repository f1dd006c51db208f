//! The ONNX graph of a sensor model computes what the native code does,
//! fed the same uniforms and times: every effect of the vocabulary alone,
//! and models of several, on the bundled sim and measured DEMs, run by
//! tract. (onnxruntime and PyTorch run the same check in dem-apply's tests.)

use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};
use dem_sensor::effects::{Bias, Noise, Startup};
use dem_sensor::{graph, Effect, Moment, SensorModel};

fn records() -> Vec<Dem> {
    let mut all = dem_core::npy::read_all(dem_testkit::testdata("sim.npy").to_str().unwrap()).unwrap();
    all.truncate(300);
    let real = dem_core::npy::read_all(dem_testkit::testdata("real.npy").to_str().unwrap()).unwrap();
    all.extend(real.into_iter().take(300));
    all
}

/// Times in the run for each record: a spread of known ones, every fifth
/// unknown (NaN).
fn times(n: usize) -> Vec<f32> {
    (0..n).map(|i| if i % 5 == 0 { f32::NAN } else { 0.05 * (i % 60) as f32 }).collect()
}

/// Native and graph outputs of `model` on the test records: the share of
/// cells whose validity differs, the largest height difference where both
/// are valid, and whether row 20 and the contract's missing cells agree.
fn compare(model: &SensorModel) -> (f64, f32) {
    let input = records();
    let n = input.len();
    let k = model.draws();
    let mut uniform = vec![0.0f32; n * k];
    for (i, u) in uniform.chunks_mut(k.max(1)).enumerate().take(n) {
        if k > 0 {
            model.uniforms(9, i as u64, Moment::UNKNOWN, u);
        }
    }
    let t = times(n);
    let mut native = input.clone();
    for (i, d) in native.iter_mut().enumerate() {
        model.apply_drawn(d, &uniform[i * k..(i + 1) * k], Some(f64::from(t[i])));
    }
    let proto = graph::sensor_model(model, "test", &[]);
    let got = graph::run_tract(&proto, model, &input, &uniform, &t).unwrap();
    agreement(&native, &got)
}

/// Native against graph outputs: the share of cells whose validity
/// differs and the largest height difference where both are valid; row 20
/// and the contract's missing cells (height 0, mask -1) are asserted.
fn agreement(native: &[Dem], got: &[Dem]) -> (f64, f32) {
    let (mut differ, mut worst) = (0usize, 0.0f32);
    for (a, b) in native.iter().zip(got) {
        assert_eq!(a[200..], b[200..], "row 20 passes through");
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                if a.is_valid(r, c) != b.is_valid(r, c) {
                    differ += 1;
                } else if a.is_valid(r, c) {
                    worst = worst.max((a.height(r, c) - b.height(r, c)).abs());
                } else {
                    assert_eq!((b.height(r, c), b.mask(r, c)), (0.0, -1.0), "a missing cell is height 0, mask -1");
                }
                assert!(b.mask(r, c).abs() == 1.0);
            }
        }
    }
    (differ as f64 / (native.len() * GRID_ROWS * COLS) as f64, worst)
}

fn check(model: &SensorModel) {
    let (differ, worst) = compare(model);
    assert!(differ <= 1e-4, "{}: {:.5} % of cells differ in validity", model.summary(), 100.0 * differ);
    assert!(worst <= 1e-5, "{}: heights differ by {worst:e}", model.summary());
}

/// Each effect at parameters where it acts on the bundled data.
fn every_effect() -> Vec<Effect> {
    Effect::examples()
}

#[test]
fn every_effect_alone_computes_the_same_in_the_graph() {
    let effects = every_effect();
    let names: std::collections::BTreeSet<&str> = effects.iter().map(Effect::name).collect();
    assert_eq!(names.len(), dem_sensor::effects::NAMES.len(), "every effect of the vocabulary is checked");
    for e in effects {
        let model = SensorModel::new(vec![e]);
        if let Some(memory) = model.map_memory() {
            check_steps(&model, memory);
            continue;
        }
        let before = records();
        let mut after = before.clone();
        model.apply_all_at(&mut after, 9, 0, None);
        assert!(before != after, "{e} acts on the test records");
        check(&model);
    }
}

/// A map's memory: the test records stepped as runs, natively and by tract
/// feeding each step's state to the next, agree; and the memory acts (a
/// run's later frames are not the frames alone).
fn check_steps(model: &SensorModel, memory: dem_sensor::effects::MapMemory) {
    let input = records();
    let (n, k) = (input.len(), model.draws());
    let uniform = model.uniforms_of(9, 0, n, None);
    let t = times(n);
    let proto = graph::sensor_model(model, "test", &[]);
    let (native, got) = dem_sensor::export::stepped(&proto, model, memory, &input, &uniform, &t).unwrap();
    let frames: Vec<_> = (0..native.len())
        .map(|i| {
            let mut d = input[i];
            model.apply_drawn(&mut d, &uniform[i * k..(i + 1) * k], None);
            d
        })
        .collect();
    assert!(native != frames, "{}: the memory acts on a run's later frames", model.summary());
    let (share, worst) = agreement(&native, &got);
    assert!(share <= 1e-4 && worst <= 1e-5, "{}: stepped, {share} of validity and {worst:e} m differ", model.summary());
}

#[test]
fn a_model_of_several_effects_computes_the_same_in_the_graph() {
    let model = SensorModel::from_json(
        r#"{"effects": [
            {"effect": "lag", "params": {"s": 0.05, "spread": 0.5}},
            {"effect": "drift", "params": {"rate": 0.05, "zrate": 0.01, "x0": 0.4}},
            {"effect": "fov", "params": {"x_min": -0.45, "x_max": 1.2}},
            {"effect": "startup", "params": {"x0": 0.3, "v": 0.25, "p": 0.3}},
            {"effect": "occlusion", "params": {"h": 0.42, "x0": 0.12}},
            {"effect": "drop-holes", "params": {"p": 0.3}},
            {"effect": "pit-fill", "params": {"g": 0.03, "p": 0.5}},
            {"effect": "mixed-cells", "params": {"up": 0.03, "down": 0.05}},
            {"effect": "floor-lift", "params": {"x": 1.45, "p": 0.4, "a": 1.2}},
            {"effect": "smoothing", "params": {"w": 0.7}},
            {"effect": "tilt", "params": {"pitch": 0.01, "roll": 0.01, "x0": 0.4, "range": 2.0}},
            {"effect": "shake", "params": {"sigma": 0.002, "edge": 0.07}},
            {"effect": "step-jitter", "params": {"sigma": 0.02, "edge": 0.1}},
            {"effect": "noise", "params": {"sigma0": 0.004, "k": 0.01}},
            {"effect": "noise", "params": {"sigma0": 0.002, "k": 0.0}},
            {"effect": "dropout", "params": {"p": 0.05}},
            {"effect": "hole-growth", "params": {"p": 0.2}},
            {"effect": "row-dropout", "params": {"p": 0.02}}
        ]}"#,
    )
    .unwrap();
    check(&model);
}

#[test]
fn the_graph_says_what_its_inputs_are() {
    let model = SensorModel::new(vec![
        Effect::Noise(Noise { sigma0: 0.01, k: 0.0, tau: 0.0 }),
        Effect::Startup(Startup { x0: 0.3, v: 0.2, p: 0.1 }),
    ]);
    let proto = graph::sensor_model(&model, "s", &[]);
    let names: Vec<&str> = proto.graph.as_ref().unwrap().input.iter().map(|i| i.name.as_str()).collect();
    assert_eq!(names, ["dem", "uniform", "time"]);
    let meta: Vec<(&str, &str)> = proto.metadata_props.iter().map(|e| (e.key.as_str(), e.value.as_str())).collect();
    assert!(meta.contains(&("dem.uniform_count", "102")), "{meta:?}");
    assert!(meta.contains(&("dem.inputs", "dem,uniform,time")), "{meta:?}");
    assert!(proto.doc_string.contains("uniform float32 (N,102)") && proto.doc_string.contains("NaN where unknown"), "{}", proto.doc_string);
    let det = SensorModel::new(vec![Effect::Bias(Bias { b: 0.01, t: 0.0 })]);
    let names: Vec<String> = graph::sensor_model(&det, "s", &[]).graph.unwrap().input.iter().map(|i| i.name.clone()).collect();
    assert_eq!(names, ["dem"], "a model without draws or time takes the DEM alone");
}

/// `testdata/effects.json`'s `every_effect` (which the onnxruntime test and
/// the PyTorch check read) is every effect's first example, in the
/// vocabulary's order: on a mismatch the message is the list to paste
/// there. (The later examples are extreme cases, such as a drift of 2 m per
/// sqrt(m), that the graph tests' tolerance allows and `dem-sensor export`'s
/// own check does not.)
#[test]
fn the_effects_json_lists_every_example() {
    let text = std::fs::read_to_string(dem_testkit::testdata("effects.json")).unwrap();
    let file: serde_json::Value = serde_json::from_str(&text).unwrap();
    let listed: Vec<Effect> = serde_json::from_value(file["every_effect"].clone()).unwrap();
    let line = |e: &Effect| {
        let params: Vec<String> = e.params().iter().map(|(n, v)| format!("\"{n}\": {v:?}")).collect();
        format!("  {{\"effect\": \"{}\", \"params\": {{{}}}}}", e.name(), params.join(", "))
    };
    let mut first = every_effect();
    first.dedup_by_key(|e| e.name());
    let want: Vec<String> = first.iter().map(line).collect();
    assert!(listed == first, "testdata/effects.json's every_effect should read:\n[\n{}\n]", want.join(",\n"));
}

/// Staircases whose steps are exactly a threshold in float32 (heights
/// `k * 0.1f32`, so a step of one is `0.1f32`, which float64 reads as more
/// than 0.1 and float32 does not), pitched a little, with a pit and a
/// lone high cell: where a threshold decided in float64 falls the other
/// way from the graph's.
fn steps_at_thresholds() -> Vec<Dem> {
    (0..240)
        .map(|i| {
            let mut d = dem_core::format::empty_dem();
            let (rise, shift) = (1 + i % 3, i % 7);
            for r in 0..GRID_ROWS {
                for c in 0..COLS {
                    let k = if i % 2 == 0 { (r + shift) / 2 } else { (GRID_ROWS - r + shift) / 2 };
                    d.set_valid(r, c, (k * rise) as f32 * 0.1);
                }
            }
            // A pit one step deep and a lone cell one step up.
            let (r, c) = (3 + i % 11, i % COLS);
            d.set_valid(r, c, d.height(r, c) - 0.1);
            d.set_valid(r + 4, (c + 2) % COLS, d.height(r + 4, (c + 2) % COLS) + 0.1);
            d.set_attitude([0.01 * (i % 5) as f32 - 0.02, 0.0, 0.0, 0.0, 0.0]);
            d
        })
        .collect()
}

#[test]
fn a_step_of_exactly_a_threshold_is_decided_alike_in_the_graph() {
    let models = [
        r#"{"effect": "edge-holes", "params": {"g": 0.1, "p": 0.6}}"#,
        r#"{"effect": "rim-holes", "params": {"g": 0.1, "p": 0.6}}"#,
        r#"{"effect": "pit-fill", "params": {"g": 0.1, "p": 0.8}}"#,
        r#"{"effect": "drop-holes", "params": {"p": 0.7}}"#,
        r#"{"effect": "drop-blend", "params": {"p": 0.7, "a": 0.6}}"#,
        r#"{"effect": "riser-blend", "params": {"foot": 0.4, "top": -0.3}}"#,
        r#"{"effect": "floor-lift", "params": {"x": 1.45, "p": 0.7, "a": 1.5}}"#,
        r#"{"effect": "mixed-cells", "params": {"up": 0.04, "down": 0.06}}"#,
        r#"{"effect": "occlusion", "params": {"h": 0.3, "x0": 0.0}}"#,
        r#"{"effect": "view-top", "params": {"h": 0.3, "t": 0.3}}"#,
    ];
    let input = steps_at_thresholds();
    let n = input.len();
    for json in models {
        let model = SensorModel::from_json(&format!(r#"{{"effects": [{json}]}}"#)).unwrap();
        let k = model.draws();
        let mut uniform = vec![0.0f32; n * k];
        if k > 0 {
            for (i, u) in uniform.chunks_mut(k).enumerate() {
                model.uniforms(3, i as u64, Moment::UNKNOWN, u);
            }
        }
        let t = vec![f32::NAN; n];
        let mut native = input.clone();
        for (i, d) in native.iter_mut().enumerate() {
            model.apply_drawn(d, &uniform[i * k..(i + 1) * k], None);
        }
        assert!(native != input, "{json} acts on the staircases");
        let got = graph::run_tract(&graph::sensor_model(&model, "test", &[]), &model, &input, &uniform, &t).unwrap();
        for (i, (a, b)) in native.iter().zip(&got).enumerate() {
            for r in 0..GRID_ROWS {
                for c in 0..COLS {
                    assert_eq!(a.is_valid(r, c), b.is_valid(r, c), "{json}: record {i}, cell ({r}, {c}): validity");
                    if a.is_valid(r, c) {
                        let d = (a.height(r, c) - b.height(r, c)).abs();
                        assert!(d <= 1e-6, "{json}: record {i}, cell ({r}, {c}): heights {} and {}", a.height(r, c), b.height(r, c));
                    }
                }
            }
        }
    }
}
