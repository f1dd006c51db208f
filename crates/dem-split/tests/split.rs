//! Shards equal the whole (issue 14): `dem-split -> tool per shard with
//! --first-index -> dem-cat` gives the bytes of one run on the whole stream,
//! for every tool that draws per record, run by hand, with xargs and with
//! GNU parallel (the recipe of docs/scale-out.md).

use std::fs;
use std::path::Path;
use std::process::Command;

use dem_testkit::{arg, bin, ok, run, stderr, tempdir, testdata};

fn td(name: &str) -> String {
    testdata(name).to_string_lossy().into_owned()
}

/// The manifest rows: (shard, first_index, records, labels).
fn manifest(csv: &[u8]) -> Vec<Vec<String>> {
    let text = String::from_utf8(csv.to_vec()).unwrap();
    text.lines().skip(1).map(|l| l.split(',').map(String::from).collect()).collect()
}

fn model_json(dir: &Path) -> String {
    let m = arg(dir, "m.json");
    fs::write(
        &m,
        r#"{"effects":[{"effect":"noise","params":{"sigma0":0.003,"k":0.01}},{"effect":"dropout","params":{"p":0.1}},
            {"effect":"startup","params":{"x0":0.3,"v":0.2,"p":0.2}},{"effect":"patch-dropout","params":{"n":1.5,"r":0.15}}]}"#,
    )
    .unwrap();
    m
}

/// Split sim.npy (with labels) into shards, run `tool` on each (its
/// arguments from `args(shard, first, labels)`), join, compare with `whole`.
fn shards_equal_whole(dir: &Path, cut: &[&str], whole: &[u8], args: impl Fn(&str, &str, &str) -> Vec<String>, tool: &str) {
    let prefix = arg(dir, &format!("part{}", cut.join("")));
    let labels = td("sim_labels.csv");
    let mut a = vec!["--labels", &labels, "--out", &prefix];
    a.extend_from_slice(cut);
    let sim = td("sim.npy");
    a.push(&sim);
    let rows = manifest(ok(&run("dem-split", &a, None)));
    assert!(rows.len() > 1);
    let mut outs = Vec::new();
    for r in &rows {
        let out = format!("{}.out", r[0]);
        let mut targs = args(&r[0], &r[1], &r[3]);
        targs.extend(["-o".to_string(), out.clone()]);
        ok(&run(tool, &targs.iter().map(String::as_str).collect::<Vec<_>>(), None));
        outs.push(out);
    }
    let mut cat: Vec<&str> = outs.iter().map(String::as_str).collect();
    let joined = arg(dir, "joined.npy");
    cat.extend(["-o", &joined]);
    ok(&run("dem-cat", &cat, None));
    assert!(fs::read(&joined).unwrap() == whole, "{tool} over {cut:?}: shards differ from the whole");
}

#[test]
fn dem_sensor_shards_equal_the_whole_also_with_times() {
    let dir = tempdir();
    let m = model_json(dir.path());
    let whole = arg(dir.path(), "whole.npy");
    ok(&run("dem-sensor", &["apply", "--model", &m, "--seed", "3", "--labels", &td("sim_labels.csv"), &td("sim.npy"), "-o", &whole], None));
    let whole = fs::read(&whole).unwrap();
    for cut in [["--shards", "3"], ["--records", "1000"], ["--records", "2000"]] {
        shards_equal_whole(
            dir.path(),
            &cut,
            &whole,
            |s, first, labels| ["apply", "--model", &m, "--seed", "3", "--first-index", first, "--labels", labels, s].map(String::from).to_vec(),
            "dem-sensor",
        );
    }
    // Without --first-index every shard would draw as record 0, 1, ...: not the whole.
    let prefix = arg(dir.path(), "naive");
    let rows = manifest(ok(&run("dem-split", &["--shards", "2", "--out", &prefix, &td("sim.npy")], None)));
    let o = arg(dir.path(), "naive.out");
    ok(&run("dem-sensor", &["apply", "--model", &m, "--seed", "3", &rows[1][0], "-o", &o], None));
    let naive = fs::read(&o).unwrap();
    let tail = &whole[whole.len() - (naive.len() - 128)..];
    assert_eq!(naive.len() - 128, 1512 * 840);
    assert_ne!(&naive[128..], tail, "a shard without --first-index draws as the start of the stream");
}

#[test]
fn dem_fill_nans_and_dem_apply_shards_equal_the_whole() {
    let dir = tempdir();
    // dem-fill-nans: the measured DEMs have the large missing areas it fills.
    let whole = arg(dir.path(), "whole.npy");
    ok(&run("dem-fill-nans", &["--seed", "5", &td("real.npy"), "-o", &whole], None));
    let whole_bytes = fs::read(&whole).unwrap();
    let prefix = arg(dir.path(), "r");
    let rows = manifest(ok(&run("dem-split", &["--records", "300", "--out", &prefix, &td("real.npy")], None)));
    let mut outs = Vec::new();
    for r in &rows {
        let out = format!("{}.out", r[0]);
        ok(&run("dem-fill-nans", &["--seed", "5", "--first-index", &r[1], &r[0], "-o", &out], None));
        outs.push(out);
    }
    let joined = arg(dir.path(), "joined.npy");
    let mut cat: Vec<&str> = outs.iter().map(String::as_str).collect();
    cat.extend(["-o", &joined]);
    ok(&run("dem-cat", &cat, None));
    assert_eq!(fs::read(&joined).unwrap(), whole_bytes, "dem-fill-nans");
    // --keep N ranks the whole stream: no shard can reproduce it.
    let o = run("dem-fill-nans", &["--keep", "5", "--first-index", "300", &rows[1][0]], None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));

    // dem-apply: per record, no randomness; shards equal the whole.
    let model = dem_testkit::onnx_one_node(dir.path(), "tanh.onnx", "Tanh");
    let whole = arg(dir.path(), "applied.npy");
    ok(&run("dem-apply", &["--model", &model, &td("sim.npy"), "-o", &whole], None));
    let rows = manifest(ok(&run("dem-split", &["--shards", "4", "--out", &arg(dir.path(), "a"), &td("sim.npy")], None)));
    let mut outs = Vec::new();
    for r in &rows {
        let out = format!("{}.out", r[0]);
        ok(&run("dem-apply", &["--model", &model, &r[0], "-o", &out], None));
        outs.push(out);
    }
    let mut cat: Vec<&str> = outs.iter().map(String::as_str).collect();
    cat.extend(["-o", &joined]);
    ok(&run("dem-cat", &cat, None));
    assert_eq!(fs::read(&joined).unwrap(), fs::read(&whole).unwrap(), "dem-apply");
    // --sample-masks draws per record: by the index in the whole.
    let whole = arg(dir.path(), "sampled.npy");
    ok(&run("dem-apply", &["--model", &model, "--sample-masks", "--seed", "2", &td("sim.npy"), "-o", &whole], None));
    let mut outs = Vec::new();
    for r in &rows {
        let out = format!("{}.sampled", r[0]);
        ok(&run("dem-apply", &["--model", &model, "--sample-masks", "--seed", "2", "--first-index", &r[1], &r[0], "-o", &out], None));
        outs.push(out);
    }
    let mut cat: Vec<&str> = outs.iter().map(String::as_str).collect();
    cat.extend(["-o", &joined]);
    ok(&run("dem-cat", &cat, None));
    assert_eq!(fs::read(&joined).unwrap(), fs::read(&whole).unwrap(), "dem-apply --sample-masks");
}

/// The recipe of docs/scale-out.md, on this machine: GNU parallel when it is
/// installed (`.ci/run` installs it), and always with xargs -P.
#[test]
fn the_scale_out_recipe_equals_one_run() {
    let dir = tempdir();
    let m = model_json(dir.path());
    let whole = arg(dir.path(), "whole.npy");
    ok(&run("dem-sensor", &["apply", "--model", &m, "--seed", "9", &td("sim.npy"), "-o", &whole], None));
    let bins = bin("dem-split").parent().unwrap().to_string_lossy().into_owned();
    let path = format!("{bins}:{}", std::env::var("PATH").unwrap_or_default());
    let has_parallel = Command::new("sh").args(["-c", "command -v parallel"]).output().is_ok_and(|o| o.status.success());
    let mut engines = vec![("xargs", "tail -n +2 shards.csv | tr , ' ' | xargs -P 2 -n 3 sh -c 'dem-sensor apply --model m.json --seed 9 --first-index $1 $0 -o $0.out'")];
    if has_parallel {
        engines.push(("parallel", "parallel --will-cite -j 2 --colsep , --header : dem-sensor apply --model m.json --seed 9 --first-index {first_index} {shard} -o {shard}.out :::: shards.csv"));
    } else {
        eprintln!("GNU parallel is not installed: the recipe ran with xargs only");
    }
    // The Slurm array script, its tasks run one after the other here.
    let slurm = dem_testkit::workspace_root().join("scripts/slurm_shards.sh").to_string_lossy().into_owned();
    let slurm_loop = format!("for i in 1 2 3; do SLURM_ARRAY_TASK_ID=$i bash {slurm} shards.csv m.json 9; done; for f in part-*.measured; do mv $f ${{f%.measured}}.out; done");
    engines.push(("slurm", slurm_loop.as_str()));
    for (name, engine) in engines {
        let script = format!("set -e; dem-split --shards 3 --out part sim.npy > shards.csv; {engine}; dem-cat part-00000.npy.out part-00001.npy.out part-00002.npy.out -o joined.npy; rm -f part-*");
        fs::copy(td("sim.npy"), dir.path().join("sim.npy")).unwrap();
        let o = Command::new("bash").args(["-c", &script]).current_dir(dir.path()).env("PATH", &path).output().unwrap();
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(fs::read(dir.path().join("joined.npy")).unwrap(), fs::read(&whole).unwrap(), "{name}");
    }
}

#[test]
fn bad_requests_are_refused_and_leave_no_shards() {
    let dir = tempdir();
    let prefix = arg(dir.path(), "p");
    // --shards needs the length; stdin has none.
    let o = run("dem-split", &["--shards", "2", "--out", &prefix], Some(fs::read(td("sim.npy")).unwrap()));
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--shards needs the stream's length"), "{}", stderr(&o));
    // Labels that do not cover the stream: refused, the shards written are removed.
    let o = run("dem-split", &["--records", "1000", "--labels", &td("real_labels.csv"), "--out", &prefix, &td("sim.npy")], None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("real_labels.csv: has 966 rows"), "{}", stderr(&o));
    assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 0, "no shard left behind");
    let o = run("dem-split", &["--records", "0", "--out", &prefix, &td("sim.npy")], None);
    assert_eq!(o.status.code(), Some(2));
    // More shards than records: as many shards as records, none empty.
    let one = arg(dir.path(), "one.npy");
    ok(&run("dem-filter", &["--index", &{
        let p = arg(dir.path(), "i.csv");
        fs::write(&p, "index\n0\n1\n").unwrap();
        p
    }, &td("sim.npy"), "-o", &one], None));
    let rows = manifest(ok(&run("dem-split", &["--shards", "5", "--out", &prefix, &one], None)));
    assert_eq!(rows.iter().map(|r| r[2].as_str()).collect::<Vec<_>>(), ["1", "1"]);
}

#[test]
fn dem_synth_by_run_ranges_equals_the_whole_world() {
    let dir = tempdir();
    let d = |n: &str| arg(dir.path(), n);
    let base = ["--seed", "4", "--real-runs", "3", "--threads", "1"];
    ok(&run("dem-synth", &[&base[..], &["--runs", "7", "--out", &d("whole")]].concat(), None));
    ok(&run("dem-synth", &[&base[..], &["--runs", "4", "--out", &d("a")]].concat(), None));
    ok(&run("dem-synth", &[&base[..], &["--first-run", "4", "--runs", "3", "--out", &d("b")]].concat(), None));
    for f in ["sim.npy", "real.npy"] {
        let joined = d(&format!("joined_{f}"));
        ok(&run("dem-cat", &[&d(&format!("a/{f}")), &d(&format!("b/{f}")), "-o", &joined], None));
        assert_eq!(fs::read(&joined).unwrap(), fs::read(d(&format!("whole/{f}"))).unwrap(), "{f}");
    }
    // Labels: the same rows, each shard indexed from 0, the run in `sequence`.
    let rows = |p: &str| fs::read_to_string(p).unwrap().lines().skip(1).map(|l| l.split_once(',').unwrap().1.to_string()).collect::<Vec<_>>();
    let mut joined = rows(&d("a/sim_labels.csv"));
    joined.extend(rows(&d("b/sim_labels.csv")));
    assert_eq!(joined, rows(&d("whole/sim_labels.csv")));
}

/// dem-eval over shards: each shard scored with `--first-index`, then
/// `dem-eval merge` of the per-record results (and, for the gap, the
/// predictions joined) gives the table of one run on the whole, byte for
/// byte, by terrain, for a model and for Identity.
#[test]
fn dem_eval_shard_tables_merge_into_the_whole() {
    let dir = tempdir();
    let d = dir.path();
    let model = dem_testkit::onnx_one_node(d, "tanh.onnx", "Tanh");
    let (sim, real, labels) = (td("sim.npy"), td("real.npy"), td("sim_labels.csv"));
    // testdata's pairs name sims 0..965: shards of 400 give three with
    // pairs and five without (an empty records file must merge too). Every
    // third sim gets a second partner, so the gap's pairs repeat records on
    // both sides, as `dem-pair`'s do.
    let pairs = arg(d, "pairs.csv");
    let mut text = String::from("sim_index,real_index\n");
    for s in 0..966u64 {
        text.push_str(&format!("{s},{s}\n"));
        if s % 3 == 0 {
            text.push_str(&format!("{s},{}\n", (s * 7 + 1) % 966));
        }
    }
    std::fs::write(&pairs, text).unwrap();
    let rows = manifest(ok(&run("dem-split", &["--records", "400", "--labels", &labels, "--out", &arg(d, "p"), &sim], None)));
    assert_eq!(rows.len(), 8);
    for method in [vec!["--model", model.as_str()], vec!["--identity"]] {
        let common = |sim: &str, labels: &str| -> Vec<String> {
            let mut a: Vec<String> = ["--sim", sim, "--real", &real, "--pairs", &pairs, "--labels-sim", labels, "--by", "terrain", "--name", "m", "--format", "csv"]
                .map(String::from)
                .to_vec();
            a.extend(method.iter().map(|s| s.to_string()));
            a
        };
        let whole = ok(&run("dem-eval", &common(&sim, &labels).iter().map(String::as_str).collect::<Vec<_>>(), None)).to_vec();
        let (mut recs, mut preds) = (Vec::new(), Vec::new());
        for r in &rows {
            let (rec, pred) = (format!("{}.rec.csv", r[0]), format!("{}.pred.npy", r[0]));
            let mut a = common(&r[0], &r[3]);
            a.extend(["--first-index", &r[1], "--records", &rec, "--emit-pred", &pred, "-o", "/dev/null"].map(String::from));
            ok(&run("dem-eval", &a.iter().map(String::as_str).collect::<Vec<_>>(), None));
            recs.push(rec);
            preds.push(pred);
        }
        let mut cat: Vec<&str> = preds.iter().map(String::as_str).collect();
        cat.push("-");
        let joined = ok(&run("dem-cat", &cat, None)).to_vec();
        let mut m: Vec<&str> = vec!["merge", "--name", "m", "--by", "terrain", "--format", "csv"];
        m.extend(recs.iter().map(String::as_str));
        m.extend(["--emitted-pred", "-", "--real", &real, "--pairs", &pairs]);
        let merged = ok(&run("dem-eval", &m, Some(joined.clone()))).to_vec();
        assert!(String::from_utf8_lossy(&whole).lines().count() >= 4, "{}", String::from_utf8_lossy(&whole));
        assert_eq!(String::from_utf8_lossy(&merged), String::from_utf8_lossy(&whole), "{method:?}: merged shards differ from the whole");
        // Without the predictions: the same table without the gap, and a note.
        let o = run("dem-eval", &m[..m.len() - 6], None);
        let no_gap = String::from_utf8_lossy(ok(&o)).into_owned();
        assert!(stderr(&o).contains("gap not computed"), "{}", stderr(&o));
        for (a, b) in no_gap.lines().zip(String::from_utf8_lossy(&whole).lines()).skip(1) {
            assert_eq!(a, &b[..b.rfind(',').unwrap() + 1], "no gap: the other columns are the same");
        }
        // Shards out of order, or one missing: refused, one line, exit 2.
        let mut swapped = m.clone();
        let k = swapped.iter().position(|a| *a == recs[0]).unwrap();
        swapped.swap(k, k + 1);
        let o = run("dem-eval", &swapped, Some(joined.clone()));
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains("does not follow") && stderr(&o).lines().count() == 1, "{}", stderr(&o));
        let mut missing = m.clone();
        missing.remove(k + 1);
        let o = run("dem-eval", &missing, Some(joined.clone()));
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains("a shard is missing"), "{}", stderr(&o));
    }
    // A records file of another kind (a table) is refused by name.
    let table = arg(d, "table.csv");
    fs::write(&table, "method,terrain,count\n").unwrap();
    let o = run("dem-eval", &["merge", "--name", "m", &table], None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("table.csv") && stderr(&o).contains("--records"), "{}", stderr(&o));
}
