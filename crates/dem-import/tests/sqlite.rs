//! ROS 2 SQLite bags (`.db3`): the same messages as an MCAP bag give the
//! same bytes out; hostile databases are refused in one line, never a panic.
//! The recordings are written by `scripts/maps_to_bag.py --format db3`
//! (the `rosbags` package's SQLite writer, Python's sqlite3).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use dem_testkit::{ok, py, run, stderr, workspace_root};

fn world(dir: &Path) -> PathBuf {
    let w = dir.join("w");
    let args =
        ["--out", w.to_str().unwrap(), "--runs", "2", "--real-runs", "2", "--seed", "5", "--terrains", "stairs-down,pallet", "--emit-maps"];
    ok(&run("dem-synth", &args, None));
    w
}

fn to_bag(world: &Path, out: &Path, args: &[&str]) {
    let script = workspace_root().join("scripts/maps_to_bag.py");
    let o = Command::new(dem_testkit::python()).arg(script).arg(world).arg("--out").arg(out).args(args).output().expect("python");
    assert!(o.status.success(), "maps_to_bag.py failed:\n{}", String::from_utf8_lossy(&o.stderr));
}

fn import(out: &Path, recording: &Path) -> Output {
    run("dem-import", &["--out", out.to_str().unwrap(), recording.to_str().unwrap()], None)
}

/// The NPY and labels a recording imports to, alone (so its sequence is 0).
fn outputs(dir: &Path, recording: &Path) -> (Vec<u8>, String) {
    let out = dir.join(format!("out-{}", recording.file_name().unwrap().to_str().unwrap()));
    let o = import(&out, recording);
    ok(&o);
    let stem = if recording.is_dir() { recording.file_name() } else { recording.file_stem() }.unwrap().to_str().unwrap().to_string();
    let npy = std::fs::read(out.join(format!("{stem}.npy"))).unwrap();
    let labels = std::fs::read_to_string(out.join(format!("{stem}_labels.csv"))).unwrap();
    (npy, labels)
}

#[test]
fn db3_recordings_import_to_the_same_bytes_as_the_mcap_of_the_same_messages() {
    let dir = tempfile::tempdir().unwrap();
    let w = world(dir.path());
    // Maps recorded out of stamp order, TF arriving after the maps that need it.
    let defects = ["--sequences", "1", "--shuffle-maps", "--tf-late"];
    let mcap = dir.path().join("pallet_mcap");
    to_bag(&w, &mcap, &[&["--format", "mcap", "--compression", "zstd"][..], &defects].concat());
    let db3 = dir.path().join("pallet_db3");
    to_bag(&w, &db3, &[&["--format", "db3", "--verify"][..], &defects].concat());
    assert!(db3.join("metadata.yaml").is_file() && db3.join("pallet_db3.db3").is_file());
    let want = outputs(dir.path(), &mcap);
    assert!(want.0.len() > 128 + 840 * 10, "{} bytes of NPY", want.0.len());
    // A rosbag2 folder (metadata.yaml beside the .db3).
    let got = outputs(dir.path(), &db3);
    assert!(got.0 == want.0, "the .db3 folder's NPY differs from the MCAP's");
    assert_eq!(got.1, want.1, "labels");
    // A single .db3 file.
    let single = dir.path().join("single.db3");
    std::fs::copy(db3.join("pallet_db3.db3"), &single).unwrap();
    let got = outputs(dir.path(), &single);
    assert!(got.0 == want.0, "the single .db3's NPY differs from the MCAP's");
    assert_eq!(got.1, want.1, "labels");
    // A bag split in two files (NAME_0.db3 holds the first half of the rows,
    // NAME_1.db3 the rest), as rosbag2 --max-bag-size writes.
    let split = dir.path().join("split");
    std::fs::create_dir(&split).unwrap();
    py(
        dir.path(),
        &format!(
            "import shutil, sqlite3\n\
             n = sqlite3.connect('{src}').execute('SELECT count(*) FROM messages').fetchone()[0]\n\
             for k, cond in ((0, 'rowid > ?'), (1, 'rowid <= ?')):\n\
             \x20   p = 'split/split_%d.db3' % k\n\
             \x20   shutil.copy('{src}', p)\n\
             \x20   c = sqlite3.connect(p)\n\
             \x20   c.execute('DELETE FROM messages WHERE ' + cond, (n // 2,))\n\
             \x20   c.commit()\n\
             \x20   c.execute('VACUUM')\n\
             \x20   c.close()\n",
            src = single.display()
        ),
    );
    let got = outputs(dir.path(), &split);
    assert!(got.0 == want.0, "the split .db3 folder's NPY differs from the MCAP's");
    assert_eq!(got.1, want.1, "labels");
}

/// `recording` is not imported: no panic, exit 2, one line naming it with
/// `why` in it.
fn refused(dir: &Path, recording: &Path, why: &str) {
    let o = import(&dir.join("refused"), recording);
    let log = stderr(&o);
    assert!(!log.contains("panicked"), "{log}");
    assert_eq!(o.status.code(), Some(2), "{log}");
    let name = recording.file_name().unwrap().to_str().unwrap();
    let lines: Vec<&str> = log.lines().filter(|l| l.contains(name)).collect();
    assert_eq!(lines.len(), 1, "{log}");
    assert!(lines[0].contains("not imported") && lines[0].contains(why), "{log}");
}

#[test]
fn hostile_db3_files_are_refused_in_one_line_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let w = world(d);
    let bag = d.join("good");
    to_bag(&w, &bag, &["--format", "db3", "--sequences", "0"]);
    let good = std::fs::read(bag.join("good.db3")).unwrap();

    // Not SQLite at all.
    let junk = d.join("junk.db3");
    std::fs::write(&junk, b"hello, this is not a database at all, but long enough for a header of 100 bytes ...........").unwrap();
    refused(d, &junk, "not a SQLite database");
    // The magic alone.
    let magic = d.join("magic.db3");
    std::fs::write(&magic, b"SQLite format 3\0").unwrap();
    refused(d, &magic, "truncated");
    // Cut short (a copy broken off).
    let cut = d.join("cut.db3");
    std::fs::write(&cut, &good[..good.len() * 6 / 10]).unwrap();
    refused(d, &cut, "truncated");
    // Pages overwritten with junk: SQLite finds the database damaged.
    let mut bad = good.clone();
    for (k, b) in bad.iter_mut().enumerate().skip(4096) {
        if k % 4096 < 200 {
            *b = (k * 7 + 13) as u8;
        }
    }
    let flipped = d.join("flipped.db3");
    std::fs::write(&flipped, &bad).unwrap();
    refused(d, &flipped, "not a readable ROS 2 SQLite bag");

    // Databases of the wrong shape, made with Python's sqlite3.
    let topics = "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, \
                  serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);\
                  INSERT INTO topics VALUES (1, '/elevation_mapping/elevation_map', 'grid_map_msgs/msg/GridMap', 'cdr', '');";
    let messages =
        "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, timestamp INTEGER NOT NULL, data BLOB NOT NULL);";
    let make = |name: &str, sql: String| {
        let p = d.join(name);
        py(d, &format!("import sqlite3\nc = sqlite3.connect({:?})\nc.executescript({sql:?})\nc.commit()\n", p.to_str().unwrap()));
        p
    };
    let p = make("no_topics.db3", format!("{messages} INSERT INTO messages VALUES (1, 1, 5, x'00010000');"));
    refused(d, &p, "no table topics");
    let p = make(
        "wrong_types.db3",
        format!("{topics} CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id TEXT, timestamp TEXT, data TEXT);"),
    );
    refused(d, &p, "column messages.topic_id is declared \"TEXT\"");
    let p = make("text_data.db3", format!("{topics} {messages} INSERT INTO messages VALUES (1, 1, 5, 'not a blob');"));
    refused(d, &p, "data holds text, not a blob");
    let p = make("text_topic.db3", format!("{topics} {messages} INSERT INTO messages VALUES (1, 'one', 5, x'00');"));
    refused(d, &p, "topic_id holds Text, not an integer");
    let p = make("no_such_topic.db3", format!("{topics} {messages} INSERT INTO messages VALUES (1, 7, 5, x'00');"));
    refused(d, &p, "topic_id 7, which the topics table does not declare");
    // A map message of 65 MiB, more than a message may have: refused
    // before it is loaded.
    let p = make("huge.db3", format!("{topics} {messages} INSERT INTO messages VALUES (1, 1, 5, zeroblob(65 * 1048576));"));
    refused(d, &p, "a message of 68157440 bytes, more than the 67108864");
}
