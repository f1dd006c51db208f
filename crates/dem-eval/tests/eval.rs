//! dem-eval against a numpy implementation of the spec's pair error and of
//! the height measures (height error, roughness), on the bundled data and on
//! hand-made edge cases; the gap against dem-core's; `compare` exit codes;
//! `join`'s forms and pivot.

use std::path::Path;

use dem_core::distribution;
use dem_core::metric::dem_error;
use dem_core::{npy, table, Dem};
use dem_testkit::{arg, ok, py, run, stderr, tempdir, testdata};
use serde_json::Value;

fn td(name: &str) -> String {
    testdata(name).to_string_lossy().into_owned()
}

/// The spec's pair error and table in numpy, the obvious way: f64 from the
/// f32 inputs, the first real record of the smallest error, np.median.
const NUMPY_EVAL: &str = r#"
import json, numpy as np
def e(y, p):
    y = y[:20].astype(np.float64); p = p[:20].astype(np.float64)
    v = (y[..., 1] > 0).astype(np.float64)
    return float((((v * (y[..., 0] - p[..., 0])) ** 2 + (y[..., 1] - p[..., 1]) ** 2).sum()) / 100)
def evaluate(pred, real, pairs, split, terrain):
    sel = {}
    for s, r, sp in pairs:
        if split is None or sp == split:
            sel.setdefault(s, [])
            if r not in sel[s]: sel[s].append(r)
    recs, meas = [], []
    for s in sorted(sel):
        errs = [e(real[r], pred[s]) for r in sel[s]]
        i = int(np.argmin(errs))
        h, rp, ry = heights(pred[s], real[sel[s][i]])
        recs.append((s, sel[s][i], errs[i], terrain[s] if terrain else "", float(h.mean() * 100) if h.size else None))
        meas.append((h,) + rp + ry)
    def cm(parts):
        v = np.concatenate(parts)
        return float(v.mean() * 100) if v.size else None
    def row(t, idx):
        es = np.array([recs[k][2] for k in idx])
        r = dict(terrain=t, count=len(es), lowest=es.min(), highest=es.max(), mean=es.mean(), median=np.median(es))
        for j, name in enumerate(MEASURES):
            r[name] = cm([meas[k][j] for k in idx])
        return r
    rows = [row("all", range(len(recs)))]
    for t in ["flat", "stairs-up", "stairs-down", "pallet", "other"]:
        idx = [k for k, r in enumerate(recs) if r[3] == t]
        if idx: rows.append(row(t, idx))
    return recs, rows
MEASURES = ["height_cm", "rough_across_cm", "rough_along_cm", "real_rough_across_cm", "real_rough_along_cm"]
def rough(d):
    v = d[..., 1] > 0
    h = d[..., 0]
    return np.abs(np.diff(h, axis=1))[v[:, :-1] & v[:, 1:]], np.abs(np.diff(h, axis=0))[v[:-1] & v[1:]]
def heights(p, y):
    """abs height differences on cells valid in both; roughness of p and y (rows 0..19)."""
    p = p[:20].astype(np.float64); y = y[:20].astype(np.float64)
    both = (p[..., 1] > 0) & (y[..., 1] > 0)
    return np.abs(p[..., 0] - y[..., 0])[both], rough(p), rough(y)
"#;

/// Relative 1e-6 (absolute 1e-12 near zero): the f64 sums differ only in
/// order (numpy sums pairwise), far below that.
fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-6 * a.abs().max(b.abs()) + 1e-12
}

/// The height measures: numpy sums f64 differences of the same f32
/// heights, so they agree to rounding; null (no cells) on both sides alike.
const MEASURES: [&str; 5] = ["height_cm", "rough_across_cm", "rough_along_cm", "real_rough_across_cm", "real_rough_along_cm"];

fn check_rows(got: &Value, want: &Value) {
    let (g, w) = (got.as_array().unwrap(), want.as_array().unwrap());
    assert_eq!(g.len(), w.len(), "rows: {got} vs {want}");
    for (g, w) in g.iter().zip(w) {
        assert_eq!(g["terrain"], w["terrain"]);
        assert_eq!(g["count"], w["count"]);
        for k in ["lowest", "highest", "mean", "median"] {
            let (a, b) = (g[k].as_f64().unwrap(), w[k].as_f64().unwrap());
            assert!(close(a, b), "{} {k}: dem-eval {a}, numpy {b}", w["terrain"]);
        }
        for k in MEASURES {
            match (g[k].as_f64(), w[k].as_f64()) {
                (Some(a), Some(b)) => assert!(close(a, b), "{} {k}: dem-eval {a}, numpy {b}", w["terrain"]),
                (a, b) => assert_eq!((a, b), (None, None), "{} {k}", w["terrain"]),
            }
        }
    }
}

/// `--sim DIR/sim.npy --real DIR/real.npy --pairs DIR/pairs.csv` and `extra`.
fn eval_args(dir: &Path, extra: &[&str]) -> Vec<String> {
    let mut v = Vec::new();
    for (flag, file) in [("--sim", "sim.npy"), ("--real", "real.npy"), ("--pairs", "pairs.csv")] {
        v.extend([flag.to_string(), arg(dir, file)]);
    }
    v.extend(extra.iter().map(|s| s.to_string()));
    v
}

fn dem_eval(args: &[String]) -> std::process::Output {
    run("dem-eval", &args.iter().map(String::as_str).collect::<Vec<_>>(), None)
}

#[test]
fn random_and_edge_cases_match_numpy() {
    let dir = tempdir();
    // 60 sim records and predictions, 45 real records: random heights,
    // masks +-1 and masks in (-1, 1) in the predictions; records 0..3 of
    // each file are edge cases (all missing, all valid, masks in (-1, 1)).
    let want = py(
        dir.path(),
        &format!(
            r#"{NUMPY_EVAL}
rng = np.random.default_rng(7)
def dems(n, soft):
    d = np.zeros((n, 21, 5, 2), np.float32)
    d[:, :20, :, 0] = rng.normal(-0.07, 0.2, (n, 20, 5))
    d[:, :20, :, 1] = rng.uniform(-1, 1, (n, 20, 5)) if soft else np.where(rng.random((n, 20, 5)) < 0.8, 1, -1)
    d[:, 20, :, 0] = rng.normal(0, 0.3, (n, 5)); d[:, 20, :, 1] = 1
    d[0, :20, :, 1] = -1; d[0, :20, :, 0] = 0          # all missing
    d[1, :20, :, 1] = 1                                 # all valid
    d[2, :20, :, 1] = rng.uniform(-0.999, 0.999, (20, 5))  # masks in (-1, 1)
    return d
sim, pred, real = dems(60, False), dems(60, True), dems(45, False)
np.save("sim.npy", sim); np.save("pred.npy", pred); np.save("real.npy", real)
terr = ["flat", "stairs-up", "stairs-down", "pallet", "other"]
terrain = [terr[i] for i in rng.integers(0, 5, 60)]
with open("labels.csv", "w") as f:
    f.write("index,terrain\n" + "".join(f"{{i}},{{t}}\n" for i, t in enumerate(terrain)))
pairs = [(0, 0, "val"), (1, 1, "val"), (2, 2, "val"), (0, 1, "val"), (1, 0, "val"), (2, 1, "val")]
pairs += [(int(s), int(r), "val" if s % 3 else "train") for s, r in zip(rng.integers(3, 60, 150), rng.integers(0, 45, 150))]
with open("pairs.csv", "w") as f:
    f.write("sim_index,real_index,split\n" + "".join(f"{{s}},{{r}},{{sp}}\n" for s, r, sp in pairs))
out = {{}}
for name, p in [("pred", pred), ("identity", sim)]:
    recs, rows = evaluate(p, real, pairs, "val", terrain)
    out[name] = dict(records=recs, rows=rows)
out["all"] = evaluate(pred, real, pairs, None, None)[1]
print(json.dumps(out))
"#
        ),
    );
    let want: Value = serde_json::from_str(&want).unwrap();
    let d = dir.path();
    for (method, flag) in [("pred", vec!["--pred".to_string(), arg(d, "pred.npy")]), ("identity", vec!["--identity".into()])] {
        let rec = arg(d, &format!("{method}_records.csv"));
        let labels = arg(d, "labels.csv");
        let mut a =
            eval_args(d, &["--split", "val", "--sim-labels", &labels, "--by", "terrain", "--format", "json", "--emit-records", &rec]);
        a.extend(flag);
        let o = dem_eval(&a);
        let got: Value = serde_json::from_slice(ok(&o)).unwrap();
        check_rows(&got, &want[method]["rows"]);
        assert!(got.as_array().unwrap().iter().all(|r| r["method"] == method));
        // Per-record results: same best real record, same error, terrain.
        let text = std::fs::read_to_string(&rec).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert!(lines[0].starts_with("sim_index,real_index,error,terrain,height_cm,height_sum_m,height_n,"), "{}", lines[0]);
        let recs = want[method]["records"].as_array().unwrap();
        assert_eq!(lines.len() - 1, recs.len());
        for (line, w) in lines[1..].iter().zip(recs) {
            let f: Vec<&str> = line.split(',').collect();
            assert_eq!(f[0].parse::<u64>().unwrap(), w[0].as_u64().unwrap(), "{line}");
            assert_eq!(f[1].parse::<u64>().unwrap(), w[1].as_u64().unwrap(), "{line}");
            assert!(close(f[2].parse().unwrap(), w[2].as_f64().unwrap()), "{line} vs {w}");
            assert_eq!(f[3], w[3].as_str().unwrap());
            match w[4].as_f64() {
                Some(h) => assert!(close(f[4].parse().unwrap(), h), "{line} vs {w}"),
                None => assert_eq!(f[4], "", "{line}: no cell valid in both"),
            }
        }
        // Every row has a gap (dem-gap's, checked on the bundled data below).
        assert!(got.as_array().unwrap().iter().all(|r| r["gap"].as_f64().is_some_and(|g| g >= 0.0)), "{got}");
    }
    // Every pair (no --split), CSV output read back with dem-core.
    let out = arg(d, "t.csv");
    ok(&dem_eval(&eval_args(d, &["--pred", &arg(d, "pred.npy"), "--format", "csv", "-o", &out])));
    let rows = dem_eval::table::read_table_csv(&out).unwrap();
    check_rows(&serde_json::to_value(&rows).unwrap(), &want["all"]);
    assert_eq!(rows[0].method, "pred");
}

#[test]
fn worked_checks_of_the_spec() {
    let dir = tempdir();
    // Sim record i (the prediction, --identity) against real record i: the
    // three worked checks, each a DEM differing from y in one cell.
    py(
        dir.path(),
        r#"
import numpy as np
flat = np.zeros((21, 5, 2), np.float32); flat[:20, :, 0] = -0.07; flat[:20, :, 1] = 1; flat[20, :, 1] = 1
missing = flat.copy(); missing[:20, :, 0] = 0; missing[:20, :, 1] = -1
real = np.stack([flat, missing, flat])
sim = real.copy()
sim[0, 4, 2, 1] = 0.5     # mask 0.5 against 1
sim[1, 7, 1, 1] = 0.5     # mask 0.5 against -1
sim[2, 10, 3, 0] = -0.09  # valid height -0.09 against -0.07
np.save("sim.npy", sim); np.save("real.npy", real)
open("pairs.csv", "w").write("sim_index,real_index\n0,0\n1,1\n2,2\n")
"#,
    );
    let rec = arg(dir.path(), "r.csv");
    ok(&dem_eval(&eval_args(dir.path(), &["--identity", "--emit-records", &rec])));
    let rows: Vec<(u64, f64)> = std::fs::read_to_string(&rec)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f[0], f[1]);
            assert_eq!(f[3], "", "no labels, no terrain");
            (f[0].parse().unwrap(), f[2].parse().unwrap())
        })
        .collect();
    assert_eq!(rows.len(), 3);
    assert!((rows[0].1 - 0.0025).abs() < 1e-12, "{rows:?}");
    assert!((rows[1].1 - 0.0225).abs() < 1e-12, "{rows:?}");
    // (0.02)^2 / 100 up to the f32 rounding of -0.09 and -0.07.
    assert!((rows[2].1 - 0.000004).abs() < 1e-9, "{rows:?}");
}

#[test]
fn identity_on_the_bundled_true_pairs_by_terrain() {
    let dir = tempdir();
    let rec = arg(dir.path(), "r.csv");
    let o = run(
        "dem-eval",
        &[
            "--sim",
            &td("sim.npy"),
            "--real",
            &td("real.npy"),
            "--pairs",
            &td("pairs.csv"),
            "--identity",
            "--sim-labels",
            &td("sim_labels.csv"),
            "--by",
            "terrain",
            "--format",
            "json",
            "--emit-records",
            &rec,
            "--emit-input",
            &arg(dir.path(), "in.npy"),
            "--emit-pred",
            &arg(dir.path(), "pred.npy"),
            "--emit-closest",
            &arg(dir.path(), "closest.npy"),
        ],
        None,
    );
    let rows: Value = serde_json::from_slice(ok(&o)).unwrap();
    let rows = rows.as_array().unwrap();
    let terrains: Vec<&str> = rows.iter().map(|r| r["terrain"].as_str().unwrap()).collect();
    assert_eq!(terrains, ["all", "flat", "stairs-up", "stairs-down", "pallet", "other"]);
    assert_eq!(rows[0]["count"], 966);
    let n: u64 = rows[1..].iter().map(|r| r["count"].as_u64().unwrap()).sum();
    let weighted: f64 = rows[1..].iter().map(|r| r["count"].as_f64().unwrap() * r["mean"].as_f64().unwrap()).sum();
    assert_eq!(n, 966);
    assert!(close(weighted / 966.0, rows[0]["mean"].as_f64().unwrap()));
    // The records: the true pair (real i <-> sim i), its eq. 7.1 error, its terrain.
    let (sim, real) = (npy::read_all(&td("sim.npy")).unwrap(), npy::read_all(&td("real.npy")).unwrap());
    let labels = table::read_labels(&td("sim_labels.csv")).unwrap();
    let text = std::fs::read_to_string(&rec).unwrap();
    assert_eq!(text.lines().count(), 967);
    // --emit-*: the records behind each row, in row order, for dem-render.
    let emitted = ["in.npy", "pred.npy", "closest.npy"].map(|f| npy::read_all(&arg(dir.path(), f)).unwrap());
    for (n, line) in text.lines().skip(1).enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        let (s, r): (usize, usize) = (f[0].parse().unwrap(), f[1].parse().unwrap());
        assert_eq!(s, r);
        assert_eq!((emitted[0][n], emitted[1][n], emitted[2][n]), (sim[s], sim[s], real[r]));
        assert_eq!(f[2].parse::<f64>().unwrap(), dem_error(&real[r], &sim[s]));
        assert_eq!(f[3], labels[s].terrain.as_str());
    }
}

/// The new columns of Identity on the bundled data (true pairs, by terrain)
/// against numpy, and the gap against dem-gap's own measure of the same sets.
#[test]
fn identity_height_measures_on_the_bundled_data_match_numpy_and_dem_gap() {
    let dir = tempdir();
    let want = py(
        dir.path(),
        &format!(
            r#"{NUMPY_EVAL}
import csv
sim, real = np.load({sim:?}), np.load({real:?})
pairs = [(int(r["sim_index"]), int(r["real_index"]), None) for r in csv.DictReader(open({pairs:?}))]
terrain = [r["terrain"] for r in csv.DictReader(open({labels:?}))]
print(json.dumps(evaluate(sim, real, pairs, None, terrain)[1]))
"#,
            sim = td("sim.npy"),
            real = td("real.npy"),
            pairs = td("pairs.csv"),
            labels = td("sim_labels.csv")
        ),
    );
    let want: Value = serde_json::from_str(&want).unwrap();
    let o = run(
        "dem-eval",
        &[
            "--sim",
            &td("sim.npy"),
            "--real",
            &td("real.npy"),
            "--pairs",
            &td("pairs.csv"),
            "--identity",
            "--sim-labels",
            &td("sim_labels.csv"),
            "--by",
            "terrain",
            "--format",
            "json",
        ],
        None,
    );
    let got: Value = serde_json::from_slice(ok(&o)).unwrap();
    check_rows(&got, &want);
    let rows = got.as_array().unwrap();
    // Sim DEMs are smoother than measured ones, and close to them in height.
    let (h, across, real_across) = (
        rows[0]["height_cm"].as_f64().unwrap(),
        rows[0]["rough_across_cm"].as_f64().unwrap(),
        rows[0]["real_rough_across_cm"].as_f64().unwrap(),
    );
    assert!(h > 0.1 && h < 5.0 && across < real_across, "{}", rows[0]);
    // The gap: dem-gap's stats of the row's predictions (here the sim
    // records) against the unique real records paired with them.
    let (sim, real) = (npy::read_all(&td("sim.npy")).unwrap(), npy::read_all(&td("real.npy")).unwrap());
    let pairs = table::read_pairs(&td("pairs.csv")).unwrap();
    let labels = table::read_labels(&td("sim_labels.csv")).unwrap();
    for row in rows {
        let t = row["terrain"].as_str().unwrap();
        let in_row = |s: u64| t == "all" || labels[s as usize].terrain.as_str() == t;
        let sims: std::collections::BTreeSet<u64> = pairs.iter().map(|p| p.sim_index).filter(|&s| in_row(s)).collect();
        let reals: std::collections::BTreeSet<u64> = pairs.iter().filter(|p| in_row(p.sim_index)).map(|p| p.real_index).collect();
        let pred: Vec<_> = sims.iter().map(|&s| sim[s as usize]).collect();
        let real: Vec<_> = reals.iter().map(|&r| real[r as usize]).collect();
        let g = distribution::gap(&distribution::stats(&pred, None), &distribution::stats(&real, None));
        let got = row["gap"].as_f64().unwrap();
        assert!(close(got, g), "{t}: dem-eval gap {got}, dem-gap {g}");
    }
    // Text and Markdown show them: cm with two decimals, the gap with three.
    for fmt in ["text", "md"] {
        let o = run(
            "dem-eval",
            &["--sim", &td("sim.npy"), "--real", &td("real.npy"), "--pairs", &td("pairs.csv"), "--identity", "--format", fmt],
            None,
        );
        let out = String::from_utf8_lossy(ok(&o)).into_owned();
        for col in MEASURES.iter().chain(&["gap"]) {
            assert!(out.lines().next().unwrap().contains(col), "{fmt}: {out}");
        }
        assert!(out.contains(&format!(" {h:.2} ")) && out.contains(&format!(" {:.3}", rows[0]["gap"].as_f64().unwrap())), "{fmt}: {out}");
    }
}

/// With pairs that repeat records (dem-pair gives a sim key many measured
/// partners), the gap compares the two sides over the pairs: each pair's
/// prediction against its real partner, repeats and all, so the terrain
/// mixes agree; over the unique records they would not.
#[test]
fn the_gap_is_taken_over_the_pairs_when_records_repeat() {
    let dir = tempdir();
    let (sim, real) = (npy::read_all(&td("sim.npy")).unwrap(), npy::read_all(&td("real.npy")).unwrap());
    let labels = table::read_labels(&td("sim_labels.csv")).unwrap();
    // One flat sim stands for every flat measured record, stairs sims for
    // one each (their own poses).
    let real_labels = table::read_labels(&td("real_labels.csv")).unwrap();
    let flat = labels.iter().position(|l| l.terrain.as_str() == "flat").unwrap() as u64;
    let mut pairs: Vec<(u64, u64)> = real_labels.iter().filter(|l| l.terrain.as_str() == "flat").map(|l| (flat, l.index)).collect();
    pairs.extend(labels.iter().filter(|l| l.terrain.as_str() == "stairs-up" && l.index < 966).map(|l| (l.index, l.index)));
    pairs.sort_unstable();
    let path = arg(dir.path(), "pairs.csv");
    let text: String = pairs.iter().map(|(s, r)| format!("{s},{r}\n")).collect();
    std::fs::write(&path, format!("sim_index,real_index\n{text}")).unwrap();
    let o =
        run("dem-eval", &["--sim", &td("sim.npy"), "--real", &td("real.npy"), "--pairs", &path, "--identity", "--format", "json"], None);
    let got: Value = serde_json::from_slice(ok(&o)).unwrap();
    let got = got[0]["gap"].as_f64().unwrap();
    let gap = |p: Vec<Dem>, r: Vec<Dem>| distribution::gap(&distribution::stats(&p, None), &distribution::stats(&r, None));
    let over_pairs = gap(pairs.iter().map(|p| sim[p.0 as usize]).collect(), pairs.iter().map(|p| real[p.1 as usize]).collect());
    assert!(close(got, over_pairs), "dem-eval gap {got}, over the pairs {over_pairs}");
    let sims: std::collections::BTreeSet<u64> = pairs.iter().map(|p| p.0).collect();
    let reals: std::collections::BTreeSet<u64> = pairs.iter().map(|p| p.1).collect();
    let unique = gap(sims.iter().map(|&s| sim[s as usize]).collect(), reals.iter().map(|&r| real[r as usize]).collect());
    assert!(unique > over_pairs + 1.0, "one flat sim against every flat real is a mix gap: unique {unique}, pairs {over_pairs}");
}

#[test]
fn model_runs_on_the_selected_records_like_its_numpy_output() {
    let dir = tempdir();
    // A model that halves every value (onnx helper), and numpy's halving as
    // a prediction file: the two tables must agree.
    py(
        dir.path(),
        &format!(
            r#"
import numpy as np, onnx
from onnx import helper, TensorProto
sim = np.load({sim:?})
np.save("half.npy", sim * np.float32(0.5))
x = helper.make_tensor_value_info("dem", TensorProto.FLOAT, ["N", 21, 5, 2])
y = helper.make_tensor_value_info("dem_out", TensorProto.FLOAT, ["N", 21, 5, 2])
k = helper.make_tensor("k", TensorProto.FLOAT, [], [0.5])
g = helper.make_graph([helper.make_node("Mul", ["dem", "k"], ["dem_out"])], "half", [x], [y], [k])
m = helper.make_model(g, opset_imports=[helper.make_opsetid("", 13)])
onnx.checker.check_model(m)
onnx.save(m, "half.onnx")
"#,
            sim = td("sim.npy")
        ),
    );
    let d = dir.path();
    let base = ["--sim", &td("sim.npy"), "--real", &td("real.npy"), "--pairs", &td("pairs.csv"), "--format", "csv"];
    let m = arg(d, "half.onnx");
    let p = arg(d, "half.npy");
    let a = run("dem-eval", &[&base[..], &["--model", &m, "--batch", "100"]].concat(), None);
    let b = run("dem-eval", &[&base[..], &["--pred", &p]].concat(), None);
    assert_eq!(String::from_utf8_lossy(ok(&a)), String::from_utf8_lossy(ok(&b)));
    assert!(String::from_utf8_lossy(&a.stdout).contains("\nhalf,all,966,"));
    // Not a model: exit 2 naming the file.
    let o = run("dem-eval", &[&base[..], &["--model", &p]].concat(), None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("half.npy"));
}

fn table_csv(dir: &Path, name: &str, rows: &[(&str, &str, f64, f64)]) -> String {
    let path = arg(dir, name);
    let mut text = String::from("method,terrain,count,lowest,highest,mean,median\n");
    for (m, t, mean, median) in rows {
        text += &format!("{m},{t},56,0.005,2.6,{mean},{median}\n");
    }
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn compare_fails_on_a_worse_table_and_passes_on_an_equal_one() {
    let dir = tempdir();
    let d = dir.path();
    let base = table_csv(d, "base.csv", &[("identity", "all", 0.548, 0.130), ("paired", "all", 0.334, 0.258)]);
    let same = table_csv(d, "same.csv", &[("paired", "all", 0.334, 0.258), ("identity", "all", 0.548, 0.130)]);
    let within = table_csv(d, "within.csv", &[("identity", "all", 0.560, 0.140), ("paired", "all", 0.300, 0.258)]);
    let worse_mean = table_csv(d, "wm.csv", &[("identity", "all", 0.548, 0.130), ("paired", "all", 0.364, 0.258)]);
    let worse_median = table_csv(d, "wd.csv", &[("identity", "all", 0.548, 0.160), ("paired", "all", 0.334, 0.258)]);
    let missing = table_csv(d, "miss.csv", &[("identity", "all", 0.548, 0.130)]);
    let cmp = |a: &str, b: &str, extra: &[&str]| run("dem-eval", &[&["compare", a, b][..], extra].concat(), None);

    let o = cmp(&base, &same, &[]);
    let out = String::from_utf8_lossy(ok(&o)).into_owned();
    assert!(out.contains("baseline") && out.contains("current") && out.contains("diff"), "{out}");
    ok(&cmp(&base, &within, &[]));
    for (worse, what) in [(&worse_mean, "paired/all worse"), (&worse_median, "identity/all worse"), (&missing, "paired/all missing")] {
        let o = cmp(&base, worse, &[]);
        assert_eq!(o.status.code(), Some(1), "{worse}: {}", stderr(&o));
        assert!(stderr(&o).contains(what), "{}", stderr(&o));
        assert_eq!(stderr(&o).lines().count(), 1, "{}", stderr(&o));
        assert!(String::from_utf8_lossy(&o.stdout).contains("WORSE") || what.ends_with("missing"));
    }
    // The tolerance is absolute: +0.03 passes at 0.05.
    ok(&cmp(&base, &worse_mean, &["--tolerance", "0.05"]));
    // Machine-readable comparison.
    let o = cmp(&base, &worse_mean, &["--format", "json"]);
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v[1]["status"], "worse");
    assert!(close(v[1]["diff_mean"].as_f64().unwrap(), 0.03));
}

#[test]
fn compare_fails_when_a_height_measure_grows_and_names_it() {
    let dir = tempdir();
    let d = dir.path();
    // The columns before the frame columns (a table of an older dem-eval).
    let head = dem_eval::table::TABLE_HEADER[..13].join(",");
    // Real roughness 0.33 across, 0.45 along; the model's 0.08 and 0.5.
    let write = |name: &str, height: f64, across: f64, gap: f64| {
        let path = arg(d, name);
        std::fs::write(&path, format!("{head}\nm,all,56,0.005,2.6,0.3,0.2,{height},{across},0.5,0.33,0.45,{gap}\n")).unwrap();
        path
    };
    let gap_tol = dem_eval::table::DEFAULT_GAP_TOLERANCE;
    let base = write("base.csv", 1.5, 0.08, 3.0);
    let cmp = |cur: &str, extra: &[&str]| run("dem-eval", &[&["compare", &base, cur][..], extra].concat(), None);
    // Better or within: height +0.4 cm, roughness closer to the real one, gap equal.
    ok(&cmp(&write("within.csv", 1.9, 0.3, 3.0), &[]));
    for (name, cur, what) in [
        ("height.csv", write("height.csv", 2.1, 0.08, 3.0), "m/all worse (height_cm +0.6"),
        // |1.2 - 0.33| = 0.87 against |0.08 - 0.33| = 0.25: +0.62.
        ("rough.csv", write("rough.csv", 1.5, 1.2, 3.0), "m/all worse (rough_across +0.62"),
        ("gap.csv", write("gap.csv", 1.5, 0.08, 3.0 + gap_tol + 0.01), "m/all worse (gap +"),
    ] {
        let o = cmp(&cur, &[]);
        assert_eq!(o.status.code(), Some(1), "{name}: {}", stderr(&o));
        assert!(stderr(&o).contains(what), "{name}: {}", stderr(&o));
        assert_eq!(stderr(&o).lines().count(), 1, "{}", stderr(&o));
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        let measure = what.split(['(', ' ']).nth(3).unwrap();
        let line = out.lines().nth(2).unwrap();
        assert!(line.contains(" WORSE ") && line.ends_with(&format!(" {measure}")), "{name}: {out}");
    }
    ok(&cmp(&write("h2.csv", 2.1, 0.08, 3.0), &["--height-tolerance", "1"]));
    // |0.98 - 0.33| = 0.65: +0.4 passes at 0.5, not at 0.3.
    ok(&cmp(&write("r2.csv", 1.5, 0.98, 3.0), &[]));
    let o = cmp(&write("r3.csv", 1.5, 0.98, 3.0), &["--rough-tolerance", "0.3"]);
    assert!(stderr(&o).contains("rough_across +0.4000 > 0.3"), "{}", stderr(&o));
    // Everything at once, named together; JSON carries the diffs and the measures.
    let all = write("all.csv", 9.0, 9.0, 99.0);
    let o = cmp(&all, &["--format", "json"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("(height_cm +7.5000 > 0.5, rough_across +8.4200 > 0.5, gap +96.0000 > "), "{}", stderr(&o));
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v[0]["worse"], serde_json::json!(["height_cm", "rough_across", "gap"]));
    assert!(close(v[0]["diff_height_cm"].as_f64().unwrap(), 7.5) && close(v[0]["diff_gap"].as_f64().unwrap(), 96.0));
    assert_eq!(v[0]["current"]["real_rough_along_cm"], 0.45);
    // CSV and Markdown show them too.
    let o = cmp(&all, &["--format", "csv"]);
    let csv = String::from_utf8_lossy(&o.stdout).into_owned();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    for col in ["baseline_height_cm", "current_gap", "diff_height_cm", "diff_rough_across", "diff_rough_along", "diff_gap", "worse"] {
        assert!(header.contains(&col), "{col}: {csv}");
    }
    assert!(csv.lines().nth(1).unwrap().ends_with(",worse,height_cm;rough_across;gap"), "{csv}");
    let o = cmp(&all, &["--format", "md"]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("| diff height_cm |"));
    // A baseline of the old seven columns checks mean and median only; a
    // current table without the measures fails against one that has them.
    let old = table_csv(d, "old.csv", &[("m", "all", 0.3, 0.2)]);
    ok(&run("dem-eval", &["compare", &old, &all], None));
    let o = run("dem-eval", &["compare", &base, &old], None);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("height_cm absent"), "{}", stderr(&o));
    let o = run("dem-eval", &["compare", &base, &base, "--gap-tolerance=-1"], None);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--gap-tolerance"));
}

/// A row whose frames move unlike the real records' by more than before
/// fails, naming the frame measure; a baseline without them checks none.
#[test]
fn compare_fails_when_frames_move_unlike_the_real_ones() {
    let dir = tempdir();
    let d = dir.path();
    let head = dem_eval::table::TABLE_HEADER.join(",");
    // The real records: 5.1 mm per frame, correlation 0.7, 1.4 % flips, 0.92 persistence.
    let write = |name: &str, dh: f64, rcorr: f64, flip: f64| {
        let path = arg(d, name);
        std::fs::write(
            &path,
            format!("{head}\nm,all,56,0.005,2.6,0.3,0.2,1.5,0.08,0.5,0.33,0.45,3.0,{dh},{rcorr},{flip},0.93,5.1,0.7,0.014,0.92\n"),
        )
        .unwrap();
        path
    };
    let base = write("base.csv", 6.0, 0.6, 0.02);
    ok(&run("dem-eval", &["compare", &base, &write("within.csv", 5.5, 0.68, 0.05)], None));
    for (cur, what) in [
        (write("dh.csv", 17.3, 0.6, 0.02), "m/all worse (frame_dh +11.3000 > 1)"),
        (write("rcorr.csv", 6.0, 0.02, 0.02), "m/all worse (frame_rcorr +0.5800 > 0.05)"),
        (write("flip.csv", 6.0, 0.6, 0.1), "m/all worse (frame_flip +0.0800 > 0.05)"),
    ] {
        let o = run("dem-eval", &["compare", &base, &cur], None);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains(what), "{what}: {}", stderr(&o));
    }
    ok(&run("dem-eval", &["compare", &base, &write("dh2.csv", 7.0, 0.6, 0.02), "--frame-dh-tolerance", "2"], None));
    let older = arg(d, "older.csv");
    let text = std::fs::read_to_string(&base).unwrap();
    let cut: String = text.lines().map(|l| l.split(',').take(13).collect::<Vec<_>>().join(",") + "\n").collect();
    std::fs::write(&older, cut).unwrap();
    ok(&run("dem-eval", &["compare", &older, &write("dh3.csv", 17.3, 0.0, 0.5)], None));
}

#[test]
fn compare_reads_json_and_joined_csv_tables_and_refuses_bad_ones() {
    let dir = tempdir();
    let d = dir.path();
    let run_eval = |fmt: &str, name: &str| {
        let o = run(
            "dem-eval",
            &[
                "--sim",
                &td("sim.npy"),
                "--real",
                &td("real.npy"),
                "--pairs",
                &td("pairs.csv"),
                "--identity",
                "--name",
                name,
                "--format",
                fmt,
            ],
            None,
        );
        ok(&o).to_vec()
    };
    let json = arg(d, "t.json");
    std::fs::write(&json, [run_eval("json", "a"), run_eval("json", "b")].concat()).unwrap();
    let csv = arg(d, "t.csv");
    std::fs::write(&csv, [run_eval("csv", "a"), run_eval("csv", "b")].concat()).unwrap();
    let o = run("dem-eval", &["compare", &json, &csv, "--tolerance", "0"], None);
    let out = String::from_utf8_lossy(ok(&o)).into_owned();
    assert_eq!(out.lines().filter(|l| l.ends_with(" ok")).count(), 2, "{out}");

    for (name, text) in [
        ("garbage.csv", "hello\n"),
        ("badnum.csv", "method,terrain,count,lowest,highest,mean,median\na,all,3,0,1,zero,0\n"),
        ("dup.csv", "method,terrain,count,lowest,highest,mean,median\na,all,3,0,1,0,0\na,all,3,0,1,0,0\n"),
        ("empty.csv", ""),
        ("bad.json", "[{\"method\": \"a\"}]"),
    ] {
        let p = arg(d, name);
        std::fs::write(&p, text).unwrap();
        for args in [["compare", &csv, &p], ["compare", &p, &csv]] {
            let o = run("dem-eval", &args, None);
            assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
            assert!(stderr(&o).contains(name), "{}", stderr(&o));
        }
    }
    let o = run("dem-eval", &["compare", &csv, &arg(d, "nope.csv")], None);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn join_writes_one_table_in_every_form_and_pivots_by_terrain() {
    let dir = tempdir();
    let d = dir.path();
    let a = table_csv(d, "a.csv", &[("identity", "all", 0.548, 0.130), ("identity", "pallet", 0.25, 0.06)]);
    let b = table_csv(d, "b.csv", &[("paired", "all", 0.334, 0.258), ("paired", "stairs-up", 0.17, 0.05)]);
    let join = |extra: &[&str]| run("dem-eval", &[&["join", &a, &b][..], extra].concat(), None);

    // CSV: one header, the rows in order, every digit; it reads back as a table.
    let csv = String::from_utf8_lossy(ok(&join(&[]))).into_owned();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 5, "{csv}");
    assert!(lines[0].starts_with("method,terrain,count") && lines[1..].iter().all(|l| !l.starts_with("method")), "{csv}");
    assert!(lines[1].starts_with("identity,all,56,0.005,2.6,0.548,0.13,"), "{csv}");
    assert!(lines[4].starts_with("paired,stairs-up,"), "{csv}");
    let joined = arg(d, "joined.csv");
    ok(&join(&["-o", &joined]));
    ok(&run("dem-eval", &["compare", &joined, &joined], None));

    // JSON round trip, Markdown, one terrain.
    let json: Value = serde_json::from_slice(ok(&join(&["--format", "json"]))).unwrap();
    assert_eq!(json.as_array().unwrap().len(), 4);
    assert_eq!((json[2]["method"].as_str(), json[2]["mean"].as_f64()), (Some("paired"), Some(0.334)));
    let md = String::from_utf8_lossy(ok(&join(&["--format", "md", "--terrain", "all"]))).into_owned();
    assert_eq!(md.lines().count(), 4, "{md}");
    assert!(md.contains("| identity | all | 56 | 0.0050 | 2.6000 | 0.5480 | 0.1300 |"), "{md}");

    // A pivot: methods by terrain, a missing row shown as `-` (empty in CSV).
    let md = String::from_utf8_lossy(ok(&join(&["--pivot", "mean,median", "--format", "md"]))).into_owned();
    let rows: Vec<&str> = md.lines().collect();
    assert_eq!(rows[0], "| method | all count | all mean | all median | pallet count | pallet mean | pallet median | stairs-up count | stairs-up mean | stairs-up median |");
    assert_eq!(rows[2], "| identity | 56 | 0.5480 | 0.1300 | 56 | 0.2500 | 0.0600 | - | - | - |");
    assert_eq!(rows[3], "| paired | 56 | 0.3340 | 0.2580 | - | - | - | 56 | 0.1700 | 0.0500 |");
    let csv = String::from_utf8_lossy(ok(&join(&["--pivot", "mean"]))).into_owned();
    assert_eq!(csv.lines().nth(2), Some("paired,56,0.334,,,56,0.17"), "{csv}");

    // A row twice, an unknown measure or terrain: exit 2, one line.
    let o = run("dem-eval", &["join", &a, &a], None);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("identity/all appears twice") && stderr(&o).lines().count() == 1, "{}", stderr(&o));
    for (flag, value, says) in [("--pivot", "speed", "no measure \"speed\""), ("--terrain", "moon", "no row of that terrain")] {
        let o = join(&[flag, value]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains(says) && stderr(&o).lines().count() == 1, "{}", stderr(&o));
    }
}

#[test]
fn bad_inputs_exit_2_with_one_clear_line() {
    let dir = tempdir();
    let d = dir.path();
    std::fs::write(arg(d, "past_sim.csv"), "sim_index,real_index\n0,0\n3025,1\n").unwrap();
    std::fs::write(arg(d, "past_real.csv"), "sim_index,real_index\n0,0\n5,966\n").unwrap();
    py(d, &format!("import numpy as np; np.save('short.npy', np.load({:?})[:100])", td("sim.npy")));
    let base = |pairs: &str| -> Vec<String> {
        ["--sim", &td("sim.npy"), "--real", &td("real.npy"), "--pairs", pairs].iter().map(|s| s.to_string()).collect()
    };
    let cases: Vec<(Vec<String>, &str)> = vec![
        ([base(&arg(d, "past_sim.csv")), vec!["--identity".into()]].concat(), "line 3: sim_index 3025 is past the end"),
        ([base(&arg(d, "past_real.csv")), vec!["--identity".into()]].concat(), "line 3: real_index 966 is past the end"),
        ([base(&td("pairs.csv")), vec!["--pred".into(), arg(d, "short.npy")]].concat(), "has 100 records but"),
        (base(&td("pairs.csv")), "choose what to evaluate"),
        ([base(&td("pairs.csv")), vec!["--identity".into(), "--by".into(), "terrain".into()]].concat(), "--by terrain needs --sim-labels"),
        ([base(&td("pairs.csv")), vec!["--identity".into(), "--split".into(), "val".into()]].concat(), "no split column"),
        ([base(&td("pairs.csv")), vec!["--identity".into(), "--sim-labels".into(), td("real_labels.csv")]].concat(), "has 966 rows but"),
        (vec!["--real".into(), td("real.npy"), "--pairs".into(), td("pairs.csv"), "--identity".into()], "--sim is required"),
        ([base(&arg(d, "nope.csv")), vec!["--identity".into()]].concat(), "failed to open"),
    ];
    for (args, want) in cases {
        let o = dem_eval(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(o.stdout.is_empty());
    }
}

#[test]
fn the_table_goes_to_a_file_atomically_and_stdout_may_close_early() {
    let dir = tempdir();
    let out = arg(dir.path(), "t.md");
    let a = ["--sim", &td("sim.npy"), "--real", &td("real.npy"), "--pairs", &td("pairs.csv"), "--identity", "--format", "md"];
    let o = run("dem-eval", &[&a[..], &["-o", &out]].concat(), None);
    assert!(ok(&o).is_empty());
    assert!(std::fs::read_to_string(&out).unwrap().starts_with("| method | terrain |"));
    // `| head -c 0`: a closed stdout is not an error.
    let mut cmd = std::process::Command::new(dem_testkit::bin("dem-eval"));
    cmd.args(a).stdout(std::process::Stdio::piped()).stderr(std::process::Stdio::piped());
    let mut child = cmd.spawn().unwrap();
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // Per-record results on stdout, closed after a few bytes (`| head`).
    let mut cmd = std::process::Command::new(dem_testkit::bin("dem-eval"));
    cmd.args(a).args(["--emit-records", "-", "-o", &out]).stdout(std::process::Stdio::piped()).stderr(std::process::Stdio::piped());
    let mut child = cmd.spawn().unwrap();
    let mut first = [0u8; 10];
    std::io::Read::read_exact(child.stdout.as_mut().unwrap(), &mut first).unwrap();
    assert_eq!(&first, b"sim_index,");
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(o.stderr.is_empty(), "{}", stderr(&o));
    // Two outputs on stdout: refused.
    let o = run("dem-eval", &[&a[..], &["--emit-records", "-"]].concat(), None);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("only one output can be `-`"));
}

/// A records file of three sims, as `dem-eval --emit-records` writes it.
fn records_csv(d: &Path) -> String {
    let pairs = arg(d, "three.csv");
    std::fs::write(&pairs, "sim_index,real_index\n0,0\n1,1\n2,2\n").unwrap();
    let rec = arg(d, "r.csv");
    ok(&run(
        "dem-eval",
        &["--sim", &td("sim.npy"), "--real", &td("real.npy"), "--pairs", &pairs, "--identity", "--emit-records", &rec, "-o", "/dev/null"],
        None,
    ));
    rec
}

/// `dem-eval merge` refuses a records value no evaluation writes (NaN, an
/// infinity, a negative or out-of-range number, more differences than a
/// record has cells, a sum of none) with one line naming the file, the
/// line and the column, exit 2, nothing written.
#[test]
fn merge_refuses_values_no_evaluation_writes_naming_line_and_column() {
    let dir = tempdir();
    let d = dir.path();
    let text = std::fs::read_to_string(records_csv(d)).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let header: Vec<&str> = lines[0].split(',').collect();
    let table = arg(d, "t.csv");
    ok(&run("dem-eval", &["merge", &arg(d, "r.csv"), "--name", "m", "-o", &table], None));
    std::fs::remove_file(&table).unwrap();
    let cases: [(&str, &str, &[usize]); 11] = [
        ("error", "NaN", &[2]),
        ("error", "inf", &[2]),
        ("error", "-1", &[2]),
        ("error", "1e400", &[2]),
        ("height_sum_m", "NaN", &[2]),
        ("height_sum_m", "inf", &[2]),
        ("rough_across_sum_m", "-0.5", &[2]),
        ("real_rough_along_sum_m", "1e300", &[2]),
        ("height_n", "18446744073709551615", &[2, 3]),
        ("rough_along_n", "96", &[2]),
        ("height_n", "0", &[2]),
    ];
    for (column, value, rows) in cases {
        let mut bad: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
        for &r in rows {
            let mut f: Vec<&str> = lines[r].split(',').collect();
            f[header.iter().position(|h| *h == column).unwrap()] = value;
            bad[r] = f.join(",");
        }
        let path = arg(d, "bad.csv");
        std::fs::write(&path, bad.join("\n") + "\n").unwrap();
        let o = run("dem-eval", &["merge", &path, "--name", "m", "-o", &table], None);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{column} = {value}: {e}");
        let column = if value == "0" { "height_sum_m" } else { column };
        assert!(e.contains(&format!("bad.csv: line 3: column {column}: ")) && e.lines().count() == 1, "{column} = {value}: {e}");
        assert!(!Path::new(&table).exists());
    }
}

/// `join` and `compare` refuse an infinite pair error in a table, naming the
/// file, the line and the column (the row, on stdin); what dem-eval writes,
/// in CSV and JSON, they read back.
#[test]
fn join_and_compare_refuse_an_infinite_error_naming_line_and_column() {
    let dir = tempdir();
    let d = dir.path();
    let good = table_csv(d, "good.csv", &[("a", "all", 0.3, 0.2), ("a", "flat", 0.4, 0.3)]);
    let inf = table_csv(d, "inf.csv", &[("a", "all", 0.3, 0.2), ("a", "flat", f64::INFINITY, 0.3)]);
    let o = run("dem-eval", &["join", &inf, "--format", "json"], None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("inf.csv: line 3: column mean: inf is not a finite number"), "{}", stderr(&o));
    assert!(o.stdout.is_empty());
    let o = run("dem-eval", &["join", "-"], Some(std::fs::read(&inf).unwrap()));
    assert!(o.status.code() == Some(2) && stderr(&o).contains("-: column mean: inf is not a finite number (row a/flat)"), "{}", stderr(&o));
    let o = run("dem-eval", &["compare", &good, &inf], None);
    assert!(o.status.code() == Some(2) && stderr(&o).contains("inf.csv: line 3: column mean"), "{}", stderr(&o));
    // What join writes, join reads: CSV to JSON and back.
    let json = arg(d, "t.json");
    ok(&run("dem-eval", &["join", &good, "--format", "json", "-o", &json], None));
    let (back, direct) = (run("dem-eval", &["join", &json], None), run("dem-eval", &["join", &good], None));
    assert_eq!(String::from_utf8_lossy(ok(&back)), String::from_utf8_lossy(ok(&direct)));
}

/// Records as far apart as two DEMs of the contract can be (heights at
/// +-f32::MAX, every neighbour apart): evaluate's records, merged, in CSV
/// and JSON, are read back by join, and two files of them add up.
#[test]
fn the_contract_s_extremes_are_written_and_read_back() {
    use dem_core::format::{empty_dem, DemCells};
    let dir = tempdir();
    let d = dir.path();
    let dem = |sign: f32| -> Vec<Dem> {
        (0..6)
            .map(|i| {
                let mut x = empty_dem();
                for r in 0..20 {
                    for c in 0..5 {
                        x.set_valid(r, c, if (r + c + i) % 2 == 0 { sign * f32::MAX } else { -sign * f32::MAX });
                    }
                }
                x
            })
            .collect()
    };
    let (sim, real, pairs) = (arg(d, "xs.npy"), arg(d, "xr.npy"), arg(d, "xp.csv"));
    npy::write_all(&sim, &dem(1.0)).unwrap();
    npy::write_all(&real, &dem(-1.0)).unwrap();
    std::fs::write(&pairs, "sim_index,real_index\n0,0\n1,1\n2,2\n3,3\n4,4\n5,5\n").unwrap();
    let (rec, pred) = (arg(d, "r.csv"), arg(d, "p.npy"));
    ok(&run(
        "dem-eval",
        &["--sim", &sim, "--real", &real, "--pairs", &pairs, "--identity", "--emit-records", &rec, "--emit-pred", &pred, "-o", "/dev/null"],
        None,
    ));
    let half = |name: &str, rows: std::ops::Range<usize>| {
        let text = std::fs::read_to_string(&rec).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        let p = arg(d, name);
        std::fs::write(&p, [&lines[..1], &lines[rows]].concat().join("\n") + "\n").unwrap();
        p
    };
    let (a, b) = (half("a.csv", 1..4), half("b.csv", 4..7));
    let csv = arg(d, "m.csv");
    ok(&run("dem-eval", &["merge", &a, &b, "--name", "m", "--format", "csv", "-o", &csv], None));
    let json = arg(d, "m.json");
    let o = run(
        "dem-eval",
        &["merge", &a, &b, "--name", "g", "--format", "json", "-o", &json, "--emitted-pred", &pred, "--real", &real, "--pairs", &pairs],
        None,
    );
    ok(&o);
    let joined = String::from_utf8(ok(&run("dem-eval", &["join", &csv, &json, "--format", "csv"], None)).to_vec()).unwrap();
    assert_eq!(joined.lines().count(), 3, "{joined}");
    assert!(joined.lines().nth(1).unwrap().starts_with("m,all,6,"), "{joined}");
}

/// The frame columns against the numpy reference of the four statistics
/// (`scripts/peers/temporal.py`, its `runs` and `stats`): the predictions'
/// over the sim runs (a prediction drawing noise and holes afresh every
/// record, every sim record scored), and the real records' over the real
/// runs with their true sim partners as the reference; over all records and
/// over stairs up (the steps whose later frame is of that terrain).
#[test]
fn frame_columns_match_the_numpy_reference() {
    let dir = tempdir();
    let sensor = arg(dir.path(), "sensor.json");
    std::fs::write(
        &sensor,
        r#"{"effects": [{"effect": "noise", "params": {"sigma0": 0.01, "k": 0.02}}, {"effect": "dropout", "params": {"p": 0.2}}]}"#,
    )
    .unwrap();
    let pred = arg(dir.path(), "pred.npy");
    ok(&run("dem-sensor", &["apply", "--sensor", &sensor, "--seed", "3", &td("sim.npy"), "-o", &pred], None));
    let every_sim = arg(dir.path(), "every_sim.csv");
    let n_sim = npy::read_all(&td("sim.npy")).unwrap().len();
    let body: String = (0..n_sim).map(|i| format!("{i},{}\n", i % 966)).collect();
    std::fs::write(&every_sim, format!("sim_index,real_index\n{body}")).unwrap();
    let (sim, real, sim_labels, pairs, real_labels) =
        (td("sim.npy"), td("real.npy"), td("sim_labels.csv"), td("pairs.csv"), td("real_labels.csv"));
    let table = |args: &[&str]| -> Value {
        let mut a = vec!["--sim", &sim, "--real", &real];
        a.extend_from_slice(args);
        a.extend_from_slice(&["--sim-labels", &sim_labels, "--by", "terrain", "--format", "json"]);
        let out = ok(&run("dem-eval", &a, None)).to_vec();
        serde_json::from_slice(&out).unwrap()
    };
    let pred_rows = table(&["--pairs", &every_sim, "--pred", &pred]);
    let real_rows = table(&["--pairs", &pairs, "--identity", "--real-labels", &real_labels]);
    let peers = testkit_peers();
    let want: Value = serde_json::from_str(&py(
        dir.path(),
        &format!(
            r#"
import csv, json, sys
import numpy as np
sys.path.insert(0, "{peers}")
import temporal
def of(labels, x, ref):
    steps = temporal.runs(labels)
    terrain = [r["terrain"] for r in csv.DictReader(open(labels))]
    up = steps[[terrain[b] == "stairs-up" for b in steps[:, 1]]]
    return [temporal.stats(x, ref, steps), temporal.stats(x, ref, up)]
sim, real = np.load("{sim}"), np.load("{real}")
partner = {{int(r["real_index"]): int(r["sim_index"]) for r in csv.DictReader(open("{pairs}"))}}
sim_at_real = sim[[partner[j] for j in range(len(real))]]
print(json.dumps({{"pred": of("{sim_labels}", np.load("{pred}"), sim), "real": of("{real_labels}", real, sim_at_real)}}))
"#,
            sim = td("sim.npy"),
            real = td("real.npy"),
            pairs = td("pairs.csv"),
            sim_labels = td("sim_labels.csv"),
            real_labels = td("real_labels.csv"),
        ),
    ))
    .unwrap();
    for (side, rows, prefix) in [("pred", &pred_rows, "frame"), ("real", &real_rows, "real_frame")] {
        for (k, terrain) in ["all", "stairs-up"].into_iter().enumerate() {
            let row = rows.as_array().unwrap().iter().find(|r| r["terrain"] == terrain).unwrap();
            let w = &want[side][k];
            let got =
                |m: &str| row[format!("{prefix}_{m}")].as_f64().unwrap_or_else(|| panic!("{side} {terrain}: no {prefix}_{m} in {row}"));
            // numpy takes the differences and the mean change in float32.
            let near = |a: f64, b: f64, tol: f64, what: &str| {
                assert!((a - b).abs() <= tol * b.abs().max(1.0), "{side} {terrain} {what}: {a} vs numpy {b}")
            };
            near(got("dh_mm"), 1000.0 * w["dh"].as_f64().unwrap(), 1e-6, "dh_mm");
            near(got("flip"), w["flip"].as_f64().unwrap(), 1e-12, "flip");
            near(got("persist"), w["persist"].as_f64().unwrap(), 1e-12, "persist");
            near(got("rcorr"), w["rcorr"].as_f64().unwrap(), 1e-6, "rcorr");
        }
    }
    // Fresh noise and holes every record: the error forgets, the holes move.
    let all = |rows: &Value, m: &str| rows[0][m].as_f64().unwrap();
    assert!(all(&pred_rows, "frame_rcorr").abs() < 0.1 && all(&real_rows, "real_frame_rcorr") > 0.3, "{pred_rows} {real_rows}");
    assert!(all(&pred_rows, "frame_flip") > all(&real_rows, "real_frame_flip"));
}

/// Labels without poses: the frame columns are left out with one line
/// saying why, the rest of the table as before.
#[test]
fn frame_columns_without_poses_are_left_out_saying_why() {
    let dir = tempdir();
    let labels = arg(dir.path(), "labels.csv");
    let text = std::fs::read_to_string(td("sim_labels.csv")).unwrap();
    let cut: String = text
        .lines()
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            format!("{},{},{},{}\n", f[0], f[1], f[5], f[6])
        })
        .collect();
    std::fs::write(&labels, cut).unwrap();
    let o = run(
        "dem-eval",
        &[
            "--sim",
            &td("sim.npy"),
            "--real",
            &td("real.npy"),
            "--pairs",
            &td("pairs.csv"),
            "--identity",
            "--sim-labels",
            &labels,
            "--format",
            "csv",
        ],
        None,
    );
    let table = String::from_utf8(ok(&o).to_vec()).unwrap();
    let err = stderr(&o);
    assert!(err.contains("frame columns of") && err.contains("left out: the labels give no pose (`x`, `y`, `yaw`)"), "{err}");
    let row = table.lines().nth(1).unwrap();
    assert!(row.ends_with(",,,,,,,,"), "no frame columns: {row}");
}

/// `scripts/peers`, where the numpy references live.
fn testkit_peers() -> String {
    dem_testkit::workspace_root().join("scripts/peers").to_string_lossy().into_owned()
}
