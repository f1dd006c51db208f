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

/// The flags that switch the four motion stages off: the emulator of the
/// six sensor stages, as `testdata/` was made.
const STILL: [&str; 4] = ["--no-drift", "--no-latency", "--no-extrinsic", "--no-vibration"];

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
    let args = [&["--out", out.as_str(), "--runs", "2", "--real-runs", "2", "--seed", "1"][..], &STILL[..]].concat();
    ok(&run("dem-synth", &args, None));
    for f in ["sim.npy", "real.npy"] {
        let fresh = npy::read_all(&format!("{out}/{f}")).unwrap();
        let committed = npy::read_all(testdata(f).to_str().unwrap()).unwrap();
        assert!(!fresh.is_empty());
        assert!(fresh[..] == committed[..fresh.len()], "testdata/{f} no longer matches dem-synth: run `make testdata` and commit");
    }
}

#[test]
fn hiding_one_stage_keeps_the_sim_and_changes_the_measured() {
    let dir = tempdir();
    let full = synth(dir.path(), "full", &[]);
    for flag in [
        "--no-occlusion",
        "--no-noise",
        "--no-smoothing",
        "--no-fov",
        "--no-dropout",
        "--no-holes",
        "--no-drift",
        "--no-latency",
        "--no-extrinsic",
        "--no-vibration",
        "--no-memory",
    ] {
        let hidden = synth(dir.path(), flag.trim_start_matches('-'), &[flag]);
        assert_eq!(bytes(&full, "sim.npy"), bytes(&hidden, "sim.npy"), "{flag} changed the sim");
        assert_eq!(bytes(&full, "pairs.csv"), bytes(&hidden, "pairs.csv"));
        assert_ne!(bytes(&full, "real.npy"), bytes(&hidden, "real.npy"), "{flag} changed nothing");
    }
}

/// With noise off, every stage alone changes the measured data against all
/// stages off (smoothing, dropout and holes alone once gave
/// the all-off bytes).
#[test]
fn every_stage_alone_changes_the_data() {
    let dir = tempdir();
    let stages = ["fov", "occlusion", "smoothing", "dropout", "holes", "drift", "latency", "extrinsic", "vibration"];
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

/// The motion stages draw from streams of their own: each stage on with a
/// zero amplitude makes all its draws and changes nothing, so with every
/// other stage on, `--no-X` is the full emulator less X's effect alone
/// (the other stages' draws unchanged); and each stage alone changes the
/// six-stage data, leaving the sim as it is.
#[test]
fn the_motion_stages_keep_the_other_draws() {
    let dir = tempdir();
    for (st, zero) in [
        ("drift", &["--drift", "0", "--drift-vertical", "0", "--drift-yaw", "0"][..]),
        ("latency", &["--latency", "0"][..]),
        ("extrinsic", &["--extrinsic", "0"][..]),
        ("vibration", &["--vibration", "0", "--vibration-edge", "0"][..]),
    ] {
        let off = synth(dir.path(), &format!("no-{st}"), &[&format!("--no-{st}")]);
        let mute = synth(dir.path(), &format!("zero-{st}"), zero);
        assert_eq!(bytes(&off, "real.npy"), bytes(&mute, "real.npy"), "{st} at zero amplitude moved other draws");
    }
    let still = synth(dir.path(), "still", &STILL);
    for st in ["drift", "latency", "extrinsic", "vibration"] {
        let flag = format!("--no-{st}");
        let others: Vec<&str> = STILL.iter().copied().filter(|f| *f != flag).collect();
        let one = synth(dir.path(), st, &others);
        assert_ne!(bytes(&still, "real.npy"), bytes(&one, "real.npy"), "{st} alone changes nothing");
        assert_eq!(bytes(&still, "sim.npy"), bytes(&one, "sim.npy"), "{st} changed the sim");
    }
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
    let shape =
        py(dir.path(), &format!("import numpy as np; a=np.load('{out}/real.npy'); print(a.shape, a.dtype, int(np.isnan(a).sum()))"));
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

/// maps.npy of --emit-maps: header, then `(M, 2, n, n)` `<f4` values.
fn read_maps(path: &str) -> (usize, usize, Vec<f32>) {
    let bytes = std::fs::read(path).unwrap();
    let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize + 10;
    let dict = std::str::from_utf8(&bytes[10..len]).unwrap();
    let shape = dict.split("'shape': (").nth(1).unwrap().split(')').next().unwrap();
    let dims: Vec<usize> = shape.split(',').map(|d| d.trim().parse().unwrap()).collect();
    assert!(dict.starts_with("{'descr': '<f4', 'fortran_order': False,") && dims.len() == 4 && dims[1] == 2, "{dict}");
    assert_eq!(dims[2], dims[3]);
    let values: Vec<f32> = bytes[len..].chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().unwrap())).collect();
    assert_eq!(values.len(), dims[0] * 2 * dims[2] * dims[3], "payload of {path}");
    (dims[0], dims[2], values)
}

/// maps.csv of --emit-maps: (column, value) rows.
fn read_maps_csv(path: &str) -> Vec<Vec<(String, String)>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    assert_eq!(
        header.join(","),
        "index,sequence,time,center_x,center_y,resolution,x,y,z,yaw,pitch,flipper_fl,flipper_fr,flipper_rl,flipper_rr"
    );
    lines.map(|l| header.iter().cloned().zip(l.split(',').map(String::from)).collect()).collect()
}

fn field(row: &[(String, String)], name: &str) -> f64 {
    row.iter().find(|(k, _)| k == name).unwrap().1.parse().unwrap()
}

/// Rebuild every measured DEM from its emitted map window alone, with the
/// rule dem-import uses: for each DEM cell the four quarter centres (robot
/// frame offsets +-2.5 cm, turned by yaw) are looked up in the window at
/// i = floor((center_x + L/2 - x) / res), j = floor((center_y + L/2 - y) / res);
/// the cell is valid with at least 2 non-NaN samples, its height their mean
/// minus z. It must equal real.npy: same validity, heights within 1e-5 m.
/// The pose is the one the DEM was cut around: the labels' (true) pose
/// when `still` (motion stages off), else near it (drift, latency).
fn rebuild_dems_from_maps(out: &str, still: bool) -> usize {
    use dem_core::format::{col_center_y, row_center_x};
    use dem_synth::pose::Pose;
    let real = npy::read_all(&format!("{out}/real.npy")).unwrap();
    let labels = table::read_labels(&format!("{out}/real_labels.csv")).unwrap();
    let (m, n, maps) = read_maps(&format!("{out}/maps.npy"));
    let rows = read_maps_csv(&format!("{out}/maps.csv"));
    assert_eq!((m, n, rows.len()), (real.len(), 80, real.len()));
    let mut valid = 0;
    for (k, row) in rows.iter().enumerate() {
        let l = &labels[k];
        assert_eq!(field(row, "index"), k as f64);
        assert_eq!((Some(field(row, "sequence") as u64), Some(field(row, "time"))), (l.sequence, l.time));
        let pose = Pose {
            x: field(row, "x"),
            y: field(row, "y"),
            z: field(row, "z"),
            yaw: field(row, "yaw"),
            pitch: field(row, "pitch"),
            flippers: ["flipper_fl", "flipper_fr", "flipper_rl", "flipper_rr"].map(|f| field(row, f)),
        };
        let micro = |v: f64| (v * 1e6).round() / 1e6;
        if still {
            assert_eq!((Some(micro(pose.x)), Some(micro(pose.y)), Some(micro(pose.yaw))), (l.x, l.y, l.yaw));
        } else {
            let (dx, dy, dyaw) = (pose.x - l.x.unwrap(), pose.y - l.y.unwrap(), pose.yaw - l.yaw.unwrap());
            assert!(dx.abs() < 0.3 && dy.abs() < 0.3 && dyaw.abs() < 0.2, "record {k}: cut {dx} {dy} {dyaw} from the true pose");
        }
        let att = real[k].attitude();
        let expected = [pose.pitch, pose.flippers[0], pose.flippers[1], pose.flippers[2], pose.flippers[3]];
        assert_eq!(att, expected.map(|v| v as f32), "record {k}: attitude");
        let res = field(row, "resolution");
        let (cx, cy) = (field(row, "center_x"), field(row, "center_y"));
        assert_eq!(res, 0.05);
        let half = n as f64 * res / 2.0;
        let elevation = &maps[k * 2 * n * n..][..n * n];
        for r in 0..20 {
            for c in 0..5 {
                let (mut sum, mut count) = (0.0f64, 0);
                for (dx, dy) in [(-0.025, -0.025), (-0.025, 0.025), (0.025, -0.025), (0.025, 0.025)] {
                    let (x, y) = pose.to_world(row_center_x(r) + dx, col_center_y(c) + dy);
                    let (i, j) = (((cx + half - x) / res).floor(), ((cy + half - y) / res).floor());
                    assert!((0.0..n as f64).contains(&i) && (0.0..n as f64).contains(&j), "DEM outside the window");
                    let h = elevation[i as usize * n + j as usize];
                    if !h.is_nan() {
                        sum += h as f64;
                        count += 1;
                    }
                }
                let ok = count >= 2;
                assert_eq!(ok, real[k].is_valid(r, c), "record {k} cell ({r}, {c}): validity ({count} samples)");
                if ok {
                    let h = (sum / count as f64 - pose.z) as f32;
                    let d = (h - real[k].height(r, c)).abs();
                    assert!(d <= 1e-5, "record {k} cell ({r}, {c}): {h} against {}", real[k].height(r, c));
                    valid += 1;
                }
            }
        }
    }
    valid
}

#[test]
fn emit_maps_rebuilds_every_measured_dem_and_changes_nothing_else() {
    let dir = tempdir();
    let plain = synth(dir.path(), "plain", &[]);
    let maps = synth(dir.path(), "maps", &["--emit-maps"]);
    for f in ["sim.npy", "real.npy", "sim_labels.csv", "real_labels.csv", "pairs.csv"] {
        assert_eq!(bytes(&plain, f), bytes(&maps, f), "--emit-maps changed {f}");
    }
    assert!(!std::path::Path::new(&plain).join("maps.npy").exists() && !std::path::Path::new(&plain).join("maps.csv").exists());
    let valid = rebuild_dems_from_maps(&maps, false);
    assert!(valid > 1000, "only {valid} valid cells checked");
    // A maximum variance low enough that seen cells become holes: the
    // variance layer keeps them, the elevation layer does not.
    let thin = synth(dir.path(), "thin", &["--emit-maps", "--max-variance", "2e-5"]);
    rebuild_dems_from_maps(&thin, false);
    let still = synth(dir.path(), "still", &[&["--emit-maps"][..], &STILL[..]].concat());
    assert!(rebuild_dems_from_maps(&still, true) > 1000);
    let (_, n, values) = read_maps(&format!("{thin}/maps.npy"));
    let holes = values
        .chunks_exact(2 * n * n)
        .flat_map(|m| m[..n * n].iter().zip(&m[n * n..]))
        .filter(|(h, v)| h.is_nan() && !v.is_nan())
        .inspect(|(_, v)| assert!(**v > 2e-5))
        .count();
    assert!(holes > 100, "{holes} cells above the maximum variance");
    // Without holes every seen cell has its height (and the DEM needs 1 of 4).
    let all = synth(dir.path(), "all", &["--emit-maps", "--no-holes"]);
    let (_, _, values) = read_maps(&format!("{all}/maps.npy"));
    for m in values.chunks_exact(2 * n * n) {
        assert!(m[..n * n].iter().zip(&m[n * n..]).all(|(h, v)| h.is_nan() == v.is_nan()));
    }
    let shape =
        py(dir.path(), &format!("import numpy as np; a=np.load('{maps}/maps.npy'); print(a.shape, a.dtype, a.flags['C_CONTIGUOUS'])"));
    assert_eq!(shape.trim(), format!("({}, 2, 80, 80) float32 True", npy::read_all(&format!("{maps}/real.npy")).unwrap().len()));
}
