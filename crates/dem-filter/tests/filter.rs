//! dem-filter on the bundled test data, the way users run it.

use dem_core::format::{DemCells, Terrain};
use dem_core::{npy, table};
use dem_testkit::{arg, ok, run, stderr, tempdir, testdata};

fn td(name: &str) -> String {
    testdata(name).to_string_lossy().into_owned()
}

#[test]
fn an_index_and_its_complement_join_back_to_the_input() {
    let dir = tempdir();
    let idx = arg(dir.path(), "idx.csv");
    let rows: String = (0..3025).filter(|i| i % 7 == 3 || i % 11 == 0).map(|i| format!("{i}\n")).collect();
    std::fs::write(&idx, format!("index\n{rows}")).unwrap();
    let (a, b) = (arg(dir.path(), "a.npy"), arg(dir.path(), "b.npy"));
    let (ia, ib) = (arg(dir.path(), "a.csv"), arg(dir.path(), "b.csv"));
    ok(&run("dem-filter", &["--index", &idx, &td("sim.npy"), "-o", &a, "--emit-index", &ia], None));
    ok(&run("dem-filter", &["--index", &idx, "--invert", "-o", &b, "--emit-index", &ib], Some(std::fs::read(td("sim.npy")).unwrap())));
    let input = npy::read_all(&td("sim.npy")).unwrap();
    let (ra, rb) = (npy::read_all(&a).unwrap(), npy::read_all(&b).unwrap());
    let (xa, xb) = (table::read_index(&ia).unwrap(), table::read_index(&ib).unwrap());
    assert_eq!(ra.len(), xa.len());
    assert_eq!(rb.len(), xb.len());
    assert!(!ra.is_empty() && !rb.is_empty());
    let mut joined = vec![None; input.len()];
    for (i, d) in xa.iter().zip(&ra).chain(xb.iter().zip(&rb)) {
        assert!(joined[*i as usize].replace(*d).is_none(), "index {i} in both halves");
    }
    let joined: Vec<_> = joined.into_iter().map(|d| d.expect("every index in one half")).collect();
    assert!(joined == input);
}

#[test]
fn terrain_and_other_rules_follow_the_labels_and_labels_follow_the_records() {
    let dir = tempdir();
    let (out, labels) = (arg(dir.path(), "o.npy"), arg(dir.path(), "l.csv"));
    let o = run(
        "dem-filter",
        &[
            "--labels",
            &td("sim_labels.csv"),
            "--terrain",
            "stairs-up,pallet,other",
            "--drop-other",
            &td("sim.npy"),
            "-o",
            &out,
            "--emit-labels",
            &labels,
        ],
        None,
    );
    ok(&o);
    let kept = table::read_labels(&labels).unwrap();
    let all = table::read_labels(&td("sim_labels.csv")).unwrap();
    let expected = all.iter().filter(|l| matches!(l.terrain, Terrain::StairsUp | Terrain::Pallet)).count();
    assert_eq!(kept.len(), expected);
    assert!(kept.iter().all(|l| matches!(l.terrain, Terrain::StairsUp | Terrain::Pallet)));
    assert_eq!(npy::read_all(&out).unwrap().len(), expected);
    assert!(stderr(&o).contains(&format!("kept {expected} of 3025")));
}

/// --max-time keeps the records at most that far into their run: 0 gives
/// each run's first frame (what `make demo` shows as startup frames), the
/// labels' records with time <= t in general; labels without a time are
/// refused, naming the file and line.
#[test]
fn max_time_keeps_the_first_seconds_of_every_run() {
    let dir = tempdir();
    let all = table::read_labels(&td("real_labels.csv")).unwrap();
    let real = npy::read_all(&td("real.npy")).unwrap();
    for t in ["0", "1.5"] {
        let (out, idx) = (arg(dir.path(), "t.npy"), arg(dir.path(), "t.csv"));
        ok(&run(
            "dem-filter",
            &["--labels", &td("real_labels.csv"), "--max-time", t, &td("real.npy"), "-o", &out, "--emit-index", &idx],
            None,
        ));
        let max: f64 = t.parse().unwrap();
        let want: Vec<usize> = all.iter().filter(|l| l.time.unwrap() <= max).map(|l| l.index as usize).collect();
        assert_eq!(table::read_index(&idx).unwrap(), want.iter().map(|&i| i as u64).collect::<Vec<_>>());
        assert_eq!(npy::read_all(&out).unwrap(), want.iter().map(|&i| real[i]).collect::<Vec<_>>());
        if t == "0" {
            let runs: std::collections::BTreeSet<_> = all.iter().map(|l| l.sequence).collect();
            assert_eq!(want.len(), runs.len(), "one first frame per run");
        }
    }
    let bare = arg(dir.path(), "bare.csv");
    std::fs::write(&bare, "index,terrain\n0,flat\n1,flat\n").unwrap();
    let o = run("dem-filter", &["--labels", &bare, "--max-time", "0", &td("real.npy")], None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("bare.csv") && stderr(&o).contains("line 2") && stderr(&o).contains("no time"), "{}", stderr(&o));
    let o = run("dem-filter", &["--max-time", "0", &td("real.npy")], None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// --min-time keeps the records at least that far into their run (past the
/// startup frames); with --max-time, a window of each run.
#[test]
fn min_time_leaves_out_the_first_seconds_of_every_run() {
    let dir = tempdir();
    let all = table::read_labels(&td("real_labels.csv")).unwrap();
    for (args, lo, hi) in [(vec!["--min-time", "2"], 2.0, f64::INFINITY), (vec!["--min-time", "1", "--max-time", "3"], 1.0, 3.0)] {
        let idx = arg(dir.path(), "t.csv");
        let mut a = vec!["--labels".to_string(), td("real_labels.csv")];
        a.extend(args.iter().map(|s| s.to_string()));
        a.extend([td("real.npy"), "-o".into(), arg(dir.path(), "t.npy"), "--emit-index".into(), idx.clone()]);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        let o = run("dem-filter", &a, None);
        ok(&o);
        let want: Vec<u64> = all.iter().filter(|l| (lo..=hi).contains(&l.time.unwrap())).map(|l| l.index).collect();
        assert!(!want.is_empty() && want.len() < all.len());
        assert_eq!(table::read_index(&idx).unwrap(), want);
        assert!(stderr(&o).contains(&format!("{} time", all.len() - want.len())), "{}", stderr(&o));
    }
    let o = run("dem-filter", &["--min-time", "2", &td("real.npy")], None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--min-time"), "{}", stderr(&o));
}

#[test]
fn runs_and_except_runs_split_the_stream_by_the_labels_sequence() {
    let dir = tempdir();
    let all = table::read_labels(&td("real_labels.csv")).unwrap();
    let real = npy::read_all(&td("real.npy")).unwrap();
    let held = [10u64, 11, 17];
    let mut got = Vec::new();
    for flag in ["--runs", "--except-runs"] {
        let (out, idx, labels) = (arg(dir.path(), "r.npy"), arg(dir.path(), "r.csv"), arg(dir.path(), "l.csv"));
        let o = run(
            "dem-filter",
            &[
                "--labels",
                &td("real_labels.csv"),
                flag,
                "10,11,17",
                &td("real.npy"),
                "-o",
                &out,
                "--emit-index",
                &idx,
                "--emit-labels",
                &labels,
            ],
            None,
        );
        ok(&o);
        let keep_held = flag == "--runs";
        let want: Vec<u64> = all.iter().filter(|l| held.contains(&l.sequence.unwrap()) == keep_held).map(|l| l.index).collect();
        assert!(!want.is_empty());
        let index = table::read_index(&idx).unwrap();
        assert_eq!(index, want, "{flag}");
        assert_eq!(npy::read_all(&out).unwrap(), want.iter().map(|&i| real[i as usize]).collect::<Vec<_>>());
        let kept_runs: std::collections::BTreeSet<u64> = table::read_labels(&labels).unwrap().iter().map(|l| l.sequence.unwrap()).collect();
        assert_eq!(kept_runs.iter().all(|r| held.contains(r)), keep_held, "{kept_runs:?}");
        assert!(stderr(&o).contains(&format!("{} run", all.len() - want.len())), "{}", stderr(&o));
        got.extend(index);
    }
    got.sort_unstable();
    assert_eq!(got, (0..all.len() as u64).collect::<Vec<_>>(), "the two halves are the whole, once");

    let bare = arg(dir.path(), "bare.csv");
    std::fs::write(&bare, "index,terrain\n0,flat\n").unwrap();
    let o = run("dem-filter", &["--labels", &bare, "--runs", "1", &td("real.npy")], None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("bare.csv") && stderr(&o).contains("no sequence"), "{}", stderr(&o));
    for args in [&["--runs", "1", "x.npy"][..], &["--labels", "l.csv", "--runs", "1", "--except-runs", "2", "x.npy"]] {
        let o = run("dem-filter", args, None);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert_eq!(stderr(&o).trim().lines().count(), 1, "{}", stderr(&o));
    }
}

#[test]
fn unique_drops_exact_duplicates_and_valid_rules_hold() {
    let dir = tempdir();
    let out = arg(dir.path(), "u.npy");
    ok(&run("dem-filter", &["--unique", &td("sim.npy"), "-o", &out], None));
    let u = npy::read_all(&out).unwrap();
    let set: std::collections::HashSet<Vec<u32>> = u.iter().map(|d| d.iter().map(|v| v.to_bits()).collect()).collect();
    assert_eq!(set.len(), u.len(), "duplicates left");
    assert!(u.len() < 3025, "flat sim records repeat");

    let o = run("dem-filter", &["--rows", "6..20", "--min-rows", "12", "--min-valid", "0.7", &td("real.npy")], None);
    let kept = npy::NpyReader::new(ok(&o), "stdout", None).read_to_end().unwrap();
    assert!(!kept.is_empty());
    for d in &kept {
        assert!(d.valid_cells() >= 70);
        assert!((6..20).filter(|&r| (0..5).all(|c| d.is_valid(r, c))).count() >= 12);
    }
}

#[test]
fn bad_inputs_exit_2_naming_the_file_and_leave_no_output() {
    let dir = tempdir();
    let out = arg(dir.path(), "o.npy");
    let bad_idx = arg(dir.path(), "bad.csv");
    std::fs::write(&bad_idx, "index\n1\nx\n").unwrap();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (vec!["--labels".into(), td("real_labels.csv"), "--drop-other".into(), td("sim.npy")], "real_labels.csv"),
        // Labels shorter than the stream, no rule reading them: refused, not a panic.
        (
            vec!["--labels".into(), td("real_labels.csv"), "--emit-labels".into(), arg(dir.path(), "l.csv"), td("sim.npy")],
            "real_labels.csv: has",
        ),
        (vec!["--index".into(), bad_idx.clone(), td("sim.npy")], "line 3"),
        (vec!["--terrain".into(), "flat".into(), td("sim.npy")], "--labels"),
        (vec!["--rows".into(), "6..25".into(), td("sim.npy")], "6..25"),
        (vec![arg(dir.path(), "missing.npy")], "missing.npy"),
    ];
    for (mut args, needle) in cases {
        args.extend(["-o".into(), out.clone()]);
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = run("dem-filter", &a, None);
        assert_eq!(o.status.code(), Some(2), "{a:?}");
        assert!(stderr(&o).contains(needle), "{a:?}: {}", stderr(&o));
        assert!(!std::path::Path::new(&out).exists(), "{a:?} left an output file");
    }
}
