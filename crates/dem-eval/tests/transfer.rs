//! `dem-eval transfer` as users run it, against a numpy implementation of the
//! same ridge fits (np.linalg.solve), on testdata split by run.

use dem_testkit::{arg, ok, py, run, stderr, tempdir, testdata};
use serde_json::Value;

fn td(name: &str) -> String {
    testdata(name).to_string_lossy().into_owned()
}

/// Splits testdata by run (measured runs 10..19 are the test set) and writes
/// the expected table of the transfer test in numpy.
const NUMPY: &str = r#"
import csv, json, numpy as np
TERR = ["flat", "stairs-up", "stairs-down", "pallet", "other"]
def labels(p): return list(csv.DictReader(open(p)))
def subset(npy, lab, keep, name):
    d = np.load(npy); l = labels(lab); idx = [i for i, r in enumerate(l) if keep(int(r["sequence"]))]
    np.save(name + ".npy", d[idx])
    with open(name + "_labels.csv", "w") as f:
        f.write("index,terrain,x,y,yaw,sequence,time\n")
        for k, i in enumerate(idx):
            r = l[i]; f.write(",".join([str(k), r["terrain"], r["x"], r["y"], r["yaw"], r["sequence"], r["time"]]) + "\n")
    return d[idx], [TERR.index(l[i]["terrain"]) for i in idx]
sim, st = subset(SIM, SIML, lambda s: s < 10 or s >= 20, "sim")
real, rt = subset(REAL, REALL, lambda s: s < 10, "real")
test, tt = subset(REAL, REALL, lambda s: s >= 10, "test")
# A middle set: sim with the measured DEMs' rear rows blanked half the time.
mid = sim.copy(); mid[::2, :6, :, 0] = 0; mid[::2, :6, :, 1] = -1
np.save("mid.npy", mid)
def feats(d):
    v = (d[:, :20, :, 1] > 0).reshape(len(d), 100).astype(np.float64)
    h = np.where(v > 0, d[:, :20, :, 0].reshape(len(d), 100).astype(np.float64), 0.0)
    return np.concatenate([h, v], 1)
def fit(x, y, lam):
    mu = x.mean(0); sd = np.sqrt(((x - mu) ** 2).mean(0)); sd[sd ** 2 <= 1e-12] = 1.0
    z = np.concatenate([(x - mu) / sd, np.ones((len(x), 1))], 1)
    a = z.T @ z; n = len(x)
    a[np.arange(200), np.arange(200)] += lam * n; a[200, 200] += 1e-9 * n
    w = np.linalg.solve(a, z.T @ y)
    return lambda q: np.concatenate([(q - mu) / sd, np.ones((len(q), 1))], 1) @ w
xt = feats(test); yt = test[:, 20, 1:5, 0].astype(np.float64)
out = {}
for name, d, t in [("sim", sim, st), ("mid", mid, st), ("measured", real, rt)]:
    x = feats(d)
    f = fit(x, d[:, 20, 1:5, 0].astype(np.float64), 1.0)
    c = fit(x, np.eye(5)[t], 1.0)
    out[name] = [float(np.abs(f(xt) - yt).mean()), float((np.argmax(c(xt), 1) != np.array(tt)).mean())]
print(json.dumps(out))
"#;

#[test]
fn transfer_matches_numpy_ridge_fits_and_reports_the_share_closed() {
    let dir = tempdir();
    let code = NUMPY
        .replace("SIML", &format!("{:?}", td("sim_labels.csv")))
        .replace("REALL", &format!("{:?}", td("real_labels.csv")))
        .replace("SIM", &format!("{:?}", td("sim.npy")))
        .replace("REAL", &format!("{:?}", td("real.npy")));
    let want: Value = serde_json::from_str(py(dir.path(), &code).trim()).unwrap();
    let p = |n: &str| arg(dir.path(), n);
    let args = |fmt: &str| -> Vec<String> {
        let mut a: Vec<String> = vec!["transfer".into(), "--test".into(), p("test.npy"), "--test-labels".into(), p("test_labels.csv")];
        for (name, npy, lab) in
            [("sim", "sim.npy", "sim_labels.csv"), ("mid", "mid.npy", "sim_labels.csv"), ("measured", "real.npy", "real_labels.csv")]
        {
            a.extend(["--train".into(), name.into(), p(npy), p(lab)]);
        }
        a.extend(["--format".into(), fmt.into(), "--seed".into(), "3".into(), "--by-terrain".into()]);
        a
    };
    let json_args = args("json");
    let out = run("dem-eval", &json_args.iter().map(String::as_str).collect::<Vec<_>>(), None);
    let rows: Value = serde_json::from_slice(ok(&out)).unwrap();
    let all: Vec<&Value> = rows.as_array().unwrap().iter().filter(|r| r["terrain"] == "all").collect();
    assert_eq!(all.len(), 3);
    let mut e = std::collections::HashMap::new();
    for r in &all {
        let name = r["train"].as_str().unwrap();
        let (f, t) = (r["flipper_mae_rad"].as_f64().unwrap(), r["terrain_error"].as_f64().unwrap());
        let (wf, wt) = (want[name][0].as_f64().unwrap(), want[name][1].as_f64().unwrap());
        // Both solve the same normal equations in f64; the features come from f32.
        assert!((f - wf).abs() < 1e-6, "{name}: flipper {f} vs numpy {wf}");
        assert!((t - wt).abs() < 1e-9, "{name}: terrain error {t} vs numpy {wt}");
        e.insert(name.to_string(), f);
    }
    let mid = all.iter().find(|r| r["train"] == "mid").unwrap();
    let closed = (e["sim"] - e["mid"]) / (e["sim"] - e["measured"]);
    assert!((mid["flipper_closed"].as_f64().unwrap() - closed).abs() < 1e-9);
    let (lo, hi) = (mid["flipper_closed_lo"].as_f64().unwrap(), mid["flipper_closed_hi"].as_f64().unwrap());
    assert!(lo <= hi && lo < closed + 1e-9 && closed - 1e-9 < hi, "{lo} .. {hi} around {closed}");
    assert!(all[0]["flipper_closed"].is_null() && all[2]["flipper_closed"].is_null(), "baseline and oracle close nothing");
    assert!(rows.as_array().unwrap().len() > 3, "--by-terrain adds rows");
    // The same seed gives the same interval; the text table names every set.
    let again = run("dem-eval", &json_args.iter().map(String::as_str).collect::<Vec<_>>(), None);
    assert_eq!(ok(&again), ok(&out));
    let text_args = args("text");
    let text = String::from_utf8(ok(&run("dem-eval", &text_args.iter().map(String::as_str).collect::<Vec<_>>(), None)).to_vec()).unwrap();
    assert!(text.contains("mae_rad") && text.contains("measured"), "{text}");
}

#[test]
fn transfer_refuses_bad_input_with_one_line() {
    let dir = tempdir();
    let (sim, siml, real, reall) = (td("sim.npy"), td("sim_labels.csv"), td("real.npy"), td("real_labels.csv"));
    // Labels of another file: counts differ.
    let out = run(
        "dem-eval",
        &["transfer", "--test", &real, "--test-labels", &reall, "--train", "sim", &sim, &reall, "--train", "m", &real, &reall],
        None,
    );
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("real_labels.csv") && stderr(&out).lines().count() == 1, "{}", stderr(&out));
    // One training set is not a comparison.
    let out = run("dem-eval", &["transfer", "--test", &real, "--test-labels", &reall, "--train", "sim", &sim, &siml], None);
    assert_eq!(out.status.code(), Some(2));
    // A test set without flipper angles cannot test the regressor.
    let flat = arg(dir.path(), "zero.npy");
    py(dir.path(), &format!("import numpy as np\nd = np.load({real:?}); d[:, 20, :, 0] = 0; np.save({flat:?}, d)"));
    let out = run(
        "dem-eval",
        &["transfer", "--test", &flat, "--test-labels", &reall, "--train", "s", &sim, &siml, "--train", "m", &real, &reall],
        None,
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("flipper"), "{}", stderr(&out));
    let out = run("dem-eval", &["transfer", "--help"], None);
    assert!(String::from_utf8_lossy(ok(&out)).contains("Examples:"));
}
