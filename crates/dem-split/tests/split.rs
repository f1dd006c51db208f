//! Shards equal the whole: `dem-split -> tool per shard with
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
    ok(&run(
        "dem-sensor",
        &["apply", "--sensor", &m, "--seed", "3", "--labels", &td("sim_labels.csv"), &td("sim.npy"), "-o", &whole],
        None,
    ));
    let whole = fs::read(&whole).unwrap();
    for cut in [["--shards", "3"], ["--records", "1000"], ["--records", "2000"]] {
        shards_equal_whole(
            dir.path(),
            &cut,
            &whole,
            |s, first, labels| {
                ["apply", "--sensor", &m, "--seed", "3", "--first-index", first, "--labels", labels, s].map(String::from).to_vec()
            },
            "dem-sensor",
        );
    }
    // Without --first-index every shard would draw as record 0, 1, ...: not the whole.
    let prefix = arg(dir.path(), "naive");
    let rows = manifest(ok(&run("dem-split", &["--shards", "2", "--out", &prefix, &td("sim.npy")], None)));
    let o = arg(dir.path(), "naive.out");
    ok(&run("dem-sensor", &["apply", "--sensor", &m, "--seed", "3", &rows[1][0], "-o", &o], None));
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
    ok(&run("dem-sensor", &["apply", "--sensor", &m, "--seed", "9", &td("sim.npy"), "-o", &whole], None));
    let bins = bin("dem-split").parent().unwrap().to_string_lossy().into_owned();
    let path = format!("{bins}:{}", std::env::var("PATH").unwrap_or_default());
    let has_parallel = Command::new("sh").args(["-c", "command -v parallel"]).output().is_ok_and(|o| o.status.success());
    let mut engines = vec![("xargs", "tail -n +2 shards.csv | tr , ' ' | xargs -P 2 -n 3 sh -c 'dem-sensor apply --sensor m.json --seed 9 --first-index $1 $0 -o $0.out'")];
    if has_parallel {
        engines.push(("parallel", "parallel --will-cite -j 2 --colsep , --header : dem-sensor apply --sensor m.json --seed 9 --first-index {first_index} {shard} -o {shard}.out :::: shards.csv"));
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
    ok(&run(
        "dem-filter",
        &[
            "--index",
            &{
                let p = arg(dir.path(), "i.csv");
                fs::write(&p, "index\n0\n1\n").unwrap();
                p
            },
            &td("sim.npy"),
            "-o",
            &one,
        ],
        None,
    ));
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
    let rows =
        |p: &str| fs::read_to_string(p).unwrap().lines().skip(1).map(|l| l.split_once(',').unwrap().1.to_string()).collect::<Vec<_>>();
    let mut joined = rows(&d("a/sim_labels.csv"));
    joined.extend(rows(&d("b/sim_labels.csv")));
    assert_eq!(joined, rows(&d("whole/sim_labels.csv")));
}

/// dem-eval over shards: each shard scored with `--first-index`, then
/// `dem-eval merge` of the per-record results (and, for the gap, the
/// predictions joined) gives the table of one run on the whole, byte for
/// byte, by terrain (the frame columns too, from the whole set's labels),
/// for a model and for Identity.
#[test]
fn dem_eval_shard_tables_merge_into_the_whole() {
    let dir = tempdir();
    let d = dir.path();
    let model = dem_testkit::onnx_one_node(d, "tanh.onnx", "Tanh");
    let (sim, real, labels, real_labels) = (td("sim.npy"), td("real.npy"), td("sim_labels.csv"), td("real_labels.csv"));
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
            let mut a: Vec<String> = [
                "--sim",
                sim,
                "--real",
                &real,
                "--pairs",
                &pairs,
                "--sim-labels",
                labels,
                "--real-labels",
                &real_labels,
                "--by",
                "terrain",
                "--name",
                "m",
                "--format",
                "csv",
            ]
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
            a.extend(["--first-index", &r[1], "--emit-records", &rec, "--emit-pred", &pred, "-o", "/dev/null"].map(String::from));
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
        // The frame columns: the whole set's runs and sims, as one run has them.
        m.extend(["--sim-labels", &labels, "--sim", &sim, "--real-labels", &real_labels]);
        let merged = ok(&run("dem-eval", &m, Some(joined.clone()))).to_vec();
        assert!(String::from_utf8_lossy(&whole).lines().count() >= 4, "{}", String::from_utf8_lossy(&whole));
        assert!(!String::from_utf8_lossy(&whole).lines().nth(1).unwrap().ends_with(",,,,,,,,"), "frame columns in the whole's table");
        assert_eq!(String::from_utf8_lossy(&merged), String::from_utf8_lossy(&whole), "{method:?}: merged shards differ from the whole");
        // Without the predictions: the same table without the gap, and a note.
        let o = run("dem-eval", &m[..m.len() - 12], None);
        let no_gap = String::from_utf8_lossy(ok(&o)).into_owned();
        assert!(stderr(&o).contains("gap not computed"), "{}", stderr(&o));
        let first = |l: &str| l.split(',').take(12).collect::<Vec<_>>().join(",");
        for (a, b) in no_gap.lines().zip(String::from_utf8_lossy(&whole).lines()).skip(1) {
            assert_eq!(first(a), first(b), "no gap: the other columns are the same");
            assert!(a.ends_with(",,,,,,,,,"), "no gap and no frame columns: {a}");
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
    assert!(stderr(&o).contains("table.csv") && stderr(&o).contains("--emit-records"), "{}", stderr(&o));
}

/// Every file in `dir` (temp files too), by name, with its bytes.
fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (e.file_name().to_string_lossy().into_owned(), fs::read(e.path()).unwrap_or_default())
        })
        .collect();
    v.sort();
    v
}

/// `dem-split ARGS >> target`: stdout opened for appending to `target`.
fn split_appending_to(target: &str, args: &[&str], stdin: Option<&str>) -> std::process::Output {
    let out = fs::OpenOptions::new().append(true).open(target).unwrap();
    let input = match stdin {
        Some(p) => std::process::Stdio::from(fs::File::open(p).unwrap()),
        None => std::process::Stdio::null(),
    };
    Command::new(bin("dem-split")).args(args).stdin(input).stdout(out).output().unwrap()
}

/// The manifest on stdout is checked against every input, the labels
/// included, also through a symlink and with the input on stdin:
/// `dem-split ... s.npy >> s.npy` is refused and changes nothing.
#[test]
fn the_manifest_never_overwrites_an_input() {
    let dir = tempdir();
    let d = dir.path();
    let (s, l, link, p) = (arg(d, "s.npy"), arg(d, "l.csv"), arg(d, "link.npy"), arg(d, "ap"));
    fs::copy(td("sim.npy"), &s).unwrap();
    fs::copy(td("sim_labels.csv"), &l).unwrap();
    std::os::unix::fs::symlink(&s, &link).unwrap();
    let before = files(d);
    let cases: Vec<(&str, Vec<&str>, Option<&str>, &str)> = vec![
        (&s, vec!["--records", "1000", "--out", &p, &s], None, "the input"),
        (&l, vec!["--records", "1000", "--labels", &l, "--out", &p, &s], None, "the labels"),
        (&s, vec!["--records", "1000", "--out", &p, &link], None, "the input through a symlink"),
        (&link, vec!["--records", "1000", "--out", &p, &s], None, "stdout through a symlink"),
        (&s, vec!["--records", "1000", "--out", &p, "-"], Some(&s), "the input on stdin"),
    ];
    for (target, args, stdin, what) in cases {
        let o = split_appending_to(target, &args, stdin);
        assert_eq!(o.status.code(), Some(2), "{what}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("output stdout would overwrite the input") && stderr(&o).lines().count() == 1,
            "{what}: {}",
            stderr(&o)
        );
        assert!(files(d) == before, "{what}: the folder changed");
    }
}

/// A refused or failed run leaves the split that was there as it was: labels
/// a row short or long, a bad labels row, a full disk for the manifest.
#[test]
fn a_refused_or_failed_split_leaves_the_earlier_one_untouched() {
    let dir = tempdir();
    let out = dir.path().join("out");
    fs::create_dir(&out).unwrap();
    let prefix = arg(&out, "prev");
    let sim = td("sim.npy");
    let labels = fs::read_to_string(td("sim_labels.csv")).unwrap();
    let lines: Vec<&str> = labels.lines().collect();
    let variant = |name: &str, rows: Vec<String>| {
        let p = arg(dir.path(), name);
        fs::write(&p, rows.join("\n") + "\n").unwrap();
        p
    };
    let short = variant("short.csv", lines[..lines.len() - 1].iter().map(|l| l.to_string()).collect());
    let mut long_rows: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    long_rows.push(format!("3025,{}", lines.last().unwrap().split_once(',').unwrap().1));
    let long = variant("long.csv", long_rows);
    let mut bad_rows: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    bad_rows[1999] = format!("1998,lava,{}", bad_rows[1999].splitn(3, ',').nth(2).unwrap());
    let bad = variant("bad.csv", bad_rows);
    ok(&run("dem-split", &["--records", "1000", "--labels", &td("sim_labels.csv"), "--out", &prefix, &sim], None));
    let before = files(&out);
    assert_eq!(before.len(), 8);
    let cases = [(&short, "short.csv: has 3024 rows but"), (&long, "long.csv: has 3026 rows but"), (&bad, "bad.csv: line 2000")];
    for (l, says) in cases {
        let o = run("dem-split", &["--records", "1000", "--labels", l, "--out", &prefix, &sim], None);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains(says), "{says}: {}", stderr(&o));
        assert!(files(&out) == before, "{says}: the earlier split changed");
    }
    // A full disk for the manifest: exit 1, nothing renamed, no temp file left.
    for cut in [["--records", "1000"], ["--shards", "3"]] {
        let full = fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
        let o = Command::new(bin("dem-split")).args(cut).args(["--out", &prefix, &sim]).stdout(full).output().unwrap();
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains("No space left"), "{}", stderr(&o));
        assert!(files(&out) == before, "{cut:?} > /dev/full: the earlier split changed");
    }
}

/// A split to a prefix replaces the split that was there: the shards (and
/// labels) beyond the new ones are removed, named on stderr, so
/// `part-*.npy` is the new split; a file of that name that is the input stays.
#[test]
fn a_split_replaces_an_earlier_split_to_the_same_prefix() {
    let dir = tempdir();
    let d = dir.path();
    let prefix = arg(d, "part");
    let sim = td("sim.npy");
    ok(&run("dem-split", &["--shards", "4", "--labels", &td("sim_labels.csv"), "--out", &prefix, &sim], None));
    fs::write(arg(d, "part-00001.npy.out"), b"a tool's output").unwrap();
    let o = run("dem-split", &["--shards", "2", "--out", &prefix, &sim], None);
    let rows = manifest(ok(&o));
    assert_eq!(rows.len(), 2);
    let names: Vec<String> = files(d).into_iter().map(|f| f.0).collect();
    assert_eq!(names, ["part-00000.npy", "part-00001.npy", "part-00001.npy.out"]);
    let e = stderr(&o);
    assert!(
        e.contains("removed 6 files an earlier split to this prefix left beyond these 2 shards") && e.contains("part-00003_labels.csv"),
        "{e}"
    );
    // The input named as a shard of the prefix is never removed.
    let input = arg(d, "part-00007.npy");
    fs::copy(&sim, &input).unwrap();
    let o = run("dem-split", &["--shards", "3", "--out", &prefix, &input], None);
    ok(&o);
    assert!(fs::read(&input).unwrap() == fs::read(&sim).unwrap());
    assert!(stderr(&o).contains("kept") && stderr(&o).contains("part-00007.npy"), "{}", stderr(&o));
    let names: Vec<String> = files(d).into_iter().map(|f| f.0).collect();
    assert_eq!(names, ["part-00000.npy", "part-00001.npy", "part-00001.npy.out", "part-00002.npy", "part-00007.npy"]);
}

/// `kill -9` in the middle of a split leaves no shard, only temp files,
/// and the next run beside them removes them.
#[test]
fn a_killed_split_leaves_only_temp_files_the_next_run_removes() {
    use std::io::Write;
    let dir = tempdir();
    let d = dir.path();
    let prefix = arg(d, "k");
    let mut child = Command::new(bin("dem-split"))
        .args(["--records", "1000", "--out", &prefix, "-"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // 6,050 records and stdin kept open: six shards done, the seventh waits.
    let sim = fs::read(td("sim.npy")).unwrap();
    let mut stdin = child.stdin.take().unwrap();
    stdin.write_all(&sim).unwrap();
    stdin.write_all(&sim).unwrap();
    stdin.flush().unwrap();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while files(d).len() < 7 && std::time::Instant::now() < deadline {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    std::thread::sleep(std::time::Duration::from_millis(200));
    child.kill().unwrap();
    child.wait().unwrap();
    drop(stdin);
    let left = files(d);
    assert!(left.len() >= 7, "{:?}", left.iter().map(|f| &f.0).collect::<Vec<_>>());
    assert!(
        left.iter().all(|(n, _)| n.starts_with('.') && n.contains("k-0000") && n.ends_with(".tmp")),
        "only temp files: {:?}",
        left.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    let o = run("dem-split", &["--records", "1000", "--out", &prefix, &td("sim.npy")], None);
    ok(&o);
    assert!(stderr(&o).contains("a temp file left by a killed run"), "{}", stderr(&o));
    let names: Vec<String> = files(d).into_iter().map(|f| f.0).collect();
    assert_eq!(names, ["k-00000.npy", "k-00001.npy", "k-00002.npy", "k-00003.npy"]);
}

/// Labels rows keep every column and byte (quoted fields, extra columns,
/// CRLF line ends) but their index, which counts from 0 in each shard; a
/// row the CSV reader would misread (a stray quote) is refused naming its line.
#[test]
fn labels_keep_their_columns_and_bytes_but_the_index() {
    let dir = tempdir();
    let d = dir.path();
    let l = arg(d, "l.csv");
    let header = "index,terrain,x,note,camera\r\n";
    let rest = |i: usize| format!("{},{i}.5,\"run {i}, \"\"left\"\"\",\"cam,{}\"\r\n", ["flat", "pallet", "stairs-up"][i % 3], i % 2);
    let mut text = String::from(header);
    for i in 0..3025 {
        text.push_str(&format!("{i},{}", rest(i)));
    }
    fs::write(&l, &text).unwrap();
    let rows = manifest(ok(&run("dem-split", &["--records", "1000", "--labels", &l, "--out", &arg(d, "p"), &td("sim.npy")], None)));
    assert_eq!(rows.len(), 4);
    for (k, r) in rows.iter().enumerate() {
        let mut want = String::from(header);
        for n in 0..r[2].parse::<usize>().unwrap() {
            want.push_str(&format!("{n},{}", rest(1000 * k + n)));
        }
        assert!(fs::read_to_string(&r[3]).unwrap() == want, "shard {k}'s labels");
    }
    // The shards' labels are labels every reader takes: split a shard again with them.
    ok(&run("dem-split", &["--records", "300", "--labels", &rows[1][3], "--out", &arg(d, "again"), &rows[1][0]], None));
    // A quote inside an unquoted field: refused, naming the line.
    let lines: Vec<&str> = text.split_inclusive('\n').collect();
    let mut stray = lines.clone();
    let broken = lines[5].replacen(",pallet,", ",pal\"let,", 1);
    stray[5] = &broken;
    fs::write(&l, stray.concat()).unwrap();
    let o = run("dem-split", &["--records", "1000", "--labels", &l, "--out", &arg(d, "q"), &td("sim.npy")], None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("l.csv: line 6: unbalanced quotes"), "{}", stderr(&o));
    assert!(!Path::new(&arg(d, "q-00000.npy")).exists());
}

/// Through a pipe the shards are in place before the manifest names them:
/// a reader that starts on each row as it comes finds its shard whole.
#[test]
fn a_pipe_reader_finds_every_shard_the_manifest_names() {
    use std::io::BufRead;
    let dir = tempdir();
    let prefix = arg(dir.path(), "part");
    let mut child = Command::new(bin("dem-split"))
        .args(["--records", "500", "--out", &prefix, &td("sim.npy")])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let lines = std::io::BufReader::new(child.stdout.take().unwrap()).lines();
    let mut n = 0;
    for line in lines.skip(1) {
        let line = line.unwrap();
        let (shard, rest) = line.split_once(',').unwrap();
        let records: u64 = rest.rsplit(',').next().unwrap().parse().unwrap();
        assert_eq!(fs::metadata(shard).unwrap().len(), 128 + records * 840, "{shard} whole when its row is read");
        n += 1;
    }
    assert!(child.wait().unwrap().success());
    assert_eq!(n, 7);
}
