//! dem-train as users run it: short runs on testdata, resume, determinism,
//! export checked by onnxruntime, dem-apply against the trainer, refusals.

use std::path::Path;

use dem_core::format::DemCells;
use dem_core::npy;
use dem_nn::train::checkpoint;
use dem_testkit::{arg, ok, py, run, stderr, tempdir, testdata};

fn td(name: &str) -> String {
    testdata(name).to_string_lossy().into_owned()
}

/// A small train/val pairs file over testdata: real i <-> sim i, val for
/// every third key.
fn pairs(dir: &Path) -> String {
    let text: String = std::iter::once("sim_index,real_index,split\n".to_string())
        .chain((0..966).map(|i| format!("{i},{i},{}\n", if i % 3 == 0 { "val" } else { "train" })))
        .collect();
    let p = arg(dir, "pairs.csv");
    std::fs::write(&p, text).unwrap();
    p
}

fn train(dir: &Path, run_dir: &str, extra: &[&str]) -> std::process::Output {
    let (sim, real, pairs) = (td("sim.npy"), td("real.npy"), pairs(dir));
    let mut args = vec!["--sim", &sim, "--real", &real, "--pairs", &pairs, "--out", run_dir, "--width", "4", "--batch", "16"];
    args.extend_from_slice(extra);
    run("dem-train", &args, None)
}

fn losses(run_dir: &str) -> Vec<f64> {
    let text = std::fs::read_to_string(Path::new(run_dir).join("losses.csv")).unwrap();
    text.lines().skip(1).map(|l| l.split(',').nth(6).unwrap().parse().unwrap()).collect()
}

#[test]
fn a_short_run_lowers_the_losses_and_writes_the_run_files() {
    let d = tempdir();
    let r = arg(d.path(), "run");
    let out = train(d.path(), &r, &["--max-steps", "60", "--seed", "3"]);
    ok(&out);
    let l = losses(&r);
    assert_eq!(l.len(), 60);
    let first: f64 = l[..5].iter().sum::<f64>() / 5.0;
    let last: f64 = l[55..].iter().sum::<f64>() / 5.0;
    assert!(last < 0.8 * first, "generator loss {first} -> {last}");
    // A val row at the end of the run, with the val keys counted.
    let val = std::fs::read_to_string(Path::new(&r).join("val.csv")).unwrap();
    let row: Vec<&str> = val.lines().nth(1).expect("a val row").split(',').collect();
    assert_eq!(row[2], "322", "{val}");
    assert!(stderr(&out).contains("samples/s"));
    // The run's curves as a picture; a folder without a run is refused.
    let png = arg(d.path(), "curves.png");
    ok(&run("dem-train", &["curves", &r, "-o", &png], None));
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
    let none = arg(d.path(), "none");
    let out = run("dem-train", &["curves", &none, "-o", &arg(d.path(), "x.png")], None);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("losses.csv") && stderr(&out).lines().count() == 1, "{}", stderr(&out));
    assert!(!Path::new(&arg(d.path(), "x.png")).exists());
}

#[test]
fn the_default_length_keeps_long_epochs_within_the_step_budget() {
    // Batch 8 over testdata's 3,025 sims: 379 steps an epoch, so 30 epochs
    // would be 11,370 steps; the default stops at the first whole epoch
    // past 1,500 steps (4 epochs), an explicit --epochs is kept, and at
    // batch 64 (48 steps an epoch) the default is 30 epochs.
    let d = tempdir();
    let (sim, real, pairs) = (td("sim.npy"), td("real.npy"), pairs(d.path()));
    let logged = |name: &str, batch: &str, extra: &[&str]| {
        let r = arg(d.path(), name);
        let mut args =
            vec!["--sim", &sim, "--real", &real, "--pairs", &pairs, "--out", &r, "--width", "4", "--batch", batch, "--max-steps", "1"];
        args.extend_from_slice(extra);
        let out = run("dem-train", &args, None);
        ok(&out);
        stderr(&out)
    };
    let cut = logged("cut", "8", &[]);
    assert!(cut.contains("379 steps per epoch, 4 epochs (the default 30, cut to about 1500 steps),"), "{cut}");
    let given = logged("given", "8", &["--epochs", "30"]);
    assert!(given.contains("379 steps per epoch, 30 epochs,"), "{given}");
    let short = logged("short", "64", &[]);
    assert!(short.contains("48 steps per epoch, 30 epochs (the default),"), "{short}");
    // The help text states the budget the library uses.
    let help = run("dem-train", &["--help"], None);
    ok(&help);
    let words = String::from_utf8_lossy(&help.stdout).split_whitespace().collect::<Vec<_>>().join(" ");
    let said = format!(
        "[default: {}, or fewer when an epoch is long: as many whole epochs as reach {} steps]",
        dem_train::session::DEFAULT_EPOCHS,
        dem_train::session::STEP_BUDGET
    );
    assert!(words.contains(&said), "{words}");
}

#[test]
fn resume_continues_exactly_and_threads_do_not_change_the_model() {
    let d = tempdir();
    let (a, b, c) = (arg(d.path(), "a"), arg(d.path(), "b"), arg(d.path(), "c"));
    ok(&train(d.path(), &a, &["--max-steps", "24", "--threads", "2"]));
    ok(&train(d.path(), &b, &["--max-steps", "10", "--threads", "2"]));
    let out = train(d.path(), &b, &["--max-steps", "24", "--resume"]);
    ok(&out);
    assert!(stderr(&out).contains("resuming"), "{}", stderr(&out));
    ok(&train(d.path(), &c, &["--max-steps", "24", "--threads", "1"]));
    let ck = |r: &str| std::fs::read(Path::new(r).join("checkpoint.bin")).unwrap();
    assert!(ck(&a) == ck(&b), "resumed run differs from the uninterrupted one");
    assert!(ck(&a) == ck(&c), "one thread and two threads differ");
    assert_eq!(losses(&a), losses(&b));
    // A settings clash on resume is refused.
    let out = train(d.path(), &b, &["--max-steps", "30", "--resume", "--lr", "0.001"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("--lr differs"), "{}", stderr(&out));
}

#[test]
fn checkpoints_round_trip() {
    let d = tempdir();
    let r = arg(d.path(), "run");
    ok(&train(d.path(), &r, &["--max-steps", "3"]));
    let p = arg(Path::new(&r), "checkpoint.bin");
    let (meta, gan) = checkpoint::load(&p).unwrap();
    assert_eq!(meta.step, 3);
    assert_eq!(meta.adam_steps, [3; 4]);
    let q = arg(d.path(), "again.bin");
    checkpoint::save(&q, &gan, &meta).unwrap();
    assert_eq!(std::fs::read(&p).unwrap(), std::fs::read(&q).unwrap());
    // A truncated file is refused, naming it.
    let bytes = std::fs::read(&p).unwrap();
    std::fs::write(&q, &bytes[..bytes.len() - 4]).unwrap();
    let e = checkpoint::load(&q).unwrap_err().to_string();
    assert!(e.contains("again.bin"), "{e}");
}

#[test]
fn export_matches_the_trainer_in_onnxruntime_and_dem_apply() {
    let d = tempdir();
    let r = arg(d.path(), "run");
    ok(&train(d.path(), &r, &["--max-steps", "8"]));
    let model = arg(d.path(), "gy.onnx");
    let out = run("dem-train", &["export", &r, "-o", &model], None);
    ok(&out);
    assert!(stderr(&out).contains("tract reproduces the trainer"), "{}", stderr(&out));
    // The trainer's own forward pass on the check records.
    let (_, gan) = checkpoint::load(&arg(Path::new(&r), "checkpoint.bin")).unwrap();
    let check = npy::read_all(&arg(Path::new(&r), "check_sim.npy")).unwrap();
    let want = gan.generate(true, &check);
    let by_ort = npy::read_all(&dem_testkit::onnxruntime(d.path(), &model, &arg(Path::new(&r), "check_sim.npy"), 4096, "ort.npy")).unwrap();
    assert_eq!(by_ort.len(), want.len());
    let worst = by_ort.iter().flatten().zip(want.iter().flatten()).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    assert!(worst < 1e-4, "onnxruntime differs from the trainer by {worst}");
    // dem-apply streams the same records through tract.
    let applied = arg(d.path(), "applied.npy");
    ok(&run("dem-apply", &["--model", &model, "-o", &applied, &arg(Path::new(&r), "check_sim.npy")], None));
    let got = npy::read_all(&applied).unwrap();
    assert_eq!(got.len(), want.len());
    let diff = got.iter().zip(&want).flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y).abs())).fold(0.0f32, f32::max);
    assert!(diff < 1e-4, "dem-apply differs from the trainer by {diff}");
    // G_X exports too.
    ok(&run("dem-train", &["export", &r, "-o", &arg(d.path(), "gx.onnx"), "--generator", "x"], None));
    // The file says what it is: read by onnxruntime (the peer) and by
    // dem-apply --info, the same data hashes as Python's hashlib.
    let peer = py(
        d.path(),
        &format!(
            "import hashlib, onnxruntime as ort\n\
             m = ort.InferenceSession({model:?}).get_modelmeta().custom_metadata_map\n\
             print(m['dem.seed']); print(m['dem.architecture']); print(m['dem.data.sim']); print(m['dem.validation'].splitlines()[0])\n\
             print(hashlib.sha256(open({:?}, 'rb').read()).hexdigest())",
            td("sim.npy")
        ),
    );
    let peer: Vec<&str> = peer.lines().collect();
    assert_eq!(&peer[..2], ["0", "residual head, width 4"]);
    assert_eq!(peer[2], format!("{}, 3025 records, sha256 {}", td("sim.npy"), peer[4]));
    assert_eq!(peer[3], "epoch,step,count,lowest,highest,mean,median");
    let info = run("dem-apply", &["--model", &model, "--info"], None);
    ok(&info);
    let text = String::from_utf8_lossy(&info.stdout);
    for want in [
        "engine: native generator (residual, width 4)",
        "dem.seed: 0",
        &format!("dem.data.sim: {}", peer[2]),
        "dem.validation:",
        "  epoch,step",
    ] {
        assert!(text.contains(want), "no {want:?} in\n{text}");
    }
    assert!(text.contains("dem.trained: 8 steps"), "{text}");
}

/// A generator exported with `--residual` carries the sensor model, and
/// dem-apply and dem-eval --model apply it after the network: the same
/// bytes as the network alone piped through dem-sensor apply, with each
/// record's time from the labels.
#[test]
fn a_residual_sensor_model_travels_with_the_generator() {
    let d = tempdir();
    let r = arg(d.path(), "run");
    ok(&train(d.path(), &r, &["--max-steps", "8"]));
    let sensor = arg(d.path(), "residual.json");
    std::fs::write(
        &sensor,
        r#"{"effects": [{"effect": "startup", "params": {"x0": 0.4, "v": 0.2, "p": 0.1}},
                        {"effect": "noise", "params": {"sigma0": 0.003, "k": 0.01}}]}"#,
    )
    .unwrap();
    let model = arg(d.path(), "gy.onnx");
    let out = run("dem-train", &["export", &r, "-o", &model, "--residual", &sensor], None);
    ok(&out);
    assert!(stderr(&out).contains("with the residual sensor model startup"), "{}", stderr(&out));
    let info = String::from_utf8_lossy(&run("dem-apply", &["--model", &model, "--info"], None).stdout).into_owned();
    assert!(info.contains("dem.residual: {\"effects\":[{\"effect\":\"startup\"") && info.contains("dem.residual.source: "), "{info}");
    // The first 200 sim records of testdata (first frames of runs among them).
    let (sim, labels) = (arg(d.path(), "sim.npy"), arg(d.path(), "sim_labels.csv"));
    npy::write_all(&sim, &npy::read_all(&td("sim.npy")).unwrap()[..200]).unwrap();
    let text = std::fs::read_to_string(td("sim_labels.csv")).unwrap();
    std::fs::write(&labels, text.lines().take(201).map(|l| format!("{l}\n")).collect::<String>()).unwrap();
    let whole = arg(d.path(), "whole.npy");
    let out = run("dem-apply", &["--model", &model, "--labels", &labels, "--seed", "5", "--batch", "7", &sim, "-o", &whole], None);
    ok(&out);
    assert!(stderr(&out).contains("then its residual sensor model: startup"), "{}", stderr(&out));
    let net = arg(d.path(), "net.npy");
    ok(&run("dem-apply", &["--model", &model, "--network-only", &sim, "-o", &net], None));
    let piped = arg(d.path(), "piped.npy");
    ok(&run("dem-sensor", &["apply", "--sensor", &sensor, "--labels", &labels, "--seed", "5", &net, "-o", &piped], None));
    assert_eq!(std::fs::read(&whole).unwrap(), std::fs::read(&piped).unwrap(), "dem-apply with the residual != network | dem-sensor apply");
    assert_ne!(std::fs::read(&whole).unwrap(), std::fs::read(&net).unwrap(), "the residual changed nothing");
    // A shard (records 120..) with --first-index gets the whole's draws.
    let (shard, shard_labels) = (arg(d.path(), "shard.npy"), arg(d.path(), "shard_labels.csv"));
    npy::write_all(&shard, &npy::read_all(&sim).unwrap()[120..]).unwrap();
    let mut lines = text.lines();
    let head = lines.next().unwrap().to_string();
    // A shard's labels are its own, indexed from 0 (as dem-split writes them).
    let rows: Vec<String> = lines.skip(120).take(80).enumerate().map(|(i, l)| format!("{i},{}", l.split_once(',').unwrap().1)).collect();
    std::fs::write(&shard_labels, format!("{head}\n{}\n", rows.join("\n"))).unwrap();
    let part = arg(d.path(), "part.npy");
    ok(&run(
        "dem-apply",
        &["--model", &model, "--labels", &shard_labels, "--seed", "5", "--first-index", "120", &shard, "-o", &part],
        None,
    ));
    assert_eq!(npy::read_all(&part).unwrap(), npy::read_all(&whole).unwrap()[120..].to_vec());
    // Labels shorter than the stream: refused, nothing written.
    let short = arg(d.path(), "short.npy");
    let out = run("dem-apply", &["--model", &model, "--labels", &shard_labels, &sim, "-o", &short], None);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("shard_labels.csv") && stderr(&out).lines().count() == 1, "{}", stderr(&out));
    assert!(!Path::new(&short).exists());
    // dem-eval --model scores what dem-apply writes.
    let pairs = arg(d.path(), "pairs200.csv");
    std::fs::write(
        &pairs,
        std::iter::once("sim_index,real_index\n".to_string()).chain((0..200).map(|i| format!("{i},{i}\n"))).collect::<String>(),
    )
    .unwrap();
    let real = td("real.npy");
    let eval = |extra: &[&str]| {
        let mut a = vec!["--sim", &sim, "--real", &real, "--pairs", &pairs, "--sim-labels", &labels, "--name", "g", "--format", "csv"];
        a.extend_from_slice(extra);
        let out = run("dem-eval", &a, None);
        ok(&out);
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    assert_eq!(eval(&["--model", &model, "--seed", "5"]), eval(&["--pred", &whole]));
    assert_eq!(eval(&["--model", &model, "--network-only"]), eval(&["--pred", &net]));
    // G_X has no residual; a bad sensor model is refused before anything is written.
    let out = run("dem-train", &["export", &r, "-o", &arg(d.path(), "gx.onnx"), "--generator", "x", "--residual", &sensor], None);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    let bad = arg(d.path(), "bad.json");
    std::fs::write(&bad, r#"{"effects": [{"effect": "noise", "params": {"sigma0": -1, "k": 0}}]}"#).unwrap();
    let out = run("dem-train", &["export", &r, "-o", &arg(d.path(), "g2.onnx"), "--residual", &bad], None);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("bad.json") && !d.path().join("g2.onnx").exists(), "{}", stderr(&out));
}

/// `export --heights input`: the model keeps the input's heights under its
/// network's holes, in dem-apply (by default, with --network-only too) and
/// dem-eval --model; `dem-apply --heights` says the same of any model.
#[test]
fn a_generator_exported_with_input_heights_keeps_the_sims_heights() {
    let d = tempdir();
    let r = arg(d.path(), "run");
    ok(&train(d.path(), &r, &["--max-steps", "8"]));
    let sensor = arg(d.path(), "residual.json");
    std::fs::write(&sensor, r#"{"effects": [{"effect": "noise", "params": {"sigma0": 0.003, "k": 0.01}}]}"#).unwrap();
    let (plain, held) = (arg(d.path(), "plain.onnx"), arg(d.path(), "held.onnx"));
    ok(&run("dem-train", &["export", &r, "-o", &plain], None));
    let out = run("dem-train", &["export", &r, "-o", &held, "--heights", "input", "--residual", &sensor], None);
    ok(&out);
    assert!(stderr(&out).contains("heights from the input under its holes"), "{}", stderr(&out));
    let info = String::from_utf8_lossy(&run("dem-apply", &["--model", &held, "--info"], None).stdout).into_owned();
    assert!(info.contains("dem.heights: input"), "{info}");
    let sim = arg(d.path(), "sim.npy");
    let input = npy::read_all(&td("sim.npy")).unwrap()[..150].to_vec();
    npy::write_all(&sim, &input).unwrap();
    let net = arg(d.path(), "net.npy");
    ok(&run("dem-apply", &["--model", &plain, &sim, "-o", &net], None));
    // The stored mode, --network-only: the network's holes, the sim's heights.
    let kept = arg(d.path(), "kept.npy");
    let out = run("dem-apply", &["--model", &held, "--network-only", &sim, "-o", &kept], None);
    ok(&out);
    assert!(stderr(&out).contains("the input's heights under its holes"), "{}", stderr(&out));
    let (net_recs, kept_recs) = (npy::read_all(&net).unwrap(), npy::read_all(&kept).unwrap());
    let mut from_sim = 0;
    for ((x, n), k) in input.iter().zip(&net_recs).zip(&kept_recs) {
        assert_eq!(k.attitude(), x.attitude());
        for (row, col) in (0..20).flat_map(|row| (0..5).map(move |col| (row, col))) {
            assert_eq!(k.is_valid(row, col), n.is_valid(row, col), "the network's holes");
            assert_eq!(k.mask(row, col).abs(), 1.0);
            match (k.is_valid(row, col), x.is_valid(row, col)) {
                (true, true) => {
                    assert_eq!(k.height(row, col), x.height(row, col));
                    from_sim += 1;
                }
                (true, false) => assert_eq!(k.height(row, col), n.height(row, col)),
                (false, _) => assert_eq!(k.height(row, col), 0.0),
            }
        }
    }
    assert!(from_sim > 1000, "{from_sim} cells from the sim");
    // --heights overrides the stored mode, either way.
    let over = arg(d.path(), "over.npy");
    ok(&run("dem-apply", &["--model", &plain, "--heights", "input", &sim, "-o", &over], None));
    assert_eq!(std::fs::read(&over).unwrap(), std::fs::read(&kept).unwrap());
    ok(&run("dem-apply", &["--model", &held, "--network-only", "--heights", "network", &sim, "-o", &over], None));
    assert_eq!(std::fs::read(&over).unwrap(), std::fs::read(&net).unwrap());
    // With its residual: the same bytes as the held heights through dem-sensor apply.
    let whole = arg(d.path(), "whole.npy");
    ok(&run("dem-apply", &["--model", &held, "--seed", "3", &sim, "-o", &whole], None));
    let piped = arg(d.path(), "piped.npy");
    ok(&run("dem-sensor", &["apply", "--sensor", &sensor, "--seed", "3", &kept, "-o", &piped], None));
    assert_eq!(std::fs::read(&whole).unwrap(), std::fs::read(&piped).unwrap());
    // dem-eval --model scores what dem-apply writes.
    let pairs = arg(d.path(), "pairs150.csv");
    std::fs::write(
        &pairs,
        std::iter::once("sim_index,real_index\n".to_string()).chain((0..150).map(|i| format!("{i},{i}\n"))).collect::<String>(),
    )
    .unwrap();
    let real = td("real.npy");
    let eval = |extra: &[&str]| {
        let mut a = vec!["--sim", &sim, "--real", &real, "--pairs", &pairs, "--name", "g", "--format", "csv"];
        a.extend_from_slice(extra);
        let out = run("dem-eval", &a, None);
        ok(&out);
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    assert_eq!(eval(&["--model", &held, "--seed", "3"]), eval(&["--pred", &whole]));
    assert_eq!(eval(&["--model", &held, "--network-only"]), eval(&["--pred", &kept]));
    // A bad value and G_X are refused before anything is written.
    let out = run("dem-apply", &["--model", &held, "--heights", "sim", &sim, "-o", &over], None);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("network or input"), "{}", stderr(&out));
    let gx = arg(d.path(), "gx.onnx");
    let out = run("dem-train", &["export", &r, "-o", &gx, "--generator", "x", "--heights", "input"], None);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(!Path::new(&gx).exists());
}

#[test]
fn bad_inputs_are_refused_clearly() {
    let d = tempdir();
    let (sim, real) = (td("sim.npy"), td("real.npy"));
    let r = arg(d.path(), "run");
    // Pairs past the data.
    let bad = arg(d.path(), "bad.csv");
    std::fs::write(&bad, "sim_index,real_index\n0,0\n1,5000\n").unwrap();
    let out = run("dem-train", &["--sim", &sim, "--real", &real, "--pairs", &bad, "--out", &r], None);
    assert_eq!(out.status.code(), Some(2));
    let e = stderr(&out);
    assert!(e.contains("bad.csv") && e.contains("line 3") && e.contains("real_index 5000"), "{e}");
    assert_eq!(e.lines().count(), 1, "{e}");
    // An empty sim set.
    let empty = arg(d.path(), "empty.npy");
    std::fs::write(&empty, b"").unwrap();
    let out = run("dem-train", &["--sim", &empty, "--real", &real, "--out", &r], None);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("empty.npy") && stderr(&out).contains("no records"), "{}", stderr(&out));
    // Records of the wrong shape.
    let wrong = arg(d.path(), "wrong.npy");
    py(d.path(), &format!("import numpy as np; np.save({wrong:?}, np.zeros((3, 21, 5, 3), np.float32))"));
    let out = run("dem-train", &["--sim", &wrong, "--real", &real, "--out", &r], None);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("wrong.npy") && stderr(&out).contains("shape"), "{}", stderr(&out));
    // Resume without a run; export of nothing.
    let out = run("dem-train", &["--sim", &sim, "--real", &real, "--out", &arg(d.path(), "none"), "--resume"], None);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    let out = run("dem-train", &["export", &arg(d.path(), "none"), "-o", &arg(d.path(), "m.onnx")], None);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(!d.path().join("m.onnx").exists());
    // Missing --out.
    let out = run("dem-train", &["--sim", &sim, "--real", &real], None);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn a_sensor_model_is_applied_first_and_must_be_given_again_on_resume() {
    let d = tempdir();
    let r = arg(d.path(), "run");
    let sensor = arg(d.path(), "sensor.json");
    std::fs::write(&sensor, r#"{"effects": [{"effect": "dropout", "params": {"p": 0.1}}]}"#).unwrap();
    let out = train(d.path(), &r, &["--max-steps", "4", "--sensor", &sensor, "--seed", "2"]);
    ok(&out);
    assert!(stderr(&out).contains("applied sensor model"), "{}", stderr(&out));
    // The check records are the sims as the sensor model left them.
    let check = npy::read_all(&arg(Path::new(&r), "check_sim.npy")).unwrap();
    let missing = check.iter().flat_map(|d| d[..200].chunks(2).map(|c| c[1] < 0.0)).filter(|m| *m).count();
    assert!(missing > 0, "dropout left no missing cell in the check records");
    let (meta, _) = checkpoint::load(&arg(Path::new(&r), "checkpoint.bin")).unwrap();
    assert!(meta.sensor.is_some());
    let out = train(d.path(), &r, &["--max-steps", "6", "--resume"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("give the same --sensor"), "{}", stderr(&out));
    ok(&train(d.path(), &r, &["--max-steps", "6", "--resume", "--sensor", &sensor]));
}
