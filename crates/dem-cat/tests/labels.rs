//! `dem-cat --labels ... --emit-labels`: labels joined alongside their
//! records, each file's rows re-indexed to their place in the joined stream.

use std::fs;
use std::path::Path;

use dem_testkit::{arg, ok, run, stderr, tempdir, testdata};

/// Shards of `file` with their labels (dem-split, each re-indexed from 0).
fn shards(d: &Path, file: &str, labels: &str) -> Vec<(String, String)> {
    let manifest = ok(&run(
        "dem-split",
        &[
            "--records",
            "1000",
            "--labels",
            &testdata(labels).display().to_string(),
            "--out",
            &arg(d, "part"),
            &testdata(file).display().to_string(),
        ],
        None,
    ))
    .to_vec();
    String::from_utf8(manifest)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[0].to_string(), f[3].to_string())
        })
        .collect()
}

#[test]
fn joined_labels_index_the_joined_stream() {
    let dir = tempdir();
    let d = dir.path();
    let parts = shards(d, "sim.npy", "sim_labels.csv");
    assert!(parts.len() >= 3, "{parts:?}");
    // Each shard's labels restart at 0.
    assert!(fs::read_to_string(&parts[1].1).unwrap().lines().nth(1).unwrap().starts_with("0,"));
    let (npy, csv) = (arg(d, "joined.npy"), arg(d, "joined_labels.csv"));
    let mut args: Vec<String> = parts.iter().map(|p| p.0.clone()).collect();
    let labels: Vec<String> = parts.iter().map(|p| p.1.clone()).collect();
    args.extend(["--labels".into(), labels.join(","), "-o".into(), npy.clone(), "--emit-labels".into(), csv.clone()]);
    ok(&run("dem-cat", &args.iter().map(String::as_str).collect::<Vec<_>>(), None));
    // The shards joined are the whole again: records and labels, byte for byte.
    assert_eq!(fs::read(&npy).unwrap(), fs::read(testdata("sim.npy")).unwrap());
    assert_eq!(fs::read(&csv).unwrap(), fs::read(testdata("sim_labels.csv")).unwrap());
    // Repeated --labels is the same as a comma-separated list.
    let csv2 = arg(d, "again.csv");
    let mut args: Vec<String> = parts.iter().map(|p| p.0.clone()).collect();
    for l in &labels {
        args.extend(["--labels".into(), l.clone()]);
    }
    args.extend(["-o".into(), arg(d, "again.npy"), "--emit-labels".into(), csv2.clone()]);
    ok(&run("dem-cat", &args.iter().map(String::as_str).collect::<Vec<_>>(), None));
    assert_eq!(fs::read(&csv2).unwrap(), fs::read(&csv).unwrap());
}

#[test]
fn labels_that_do_not_fit_are_refused_with_no_output() {
    let dir = tempdir();
    let d = dir.path();
    let (sim, real) = (testdata("sim.npy").display().to_string(), testdata("real.npy").display().to_string());
    let (sl, rl) = (testdata("sim_labels.csv").display().to_string(), testdata("real_labels.csv").display().to_string());
    let (npy, csv) = (arg(d, "o.npy"), arg(d, "o.csv"));
    let other_columns = arg(d, "cols.csv");
    let text = fs::read_to_string(&rl).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let mut changed = format!("{header},note\n");
    for l in lines {
        changed.push_str(&format!("{l},x\n"));
    }
    fs::write(&other_columns, changed).unwrap();
    for (args, says) in [
        (vec![sim.as_str(), real.as_str(), "--labels", rl.as_str(), "--emit-labels", csv.as_str(), "-o", npy.as_str()], "one per input"),
        (
            vec![sim.as_str(), real.as_str(), "--labels", &format!("{rl},{sl}"), "--emit-labels", csv.as_str(), "-o", npy.as_str()],
            "rows but",
        ),
        (
            vec![
                sim.as_str(),
                real.as_str(),
                "--labels",
                &format!("{sl},{other_columns}"),
                "--emit-labels",
                csv.as_str(),
                "-o",
                npy.as_str(),
            ],
            "same columns",
        ),
        (vec![sim.as_str(), "--labels", sl.as_str(), "-o", npy.as_str()], "--emit-labels"),
    ] {
        let o = run("dem-cat", &args, None);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(says), "{args:?}: {}", stderr(&o));
        assert!(!Path::new(&npy).exists() && !Path::new(&csv).exists(), "{args:?} left output");
    }
}
