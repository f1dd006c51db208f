//! dem-synth run the way users run it: files, flags, numpy reading them.

use dem_core::format::DemCells;
use dem_core::{npy, table};
use dem_testkit::{arg, ok, py, run, stderr, tempdir, testdata};

fn synth(dir: &std::path::Path, name: &str, extra: &[&str]) -> String {
    let out = arg(dir, name);
    let mut args = vec!["--out", out.as_str(), "--runs", "5", "--real-runs", "3"];
    args.extend_from_slice(extra);
    if !extra.contains(&"--seed") {
        args.extend_from_slice(&["--seed", "1"]);
    }
    ok(&run("dem-synth", &args, None));
    out
}

fn bytes(dir: &str, file: &str) -> Vec<u8> {
    std::fs::read(format!("{dir}/{file}")).unwrap()
}

#[test]
fn same_seed_same_bytes_on_any_thread_count() {
    let dir = tempdir();
    let a = synth(dir.path(), "a", &["--threads", "1"]);
    let b = synth(dir.path(), "b", &["--threads", "2"]);
    for f in ["sim.npy", "real.npy", "sim_labels.csv", "real_labels.csv", "pairs.csv"] {
        assert_eq!(bytes(&a, f), bytes(&b, f), "{f} differs between thread counts");
    }
    let c = synth(dir.path(), "c", &["--seed", "2"]);
    assert_ne!(bytes(&a, "real.npy"), bytes(&c, "real.npy"));
}

#[test]
fn first_runs_reproduce_the_committed_testdata() {
    let dir = tempdir();
    let out = arg(dir.path(), "t");
    ok(&run("dem-synth", &["--out", &out, "--runs", "2", "--real-runs", "2", "--seed", "1"], None));
    for f in ["sim.npy", "real.npy"] {
        let fresh = npy::read_all(&format!("{out}/{f}")).unwrap();
        let committed = npy::read_all(testdata(f).to_str().unwrap()).unwrap();
        assert!(!fresh.is_empty());
        assert!(
            fresh[..] == committed[..fresh.len()],
            "testdata/{f} no longer matches dem-synth: run `make testdata` and commit"
        );
    }
}

#[test]
fn hiding_one_stage_keeps_the_sim_and_changes_the_measured() {
    let dir = tempdir();
    let full = synth(dir.path(), "full", &[]);
    for flag in ["--no-occlusion", "--no-noise", "--no-smoothing", "--no-fov", "--no-dropout", "--no-holes"] {
        let hidden = synth(dir.path(), flag.trim_start_matches('-'), &[flag]);
        assert_eq!(bytes(&full, "sim.npy"), bytes(&hidden, "sim.npy"), "{flag} changed the sim");
        assert_eq!(bytes(&full, "pairs.csv"), bytes(&hidden, "pairs.csv"));
        assert_ne!(bytes(&full, "real.npy"), bytes(&hidden, "real.npy"), "{flag} changed nothing");
    }
}

/// With noise off, every stage alone changes the measured data against all
/// stages off (issue 12: smoothing, dropout and holes alone used to give
/// the all-off bytes).
#[test]
fn every_stage_alone_changes_the_data() {
    let dir = tempdir();
    let stages = ["fov", "occlusion", "smoothing", "dropout", "holes"];
    let all_off: Vec<String> = stages.iter().chain(&["noise"]).map(|s| format!("--no-{s}")).collect();
    let refs: Vec<&str> = all_off.iter().map(String::as_str).collect();
    let off = synth(dir.path(), "off", &refs);
    for st in stages {
        let only: Vec<&str> = refs.iter().copied().filter(|f| *f != format!("--no-{st}")).collect();
        let d = synth(dir.path(), &format!("only-{st}"), &only);
        assert_ne!(bytes(&off, "real.npy"), bytes(&d, "real.npy"), "{st} alone changes nothing");
    }
}

/// Common random numbers: switching dark patches off changes the cells
/// near patches only; elsewhere the same pixels get the same noise, so most
/// cells valid in both have the very same height.
#[test]
fn switching_a_stage_off_keeps_the_other_draws() {
    let dir = tempdir();
    let full = synth(dir.path(), "full", &[]);
    let hidden = synth(dir.path(), "nodark", &["--no-dropout"]);
    let a = npy::read_all(&format!("{full}/real.npy")).unwrap();
    let b = npy::read_all(&format!("{hidden}/real.npy")).unwrap();
    let (mut both, mut same) = (0usize, 0usize);
    for (x, y) in a.iter().zip(&b) {
        for r in 0..20 {
            for c in 0..5 {
                if x.is_valid(r, c) && y.is_valid(r, c) {
                    both += 1;
                    same += usize::from(x.height(r, c) == y.height(r, c));
                }
            }
        }
    }
    assert!(both > 0 && same as f64 > 0.6 * both as f64, "{same} of {both} cells equal");
}

#[test]
fn outputs_are_consistent_and_numpy_reads_them() {
    let dir = tempdir();
    let out = synth(dir.path(), "d", &[]);
    let sim = npy::read_all(&format!("{out}/sim.npy")).unwrap();
    let real = npy::read_all(&format!("{out}/real.npy")).unwrap();
    let sim_labels = table::read_labels(&format!("{out}/sim_labels.csv")).unwrap();
    let real_labels = table::read_labels(&format!("{out}/real_labels.csv")).unwrap();
    let pairs = table::read_pairs(&format!("{out}/pairs.csv")).unwrap();
    assert_eq!(sim.len(), sim_labels.len());
    assert_eq!(real.len(), real_labels.len());
    assert_eq!(pairs.len(), real.len());
    assert!(sim.len() > 3 * real.len() / 2, "5 runs sim, 3 measured");
    for p in &pairs {
        let (s, r) = (&sim_labels[p.sim_index as usize], &real_labels[p.real_index as usize]);
        assert_eq!((s.x, s.y, s.yaw, s.sequence, s.time), (r.x, r.y, r.yaw, r.sequence, r.time));
        assert_eq!(p.sim_index, p.real_index, "measured runs come first");
        // Same pose, same attitude row.
        assert_eq!(sim[p.sim_index as usize].attitude(), real[p.real_index as usize].attitude());
    }
    let shape = py(
        dir.path(),
        &format!("import numpy as np; a=np.load('{out}/real.npy'); print(a.shape, a.dtype, int(np.isnan(a).sum()))"),
    );
    assert_eq!(shape.trim(), format!("({}, 21, 5, 2) float32 0", real.len()));
}

#[test]
fn every_run_starts_blind_behind_the_robot() {
    let real = npy::read_all(testdata("real.npy").to_str().unwrap()).unwrap();
    let labels = table::read_labels(testdata("real_labels.csv").to_str().unwrap()).unwrap();
    let starts: Vec<usize> = labels.iter().filter(|l| l.time == Some(0.0)).map(|l| l.index as usize).collect();
    assert_eq!(starts.len(), 20);
    let valid = |d: &dem_core::Dem, rows: std::ops::Range<usize>| {
        rows.flat_map(|r| (0..5).map(move |c| (r, c))).filter(|&(r, c)| d.is_valid(r, c)).count()
    };
    for i in starts {
        let (behind, ahead) = (valid(&real[i], 0..6), valid(&real[i], 14..20));
        assert_eq!(behind, 0, "record {i} sees behind the robot at startup");
        assert!(ahead >= 20, "record {i} sees only {ahead} of 30 far cells");
    }
}

#[test]
fn bad_arguments_exit_2_and_write_nothing() {
    let dir = tempdir();
    let out = arg(dir.path(), "x");
    for args in [
        vec!["--out", out.as_str(), "--runs", "2", "--real-runs", "3"],
        vec!["--out", out.as_str(), "--terrains", "lava"],
        vec!["--out", out.as_str(), "--dt", "0"],
    ] {
        let o = run("dem-synth", &args, None);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(!std::path::Path::new(&out).join("sim.npy").exists());
    }
}
