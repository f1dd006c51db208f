//! One flag vocabulary across the tools (docs/design.md, "Flags"): what
//! every tool's help shows, and the old spellings, still accepted for a
//! release as hidden aliases, giving the same bytes as the new ones.

use dem_testkit::{arg, help, ok, run, tempdir, testdata};

/// The options part of a help text (the examples may show anything).
fn options(tool: &[&str]) -> String {
    let h = help(tool);
    h.split("Examples:").next().unwrap().to_string()
}

#[test]
fn every_output_is_dash_o_out_and_old_spellings_are_hidden() {
    let writers: &[&[&str]] = &[
        &["dem-apply"],
        &["dem-cat"],
        &["dem-clean-pallet"],
        &["dem-eval"],
        &["dem-eval", "transfer"],
        &["dem-eval", "merge"],
        &["dem-eval", "join"],
        &["dem-fill-nans"],
        &["dem-filter"],
        &["dem-gap"],
        &["dem-import"],
        &["dem-pair"],
        &["dem-render"],
        &["dem-sensor", "apply"],
        &["dem-split"],
        &["dem-synth"],
        &["dem-train"],
        &["dem-train", "export"],
        &["dem-train", "curves"],
    ];
    for tool in writers {
        let h = options(tool);
        assert!(h.contains("-o, --out <"), "{tool:?}: no `-o, --out`:\n{h}");
        for old in ["--output", "--labels-sim", "--labels-real", "--max-dist ", "--max-distance"] {
            assert!(!h.contains(old), "{tool:?} shows the old spelling {old}:\n{h}");
        }
    }
    // A sensor JSON is --sensor, an ONNX generator --model (-m).
    for tool in [&["dem-sensor", "apply"][..], &["dem-sensor", "show"], &["dem-gap"], &["dem-train"]] {
        let h = options(tool);
        assert!(h.contains("--sensor <") && !h.contains("--model"), "{tool:?}:\n{h}");
    }
    for tool in [&["dem-apply"][..], &["dem-eval"]] {
        assert!(options(tool).contains("-m, --model <"), "{tool:?}");
    }
    // Labels of two sides; --by groups a table, dem-pair matches.
    assert!(options(&["dem-gap"]).contains("--sim-labels <") && options(&["dem-gap"]).contains("--real-labels <"));
    assert!(options(&["dem-eval"]).contains("--sim-labels <"));
    let pair = options(&["dem-pair"]);
    assert!(pair.contains("--match <") && pair.contains("--max-offset <") && pair.contains("--max-error <") && !pair.contains("--by"), "{pair}");
}

#[test]
fn old_spellings_give_the_same_bytes() {
    let dir = tempdir();
    let d = dir.path();
    let (sim, real) = (testdata("sim.npy").display().to_string(), testdata("real.npy").display().to_string());
    let (sl, rl) = (testdata("sim_labels.csv").display().to_string(), testdata("real_labels.csv").display().to_string());
    let same = |tool: &str, new: &[&str], old: &[&str]| {
        let (a, b) = (arg(d, "new.out"), arg(d, "old.out"));
        ok(&run(tool, &[new, &["-o", &a]].concat(), None));
        ok(&run(tool, &[old, &["--output", &b]].concat(), None));
        assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "{tool}: {new:?} vs {old:?}");
    };
    same(
        "dem-pair",
        &["--match", "pose", "--sim-labels", &sl, "--real-labels", &rl, "--max-offset", "0.03"],
        &["--by", "pose", "--sim-labels", &sl, "--real-labels", &rl, "--max-dist", "0.03"],
    );
    same(
        "dem-pair",
        &["--match", "content", "--sim", &sim, "--real", &real, "--max-error", "0.5"],
        &["--by", "content", "--sim", &sim, "--real", &real, "--max-distance", "0.5"],
    );
    let sensor = arg(d, "s.json");
    std::fs::write(&sensor, r#"{"effects": [{"effect": "noise", "params": {"sigma0": 0.002, "k": 0.01}}]}"#).unwrap();
    same("dem-sensor", &["apply", "--sensor", &sensor, "--seed", "2", &real], &["apply", "--model", &sensor, "--seed", "2", &real]);
    let pairs = testdata("pairs.csv").display().to_string();
    let eval = |labels: &str| ["--sim", &sim, "--real", &real, "--pairs", &pairs, "--identity", labels, &sl, "--by", "terrain", "--format", "csv"].map(String::from);
    let (new, old) = (eval("--sim-labels"), eval("--labels-sim"));
    same("dem-eval", &new.iter().map(String::as_str).collect::<Vec<_>>(), &old.iter().map(String::as_str).collect::<Vec<_>>());
}
