//! dem-sensor apply on the bundled sim data: deterministic by seed for any
//! thread count, equal to the independent numpy implementation of the
//! deterministic effects (crates/dem-sensor/tests/peers/hidden_effects.py), refusing bad models.

use std::process::Command;

use dem_core::format::DemCells;
use dem_core::npy;
use dem_testkit::{arg, ok, python, run, run_cmd, stderr, tempdir, testdata, workspace_root};

fn td(name: &str) -> String {
    testdata(name).to_string_lossy().into_owned()
}

const MODEL: &str = r#"{"effects": [
  {"effect": "fov", "params": {"x_min": -0.2, "x_max": 1.25}},
  {"effect": "occlusion", "params": {"h": 0.5, "x0": 0.15}},
  {"effect": "smoothing", "params": {"w": 0.6}},
  {"effect": "bias", "params": {"b": 0.01, "t": -0.02}},
  {"effect": "noise", "params": {"sigma0": 0.003, "k": 0.01}},
  {"effect": "quantization", "params": {"q": 0.005}},
  {"effect": "dropout", "params": {"p": 0.05}},
  {"effect": "row-dropout", "params": {"p": 0.02}}]}"#;

#[test]
fn apply_is_deterministic_by_seed_on_any_thread_count() {
    let dir = tempdir();
    let model = arg(dir.path(), "m.json");
    std::fs::write(&model, MODEL).unwrap();
    let sim = std::fs::read(td("sim.npy")).unwrap();
    let one = run_cmd(
        Command::new(dem_testkit::bin("dem-sensor")).args(["apply", "--sensor", &model, "--seed", "5"]).env("RAYON_NUM_THREADS", "1"),
        Some(sim.clone()),
    );
    let many = run_cmd(
        Command::new(dem_testkit::bin("dem-sensor")).args(["apply", "--sensor", &model, "--seed", "5"]).env("RAYON_NUM_THREADS", "3"),
        Some(sim.clone()),
    );
    assert!(ok(&one) == ok(&many), "thread count changed the output");
    let other = run("dem-sensor", &["apply", "--sensor", &model, "--seed", "6", &td("sim.npy")], None);
    assert!(ok(&other) != ok(&one), "the seed matters");
    let out = npy::NpyReader::new(ok(&one), "stdout", None).read_to_end().unwrap();
    let input = npy::read_all(&td("sim.npy")).unwrap();
    assert_eq!(out.len(), input.len());
    // fov: rows 0..3 (x < -0.2) and row 19 (x = 1.35) are never seen.
    assert!(out.iter().all(|d| (0..5).all(|c| !d.is_valid(0, c) && !d.is_valid(3, c) && !d.is_valid(19, c))));
    // Attitude rows pass through.
    assert!(out.iter().zip(&input).all(|(a, b)| a[200..] == b[200..]));
}

#[test]
fn deterministic_effects_equal_the_numpy_implementation() {
    let dir = tempdir();
    let small = arg(dir.path(), "s.npy");
    dem_testkit::py(dir.path(), &format!("import numpy as np\nnp.save('s.npy', np.load({:?})[::7])", td("sim.npy")));
    for spec in [
        "occlusion:h=0.45,x0=0.15",
        "fov:x_min=-0.33,x_max=0.97",
        "smoothing:w=0.4",
        "bias:b=0.02,t=0.03",
        "quantization:q=0.021",
        "edge-holes:g=0.06,p=1",
        "rim-holes:g=0.06,p=1",
        "pit-fill:g=0.03,p=1",
        "view-top:h=0.4,t=0.3",
        "lag:s=0.07,spread=0",
        "lag:s=-0.23,spread=0",
    ] {
        let (name, params) = spec.split_once(':').unwrap();
        let json_params: Vec<String> =
            params.split(',').map(|kv| kv.split_once('=').unwrap()).map(|(k, v)| format!("\"{k}\": {v}")).collect();
        let model = arg(dir.path(), "m.json");
        std::fs::write(&model, format!(r#"{{"effects": [{{"effect": "{name}", "params": {{{}}}}}]}}"#, json_params.join(", "))).unwrap();
        let rust = npy::NpyReader::new(ok(&run("dem-sensor", &["apply", "--sensor", &model, &small], None)), "stdout", None)
            .read_to_end()
            .unwrap();
        let py_out = arg(dir.path(), "p.npy");
        let o = Command::new(python())
            .arg(workspace_root().join("crates/dem-sensor/tests/peers/hidden_effects.py"))
            .args([&small, &py_out, "1", spec])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let theirs = npy::read_all(&py_out).unwrap();
        // Same cells missing; heights within 1e-6 m (f32 rounding of f64
        // arithmetic done in a different order). Quantization may land on
        // the other multiple where h/q + 1/2 is within rounding of an integer.
        let mut differ = 0;
        for (a, b) in rust.iter().zip(&theirs) {
            for r in 0..20 {
                for c in 0..5 {
                    assert_eq!(a.is_valid(r, c), b.is_valid(r, c), "{spec}: cell ({r}, {c}) validity");
                    differ += usize::from((a.height(r, c) - b.height(r, c)).abs() > 1e-6);
                }
            }
        }
        assert!(differ <= rust.len() / 100, "{spec}: {differ} heights differ");
    }
}

/// A map's memory stepped through the bundled runs (labels' runs, times and
/// poses) by dem-sensor and by the numpy peer, which reads the labels and
/// steps the runs in its own loops: with no keeping (no draw decides) the
/// same cells are missing and heights agree within 1e-5 m.
#[test]
fn a_map_s_memory_over_runs_matches_the_numpy_peer() {
    let dir = tempdir();
    let model = arg(dir.path(), "m.json");
    std::fs::write(
        &model,
        r#"{"effects": [{"effect": "dropout", "params": {"p": 0.0}}, {"effect": "map-memory", "params": {"tau": 0.9, "keep": 0.0}}]}"#,
    )
    .unwrap();
    let args = ["apply", "--sensor", &model, "--labels", &td("sim_labels.csv"), &td("sim.npy")];
    let rust = npy::NpyReader::new(ok(&run("dem-sensor", &args, None)), "stdout", None).read_to_end().unwrap();
    let py_out = arg(dir.path(), "p.npy");
    let o = Command::new(python())
        .arg(workspace_root().join("crates/dem-sensor/tests/peers/hidden_effects.py"))
        .args([&td("sim.npy"), &py_out, "1", "map-memory:tau=0.9,keep=0", "--labels", &td("sim_labels.csv")])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let theirs = npy::read_all(&py_out).unwrap();
    let sim = npy::read_all(&td("sim.npy")).unwrap();
    let (mut worst, mut moved) = (0.0f32, 0usize);
    for ((a, b), s) in rust.iter().zip(&theirs).zip(&sim) {
        for r in 0..20 {
            for c in 0..5 {
                assert_eq!(a.is_valid(r, c), b.is_valid(r, c), "cell ({r}, {c}) validity");
                if a.is_valid(r, c) {
                    worst = worst.max((a.height(r, c) - b.height(r, c)).abs());
                    moved += usize::from(!s.is_valid(r, c) || (a.height(r, c) - s.height(r, c)).abs() > 1e-3);
                }
            }
        }
    }
    assert!(worst <= 1e-5, "heights differ by {worst:e} m");
    assert!(moved > rust.len(), "the memory acts: {moved} cells of {} records differ from sim", rust.len());
}

#[test]
fn bad_models_exit_2_naming_the_file() {
    let dir = tempdir();
    let cases = [
        (r#"{"effects": [{"effect": "dropout", "params": {"p": 2}}]}"#, "not a probability"),
        (r#"{"effects": [{"effect": "blur", "params": {}}]}"#, "unknown variant"),
        ("not json", "not a sensor model"),
    ];
    for (text, why) in cases {
        let model = arg(dir.path(), "bad.json");
        std::fs::write(&model, text).unwrap();
        let o = run("dem-sensor", &["apply", "--sensor", &model, &td("sim.npy")], None);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains("bad.json") && stderr(&o).contains(why), "{}", stderr(&o));
    }
    let o = run("dem-sensor", &["apply", "--sensor", "missing.json", &td("sim.npy")], None);
    assert_eq!(o.status.code(), Some(2));
    // Values a model writes as infinities, and a show that would append to its model.
    let model = arg(dir.path(), "m.json");
    std::fs::write(&model, r#"{"effects": [{"effect": "quantization", "params": {"q": 1e-310}}]}"#).unwrap();
    let o = run("dem-sensor", &["show", "--sensor", &model], None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("q = 1e-310 must be >= 1e-4 m"), "{}", stderr(&o));
    std::fs::write(&model, r#"{"effects": [{"effect": "quantization", "params": {"q": 0.0002}}]}"#).unwrap();
    let o = run("dem-sensor", &["show", "--sensor", &model], None);
    assert_eq!(String::from_utf8_lossy(ok(&o)).trim(), "quantization(q=2.000e-4)");
    let before = std::fs::read(&model).unwrap();
    let shell = format!("{} show --sensor {model} >> {model}", dem_testkit::bin("dem-sensor").display());
    let o = dem_testkit::run_cmd(std::process::Command::new("bash").args(["-c", &shell]), None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(std::fs::read(&model).unwrap(), before, "the model is untouched");
}

#[test]
fn a_closed_stdout_is_not_an_error() {
    let dir = tempdir();
    let model = arg(dir.path(), "m.json");
    std::fs::write(&model, MODEL).unwrap();
    let mut child = Command::new(dem_testkit::bin("dem-sensor"))
        .args(["apply", "--sensor", &model, &td("sim.npy")])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// startup follows the labels' time (rows behind the blind edge x0 - v t
/// missing, the rest kept); without labels, its per-record rate p.
#[test]
fn startup_follows_the_labels_time_and_its_rate_without() {
    let dir = tempdir();
    let model = arg(dir.path(), "m.json");
    std::fs::write(&model, r#"{"effects": [{"effect": "startup", "params": {"x0": 0.47, "v": 0.25, "p": 0.3}}]}"#).unwrap();
    let sim = npy::read_all(&td("sim.npy")).unwrap();
    let labels = dem_core::table::read_labels(&td("sim_labels.csv")).unwrap();
    let o = run("dem-sensor", &["apply", "--sensor", &model, "--labels", &td("sim_labels.csv"), &td("sim.npy")], None);
    let out = npy::NpyReader::new(ok(&o), "stdout", None).read_to_end().unwrap();
    assert_eq!(out.len(), sim.len());
    for ((d, s), l) in out.iter().zip(&sim).zip(&labels) {
        let edge = 0.47 - 0.25 * l.time.unwrap();
        for r in 0..20 {
            let x = -0.55 + 0.1 * r as f64;
            for c in 0..5 {
                let want = s.is_valid(r, c) && x >= edge;
                assert_eq!(d.is_valid(r, c), want, "record {} t {:?} row {r}", l.index, l.time);
            }
        }
    }
    // Without labels: about 30 % of records have rows missing at the back.
    let o = run("dem-sensor", &["apply", "--sensor", &model, "--seed", "2", &td("sim.npy")], None);
    let out = npy::NpyReader::new(ok(&o), "stdout", None).read_to_end().unwrap();
    let blind = out.iter().filter(|d| (0..5).all(|c| !d.is_valid(0, c))).count() as f64 / out.len() as f64;
    assert!((blind - 0.3).abs() < 0.04, "share of startup frames {blind}");
    // Labels that do not cover the stream are refused.
    let short = arg(dir.path(), "short.csv");
    std::fs::write(&short, "index,terrain,time\n0,flat,0.0\n").unwrap();
    let o = run("dem-sensor", &["apply", "--sensor", &model, "--labels", &short, &td("sim.npy")], None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("short.csv"), "{}", stderr(&o));
}

/// patch-dropout removes blobs: at the same missing rate as dropout, far
/// more missing cells have a missing neighbour across the robot.
#[test]
fn patch_dropout_makes_blobs_of_its_size() {
    let dir = tempdir();
    let model = arg(dir.path(), "m.json");
    std::fs::write(&model, r#"{"effects": [{"effect": "patch-dropout", "params": {"n": 2.0, "r": 0.12}}]}"#).unwrap();
    let o = run("dem-sensor", &["apply", "--sensor", &model, "--seed", "3", &td("sim.npy")], None);
    let out = npy::NpyReader::new(ok(&o), "stdout", None).read_to_end().unwrap();
    let (mut miss, mut pairs, mut both) = (0usize, 0usize, 0usize);
    for d in &out {
        for r in 0..20 {
            for c in 0..5 {
                miss += usize::from(!d.is_valid(r, c));
                if c + 1 < 5 {
                    pairs += 1;
                    both += usize::from(!d.is_valid(r, c) && !d.is_valid(r, c + 1));
                }
            }
        }
    }
    let rate = miss as f64 / (out.len() * 100) as f64;
    let pair_rate = both as f64 / pairs as f64;
    assert!(rate > 0.03 && rate < 0.4, "missing rate {rate}");
    // Scattered cells at this rate would give rate^2 of pairs.
    assert!(pair_rate > 3.0 * rate * rate, "pairs {pair_rate} vs rate {rate}");
}

#[test]
fn only_applies_the_named_effects_with_their_draws_and_names_a_missing_one() {
    let dir = tempdir();
    let model = arg(dir.path(), "m.json");
    std::fs::write(&model, MODEL).unwrap();
    let alone = arg(dir.path(), "alone.json");
    std::fs::write(
        &alone,
        r#"{"effects": [{"effect": "noise", "params": {"sigma0": 0.003, "k": 0.01}}, {"effect": "dropout", "params": {"p": 0.05}}]}"#,
    )
    .unwrap();
    let only = run("dem-sensor", &["apply", "--sensor", &model, "--only", "dropout,noise", "--seed", "3", &td("sim.npy")], None);
    let same = run("dem-sensor", &["apply", "--sensor", &alone, "--seed", "3", &td("sim.npy")], None);
    assert!(ok(&only) == ok(&same), "--only changed the effects' draws");
    assert!(stderr(&only).contains("through noise") && !stderr(&only).contains("occlusion"), "{}", stderr(&only));
    let missing = run("dem-sensor", &["apply", "--sensor", &model, "--only", "startup", &td("sim.npy")], None);
    assert_eq!(missing.status.code(), Some(2));
    assert!(stderr(&missing).contains("m.json: the model has no startup effect (it has: fov, occlusion"), "{}", stderr(&missing));
}

/// The random motion effects against the independent numpy implementation:
/// different draws, so the same distribution. On a third of the sim
/// records, each row's residual sd (the effect's output minus the input,
/// over valid cells) agrees within 12 % (or 0.5 mm); validity is kept.
#[test]
fn motion_effects_equal_the_numpy_implementation_in_distribution() {
    let dir = tempdir();
    let small = arg(dir.path(), "s.npy");
    dem_testkit::py(dir.path(), &format!("import numpy as np\nnp.save('s.npy', np.load({:?})[::3])", td("sim.npy")));
    let input = npy::read_all(&small).unwrap();
    let row_sd = |out: &[dem_core::Dem]| -> Vec<f64> {
        (0..20)
            .map(|r| {
                let v: Vec<f64> = out
                    .iter()
                    .zip(&input)
                    .flat_map(|(a, b)| {
                        (0..5).filter(|&c| b.is_valid(r, c)).map(move |c| f64::from(a.height(r, c)) - f64::from(b.height(r, c)))
                    })
                    .collect();
                let m = v.iter().sum::<f64>() / v.len().max(1) as f64;
                (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len().max(1) as f64).sqrt()
            })
            .collect()
    };
    for spec in [
        "tilt:pitch=0.02,roll=0.015,x0=0.4,range=1.5",
        "shake:sigma=0.003,edge=0.1",
        "lag:s=0.08,spread=0.6",
        "drift:rate=0.08,zrate=0.03,x0=0.4",
    ] {
        let (name, params) = spec.split_once(':').unwrap();
        let json_params: Vec<String> =
            params.split(',').map(|kv| kv.split_once('=').unwrap()).map(|(k, v)| format!("\"{k}\": {v}")).collect();
        let model = arg(dir.path(), "m.json");
        std::fs::write(&model, format!(r#"{{"effects": [{{"effect": "{name}", "params": {{{}}}}}]}}"#, json_params.join(", "))).unwrap();
        let rust = npy::NpyReader::new(ok(&run("dem-sensor", &["apply", "--sensor", &model, "--seed", "2", &small], None)), "stdout", None)
            .read_to_end()
            .unwrap();
        let py_out = arg(dir.path(), "p.npy");
        let o = Command::new(python())
            .arg(workspace_root().join("crates/dem-sensor/tests/peers/hidden_effects.py"))
            .args([&small, &py_out, "5", spec])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let theirs = npy::read_all(&py_out).unwrap();
        for out in [&rust, &theirs] {
            assert!(
                out.iter().zip(&input).all(|(a, b)| (0..100).all(|i| a.is_valid(i / 5, i % 5) == b.is_valid(i / 5, i % 5))),
                "{spec}: validity kept"
            );
        }
        let (a, b) = (row_sd(&rust), row_sd(&theirs));
        for r in 0..20 {
            assert!(
                (a[r] - b[r]).abs() <= 0.12 * a[r].max(b[r]) + 5e-4,
                "{spec}: row {r} sd {:.4} (dem-sensor) vs {:.4} (numpy); {a:?} vs {b:?}",
                a[r],
                b[r]
            );
        }
    }
}

/// `model` applied to the bundled sim records (with `labels`, when given)
/// and the numpy reference of the frame statistics
/// (`scripts/peers/temporal.py`) over the bundled runs (frames 0.4 s
/// apart): the lag-1 correlation of the error against sim, and its sd.
fn frame_rcorr_and_sd(dir: &std::path::Path, name: &str, model: &str, labels: Option<&str>) -> (f64, f64) {
    let (sim, sensor, out) = (td("sim.npy"), arg(dir, &format!("{name}.json")), arg(dir, &format!("{name}.npy")));
    std::fs::write(&sensor, model).unwrap();
    let mut args = vec!["apply", "--sensor", &sensor, "--seed", "4", &sim, "-o", &out];
    args.extend(labels.map(|l| ["--labels", l]).into_iter().flatten());
    ok(&run("dem-sensor", &args, None));
    let got = dem_testkit::py(
        dir,
        &format!(
            r#"
import sys
import numpy as np
sys.path.insert(0, {peers:?})
import temporal
sim, x = np.load({sim:?}), np.load({out:?})
valid = (sim[..., 1] > 0) & (x[..., 1] > 0)
print(temporal.stats(x, sim, temporal.runs({labels:?}))["rcorr"], np.std((x[..., 0] - sim[..., 0])[valid]))
"#,
            peers = workspace_root().join("scripts/peers").to_string_lossy(),
            labels = td("sim_labels.csv"),
        ),
    );
    let v: Vec<f64> = got.split_whitespace().map(|v| v.parse().unwrap()).collect();
    (v[0], v[1])
}

/// A map's memory: `noise` with `tau` keeps its error over the same
/// ground where noise drawn new every frame forgets it; its spread is the
/// same; and the records reversed, their labels with them, give the same
/// records.
#[test]
fn a_map_s_memory_keeps_the_noise_over_the_same_ground() {
    let dir = tempdir();
    let labels = td("sim_labels.csv");
    let noise = |tau: f64| format!(r#"{{"effects": [{{"effect": "noise", "params": {{"sigma0": 0.01, "k": 0.0, "tau": {tau}}}}}]}}"#);
    let (fresh_rcorr, fresh_sd) = frame_rcorr_and_sd(dir.path(), "fresh", &noise(0.0), Some(&labels));
    let (kept_rcorr, kept_sd) = frame_rcorr_and_sd(dir.path(), "kept", &noise(2.0), Some(&labels));
    // exp(-0.4 / 2) = 0.82 where a cell sees the same 10 cm of ground in
    // both frames; the robot moves 11.6 cm a frame, so some see the next.
    assert!(fresh_rcorr.abs() < 0.05, "noise new every frame keeps a correlation of {fresh_rcorr}");
    assert!((0.6..0.85).contains(&kept_rcorr), "a map's memory of 2 s keeps a correlation of {kept_rcorr}");
    for sd in [fresh_sd, kept_sd] {
        assert!((sd - 0.01).abs() < 5e-4, "the noise's sd {sd} against sigma0 0.01");
    }
    // The same records and labels, last first.
    let records = npy::read_all(&td("sim.npy")).unwrap();
    let reversed: Vec<_> = records.iter().rev().cloned().collect();
    let back = arg(dir.path(), "reversed.npy");
    npy::write_all(&back, &reversed).unwrap();
    let text = std::fs::read_to_string(&labels).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let rows: Vec<&str> = lines.collect();
    let body: String = rows.iter().rev().enumerate().map(|(i, l)| format!("{i},{}\n", l.split_once(',').unwrap().1)).collect();
    let back_labels = arg(dir.path(), "reversed.csv");
    std::fs::write(&back_labels, format!("{header}\n{body}")).unwrap();
    let sensor = arg(dir.path(), "kept.json");
    let o = run("dem-sensor", &["apply", "--sensor", &sensor, "--labels", &back_labels, "--seed", "4", &back], None);
    let out = npy::NpyReader::new(ok(&o), "stdout", None).read_to_end().unwrap();
    let forward = npy::read_all(&arg(dir.path(), "kept.npy")).unwrap();
    assert!(out.iter().rev().eq(forward.iter()), "the order of the records changed their noise");
}

/// `drift` with the runs: the ground seen earlier keeps its displacement
/// from one frame to the next (a frame adds one 10 cm step of the walk to
/// some ten), where a walk drawn per record is new every frame; the
/// displacement's spread is the same.
#[test]
fn drift_walks_with_the_path_a_run_travelled() {
    let dir = tempdir();
    let model = r#"{"effects": [{"effect": "drift", "params": {"rate": 0.0, "zrate": 0.02, "x0": 1.0}}]}"#;
    let (run_rcorr, run_sd) = frame_rcorr_and_sd(dir.path(), "run", model, Some(&td("sim_labels.csv")));
    let (own_rcorr, own_sd) = frame_rcorr_and_sd(dir.path(), "own", model, None);
    assert!(own_rcorr.abs() < 0.1, "a walk per record keeps a correlation of {own_rcorr}");
    assert!(run_rcorr > 0.7, "the run's walk keeps a correlation of {run_rcorr}");
    assert!((run_sd / own_sd - 1.0).abs() < 0.1, "sd {run_sd} with the runs, {own_sd} per record");
}
