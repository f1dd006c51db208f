//! dem-pair on dem-synth data: true pairs come back, splits are by key.

use std::collections::{BTreeSet, HashMap};
use std::path::Path;

use dem_core::metric::dem_error;
use dem_core::npy;
use dem_core::table::{self, Split};
use dem_testkit::{arg, ok, run, stderr, tempdir, testdata};

fn td(name: &str) -> String {
    testdata(name).to_string_lossy().into_owned()
}

#[test]
fn pose_pairing_recovers_the_true_pairs() {
    let dir = tempdir();
    let out = arg(dir.path(), "p.csv");
    let o = run(
        "dem-pair",
        &[
            "--match",
            "pose",
            "--sim-labels",
            &td("sim_labels.csv"),
            "--real-labels",
            &td("real_labels.csv"),
            "--same-sequence",
            "--max-offset",
            "0.03",
            "-o",
            &out,
        ],
        None,
    );
    ok(&o);
    let found: BTreeSet<(u64, u64)> = table::read_pairs(&out).unwrap().iter().map(|p| (p.sim_index, p.real_index)).collect();
    let truth: BTreeSet<(u64, u64)> = table::read_pairs(&td("pairs.csv")).unwrap().iter().map(|p| (p.sim_index, p.real_index)).collect();
    assert_eq!(found, truth);
    assert!(stderr(&o).contains("966 pairs of 966 real records"), "{}", stderr(&o));
}

#[test]
fn pose_pairing_with_sim_maps_duplicates_to_one_key() {
    let dir = tempdir();
    let out = arg(dir.path(), "p.csv");
    ok(&run(
        "dem-pair",
        &[
            "--match",
            "pose",
            "--sim",
            &td("sim.npy"),
            "--sim-labels",
            &td("sim_labels.csv"),
            "--real-labels",
            &td("real_labels.csv"),
            "--same-sequence",
            "-o",
            &out,
        ],
        None,
    ));
    let sim = npy::read_all(&td("sim.npy")).unwrap();
    for p in table::read_pairs(&out).unwrap() {
        let key = p.sim_index as usize;
        // The key is the first record identical to the true partner.
        assert!(sim[..key].iter().all(|d| d != &sim[key]), "key {key} is not a first occurrence");
        assert_eq!(sim[key], sim[p.real_index as usize], "real {} paired off its pose", p.real_index);
    }
}

#[test]
fn content_pairs_are_the_nearest_and_no_key_is_in_both_splits() {
    let dir = tempdir();
    let out = arg(dir.path(), "c.csv");
    ok(&run(
        "dem-pair",
        &[
            "--match",
            "content",
            "--sim",
            &td("sim.npy"),
            "--real",
            &td("real.npy"),
            "--k",
            "2",
            "--val-fraction",
            "0.4",
            "--seed",
            "3",
            "-o",
            &out,
        ],
        None,
    ));
    let pairs = table::read_pairs(&out).unwrap();
    let mut split_of: HashMap<u64, Split> = HashMap::new();
    for p in &pairs {
        let s = p.split.expect("split column");
        assert_eq!(*split_of.entry(p.sim_index).or_insert(s), s, "key {} in both halves", p.sim_index);
    }
    let val = split_of.values().filter(|&&s| s == Split::Val).count() as f64 / split_of.len() as f64;
    assert!((0.3..0.5).contains(&val), "val fraction {val}");
    // Check the nearest by brute force for a few real records.
    let (sim, real) = (npy::read_all(&td("sim.npy")).unwrap(), npy::read_all(&td("real.npy")).unwrap());
    for r in [0u64, 100, 500, 900] {
        let y = &real[r as usize];
        // Height part of eq. 7.1: the mask term against all-valid sim is constant.
        let best = sim.iter().map(|x| dem_error(y, x)).fold(f64::INFINITY, f64::min);
        let got: Vec<_> = pairs.iter().filter(|p| p.real_index == r).collect();
        assert_eq!(got.len(), 2);
        // Rows are sorted by key, not distance: the nearest is among them.
        let e = got.iter().map(|p| dem_error(y, &sim[p.sim_index as usize])).fold(f64::INFINITY, f64::min);
        assert!((e - best).abs() < 1e-6, "real {r}: paired {e}, best {best}");
    }
}

#[test]
fn missing_inputs_for_the_method_are_usage_errors() {
    let o = run("dem-pair", &["--match", "content", "--sim", &td("sim.npy")], None);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--real"));
    let o = run("dem-pair", &["--match", "pose", "--sim-labels", &td("sim_labels.csv")], None);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--real-labels"));
}

/// `dem-pair expand`: record i of the outputs is pair i's sim and real
/// record; the sim labels carry the sim's terrain and the partner's time;
/// dem-eval's gap over the expanded pairs is its gap over the pairs.
#[test]
fn expanded_pairs_are_one_record_per_pair_at_the_partner_s_time() {
    let dir = tempdir();
    let pairs = arg(dir.path(), "c.csv");
    ok(&run(
        "dem-pair",
        &[
            "--match",
            "content",
            "--sim",
            &td("sim.npy"),
            "--real",
            &td("real.npy"),
            "--k",
            "2",
            "--val-fraction",
            "0.4",
            "--seed",
            "3",
            "-o",
            &pairs,
        ],
        None,
    ));
    let out = arg(dir.path(), "val");
    let o = run(
        "dem-pair",
        &[
            "expand",
            "--pairs",
            &pairs,
            "--sim",
            &td("sim.npy"),
            "--real",
            &td("real.npy"),
            "--sim-labels",
            &td("sim_labels.csv"),
            "--real-labels",
            &td("real_labels.csv"),
            "--split",
            "val",
            "--out",
            &out,
        ],
        None,
    );
    ok(&o);
    let val: Vec<table::Pair> = table::read_pairs(&pairs).unwrap().into_iter().filter(|p| p.split == Some(Split::Val)).collect();
    let (sim, real) = (npy::read_all(&td("sim.npy")).unwrap(), npy::read_all(&td("real.npy")).unwrap());
    let (sl, rl) = (table::read_labels(&td("sim_labels.csv")).unwrap(), table::read_labels(&td("real_labels.csv")).unwrap());
    let f = |n: &str| format!("{out}/{n}");
    let (xs, xr) = (npy::read_all(&f("sim.npy")).unwrap(), npy::read_all(&f("real.npy")).unwrap());
    let (xsl, xrl) = (table::read_labels(&f("sim_labels.csv")).unwrap(), table::read_labels(&f("real_labels.csv")).unwrap());
    let xp = table::read_pairs(&f("pairs.csv")).unwrap();
    assert_eq!((xs.len(), xr.len(), xsl.len(), xrl.len(), xp.len()), (val.len(), val.len(), val.len(), val.len(), val.len()));
    let keys: BTreeSet<u64> = val.iter().map(|p| p.sim_index).collect();
    assert!(keys.len() < val.len(), "the test needs keys with several partners");
    let mut moved = 0;
    for (i, p) in val.iter().enumerate() {
        let (s, r) = (p.sim_index as usize, p.real_index as usize);
        assert_eq!((xs[i], xr[i]), (sim[s], real[r]), "pair {i}");
        assert_eq!((xp[i].sim_index, xp[i].real_index, xp[i].split, xp[i].distance), (i as u64, i as u64, Some(Split::Val), p.distance));
        assert_eq!((xsl[i].terrain, xsl[i].time, xsl[i].sequence), (sl[s].terrain, rl[r].time, rl[r].sequence), "pair {i}");
        assert_eq!((xrl[i].terrain, xrl[i].time), (rl[r].terrain, rl[r].time));
        moved += usize::from(sl[s].time != rl[r].time);
    }
    assert!(moved > 0, "no pair took a time other than its key's");
    assert!(stderr(&o).contains(&format!("{} pairs of {} sim keys", val.len(), keys.len())), "{}", stderr(&o));

    // One gap: over the original pairs, and over the expanded ones.
    let gap = |args: &[&str]| -> f64 {
        let o = run("dem-eval", &[args, &["--identity", "--format", "csv"]].concat(), None);
        let t = String::from_utf8(ok(&o).to_vec()).unwrap();
        let col = t.lines().next().unwrap().split(',').position(|c| c == "gap").unwrap();
        t.lines().nth(1).unwrap().split(',').nth(col).unwrap().parse().unwrap()
    };
    let whole = gap(&["--sim", &td("sim.npy"), "--real", &td("real.npy"), "--pairs", &pairs, "--split", "val"]);
    let expanded = gap(&["--sim", &f("sim.npy"), "--real", &f("real.npy"), "--pairs", &f("pairs.csv")]);
    assert!((whole - expanded).abs() < 1e-9, "{whole} vs {expanded}");

    // Expanded again into the same folder without labels: the earlier
    // expansion's label files go, as they describe other records.
    let o = run(
        "dem-pair",
        &["expand", "--pairs", &pairs, "--sim", &td("sim.npy"), "--real", &td("real.npy"), "--split", "train", "--out", &out],
        None,
    );
    ok(&o);
    assert!(!Path::new(&f("sim_labels.csv")).exists() && !Path::new(&f("real_labels.csv")).exists(), "stale labels left in {out}");
    assert!(stderr(&o).contains("removed") && stderr(&o).contains("sim_labels.csv"), "{}", stderr(&o));
}

#[test]
fn expand_refuses_a_pair_past_the_end_and_leaves_nothing() {
    let dir = tempdir();
    let pairs = arg(dir.path(), "p.csv");
    std::fs::write(&pairs, "sim_index,real_index\n0,0\n1,999999\n").unwrap();
    let out = arg(dir.path(), "x");
    let o = run("dem-pair", &["expand", "--pairs", &pairs, "--sim", &td("sim.npy"), "--real", &td("real.npy"), "--out", &out], None);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(e.contains(&pairs) && e.contains("line 3") && e.contains("real_index 999999"), "{e}");
    assert!(!std::path::Path::new(&out).exists(), "a refused run left {out}");
    // A split the pairs do not have, and --match without a subcommand, are refused too.
    let o = run(
        "dem-pair",
        &["expand", "--pairs", &pairs, "--sim", &td("sim.npy"), "--real", &td("real.npy"), "--split", "val", "--out", &out],
        None,
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let o = run("dem-pair", &["--sim", &td("sim.npy")], None);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--match"), "{}", stderr(&o));
}

/// A record stream on stdin expands as the file does.
#[test]
fn expand_reads_the_real_stream_from_stdin() {
    let dir = tempdir();
    let (pairs, sim, real) = (td("pairs.csv"), td("sim.npy"), td("real.npy"));
    let (a, b) = (arg(dir.path(), "a"), arg(dir.path(), "b"));
    let expand = |real: &str, out: &str, stdin: Option<Vec<u8>>| {
        ok(&run("dem-pair", &["expand", "--pairs", &pairs, "--sim", &sim, "--real", real, "--out", out], stdin));
    };
    expand(&real, &a, None);
    expand("-", &b, Some(std::fs::read(&real).unwrap()));
    for f in ["sim.npy", "real.npy", "pairs.csv"] {
        assert_eq!(std::fs::read(format!("{a}/{f}")).unwrap(), std::fs::read(format!("{b}/{f}")).unwrap(), "{f}");
    }
}
