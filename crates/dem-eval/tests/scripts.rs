//! scripts/eval_ci.sh and scripts/thesis_table.sh on the bundled data, with
//! the binaries of this build (they need the whole workspace built, as
//! `make test` does; with `cargo test -p dem-eval` alone they say so and skip).

use std::path::{Path, PathBuf};
use std::process::Command;

use dem_testkit::{arg, ok, py, run_cmd, stderr, tempdir, testdata, workspace_root};

const TOOLS: [&str; 6] = ["dem-eval", "dem-filter", "dem-pair", "dem-clean-pallet", "dem-fill-nans", "dem-render"];

/// The folder of this build's binaries, when every tool the scripts run is in it.
fn bin_dir() -> Option<PathBuf> {
    let dir = dem_testkit::bin("dem-eval").parent()?.to_path_buf();
    let missing: Vec<_> = TOOLS.iter().filter(|t| !dir.join(t).exists()).collect();
    if missing.is_empty() {
        return Some(dir);
    }
    eprintln!("skipped: {missing:?} not built; run `cargo test --workspace` (make test)");
    None
}

fn script(name: &str, bin: &Path, out: &Path) -> Command {
    let mut c = Command::new("bash");
    c.arg(workspace_root().join("scripts").join(name)).env("BIN", bin).env("OUT", out).env_remove("MODEL");
    c
}

#[test]
fn eval_ci_passes_on_the_committed_baseline_and_fails_on_a_better_one() {
    let Some(bin) = bin_dir() else { return };
    let dir = tempdir();
    let out = dir.path().join("ci");
    let o = run_cmd(&mut script("eval_ci.sh", &bin, &out), None);
    let text = String::from_utf8_lossy(ok(&o)).into_owned();
    assert!(text.contains("identity") && text.contains(" ok"), "{text}");
    // The identity row is deterministic: exactly the baseline's.
    let base = dem_eval::table::read_table_csv(&testdata("eval_baseline.csv").to_string_lossy()).unwrap();
    let now = dem_eval::table::read_table_csv(&arg(&out, "table.csv")).unwrap();
    assert_eq!(now.iter().find(|r| r.method == "identity"), base.iter().find(|r| r.method == "identity"));

    // A baseline 0.1 better than what we get: the script fails (exit 1).
    let better = arg(dir.path(), "better.csv");
    let mut rows = now.clone();
    rows[0].mean -= 0.1;
    dem_eval::table::write_table_csv(&better, &rows).unwrap();
    let o = run_cmd(script("eval_ci.sh", &bin, &out).env("BASELINE", &better), None);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("WORSE"));
}

#[test]
fn thesis_table_makes_the_rows_and_pictures() {
    let Some(bin) = bin_dir() else { return };
    let dir = tempdir();
    let out = dir.path().join("thesis");
    // A stand-in generator for the model rows until dem-train exists: one
    // that halves every value (onnx helper).
    py(
        dir.path(),
        r#"
import onnx
from onnx import helper, TensorProto
x = helper.make_tensor_value_info("dem", TensorProto.FLOAT, ["N", 21, 5, 2])
y = helper.make_tensor_value_info("dem_out", TensorProto.FLOAT, ["N", 21, 5, 2])
k = helper.make_tensor("k", TensorProto.FLOAT, [], [0.5])
g = helper.make_graph([helper.make_node("Mul", ["dem", "k"], ["dem_out"])], "half", [x], [y], [k])
onnx.save(helper.make_model(g, opset_imports=[helper.make_opsetid("", 13)]), "half.onnx")
"#,
    );
    let model = arg(dir.path(), "half.onnx");
    let mut c = script("thesis_table.sh", &bin, &out);
    c.env("OTHER_SENSOR", "none").env("PAIRED_MODEL", &model).env("PALLET_MODEL", &model).env("NANS_MODEL", &model);
    c.env("THESIS_MODEL", &model);
    let o = run_cmd(&mut c, None);
    let md = String::from_utf8_lossy(ok(&o)).into_owned();
    for row in ["Identity (sim as is)", "Pallets cleaned, no model", "Paired data", "Fixing pallet", "Removing NaNs"] {
        assert!(md.contains(&format!("| {row} |")), "{row} missing:\n{md}");
    }
    for fig in ["identity", "pallets-cleaned", "paired-data", "fixing-pallet", "removing-nans"] {
        let png = std::fs::read(out.join(format!("fig-{fig}.png"))).unwrap();
        assert_eq!(&png[1..4], b"PNG");
    }
    let by = std::fs::read_to_string(out.join("table_by_terrain.md")).unwrap();
    assert_eq!(by.lines().count(), 2 + 6, "{by}");
    // The measures that see heights, beside equation 7.1 (identity: sim as is, ~1.5 cm).
    let header: Vec<&str> = md.lines().find(|l| l.starts_with("| method")).unwrap().split('|').map(str::trim).collect();
    let col = header.iter().position(|c| *c == "height_cm").unwrap();
    let identity = md.lines().find(|l| l.starts_with("| Identity")).unwrap();
    let cells: Vec<&str> = identity.split('|').map(str::trim).collect();
    let height: f64 = cells[col].parse().unwrap();
    assert!(height > 0.5 && height < 3.0, "{identity}");
}
