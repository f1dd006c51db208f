//! The README's pipeline and every example of every tool's `--help` run as
//! written, as a user would paste them into bash: in a scratch directory whose files carry the names the
//! examples use (made by the tools themselves from a small world), with the
//! built binaries first on PATH. Each tool's examples run in order in their
//! own copy of that directory, so one tool's outputs (dem-import's example
//! writes a `real.npy`) never become another's inputs.
//!
//! Small sizes, the only edits to the commands (and the reason the test is
//! minutes, not an hour): `dem-synth` makes 6 runs (6 measured) where a
//! command asks for 20 or 400 or leaves the default, and `dem-train` trains
//! 1 epoch where a command says 20 or leaves the default (2 where it
//! resumes to 40). The README gives each step's time at full size.
//!
//! An example is one line under `Examples:` (indented two spaces; a deeper
//! indented line continues it, `# ...` lines are comments). The help is
//! printed with `COLUMNS=1000` so clap does not wrap it.

use std::path::{Path, PathBuf};
use std::process::Command;

use dem_testkit::{bin, python, tempdir, workspace_root};

/// Every tool and subcommand with examples.
const TOOLS: [&[&str]; 19] = [
    &["dem-apply"],
    &["dem-cat"],
    &["dem-clean-pallet"],
    &["dem-eval"],
    &["dem-eval", "compare"],
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
    &["dem-sensor"],
    &["dem-split"],
    &["dem-synth"],
    &["dem-train"],
];

/// Examples not run, each with the reason.
const NOT_RUN: [(&str, &str); 1] =
    [("scripts/transfer.sh", "the whole downstream test on testdata, minutes of training; `make demo` runs it")];

/// Runs (and measured runs) of every world the examples make.
const RUNS: &str = "6";

/// The examples of `tool [subcommand] --help`.
fn examples(tool: &[&str]) -> Vec<String> {
    let help = dem_testkit::help(tool);
    let mut out: Vec<String> = Vec::new();
    let mut inside = false;
    for line in help.lines() {
        if line.starts_with("Examples:") {
            inside = true;
            continue;
        }
        if !inside {
            continue;
        }
        if !line.is_empty() && !line.starts_with(' ') {
            break;
        }
        let text = line.trim();
        if text.is_empty() || text.starts_with('#') {
            continue;
        }
        if line.starts_with("   ") {
            let last = out.last_mut().unwrap_or_else(|| panic!("{tool:?}: an example starts indented: {line}"));
            last.push('\n');
            last.push_str(text);
        } else {
            out.push(text.to_string());
        }
    }
    assert!(!out.is_empty(), "{tool:?} --help shows no example");
    out
}

/// The command with the sizes of the module comment.
fn small(cmd: &str) -> String {
    let c = cmd
        .replace("--runs 400", &format!("--runs {RUNS}"))
        .replace("--runs 20", &format!("--runs {RUNS}"))
        .replace("--real-runs 20", &format!("--real-runs {RUNS}"))
        .replace("--epochs 20", "--epochs 1")
        .replace("--epochs 40", "--epochs 2");
    // Each dem-synth that does not say how many runs: the small world;
    // each training that does not say how long: one epoch.
    let c = with_default(&c, "dem-synth ", "", &[("--runs", RUNS), ("--real-runs", RUNS)]);
    with_default(&c, "dem-train ", "--sim ", &[("--epochs", "1")])
}

/// After each `command` (up to the next `&`, `|`, `;` or line end) that
/// contains `needs`, the flags it does not give, with their values.
fn with_default(c: &str, command: &str, needs: &str, flags: &[(&str, &str)]) -> String {
    let mut out = String::new();
    let mut rest = c;
    while let Some(at) = rest.find(command) {
        let (head, tail) = rest.split_at(at + command.len());
        out.push_str(head);
        let end = tail.find(['&', '|', ';', '\n']).unwrap_or(tail.len());
        for (flag, value) in flags.iter().filter(|_| tail[..end].contains(needs)) {
            if !tail[..end].contains(&format!("{flag} ")) {
                out.push_str(&format!("{flag} {value} "));
            }
        }
        rest = tail;
    }
    out.push_str(rest);
    out
}

/// The shell block under `## A pipeline` in the README, continued lines
/// joined, comments dropped.
fn readme_pipeline() -> String {
    readme_block("## A pipeline")
}

/// The first shell block under `heading` in the README, continued lines
/// joined, comments dropped.
fn readme_block(heading: &str) -> String {
    let readme = std::fs::read_to_string(workspace_root().join("README.md")).unwrap();
    let section = readme.split(heading).nth(1).unwrap_or_else(|| panic!("README has no `{heading}`"));
    let block = section.split("```sh\n").nth(1).and_then(|b| b.split("```").next()).expect("no sh block");
    let mut out = String::new();
    for line in block.lines() {
        let text = line.trim();
        if text.starts_with('#') || text.is_empty() {
            continue;
        }
        match text.strip_suffix('\\') {
            Some(cont) => out.push_str(cont),
            None => {
                out.push_str(text);
                out.push('\n');
            }
        }
    }
    out
}

/// Run `script` in `dir` with bash, the binaries and a `python` first on PATH.
fn bash(dir: &Path, path: &str, script: &str) -> std::process::Output {
    Command::new("bash")
        .args(["-c", &format!("set -eo pipefail\n{script}")])
        .current_dir(dir)
        .env("PATH", path)
        .env("ROOT", workspace_root())
        .env("GITHUB_STEP_SUMMARY", dir.join("step_summary.md"))
        .output()
        .unwrap()
}

/// The files the examples read, made by the tools from a small world.
const FIXTURES: &str = r#"
dem-synth --out world --runs 6 --real-runs 6 --seed 1 2>/dev/null
cp world/sim.npy world/real.npy world/sim_labels.csv world/real_labels.csv .
cp sim_labels.csv l.csv
dem-pair --match pose --sim-labels sim_labels.csv --real-labels real_labels.csv --val-fraction 0.5 --seed 1 -o pairs.csv 2>/dev/null
mkdir testdata all prep
cp sim.npy real.npy sim_labels.csv real_labels.csv pairs.csv testdata/
cp sim.npy real.npy sim_labels.csv real_labels.csv pairs.csv prep/
cp "$ROOT/testdata/eval_baseline.csv" testdata/
cp world/* all/
dem-synth --out no_fov --runs 6 --real-runs 6 --seed 1 --no-fov 2>/dev/null
for m in g_y gy g; do cp "$ROOT/testdata/torch_gen_w4.onnx" $m.onnx; done
echo '{"effects": [{"effect": "noise", "params": {"sigma0": 0.002, "k": 0.01}}, {"effect": "startup", "params": {"x0": 0.45, "v": 0.2, "p": 0.25}}]}' > sensor.json
cp sensor.json s.json
dem-sensor export --sensor sensor.json -o gy-sensor.onnx 2>/dev/null
cp sensor.json start.json
dem-cat sim.npy -o part1.npy
dem-cat real.npy -o part2.npy
dem-cat sim.npy -o big.npy
dem-eval --sim sim.npy --real real.npy --pairs pairs.csv --identity --format csv > identity.csv 2>/dev/null
dem-eval --sim sim.npy --real real.npy --pairs pairs.csv --model g.onnx --format csv > model.csv 2>/dev/null
dem-eval --sim sim.npy --real real.npy --pairs pairs.csv --identity --emit-input in.npy --emit-closest closest.npy > /dev/null 2>&1
dem-filter --labels sim_labels.csv --drop-other --unique --emit-index keep.csv sim.npy -o kept.npy 2>/dev/null
mkdir gap
cp sensor.json gap/sensor.json
dem-split --shards 2 --out part sim.npy > shards.csv 2>/dev/null
for f in part-*.npy; do cp "$f" "$f.out"; done
cat > make_dems.py <<'EOF'
import sys
import numpy as np
a = np.load("sim.npy").astype(np.float64)
a[..., 0][a[..., 1] < 0] = np.nan
np.save(sys.stdout.buffer, a)
EOF
# Recordings: the emulator's maps as a ROS 1 bag and a ROS 2 MCAP file.
dem-synth --out rec --runs 2 --real-runs 2 --seed 1 --terrains stairs-up --emit-maps 2>/dev/null
mkdir field recordings
python "$ROOT/scripts/maps_to_bag.py" rec --out field/run1.bag --format ros1
cp field/run1.bag recordings/run1.bag
python "$ROOT/scripts/maps_to_bag.py" rec --out rec_mcap --format mcap
mv rec_mcap/*.mcap stairs_2024-05-01.mcap
# The README's: what `make demo` writes to out/import/recordings/.
mkdir -p out/import/recordings
cp field/run1.bag out/import/recordings/stairs_down.bag
python "$ROOT/scripts/maps_to_bag.py" rec --out out/import/recordings/pallet --format mcap
# dem-eval compare's tables, transfer's data sets.
mkdir -p out/eval_ci
cp testdata/eval_baseline.csv out/eval_ci/table.csv
cp identity.csv base.csv
cp identity.csv current.csv
cut -d, -f1-7 identity.csv > old_7_column_table.csv
dem-eval --sim sim.npy --real real.npy --pairs pairs.csv --identity --format json -o base.json 2>/dev/null
cp base.json current.json
cp base.json a.json
cp model.csv b.csv
cp identity.csv table.csv
cp real.npy real_test.npy
cp real_labels.csv real_test_labels.csv
cp real.npy real_train.npy
cp real_labels.csv real_train_labels.csv
cp sim.npy gy_sim.npy
"#;

/// The scratch directory with the fixtures made, and the PATH to run with.
struct Scratch {
    _dir: tempfile::TempDir,
    work: PathBuf,
    base: PathBuf,
    path: String,
}

impl Scratch {
    fn new() -> Scratch {
        let dir = tempdir();
        let work = dir.path().to_path_buf();
        // `python` as the examples call it: the test's interpreter.
        let shims = work.join(".bin");
        std::fs::create_dir(&shims).unwrap();
        // A script, not a symlink: a venv's python finds its packages by the
        // path it was started from.
        let shim = shims.join("python");
        std::fs::write(&shim, format!("#!/bin/sh\nexec '{}' \"$@\"\n", python().display())).unwrap();
        std::fs::set_permissions(&shim, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
        let bins: PathBuf = bin("dem-cat").parent().unwrap().to_path_buf();
        let path = format!("{}:{}:{}", bins.display(), shims.display(), std::env::var("PATH").unwrap_or_default());
        let base = work.join("fixtures");
        std::fs::create_dir(&base).unwrap();
        let o = bash(&base, &path, FIXTURES);
        assert!(o.status.success(), "fixtures:\n{}", String::from_utf8_lossy(&o.stderr));
        Scratch { _dir: dir, work, base, path }
    }

    /// A fresh copy of the fixtures, named `name`.
    fn copy(&self, name: &str) -> PathBuf {
        let here = self.work.join(name);
        let o = Command::new("cp").arg("-a").arg(&self.base).arg(&here).output().unwrap();
        assert!(o.status.success(), "cp -a: {}", String::from_utf8_lossy(&o.stderr));
        here
    }
}

/// The README's quickstart, as written, on the bundled testdata (its own
/// sizes: it is the one block that runs on them).
#[test]
fn the_readme_quickstart_runs() {
    let s = Scratch::new();
    let here = s.work.join("quickstart");
    std::fs::create_dir(&here).unwrap();
    let script = format!("cp -r \"$ROOT/testdata\" testdata\n{}", readme_block("## Quickstart"));
    assert!(script.lines().count() >= 4, "{script}");
    let o = bash(&here, &s.path, &format!("set -x\n{script}"));
    assert!(o.status.success(), "the README's quickstart failed ({}):\n{}", o.status, String::from_utf8_lossy(&o.stderr));
    for f in ["gap/report.md", "gap/sensor.json", "sensor.onnx", "modelled.png"] {
        assert!(here.join(f).exists(), "the README's quickstart wrote no {f}");
    }
}

/// The file `make demo` hands out is a product: its steps that make it
/// (preparation, G_Y, the virtual sensor) run as the demo runs them, and
/// the virtual sensor meets every goal `scripts/sensor_goals.py --goals
/// demo` checks on testdata's measured DEMs of the same poses (heights,
/// roughness, the spread of record means, whole-row holes, whole-record
/// lifts), which the demo's last lines report.
#[test]
fn the_demo_s_virtual_sensor_meets_its_goals() {
    let dir = tempdir();
    let root = workspace_root();
    let bin_dir = bin("dem-apply").parent().unwrap().to_path_buf();
    let o = Command::new("bash")
        .arg(root.join("scripts/demo_fast.sh"))
        .args(["prep", "train", "sensor"])
        .current_dir(&root)
        .env("BIN", &bin_dir)
        .env("OUT", dir.path())
        .env("PY", python())
        .env("TD", root.join("testdata"))
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "the demo's sensor steps failed ({}):\n{out}\n{}", o.status, String::from_utf8_lossy(&o.stderr));
    let goals = std::fs::read_to_string(dir.path().join("virtual_sensor_goals.txt")).unwrap();
    let lines: Vec<&str> = goals.lines().filter(|l| l.starts_with("goal (demo)")).collect();
    assert_eq!(lines.len(), 5, "{goals}");
    assert!(lines.iter().all(|l| l.ends_with(": ok")), "the demo's virtual sensor misses a goal:\n{goals}");
    assert!(dir.path().join("virtual_sensor.onnx").exists());
}

#[test]
fn the_readme_pipeline_runs() {
    let s = Scratch::new();
    let here = s.copy("readme");
    let script = small(&readme_pipeline());
    assert!(script.lines().count() >= 15, "{script}");
    let o = bash(&here, &s.path, &format!("set -x\n{script}"));
    assert!(o.status.success(), "the README's pipeline failed ({}):\n{}", o.status, String::from_utf8_lossy(&o.stderr));
    for f in ["pairs.png", "keys.png", "seen.png", "gy.onnx", "curves.png", "realistic.npy", "modelled.png", "virtual.npy"] {
        assert!(here.join(f).exists(), "the README's pipeline wrote no {f}");
    }
}

#[test]
fn every_help_example_runs() {
    let s = Scratch::new();
    let (work, path) = (&s.work, &s.path);
    let has_parallel = bash(work, path, "command -v parallel").status.success();
    let mut ran = 0;
    for tool in TOOLS {
        let here = s.copy(&tool.join("-"));
        // A skipped example's outputs are the next examples' inputs: the
        // rest of this tool's examples are skipped with it.
        let mut skipping = false;
        for example in examples(tool) {
            if let Some((_, why)) = NOT_RUN.iter().find(|(e, _)| example.starts_with(e)) {
                eprintln!("not run ({why}): {example}");
                continue;
            }
            if skipping || (example.starts_with("parallel ") && !has_parallel) {
                eprintln!("skipped (GNU parallel is not installed): {example}");
                skipping = true;
                continue;
            }
            let cmd = small(&example);
            let o = bash(&here, path, &cmd);
            assert!(
                o.status.success(),
                "{tool:?} --help example failed ({}):\n{cmd}\n--- stderr:\n{}",
                o.status,
                String::from_utf8_lossy(&o.stderr)
            );
            ran += 1;
        }
    }
    eprintln!("{ran} examples ran");
    assert!(ran >= 70, "only {ran} examples ran (75 when this test was written)");
}

#[test]
fn small_sizes_only_shrink_worlds_and_epochs() {
    assert_eq!(
        small("dem-synth --out run/ && dem-cat run/sim.npy | dem-render -o sim.png -"),
        "dem-synth --runs 6 --real-runs 6 --out run/ && dem-cat run/sim.npy | dem-render -o sim.png -"
    );
    assert_eq!(small("dem-synth --out run/ --runs 400 --real-runs 20 --seed 1"), "dem-synth --out run/ --runs 6 --real-runs 6 --seed 1");
    assert_eq!(small("dem-synth --out maps/ --runs 4 --real-runs 2 --seed 1"), "dem-synth --out maps/ --runs 4 --real-runs 2 --seed 1");
    assert_eq!(
        small("dem-synth --out w --runs 20 --seed 3 && dem-apply"),
        "dem-synth --real-runs 6 --out w --runs 6 --seed 3 && dem-apply"
    );
    assert_eq!(small("dem-train --sim s.npy --out run/ --epochs 40 --resume"), "dem-train --sim s.npy --out run/ --epochs 2 --resume");
    assert_eq!(
        small("dem-train --sim k.npy --out t/ --seed 1\ndem-train export t/"),
        "dem-train --epochs 1 --sim k.npy --out t/ --seed 1\ndem-train export t/"
    );
    assert_eq!(small("dem-render --compare a.npy b.npy -o x.png"), "dem-render --compare a.npy b.npy -o x.png");
}
