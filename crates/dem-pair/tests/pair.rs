//! dem-pair on dem-synth data: true pairs come back, splits are by key.

use std::collections::{BTreeSet, HashMap};

use dem_core::metric::dem_error;
use dem_core::table::{self, Split};
use dem_core::npy;
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
        &["--by", "pose", "--sim-labels", &td("sim_labels.csv"), "--real-labels", &td("real_labels.csv"), "--same-sequence", "--max-dist", "0.03", "-o", &out],
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
        &["--by", "pose", "--sim", &td("sim.npy"), "--sim-labels", &td("sim_labels.csv"), "--real-labels", &td("real_labels.csv"), "--same-sequence", "-o", &out],
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
        &["--by", "content", "--sim", &td("sim.npy"), "--real", &td("real.npy"), "--k", "2", "--val-fraction", "0.4", "--seed", "3", "-o", &out],
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
    let o = run("dem-pair", &["--by", "content", "--sim", &td("sim.npy")], None);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--real"));
    let o = run("dem-pair", &["--by", "pose", "--sim-labels", &td("sim_labels.csv")], None);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--real-labels"));
}
