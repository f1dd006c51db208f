//! One flag vocabulary across the tools (docs/design.md, "Flags"): one
//! spelling per concept and one concept per spelling, no aliases, hidden or
//! shown, and what every tool's help shows.

use std::collections::{BTreeMap, BTreeSet};

use dem_testkit::{arg, help, ok, run, stderr, tempdir, testdata, workspace_root};

/// Every tool and subcommand with options of its own.
const TOOLS: &[&[&str]] = &[
    &["dem-apply"],
    &["dem-cat"],
    &["dem-clean-pallet"],
    &["dem-eval"],
    &["dem-eval", "transfer"],
    &["dem-eval", "merge"],
    &["dem-eval", "join"],
    &["dem-eval", "compare"],
    &["dem-fill-nans"],
    &["dem-filter"],
    &["dem-gap"],
    &["dem-import"],
    &["dem-pair"],
    &["dem-pair", "expand"],
    &["dem-render"],
    &["dem-sensor", "apply"],
    &["dem-sensor", "show"],
    &["dem-sensor", "effects"],
    &["dem-sensor", "export"],
    &["dem-split"],
    &["dem-synth"],
    &["dem-train"],
    &["dem-train", "export"],
    &["dem-train", "curves"],
];

/// The options part of a help text (the examples may show anything).
fn options(tool: &[&str]) -> String {
    let h = help(tool);
    h.split("Examples:").next().unwrap().to_string()
}

/// Each long flag of a help text with its placeholder ("" for a switch).
fn flags(tool: &[&str]) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    for line in options(tool).lines() {
        let t = line.trim_start();
        let t = if t.len() > 4 && t.starts_with('-') && t.as_bytes()[2] == b',' { &t[4..] } else { t };
        let Some(rest) = t.strip_prefix("--") else { continue };
        let name: String = rest.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '-').collect();
        if name.is_empty() || ["help", "version", "generate"].contains(&name.as_str()) {
            continue;
        }
        let after = &rest[name.len()..];
        let value = after.strip_prefix(" <").and_then(|v| v.split('>').next()).unwrap_or("").to_string();
        out.insert(format!("--{name}"), value);
    }
    out
}

/// Every long flag of every tool: flag -> (placeholder -> tools).
fn vocabulary() -> BTreeMap<String, BTreeMap<String, Vec<String>>> {
    let mut all: BTreeMap<String, BTreeMap<String, Vec<String>>> = BTreeMap::new();
    for tool in TOOLS {
        for (flag, value) in flags(tool) {
            all.entry(flag).or_default().entry(value).or_default().push(tool.join(" "));
        }
    }
    all
}

/// A flag's words without those that only say what form a value takes:
/// `--index-csv` and `--index`, `--labels-sim` and `--sim-labels` are one
/// concept each.
fn concept(flag: &str) -> Vec<String> {
    let mut words: Vec<String> = flag
        .trim_start_matches('-')
        .split('-')
        .filter(|w| !["csv", "file", "path", "npy", "json", "onnx"].contains(w))
        .map(String::from)
        .collect();
    words.sort();
    words
}

#[test]
fn one_spelling_per_concept_and_one_concept_per_spelling() {
    let all = vocabulary();
    assert!(all.len() > 100, "the help parser finds the flags: {:?}", all.keys().collect::<Vec<_>>());
    // One concept per spelling: a flag takes the same kind of value in every
    // tool. `-o, --out` is where the output goes: a file, or a folder or
    // prefix for the tools that write several files (docs/design.md).
    for (flag, values) in all.iter().filter(|(f, _)| *f != "--out") {
        assert_eq!(values.len(), 1, "{flag} takes different values in different tools: {values:?}");
    }
    // One spelling per concept: no two flags of the same words in another form or order.
    let mut seen: BTreeMap<Vec<String>, &str> = BTreeMap::new();
    for flag in all.keys() {
        if let Some(other) = seen.insert(concept(flag), flag) {
            panic!("{other} and {flag} spell one concept two ways");
        }
    }
    // Known synonyms: the one spelling kept.
    for (kept, gone) in [
        ("--out", "--output"),
        ("--index", "--index-csv"),
        ("--sim-labels", "--labels-sim"),
        ("--real-labels", "--labels-real"),
        ("--max-offset", "--max-dist"),
        ("--max-error", "--max-distance"),
        ("--emit-records", "--records-csv"),
    ] {
        assert!(all.contains_key(kept) && !all.contains_key(gone), "{kept} is the spelling, not {gone}");
    }
    // A count of records is --records (dem-split); a per-record results file --emit-records (dem-eval).
    let records = &all["--records"];
    assert_eq!(records.values().flatten().collect::<Vec<_>>(), ["dem-split"], "{records:?}");
    assert!(all["--emit-records"].values().flatten().any(|t| t == "dem-eval"));
    // A share of a record's cells is --min-valid (dem-filter); a share of a cell's sample points --min-valid-points.
    assert_eq!(all["--min-valid"].values().flatten().collect::<Vec<_>>(), ["dem-filter"]);
    assert_eq!(all["--min-valid-points"].values().flatten().collect::<Vec<_>>(), ["dem-import"]);
    // An index CSV of records to take.
    let index: Vec<&String> = all["--index"].values().flatten().collect();
    assert_eq!(index, ["dem-filter", "dem-render"]);
    // Every tool that works in parallel takes --threads.
    let threads: BTreeSet<&String> = all["--threads"].values().flatten().collect();
    for tool in ["dem-apply", "dem-eval", "dem-gap", "dem-import", "dem-synth", "dem-train"] {
        assert!(threads.contains(&tool.to_string()), "{tool} has no --threads: {threads:?}");
    }
    // Every tool with --sim and --real can silence the swap check, by one name.
    for tool in TOOLS {
        let f = flags(tool);
        if f.contains_key("--sim") && f.contains_key("--real") {
            assert!(f.contains_key("--no-swap-check"), "{tool:?} takes --sim and --real but no --no-swap-check");
        }
    }
}

#[test]
fn no_tool_has_an_alias() {
    // In the source: no alias of a flag or subcommand, shown or hidden, and no hidden flag.
    let root = workspace_root().join("crates");
    let mut files = Vec::new();
    let mut dirs = vec![root];
    while let Some(d) = dirs.pop() {
        for e in std::fs::read_dir(&d).unwrap().map(Result::unwrap) {
            let p = e.path();
            if p.is_dir() && p.file_name().is_some_and(|n| n != "target" && n != "tests") {
                dirs.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                files.push(p);
            }
        }
    }
    let mut found = Vec::new();
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        if !text.contains("clap") && !f.ends_with("main.rs") {
            continue;
        }
        for (n, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap();
            if ["alias =", "aliases =", "alias(", "aliases(", "hide = true", "hide(true)"].iter().any(|a| code.contains(a)) {
                found.push(format!("{}:{}: {}", f.display(), n + 1, line.trim()));
            }
        }
    }
    assert!(found.is_empty(), "aliases or hidden flags:\n{}", found.join("\n"));
    // At run time: the old spellings are usage errors.
    let real = testdata("real.npy").display().to_string();
    for (tool, args) in [
        ("dem-cat", vec!["--output", "x.npy", real.as_str()]),
        ("dem-pair", vec!["--by", "content", "--sim", real.as_str(), "--real", real.as_str()]),
        ("dem-pair", vec!["--match", "content", "--max-distance", "1", "--sim", real.as_str(), "--real", real.as_str()]),
        ("dem-render", vec!["--index-csv", "k.csv", real.as_str()]),
        ("dem-eval", vec!["--sim", real.as_str(), "--real", real.as_str(), "--pairs", "p.csv", "--identity", "--records", "r.csv"]),
        ("dem-import", vec!["--min-valid", "0.5", "--out", "o", "x.bag"]),
        ("dem-sensor", vec!["apply", "--model", "s.json", real.as_str()]),
    ] {
        let o = run(tool, &args, None);
        assert_eq!(o.status.code(), Some(2), "{tool} {args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains("unexpected argument"), "{tool} {args:?}: {}", stderr(&o));
    }
}

#[test]
fn every_output_is_dash_o_out() {
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
        &["dem-pair", "expand"],
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
    assert!(
        pair.contains("--match <") && pair.contains("--max-offset <") && pair.contains("--max-error <") && !pair.contains("--by"),
        "{pair}"
    );
}

#[test]
fn the_forms_the_help_shows_work() {
    let dir = tempdir();
    let d = dir.path();
    // dem-import --flippers a,b,c,d, as its help shows it, parses (the recording is what fails).
    let o = run("dem-import", &["--flippers", "a,b,c,d", "--out", &arg(d, "imp"), &arg(d, "missing.bag")], None);
    assert!(!stderr(&o).contains("--flippers"), "{}", stderr(&o));
    let o = run("dem-import", &["--flippers", "a,b,c", "--out", &arg(d, "imp"), &arg(d, "missing.bag")], None);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--flippers takes four joint names"), "{}", stderr(&o));
    // dem-pair expand takes -o as every other tool does.
    let (sim, real, pairs) = (testdata("sim.npy"), testdata("real.npy"), testdata("pairs.csv"));
    let out = arg(d, "expanded");
    let o = run(
        "dem-pair",
        &[
            "expand",
            "--pairs",
            &pairs.display().to_string(),
            "--sim",
            &sim.display().to_string(),
            "--real",
            &real.display().to_string(),
            "-o",
            &out,
        ],
        None,
    );
    ok(&o);
    assert!(std::path::Path::new(&out).join("pairs.csv").exists());
}
