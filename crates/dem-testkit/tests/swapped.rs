//! Sim and real given the wrong way round: every tool that takes `--sim`
//! and `--real` warns on one stderr line naming both files, still does its
//! work (exit 0), is quiet with `--no-swap-check`, and says nothing when
//! the order is right.

use std::path::Path;

use dem_testkit::{arg, ok, run, stderr, tempdir, testdata};

/// The first `n` records of `file` as `name` in `dir`.
fn head(dir: &Path, file: &str, n: &str, name: &str) -> String {
    let prefix = arg(dir, name);
    ok(&run("dem-split", &["--records", n, "--out", &prefix, &testdata(file).display().to_string()], None));
    format!("{prefix}-00000.npy")
}

/// Each tool's command line with `sim` and `real` as given.
fn commands(d: &Path, sim: &str, real: &str, pairs: &str, run_name: &str) -> Vec<(&'static str, Vec<String>)> {
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    vec![
        ("dem-eval", s(&["--sim", sim, "--real", real, "--pairs", pairs, "--identity", "-o", &arg(d, &format!("{run_name}-t.txt"))])),
        ("dem-pair", s(&["--match", "content", "--sim", sim, "--real", real, "-o", &arg(d, &format!("{run_name}-p.csv"))])),
        ("dem-pair", s(&["expand", "--pairs", pairs, "--sim", sim, "--real", real, "-o", &arg(d, &format!("{run_name}-x"))])),
        (
            "dem-gap",
            s(&["--sim", sim, "--real", real, "--max-steps", "1", "--fit-records", "50", "-o", &arg(d, &format!("{run_name}-gap"))]),
        ),
        (
            "dem-train",
            s(&[
                "--sim",
                sim,
                "--real",
                real,
                "--width",
                "4",
                "--batch",
                "4",
                "--max-steps",
                "1",
                "-o",
                &arg(d, &format!("{run_name}-run")),
            ]),
        ),
    ]
}

#[test]
fn swapped_inputs_warn_naming_both_files_and_the_right_order_does_not() {
    let dir = tempdir();
    let d = dir.path();
    let (sim, real) = (head(d, "sim.npy", "60", "sim"), head(d, "real.npy", "60", "real"));
    let pairs = arg(d, "pairs.csv");
    std::fs::write(&pairs, "sim_index,real_index,split\n0,0,val\n1,1,val\n2,5,val\n").unwrap();
    let quiet_runs = commands(d, &real, &sim, &pairs, "quiet");
    for ((tool, args), (_, quiet_args)) in commands(d, &real, &sim, &pairs, "swapped").into_iter().zip(quiet_runs) {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = run(tool, &a, None);
        ok(&o);
        let e = stderr(&o);
        let warnings: Vec<&str> = e.lines().filter(|l| l.contains("look swapped")).collect();
        assert_eq!(warnings.len(), 1, "{tool} {a:?}: one warning line:\n{e}");
        let w = warnings[0];
        assert!(
            w.contains(&format!("--sim {real}")) && w.contains(&format!("--real {sim}")) && w.contains("--no-swap-check"),
            "{tool}: {w}"
        );
        // Silenced.
        let q: Vec<&str> = quiet_args.iter().map(String::as_str).chain(["--no-swap-check"]).collect();
        let quiet = run(tool, &q, None);
        ok(&quiet);
        assert!(!stderr(&quiet).contains("look swapped"), "{tool} --no-swap-check:\n{}", stderr(&quiet));
    }
    for (tool, args) in commands(d, &sim, &real, &pairs, "right") {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = run(tool, &a, None);
        ok(&o);
        assert!(!stderr(&o).contains("look swapped"), "{tool} {a:?} in the right order:\n{}", stderr(&o));
    }
}
