//! The holes a hostile test found, each closed and kept closed by a
//! run of the real binaries. docs/reliability.md lists every case with the
//! test that proves it; the test names here are the ones it cites.

use std::fs;
use std::io::Read;
use std::path::Path;
use std::process::{Command, Output, Stdio};

use dem_testkit::{arg, bin, ok, py, run, stderr, tempdir, testdata};

fn td(name: &str) -> String {
    testdata(name).to_string_lossy().into_owned()
}

/// Exit 2 and a single stderr line that starts with the tool's name and
/// contains every one of `says`.
fn refused(o: &Output, tool: &str, says: &[&str]) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{tool}: expected exit 2\n{e}");
    let lines: Vec<&str> = e.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "{tool}: expected one line\n{e}");
    assert!(lines[0].starts_with(&format!("{tool}: error: ")), "{e}");
    for s in says {
        assert!(lines[0].contains(s), "{tool}: expected {s:?} in\n{e}");
    }
}

/// Bytes of an NPY file (v1 header) with value `v` at flat index `j` of
/// record `r`.
fn patched(src: &str, r: usize, j: usize, v: f32) -> Vec<u8> {
    let mut b = fs::read(src).unwrap();
    assert_eq!(&b[..6], b"\x93NUMPY");
    let start = 10 + u16::from_le_bytes([b[8], b[9]]) as usize;
    let at = start + r * 840 + j * 4;
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
    b
}

/// Run `cmd` with stdout to a pipe, read `n` bytes, close the pipe and
/// return the exit code.
fn exit_after_reading(cmd: &mut Command, n: usize) -> Option<i32> {
    let mut child = cmd.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let mut out = child.stdout.take().unwrap();
    let mut buf = vec![0u8; n];
    out.read_exact(&mut buf).unwrap();
    drop(out);
    let o = child.wait_with_output().unwrap();
    assert!(stderr(&o).is_empty(), "a closed pipe is not an error:\n{}", stderr(&o));
    o.status.code()
}

/// A stream of `k` copies of testdata's sim.npy (3,025 records each).
fn big_stream(dir: &Path, k: usize) -> String {
    let path = arg(dir, "big.npy");
    let inputs: Vec<String> = (0..k).map(|_| td("sim.npy")).collect();
    let mut args: Vec<&str> = inputs.iter().map(String::as_str).collect();
    args.extend(["-o", &path]);
    ok(&run("dem-cat", &args, None));
    path
}

// 1. A closed pipe ends every tool quietly with exit 0.
#[test]
fn closed_pipe_exits_0_for_csv_writers() {
    let dir = tempdir();
    let big = big_stream(dir.path(), 10);
    let (sim, real) = (td("sim.npy"), td("real.npy"));
    let mut pair = Command::new(bin("dem-pair"));
    pair.args(["--match", "content", "--sim", &sim, "--real", &real, "--k", "50"]);
    assert_eq!(exit_after_reading(&mut pair, 100), Some(0));
    let mut pose = Command::new(bin("dem-pair"));
    pose.args([
        "--match",
        "pose",
        "--sim-labels",
        &td("sim_labels.csv"),
        "--real-labels",
        &td("real_labels.csv"),
        "--max-offset",
        "5",
        "--max-yaw",
        "3",
    ]);
    assert_eq!(exit_after_reading(&mut pose, 100), Some(0));
    let mut filter = Command::new(bin("dem-filter"));
    filter.args([&big, "--emit-index", "-", "-o", "/dev/null"]);
    assert_eq!(exit_after_reading(&mut filter, 100), Some(0));
}

// 2. One writer per run folder.
#[test]
fn a_run_folder_takes_one_dem_train_at_a_time() {
    let dir = tempdir();
    let out = arg(dir.path(), "run");
    let base = ["--sim", &td("sim.npy"), "--real", &td("real.npy"), "--pairs", &td("pairs.csv"), "--out", &out, "--width", "4"];
    let mut first = Command::new(bin("dem-train"));
    first.args(base).args(["--epochs", "1000"]).stdout(Stdio::null()).stderr(Stdio::null());
    let mut child = first.spawn().unwrap();
    // Wait until the first run has its data and is training.
    let losses = Path::new(&out).join("losses.csv");
    for _ in 0..600 {
        if losses.exists() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    assert!(losses.exists(), "the first run never started");
    let second = run("dem-train", &base, None);
    let resume = run("dem-train", &[&base[..], &["--resume"]].concat(), None);
    child.kill().unwrap();
    child.wait().unwrap();
    refused(&second, "dem-train", &["is in use by another dem-train"]);
    refused(&resume, "dem-train", &["is in use by another dem-train"]);
    // The lock goes with the process, also after a kill: resume works.
    let again = run("dem-train", &[&base[..], &["--resume", "--max-steps", "1"]].concat(), None);
    assert!(!stderr(&again).contains("in use"), "{}", stderr(&again));
}

// 3. Non-finite and nonsense values are refused, in one line naming the flag.
#[test]
fn non_finite_and_nonsense_values_are_refused() {
    let dir = tempdir();
    let (sim, real, pairs) = (td("sim.npy"), td("real.npy"), td("pairs.csv"));
    let out = arg(dir.path(), "o");
    let train = ["--sim", sim.as_str(), "--real", real.as_str(), "--pairs", pairs.as_str(), "--out", out.as_str()];
    let pair = ["--match", "content", "--sim", sim.as_str(), "--real", real.as_str()];
    let synth = ["--out", out.as_str(), "--runs", "2", "--real-runs", "1"];
    let cases: Vec<(&str, Vec<&str>, &str)> = vec![
        ("dem-train", [&train[..], &["--lr", "nan"]].concat(), "--lr"),
        ("dem-train", [&train[..], &["--lr", "inf"]].concat(), "--lr"),
        ("dem-train", [&train[..], &["--lr=-1"]].concat(), "--lr"),
        ("dem-train", [&train[..], &["--lambda-pair", "nan"]].concat(), "--lambda-pair"),
        ("dem-train", [&train[..], &["--lambda-cyc=-1"]].concat(), "--lambda-cyc"),
        ("dem-train", [&train[..], &["--threads", "0"]].concat(), "--threads"),
        ("dem-train", [&train[..], &["--epochs", "0"]].concat(), "--epochs"),
        ("dem-train", [&train[..], &["--checkpoint-every", "0"]].concat(), "--checkpoint-every"),
        ("dem-pair", [&pair[..], &["--max-error", "nan"]].concat(), "--max-error"),
        ("dem-pair", [&pair[..], &["--max-error=-1"]].concat(), "--max-error"),
        ("dem-pair", [&pair[..], &["--max-offset", "nan"]].concat(), "--max-offset"),
        // An old spelling is refused under the flag's name of today.
        ("dem-pair", [&pair[..], &["--max-error", "nan"]].concat(), "--max-error"),
        ("dem-pair", [&pair[..], &["--max-yaw=-1"]].concat(), "--max-yaw"),
        ("dem-synth", [&synth[..], &["--camera-height=-1"]].concat(), "--camera-height"),
        ("dem-synth", [&synth[..], &["--camera-height", "nan"]].concat(), "--camera-height"),
        ("dem-synth", [&synth[..], &["--camera-tilt", "1000"]].concat(), "--camera-tilt"),
        ("dem-synth", [&synth[..], &["--threads", "0"]].concat(), "--threads"),
        ("dem-synth", ["--out", out.as_str(), "--runs", "0"].to_vec(), "--runs"),
        ("dem-apply", ["--model", "m.onnx", "--threads", "0"].to_vec(), "--threads"),
        ("dem-filter", ["--min-valid", "nan", sim.as_str()].to_vec(), "--min-valid"),
        ("dem-fill-nans", ["--keep-fraction", "inf", sim.as_str()].to_vec(), "--keep-fraction"),
        ("dem-render", ["--vmin", "nan", sim.as_str(), "-o", "x.png"].to_vec(), "--vmin"),
        ("dem-gap", ["--sim", sim.as_str(), "--real", real.as_str(), "--out", out.as_str(), "--min-gain", "nan"].to_vec(), "--min-gain"),
        ("dem-pair", ["--match", "content", "--seed", "-1"].to_vec(), "--seed"),
    ];
    for (tool, args, flag) in cases {
        let o = run(tool, &args, None);
        refused(&o, tool, &[flag]);
    }
    assert!(!Path::new(&out).exists(), "no refused run leaves a folder");
}

#[test]
fn sensor_models_with_unknown_keys_or_huge_values_are_refused() {
    let dir = tempdir();
    for (name, json, says) in [
        ("huge.json", r#"{"effects":[{"effect":"bias","params":{"b":3e38,"t":0}}]}"#, "b = 3e38 is outside"),
        ("key.json", r#"{"effects":[{"effect":"bias","params":{"b":0.1,"t":0,"tilt":1}}]}"#, "unknown field `tilt`"),
        ("top.json", r#"{"effects":[],"efects":[]}"#, "unknown field `efects`"),
    ] {
        let m = arg(dir.path(), name);
        fs::write(&m, json).unwrap();
        let o = run("dem-sensor", &["apply", "--sensor", &m, &td("sim.npy"), "-o", &arg(dir.path(), "o.npy")], None);
        refused(&o, "dem-sensor", &[name, says]);
    }
    assert!(!dir.path().join("o.npy").exists());
}

// 4. Infinite heights (and NaN masks) are refused by every reader.
#[test]
fn infinite_values_are_refused_by_every_tool_naming_the_record() {
    let dir = tempdir();
    let bad = arg(dir.path(), "inf.npy");
    // Record 5, row 3, column 2, height.
    fs::write(&bad, patched(&td("sim.npy"), 5, 3 * 10 + 2 * 2, f32::INFINITY)).unwrap();
    let nanmask = arg(dir.path(), "nanmask.npy");
    fs::write(&nanmask, patched(&td("real.npy"), 7, 4 * 10 + 1, f32::NAN)).unwrap();
    let id = arg(dir.path(), "id.json");
    fs::write(&id, r#"{"effects":[{"effect":"noise","params":{"sigma0":0.003,"k":0.01}}]}"#).unwrap();
    let o = |n: &str| arg(dir.path(), n);
    let inf_says = ["inf.npy: record 5", "inf in the height at row 3, column 2"];
    let real = td("real.npy");
    let pairs = td("pairs.csv");
    let cases: Vec<(&str, Vec<String>, [&str; 2])> = vec![
        ("dem-cat", vec![bad.clone(), "-o".into(), o("a.npy")], inf_says),
        ("dem-filter", vec![bad.clone(), "-o".into(), o("b.npy")], inf_says),
        ("dem-sensor", vec!["apply".into(), "--sensor".into(), id.clone(), bad.clone(), "-o".into(), o("c.npy")], inf_says),
        (
            "dem-pair",
            vec!["--match".into(), "content".into(), "--sim".into(), bad.clone(), "--real".into(), real.clone(), "-o".into(), o("d.csv")],
            inf_says,
        ),
        (
            "dem-eval",
            vec!["--sim".into(), bad.clone(), "--real".into(), real.clone(), "--pairs".into(), pairs.clone(), "--identity".into()],
            inf_says,
        ),
        ("dem-gap", vec!["--sim".into(), bad.clone(), "--real".into(), real.clone(), "--out".into(), o("gap")], inf_says),
        ("dem-fill-nans", vec![bad.clone(), "-o".into(), o("e.npy")], inf_says),
        ("dem-clean-pallet", vec![bad.clone(), "-o".into(), o("f.npy")], inf_says),
        ("dem-render", vec![bad.clone(), "--start".into(), "0".into(), "-o".into(), o("g.png")], inf_says),
        ("dem-cat", vec![nanmask.clone(), "-o".into(), o("h.npy")], ["nanmask.npy: record 7", "NaN in the mask at row 4, column 0"]),
    ];
    for (tool, args, says) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        refused(&run(tool, &args, None), tool, &says);
    }
    let left: Vec<String> = fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    let mut left = left.into_iter().filter(|f| !["inf.npy", "nanmask.npy", "id.json"].contains(&f.as_str())).collect::<Vec<_>>();
    left.retain(|f| f != "gap" || fs::read_dir(dir.path().join("gap")).unwrap().count() > 0);
    assert!(left.is_empty(), "outputs left behind: {left:?}");
}

fn onnx_model(dir: &Path, name: &str, op: &str) -> String {
    dem_testkit::onnx_one_node(dir, name, op)
}

// 5. Bad model output is refused, not scored.
#[test]
fn dem_eval_refuses_nan_and_inf_model_output() {
    let dir = tempdir();
    let eval = |model: &str| {
        run("dem-eval", &["--sim", &td("sim.npy"), "--real", &td("real.npy"), "--pairs", &td("pairs.csv"), "--model", model], None)
    };
    // log(-0.07) is NaN; 1/0 (a missing cell's height) is an infinity.
    let nan = onnx_model(dir.path(), "log.onnx", "Log");
    refused(&eval(&nan), "dem-eval", &["log.onnx", "the model's output for record", "is NaN"]);
    let inf = onnx_model(dir.path(), "recip.onnx", "Reciprocal");
    refused(&eval(&inf), "dem-eval", &["recip.onnx", "is inf"]);
}

#[test]
fn a_model_that_changes_the_attitude_is_warned_about_and_refused_under_strict() {
    let dir = tempdir();
    let neg = onnx_model(dir.path(), "neg.onnx", "Neg");
    let ident = onnx_model(dir.path(), "ident.onnx", "Identity");
    let out = arg(dir.path(), "o.npy");
    let warned = run("dem-apply", &["--model", &neg, &td("real.npy"), "-o", &out], None);
    ok(&warned);
    assert!(stderr(&warned).contains("does not pass row 20 (the attitude) through: 966 record(s)"), "{}", stderr(&warned));
    let strict = run("dem-apply", &["--model", &neg, "--strict", &td("real.npy"), "-o", &arg(dir.path(), "s.npy")], None);
    refused(&strict, "dem-apply", &["--strict", "record 0", "row 20"]);
    assert!(!dir.path().join("s.npy").exists());
    let fine = run("dem-apply", &["--model", &ident, "--strict", &td("real.npy"), "-o", &out], None);
    assert!(!stderr(&ok_out(fine)).contains("row 20"));
    let eval = |model: &str, strict: bool| {
        let mut a = vec!["--sim", "x", "--real", "x", "--pairs", "x", "--model", model];
        let (s, r, p) = (td("sim.npy"), td("real.npy"), td("pairs.csv"));
        let owned = [s, r, p];
        a[1] = &owned[0];
        a[3] = &owned[1];
        a[5] = &owned[2];
        if strict {
            a.push("--strict");
        }
        run("dem-eval", &a, None)
    };
    let w = eval(&neg, false);
    ok(&w);
    assert!(stderr(&w).contains("does not pass row 20"), "{}", stderr(&w));
    refused(&eval(&neg, true), "dem-eval", &["--strict", "row 20"]);
}

fn ok_out(o: Output) -> Output {
    ok(&o);
    o
}

// 6. Indices past the end are refused, naming the CSV line.
#[test]
fn index_csvs_past_the_end_are_refused_naming_the_line() {
    let dir = tempdir();
    let idx = arg(dir.path(), "i.csv");
    fs::write(&idx, "index\n0\n5\n3025\n").unwrap();
    let out = arg(dir.path(), "k.npy");
    refused(
        &run("dem-filter", &["--index", &idx, &td("sim.npy"), "-o", &out], None),
        "dem-filter",
        &["i.csv: line 4", "index 3025 is past the end"],
    );
    assert!(!Path::new(&out).exists());
    refused(
        &run("dem-render", &["--index", &idx, &td("sim.npy"), "-o", &arg(dir.path(), "k.png")], None),
        "dem-render",
        &["i.csv: line 4", "index 3025 is past the end"],
    );
    // dem-eval --split val checks the train rows too.
    let pairs = arg(dir.path(), "p.csv");
    fs::write(&pairs, "sim_index,real_index,split\n0,0,val\n1,99999,train\n").unwrap();
    let o = run("dem-eval", &["--sim", &td("sim.npy"), "--real", &td("real.npy"), "--pairs", &pairs, "--split", "val", "--identity"], None);
    refused(&o, "dem-eval", &["p.csv: line 3", "real_index 99999 is past the end"]);
}

// 7. No output overwrites an input.
#[test]
fn no_output_overwrites_an_input() {
    let dir = tempdir();
    let s = arg(dir.path(), "s.npy");
    fs::copy(td("sim.npy"), &s).unwrap();
    let m = onnx_model(dir.path(), "m.onnx", "Identity");
    let before = (fs::read(&s).unwrap(), fs::read(&m).unwrap());
    let (real, pairs) = (td("real.npy"), td("pairs.csv"));
    let cases: Vec<(&str, Vec<&str>)> = vec![
        ("dem-eval", vec!["--sim", &s, "--real", &real, "--pairs", &pairs, "--identity", "--emit-pred", &s]),
        ("dem-pair", vec!["--match", "content", "--sim", &s, "--real", &real, "-o", &s]),
        ("dem-apply", vec!["-m", &m, &s, "-o", &m]),
        ("dem-filter", vec![&s, "--emit-index", &s, "-o", "/dev/null"]),
        ("dem-cat", vec![&s, "-o", &s]),
        ("dem-fill-nans", vec![&s, "-o", &s]),
        ("dem-clean-pallet", vec![&s, "-o", &s]),
    ];
    for (tool, args) in cases {
        refused(&run(tool, &args, None), tool, &["would overwrite the input"]);
    }
    // A redirected stdout that is an input (`dem-filter s.npy >> s.npy`).
    let append = fs::OpenOptions::new().append(true).open(&s).unwrap();
    let o = Command::new(bin("dem-filter")).arg(&s).stdin(Stdio::null()).stdout(append).output().unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("output stdout would overwrite the input"), "{}", stderr(&o));
    assert_eq!((fs::read(&s).unwrap(), fs::read(&m).unwrap()), before, "inputs untouched");
}

// 8. What a kill leaves: stale temp files are cleaned; a redirected file
// stays readable up to its last complete chunk.
#[test]
fn stale_temp_files_of_a_killed_run_are_removed_on_the_next_run() {
    let dir = tempdir();
    let host = fs::read_to_string("/proc/sys/kernel/hostname").unwrap().trim().replace(['/', '.'], "_");
    // pid 4194304 is above Linux's pid_max: never alive.
    let stale = dir.path().join(format!(".out.npy.{host}-4194304.Ab12Cd.tmp"));
    fs::write(&stale, vec![0u8; 1 << 20]).unwrap();
    let o = run("dem-cat", &[&td("real.npy"), "-o", &arg(dir.path(), "out.npy")], None);
    ok(&o);
    assert!(!stale.exists());
    assert!(stderr(&o).contains("a temp file left by a killed run (pid 4194304)"), "{}", stderr(&o));
}

#[test]
fn a_killed_write_to_a_redirected_stdout_reads_up_to_its_last_complete_chunk() {
    let dir = tempdir();
    let path = arg(dir.path(), "redirected.npy");
    let file = fs::File::create(&path).unwrap();
    let mut child = Command::new(bin("dem-cat")).stdin(Stdio::piped()).stdout(file).stderr(Stdio::null()).spawn().unwrap();
    // Feed five arrays of 3,025 records and keep stdin open, so dem-cat
    // waits, blocked, with its work on disk.
    let big = fs::read(td("sim.npy")).unwrap();
    let mut stdin = child.stdin.take().unwrap();
    use std::io::Write;
    for _ in 0..5 {
        stdin.write_all(&big).unwrap();
    }
    stdin.flush().unwrap();
    // The header is patched each time 4,096 or more records have come in
    // since the last patch: after arrays 2 and 4, so it says 12,100.
    let want = 4 * 3025u64;
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while fs::metadata(&path).unwrap().len() < 128 + want * 840 && std::time::Instant::now() < deadline {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    std::thread::sleep(std::time::Duration::from_millis(200));
    child.kill().unwrap();
    child.wait().unwrap();
    drop(stdin);
    let shape = py(dir.path(), "import numpy as np; print(np.load('redirected.npy').shape[0])");
    assert_eq!(shape.trim(), want.to_string(), "numpy reads the complete chunks");
}

// 9. Messages: one line naming the tool; outputs checked before the work.
#[test]
fn usage_errors_are_one_line_naming_the_tool() {
    refused(&run("dem-pair", &["--match", "content", "--seed", "-1"], None), "dem-pair", &["--seed"]);
    refused(&run("dem-cat", &["--no-such-flag"], None), "dem-cat", &["--no-such-flag"]);
    refused(&run("dem-eval", &["--identity", "--model", "m.onnx"], None), "dem-eval", &["cannot be used with"]);
    refused(&run("dem-synth", &[], None), "dem-synth", &["--out"]);
}

#[test]
fn an_empty_input_is_named() {
    let dir = tempdir();
    let empty = arg(dir.path(), "empty.npy");
    fs::write(&empty, b"").unwrap();
    let o = run("dem-pair", &["--match", "content", "--sim", &empty, "--real", &td("real.npy")], None);
    refused(&o, "dem-pair", &["empty.npy: holds no records"]);
    let run_dir = arg(dir.path(), "run");
    let o = run("dem-train", &["--sim", &empty, "--real", &td("real.npy"), "--out", &run_dir], None);
    refused(&o, "dem-train", &["empty.npy: no records"]);
    assert!(!Path::new(&run_dir).exists(), "a refused run leaves no folder");
}

#[test]
fn dem_gap_checks_its_out_folder_before_the_analysis() {
    let dir = tempdir();
    let file = arg(dir.path(), "a_file");
    fs::write(&file, b"x").unwrap();
    let o = run("dem-gap", &["--sim", &td("sim.npy"), "--real", &td("real.npy"), "--out", &file], None);
    refused(&o, "dem-gap", &["is a file, not a folder"]);
    // Its sensor model is an input: --out beside it must not overwrite it.
    let gap = dir.path().join("gap");
    fs::create_dir(&gap).unwrap();
    let model = gap.join("sensor.json");
    fs::write(&model, r#"{"effects":[]}"#).unwrap();
    let o = run(
        "dem-gap",
        &["--sim", &td("sim.npy"), "--real", &td("real.npy"), "--sensor", &model.to_string_lossy(), "--out", &gap.to_string_lossy()],
        None,
    );
    refused(&o, "dem-gap", &["would overwrite the input"]);
}

#[test]
fn unwritable_outputs_exit_2_a_full_disk_exits_1() {
    let dir = tempdir();
    let missing = arg(dir.path(), "no/such/folder/o.npy");
    let o = run("dem-cat", &[&td("real.npy"), "-o", &missing], None);
    refused(&o, "dem-cat", &["failed to open", "no/such/folder/o.npy"]);
    let o = run("dem-cat", &[&td("real.npy"), "-o", dir.path().to_str().unwrap()], None);
    refused(&o, "dem-cat", &["is a folder"]);
    // /dev/full: every write fails with ENOSPC, an I/O failure.
    let o = run("dem-cat", &[&td("real.npy"), "-o", "/dev/full"], None);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("/dev/full") && stderr(&o).contains("No space left"), "{}", stderr(&o));
}

// 10. dem-eval streams: blocks of selected records, a prediction stream whose
// arrays split differently from the sim file's, reals read by index. The
// result is the same as evaluating the same records as Identity.
#[test]
fn dem_eval_in_blocks_equals_identity_whatever_the_array_boundaries() {
    let dir = tempdir();
    let sim = arg(dir.path(), "sim3.npy");
    let (t, r) = (td("sim.npy"), td("real.npy"));
    ok(&run("dem-cat", &[&t, &t, &t, "-o", &sim], None));
    // The same records as a stream of 4,096-record arrays (what a pipe carries).
    let piped = run("dem-cat", &[&t, &t, &t], None);
    let pred = arg(dir.path(), "pred.npy");
    fs::write(&pred, ok(&piped)).unwrap();
    let pairs = arg(dir.path(), "pairs.csv");
    let rows: String = (0..9075u64).map(|i| format!("{i},{}\n", (i * 7) % 966)).collect();
    fs::write(&pairs, format!("sim_index,real_index\n{rows}")).unwrap();
    let table = |method: &[&str], emit: &str| {
        let mut a = vec!["--sim", &sim, "--real", &r, "--pairs", &pairs, "--format", "csv", "--name", "x", "--emit-pred", emit];
        a.extend_from_slice(method);
        ok(&run("dem-eval", &a, None)).to_vec()
    };
    let (e1, e2) = (arg(dir.path(), "e1.npy"), arg(dir.path(), "e2.npy"));
    assert_eq!(table(&["--identity"], &e1), table(&["--pred", &pred], &e2));
    assert_eq!(fs::read(&e1).unwrap(), fs::read(&sim).unwrap(), "every record, in order, as one array");
    // A prediction file one record short is refused, naming it.
    let short = arg(dir.path(), "short.npy");
    ok(&run(
        "dem-filter",
        &["--min-valid", "0", &sim, "-o", &short, "--index", &{
            let p = arg(dir.path(), "keep.csv");
            fs::write(&p, format!("index\n{}", (0..9074).map(|i| format!("{i}\n")).collect::<String>())).unwrap();
            p
        }],
        None,
    ));
    let o = run("dem-eval", &["--sim", &sim, "--real", &r, "--pairs", &pairs, "--pred", &short], None);
    refused(&o, "dem-eval", &["short.npy: has 9074 records", "one record per sim record"]);
}

// A running run shows its work: losses.csv gets every step as it is made
// (not at checkpoints), and without a terminal stderr gets progress lines.
#[test]
fn a_running_dem_train_writes_every_step_and_logs_progress_lines() {
    let dir = tempdir();
    let out = arg(dir.path(), "run");
    let mut child = Command::new(bin("dem-train"))
        .args(["--sim", &td("sim.npy"), "--real", &td("real.npy"), "--pairs", &td("pairs.csv"), "--out", &out])
        .args(["--width", "4", "--batch", "8", "--epochs", "1000", "--log-every", "0.05"])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (losses, ck) = (Path::new(&out).join("losses.csv"), Path::new(&out).join("checkpoint.bin"));
    let mut seen = 0;
    for _ in 0..600 {
        seen = fs::read_to_string(&losses).map_or(0, |t| t.lines().count().saturating_sub(1));
        if seen >= 3 {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    // 379 steps an epoch (3,025 sims, batch 8): the first checkpoint is far.
    let before_checkpoint = !ck.exists();
    child.kill().unwrap();
    let o = child.wait_with_output().unwrap();
    assert!(seen >= 3 && before_checkpoint, "{seen} rows before the first checkpoint");
    let e = stderr(&o);
    assert!(e.lines().any(|l| l.starts_with("dem-train: step ") && l.contains("samples/s, eta")), "{e}");
}
