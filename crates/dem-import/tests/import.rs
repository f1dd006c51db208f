//! dem-import against recordings written by an independent implementation:
//! `dem-synth --emit-maps` gives the emulator's 5 cm elevation maps, poses
//! and flipper angles; `scripts/maps_to_bag.py` turns them into ROS 1 bags
//! and ROS 2 MCAP bags with the `rosbags` package (its own serializers, the
//! genuine grid_map_msgs/tf2_msgs/sensor_msgs definitions); dem-import of
//! those must give dem-synth's measured DEMs of the same poses.

use std::path::{Path, PathBuf};
use std::process::Command;

use dem_core::{npy, table, Dem};
use dem_testkit::{ok, run, stderr, workspace_root};

fn python() -> PathBuf {
    dem_testkit::python()
}

/// A world with its maps: runs of stairs down and a pallet, both measured.
/// `extra` flags change the camera.
fn world(dir: &Path, name: &str, seed: &str, extra: &[&str]) -> PathBuf {
    let w = dir.join(name);
    let mut args = vec![
        "--out",
        w.to_str().unwrap(),
        "--runs",
        "2",
        "--real-runs",
        "2",
        "--seed",
        seed,
        "--terrains",
        "stairs-down,pallet",
        "--emit-maps",
    ];
    args.extend_from_slice(extra);
    ok(&run("dem-synth", &args, None));
    w
}

fn to_bag(world: &Path, out: &Path, args: &[&str]) {
    let script = workspace_root().join("scripts/maps_to_bag.py");
    let o = Command::new(python()).arg(script).arg(world).arg("--out").arg(out).args(args).output().expect("python");
    assert!(o.status.success(), "maps_to_bag.py failed:\n{}", String::from_utf8_lossy(&o.stderr));
}

fn read_npy(p: &Path) -> Vec<Dem> {
    npy::read_all(p.to_str().unwrap()).unwrap()
}

/// The real records of run `seq`, from dem-synth's labels.
fn expected(world: &Path, seq: u64) -> Vec<Dem> {
    let all = read_npy(&world.join("real.npy"));
    let labels = table::read_labels(world.join("real_labels.csv").to_str().unwrap()).unwrap();
    let out: Vec<Dem> = labels.iter().filter(|l| l.sequence == Some(seq)).map(|l| all[l.index as usize]).collect();
    assert!(out.len() > 10, "run {seq} has {} records", out.len());
    out
}

/// Same validity everywhere; heights within 1e-5 m (the maps carry f32
/// heights where the emulator averages f64); attitude within 1e-6 rad.
fn assert_same(got: &[Dem], want: &[Dem], what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: record count");
    let mut worst = 0f32;
    let mut valid = 0;
    for (k, (g, w)) in got.iter().zip(want).enumerate() {
        for cell in 0..100 {
            let (gh, gm, wh, wm) = (g[2 * cell], g[2 * cell + 1], w[2 * cell], w[2 * cell + 1]);
            assert_eq!(gm, wm, "{what}: record {k} cell {cell}: mask {gm} vs {wm}");
            if wm > 0.0 {
                valid += 1;
                worst = worst.max((gh - wh).abs());
            }
        }
        for c in 0..5 {
            assert!(
                (g[200 + 2 * c] - w[200 + 2 * c]).abs() < 1e-6,
                "{what}: record {k} attitude {c}: {} vs {}",
                g[200 + 2 * c],
                w[200 + 2 * c]
            );
        }
    }
    assert!(worst <= 1e-5, "{what}: heights differ by up to {worst} m");
    assert!(valid > 1000, "{what}: only {valid} valid cells compared");
}

fn import(out: &Path, extra: &[&str], recordings: &[&Path]) -> std::process::Output {
    let mut args = vec!["--out".to_string(), out.display().to_string()];
    args.extend(extra.iter().map(|s| s.to_string()));
    args.extend(recordings.iter().map(|p| p.display().to_string()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    run("dem-import", &args, None)
}

#[test]
fn ros1_bags_and_ros2_mcap_reproduce_the_emulators_dems() {
    let dir = tempfile::tempdir().unwrap();
    let w = world(dir.path(), "w", "5", &[]);
    // ROS 1, lz4 chunks, maps recorded out of stamp order, TF arriving after
    // the maps that need it.
    let bag = dir.path().join("stairs.bag");
    to_bag(&w, &bag, &["--format", "ros1", "--sequences", "0", "--compression", "lz4", "--shuffle-maps", "--tf-late"]);
    // ROS 2 MCAP bag folder, zstd, row-major layers.
    let mcap = dir.path().join("pallet");
    to_bag(&w, &mcap, &["--format", "mcap", "--sequences", "1", "--compression", "zstd", "--row-major"]);
    let out = dir.path().join("out");
    let o = import(&out, &["--terrain", "pallet"], &[&bag, &mcap]);
    ok(&o);
    let log = stderr(&o);
    assert!(log.contains("stairs.bag:") && log.contains("pallet:") && log.contains("DEMs"), "{log}");
    assert_same(&read_npy(&out.join("stairs.npy")), &expected(&w, 0), "ros1 bag");
    assert_same(&read_npy(&out.join("pallet.npy")), &expected(&w, 1), "mcap folder");
    // Labels: in stamp order from time 0, the pose from TF, the recording's ordinal.
    let labels = std::fs::read_to_string(out.join("pallet_labels.csv")).unwrap();
    let mut lines = labels.lines();
    assert_eq!(lines.next(), Some("index,terrain,x,y,yaw,sequence,time"));
    let first: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!((first[0], first[1], first[5], first[6]), ("0", "pallet", "1", "0.0"));
    let synth_labels = std::fs::read_to_string(w.join("real_labels.csv")).unwrap();
    let synth_first = synth_labels.lines().find(|l| l.split(',').nth(5) == Some("1")).unwrap();
    let sx: f64 = synth_first.split(',').nth(2).unwrap().parse().unwrap();
    assert!((first[2].parse::<f64>().unwrap() - sx).abs() < 1e-5);
    // Every other tool reads the output.
    ok(&run(
        "dem-cat",
        &[
            out.join("stairs.npy").to_str().unwrap(),
            out.join("pallet.npy").to_str().unwrap(),
            "-o",
            dir.path().join("all.npy").to_str().unwrap(),
        ],
        None,
    ));
    ok(&run(
        "dem-filter",
        &[
            "--labels",
            out.join("stairs_labels.csv").to_str().unwrap(),
            "--drop-other",
            out.join("stairs.npy").to_str().unwrap(),
            "-o",
            dir.path().join("f.npy").to_str().unwrap(),
        ],
        None,
    ));
}

#[test]
fn another_camera_mount_and_seed_with_bz2_and_thinning() {
    let dir = tempfile::tempdir().unwrap();
    let w = world(dir.path(), "high", "9", &["--camera-height", "0.7", "--camera-tilt", "25"]);
    let bag = dir.path().join("high.bag");
    to_bag(&w, &bag, &["--format", "ros1", "--sequences", "1", "--compression", "bz2"]);
    let out = dir.path().join("out");
    ok(&import(&out, &[], &[&bag]));
    let want = expected(&w, 1);
    assert_same(&read_npy(&out.join("high.npy")), &want, "bz2 bag, camera 0.7 m / 25 deg");
    // --every 0.8 keeps every other map (they are 0.4 s apart).
    let thin = dir.path().join("thin");
    let o = import(&thin, &["--every", "0.79"], &[&bag]);
    ok(&o);
    let kept: Vec<_> = want.iter().step_by(2).copied().collect();
    assert_same(&read_npy(&thin.join("high.npy")), &kept, "--every");
    assert!(stderr(&o).contains("left out by --every"), "{}", stderr(&o));
}

#[test]
fn bad_recordings_are_named_skipped_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let w = world(dir.path(), "w", "3", &[]);
    let want = expected(&w, 0);

    // A map without a transform: skipped, named, exit 1; --keep-going: exit 0.
    let bag = dir.path().join("notf.bag");
    to_bag(&w, &bag, &["--format", "ros1", "--sequences", "0", "--extra-map-without-tf"]);
    let out = dir.path().join("o1");
    let o = import(&out, &[], &[&bag]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let log = stderr(&o);
    assert!(
        log.contains("notf.bag: topic /elevation_mapping/elevation_map, message")
            && log.contains("no transform base_footprint -> base_link at 1699999970.000 s (recorded"),
        "{log}"
    );
    assert!(log.contains("1 without a transform"), "{log}");
    assert_same(&read_npy(&out.join("notf.npy")), &want, "the other maps");
    ok(&import(&dir.path().join("o2"), &["--keep-going"], &[&bag]));

    // A map message cut short (a broken driver, a disk error): named, the others kept.
    let cut_msg = dir.path().join("cutmsg.bag");
    to_bag(&w, &cut_msg, &["--format", "ros1", "--sequences", "0", "--damaged-map", "3"]);
    let out = dir.path().join("o0");
    let o = import(&out, &[], &[&cut_msg]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let log = stderr(&o);
    assert!(
        log.contains("cutmsg.bag: topic /elevation_mapping/elevation_map, message 3: layer elevation: data: 6400 elements cannot fit"),
        "{log}"
    );
    assert!(log.contains("1 skipped: 1 damaged"), "{log}");
    let without_3: Vec<_> = want.iter().enumerate().filter(|(k, _)| *k != 3).map(|(_, d)| *d).collect();
    assert_same(&read_npy(&out.join("cutmsg.npy")), &without_3, "the undamaged maps");

    // An unknown layer: every map skipped, the layers the map has are named.
    let o = import(&dir.path().join("o3"), &["--layer", "height"], &[&bag]);
    assert_eq!(o.status.code(), Some(1));
    let log = stderr(&o);
    assert!(log.contains("message 1: no layer \"height\" (the map has: elevation, variance)"), "{log}");

    // A truncated bag (a recorder killed mid-write): the maps before the break.
    let whole = dir.path().join("whole.bag");
    to_bag(&w, &whole, &["--format", "ros1", "--sequences", "0"]);
    truncated_keeps_the_maps_before_the_break(&whole, &dir.path().join("cut.bag"), &want);

    // A truncated MCAP file the same way.
    let mdir = dir.path().join("m");
    to_bag(&w, &mdir, &["--format", "mcap", "--sequences", "0"]);
    let mfile = std::fs::read_dir(&mdir).unwrap().flatten().map(|e| e.path()).find(|p| p.extension().is_some_and(|x| x == "mcap")).unwrap();
    truncated_keeps_the_maps_before_the_break(&mfile, &dir.path().join("mcut.mcap"), &want);

    // Not a recording at all, and a .db3 that is SQLite's magic alone: named, not imported.
    let junk = dir.path().join("junk.bag");
    std::fs::write(&junk, b"hello").unwrap();
    let o = import(&dir.path().join("o6"), &[], &[&junk]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("junk.bag: not imported") && stderr(&o).contains("not a ROS 1 bag"), "{}", stderr(&o));
    let db3 = dir.path().join("x.db3");
    std::fs::write(&db3, b"SQLite format 3\0").unwrap();
    assert!(stderr(&import(&dir.path().join("o7"), &[], &[&db3])).contains("x.db3: not imported"));
}

/// `whole` cut to 60 % as `cut`: exit 1, the break named with its byte
/// offset, and the maps before it imported.
fn truncated_keeps_the_maps_before_the_break(whole: &Path, cut: &Path, want: &[Dem]) {
    let bytes = std::fs::read(whole).unwrap();
    std::fs::write(cut, &bytes[..bytes.len() * 6 / 10]).unwrap();
    let out = cut.with_extension("out");
    let o = import(&out, &[], &[cut]);
    assert_eq!(o.status.code(), Some(1));
    let name = cut.file_name().unwrap().to_str().unwrap();
    assert!(stderr(&o).contains(&format!("{name}: byte")) && stderr(&o).contains("truncated"), "{}", stderr(&o));
    let got = read_npy(&out.join(cut.file_stem().unwrap()).with_extension("npy"));
    assert!(!got.is_empty() && got.len() < want.len(), "{} of {}", got.len(), want.len());
    assert_same(&got, &want[..got.len()], name);
}

#[test]
fn usage_errors_exit_2_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a");
    std::fs::create_dir_all(a.join("x")).unwrap();
    let b = dir.path().join("b");
    std::fs::create_dir_all(b.join("x")).unwrap();
    // Two recordings that would write the same output.
    let o = import(&dir.path().join("out"), &[], &[&a.join("x"), &b.join("x")]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("would both write"));
    let o = run("dem-import", &["--out", dir.path().to_str().unwrap(), "/nonexistent.bag"], None);
    assert_eq!(o.status.code(), Some(2));
    let o = run("dem-import", &["--out", dir.path().to_str().unwrap(), "--flippers", "a,b", "x.bag"], None);
    assert_eq!(o.status.code(), Some(2));
    let help = run("dem-import", &["--help"], None);
    assert!(String::from_utf8_lossy(ok(&help)).contains("dem-import --out dems/"));
}
