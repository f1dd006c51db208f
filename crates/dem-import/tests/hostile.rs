//! dem-import under hostile input: recordings built byte by byte (a small
//! ROS 1 bag and MCAP writer below, ROS 1 serialization of the three
//! message types) with lying lengths, decompression bombs, huge values and
//! damaged messages, each run through the real binary. No run may panic
//! (exit 101) or abort; bad input exits 2 in one line naming the file, a
//! damaged part is skipped with a warning naming its byte offset or its
//! message, and the rest of the recording is imported.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use dem_core::npy;
use dem_testkit::{bin, run, stderr, tempdir};

mod common;
use common::*;

// ---------------------------------------------------------------- running

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn import(out: &Path, extra: &[&str], recordings: &[&Path]) -> Output {
    let mut args = vec!["--out".to_string(), out.display().to_string()];
    args.extend(extra.iter().map(|s| s.to_string()));
    args.extend(recordings.iter().map(|p| p.display().to_string()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    run("dem-import", &args, None)
}

/// Peak resident memory (kB) of `dem-import ARGS` by `/usr/bin/time -v`
/// (None where that is missing), with its output.
fn peak_kb(args: &[&str]) -> (Option<u64>, Output) {
    if !Path::new("/usr/bin/time").exists() {
        return (None, Command::new(bin("dem-import")).args(args).output().unwrap());
    }
    let o = Command::new("/usr/bin/time").arg("-v").arg(bin("dem-import")).args(args).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    let kb = err.lines().find_map(|l| l.trim().strip_prefix("Maximum resident set size (kbytes): ")).and_then(|v| v.parse().ok());
    let own: String = err
        .lines()
        .take_while(|l| !l.starts_with("\tCommand being timed") && !l.starts_with("Command exited with non-zero status"))
        .map(|l| format!("{l}\n"))
        .collect();
    (kb, Output { status: o.status, stdout: o.stdout, stderr: own.into_bytes() })
}

/// No panic, no abort: an exit code that is 0, 1 or 2, and nothing on
/// stderr that a panic prints.
fn no_panic(o: &Output, what: &str) {
    let e = stderr(o);
    assert!(matches!(o.status.code(), Some(0..=2)), "{what}: exit {:?}\n{e}", o.status.code());
    assert!(!e.contains("panicked") && !e.contains("memory allocation"), "{what}:\n{e}");
}

/// Exit 2 and one line `dem-import: error: NAME...` containing `says`.
fn refused_in_one_line(o: &Output, name: &str, says: &[&str]) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{name}: {e}");
    let lines: Vec<&str> = e.lines().collect();
    assert_eq!(lines.len(), 1, "{name}: one line expected:\n{e}");
    assert!(lines[0].starts_with("dem-import: error: ") && lines[0].contains(&format!("{name}: ")), "{e}");
    for s in says {
        assert!(lines[0].contains(s), "{name}: {s:?} expected in\n{e}");
    }
}

fn dems(p: &Path) -> usize {
    npy::read_all(p.to_str().unwrap()).unwrap().len()
}

// ---------------------------------------------------------------- the cases

#[test]
fn mcap_lengths_near_2_pow_64_and_huge_declared_sizes_are_refused_before_allocating() {
    let dir = tempdir();
    let d = dir.path();
    // The hostile test's file: a Header record of length 2^64 - 1 in 17 bytes.
    let mut cases: Vec<(String, Vec<u8>)> = Vec::new();
    for (name, op, len) in [
        ("u64", 0x01u8, u64::MAX),
        ("u64m9", 0x06, u64::MAX - 9),
        ("p40", 0x06, 1u64 << 40),
        ("p30", 0x05, 1 << 30),
        ("p28", 0x03, 1 << 28),
    ] {
        let mut b = MCAP_MAGIC.to_vec();
        b.push(op);
        b.extend(len.to_le_bytes());
        cases.push((name.to_string(), b));
    }
    // MCAP magic and random bytes (a fixed generator).
    let mut x = 0x2545F4914F6CDD1Du64;
    for k in 0..12 {
        let mut b = MCAP_MAGIC.to_vec();
        for _ in 0..(64 + 97 * k) {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            b.push(x as u8);
        }
        cases.push((format!("random{k}"), b));
    }
    for (name, bytes) in &cases {
        let p = write(d, &format!("{name}.mcap"), bytes);
        let out = d.join("o").join(name);
        let (kb, o) = peak_kb(&["--out", out.to_str().unwrap(), p.to_str().unwrap()]);
        no_panic(&o, name);
        refused_in_one_line(&o, &format!("{name}.mcap"), &["not imported"]);
        if let Some(kb) = kb {
            assert!(kb < 100 * 1024, "{name}: peak {kb} kB");
        }
        assert!(!out.exists(), "{name}: a refused run leaves no output folder");
    }
    let o = import(&d.join("o1"), &[], &[&d.join("u64.mcap")]);
    refused_in_one_line(&o, "u64.mcap", &["byte 8: record op 0x01 declares 18446744073709551615 bytes, 0 are left in the file"]);
}

#[test]
fn lengths_inside_zstd_lz4_and_plain_chunks_are_stepped_over_and_the_maps_around_them_kept() {
    let dir = tempdir();
    let d = dir.path();
    let messages = good_messages(6);
    let recs = mcap_message_records(&messages);
    let (first, second) = recs.split_at(recs.len() / 2);
    let good = |rs: &[Vec<u8>], codec: &str| mcap_chunk(codec, &rs.concat(), None, 0);
    // Records whose lengths run past their chunk, inside each compression.
    let mut lying = mcap_record(0x05, &[0; 30]);
    lying[1..9].copy_from_slice(&(u64::MAX - 5).to_le_bytes());
    let mut also = mcap_record(0x04, &[0; 10]);
    also[1..9].copy_from_slice(&u64::MAX.to_le_bytes());
    let hostile = [
        mcap_chunk("", &lying, None, 0),
        mcap_chunk("zstd", &also, None, 0),
        mcap_chunk("lz4", &lying, None, 0),
        // Garbage where compressed records should be.
        mcap_chunk_raw("zstd", 100, 0, b"\x28\xb5\x2f\xfd garbage garbage garbage"),
        mcap_chunk_raw("lz4", 100, 0, b"\x04\x22\x4d\x18 garbage garbage garbage"),
        // 2^40 uncompressed bytes declared; 2^64 - 1.
        mcap_chunk("zstd", &[0; 10], Some(1 << 40), 0),
        mcap_chunk("lz4", &[0; 10], Some(u64::MAX), 0),
        // A bomb: declares 1000 bytes, holds 64 MB of zeros.
        mcap_chunk("zstd", &vec![0; 64 << 20], Some(1000), 0),
        // A CRC that does not match.
        mcap_chunk("", &second[0], None, 0x1234_5678),
        // A message on a channel never declared.
        mcap_record(0x05, &[99, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 2, 3]),
    ];
    let mut body = vec![good(first, "zstd")];
    body.extend(hostile.iter().cloned());
    body.push(good(second, "lz4"));
    let bytes = mcap(&body);
    // Where the first hostile record starts: magic, Header, the good chunk.
    let at = MCAP_MAGIC.len() + 9 + 4 + 4 + "ros1".len() + "hostile.rs".len() + body[0].len();
    let p = write(d, "chunks.mcap", &bytes);
    let out = d.join("o");
    let (kb, o) = peak_kb(&["--out", out.to_str().unwrap(), p.to_str().unwrap()]);
    no_panic(&o, "chunks.mcap");
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains(&format!("chunks.mcap: byte {at}: chunk, record at byte 0 of its 39 uncompressed bytes: record op 0x05 declares 18446744073709551610 bytes, 30 are left in the chunk")), "{e}");
    assert!(e.contains("6 maps -> 6 DEMs"), "{e}");
    assert_eq!(dems(&out.join("chunks.npy")), 6);
    // Each hostile part is counted (some warnings are only counted).
    assert!(e.contains(&format!("{} skipped: {} damaged", hostile.len(), hostile.len())), "{e}");
    if let Some(kb) = kb {
        assert!(kb < 100 * 1024, "peak {kb} kB");
    }
    // One by one, each names what it is.
    for (k, (rec, says)) in hostile
        .iter()
        .zip([
            "30 are left in the chunk",
            "declares 18446744073709551615 bytes, 10 are left in the chunk",
            "30 are left in the chunk",
            "zstd chunk",
            "lz4 chunk",
            "a chunk of 1099511627776 bytes is larger than the 33554432 bytes (32 MiB) limit",
            "a chunk of 18446744073709551615 bytes is larger than the 33554432 bytes (32 MiB) limit",
            "zstd chunk decompresses to more than the 1000 bytes its header says",
            "CRC",
            "a message on channel 99, which was never declared",
        ])
        .enumerate()
    {
        let mut one = vec![good(first, "zstd")];
        one.push(rec.clone());
        one.push(good(second, ""));
        let p = write(d, &format!("one{k}.mcap"), &mcap(&one));
        let o = import(&d.join(format!("o{k}")), &["--keep-going"], &[&p]);
        no_panic(&o, says);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(0), "{e}");
        assert!(e.contains(&format!("one{k}.mcap: byte {at}: ")) && e.contains(says), "{says}:\n{e}");
        assert!(e.contains("6 maps -> 6 DEMs") && e.contains("1 skipped: 1 damaged"), "{e}");
    }
    // A top-level record near 2^64 after the maps: the file breaks there.
    let mut tail = vec![good(first, "zstd"), good(second, "")];
    let mut broken = mcap_record(0x05, &[]);
    broken[1..9].copy_from_slice(&(u64::MAX - 8).to_le_bytes());
    tail.push(broken);
    let bytes = mcap(&tail);
    let at = bytes.len() - 9 - 29 - 8;
    let p = write(d, "tail.mcap", &bytes);
    let o = import(&d.join("ot"), &[], &[&p]);
    no_panic(&o, "tail");
    let e = stderr(&o);
    assert!(
        e.contains(&format!("tail.mcap: byte {at}: record op 0x05 declares 18446744073709551607 bytes")) && e.contains("6 maps -> 6 DEMs"),
        "{e}"
    );
}

/// A compressed chunk of `mb` MB of zeros saying it holds `size` bytes.
fn ros1_bomb(compression: &str, size: u32, mb: usize) -> Vec<u8> {
    use std::io::Write;
    let zeros = vec![0u8; 1 << 20];
    let data = match compression {
        "bz2" => {
            let mut e = bzip2::write::BzEncoder::new(Vec::new(), bzip2::Compression::fast());
            for _ in 0..mb {
                e.write_all(&zeros).unwrap();
            }
            e.finish().unwrap()
        }
        "lz4" => {
            let mut e = lz4::EncoderBuilder::new().build(Vec::new()).unwrap();
            for _ in 0..mb {
                e.write_all(&zeros).unwrap();
            }
            let (out, r) = e.finish();
            r.unwrap();
            out
        }
        _ => unreachable!(),
    };
    ros1_chunk(compression, size, &data)
}

#[test]
fn ros1_chunk_bombs_are_cut_at_their_declared_size_in_bounded_memory() {
    let dir = tempdir();
    let d = dir.path();
    let recs = bag_records(&good_messages(5));
    let mid = recs.len() / 2;
    for (compression, size, mb, says) in [
        ("bz2", 1000, 300, "bz2 chunk decompresses to more than the 1000 bytes its header says"),
        ("lz4", 1000, 500, "lz4 chunk decompresses to more than the 1000 bytes its header says"),
        ("lz4", 32 << 20, 500, "lz4 chunk decompresses to more than the 33554432 bytes its header says"),
        ("bz2", u32::MAX, 1, "a chunk of 4294967295 bytes is larger than the 33554432 bytes (32 MiB) limit"),
    ] {
        let mut with = recs[..mid].to_vec();
        let at = BAG_MAGIC.len() + with.iter().map(Vec::len).sum::<usize>();
        with.push(ros1_bomb(compression, size, mb));
        with.extend(recs[mid..].iter().cloned());
        let name = format!("bomb_{compression}_{size}.bag");
        let p = write(d, &name, &bag(&with));
        let out = d.join(&name).with_extension("out");
        let (kb, o) = peak_kb(&["--out", out.to_str().unwrap(), p.to_str().unwrap()]);
        no_panic(&o, &name);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{e}");
        assert!(e.contains(&format!("{name}: byte {at}: {says}")), "{e}");
        assert!(e.contains("5 maps -> 5 DEMs") && e.contains("1 skipped: 1 damaged"), "{e}");
        if let Some(kb) = kb {
            eprintln!("{name}: {mb} MB of zeros declared as {size} bytes: peak {} MB", kb / 1024);
            assert!(kb < 100 * 1024, "{name}: peak {kb} kB");
        }
        assert_eq!(dems(&out.join(p.file_stem().unwrap()).with_extension("npy")), 5);
    }
}

#[test]
fn keep_going_imports_the_good_recordings_beside_hostile_ones() {
    let dir = tempdir();
    let d = dir.path();
    let ok = write(d, "ok.bag", &bag(&bag_records(&good_messages(4))));
    let mut u64_mcap = MCAP_MAGIC.to_vec();
    u64_mcap.push(1);
    u64_mcap.extend(u64::MAX.to_le_bytes());
    let hostile = write(d, "u64.mcap", &u64_mcap);
    let junk = write(d, "junk.bag", b"hello");
    let out = d.join("o");
    let o = import(&out, &["--keep-going"], &[&ok, &hostile, &junk]);
    no_panic(&o, "batch");
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{e}");
    assert!(e.contains("ok.bag: 4 maps -> 4 DEMs"), "{e}");
    assert!(e.contains("u64.mcap: not imported: byte 8: record op 0x01 declares 18446744073709551615 bytes"), "{e}");
    assert!(e.contains("junk.bag: not imported: not a ROS 1 bag"), "{e}");
    assert!(e.contains("4 DEMs from 3 recordings"), "{e}");
    assert_eq!(dems(&out.join("ok.npy")), 4);
    // Without --keep-going: the same outputs, then exit 2 (bad input).
    let out2 = d.join("o2");
    let o = import(&out2, &[], &[&ok, &hostile, &junk]);
    no_panic(&o, "batch");
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.lines().last().unwrap().starts_with("dem-import: error: 2 of 3 recordings could not be imported"), "{e}");
    assert_eq!(dems(&out2.join("ok.npy")), 4);
}

#[test]
fn threads_are_bounded_and_a_refused_run_leaves_no_output_folder() {
    let dir = tempdir();
    let d = dir.path();
    let ok = write(d, "ok.bag", &bag(&bag_records(&good_messages(2))));
    let out = d.join("o").join("new");
    let o = import(&out, &["--threads", "100000"], &[&ok]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("'--threads <THREADS>': 100000 is not in 1..=1024"), "{}", stderr(&o));
    let o = import(&out, &["--threads", "0"], &[&ok]);
    assert_eq!(o.status.code(), Some(2));
    // A missing recording, not a recording, a wrong --map-topic: exit 2 in one line, no folder.
    let o = import(&out, &[], &[&d.join("missing.bag")]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("missing.bag"), "{}", stderr(&o));
    let junk = write(d, "junk.bag", b"hello");
    refused_in_one_line(&import(&out, &[], &[&junk]), "junk.bag", &["not imported: not a ROS 1 bag"]);
    let junk_mcap = write(d, "junk.mcap", b"hello");
    refused_in_one_line(&import(&out, &[], &[&junk_mcap]), "junk.mcap", &["not an MCAP file"]);
    let o = import(&out, &["--map-topic", "/tf"], &[&ok]);
    refused_in_one_line(&o, "ok.bag", &["topic /tf holds tf2_msgs/TFMessage, not grid_map_msgs/GridMap"]);
    let o = import(&out, &["--map-topic", "/nope"], &[&ok]);
    refused_in_one_line(&o, "ok.bag", &["no topic /nope"]);
    assert!(!d.join("o").exists(), "a refused run created its output folder");
    // --threads 2 over one recording runs.
    let o = import(&out, &["--threads", "2"], &[&ok]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

#[test]
fn huge_finite_values_are_skipped_naming_the_message_and_the_value() {
    let dir = tempdir();
    let d = dir.path();
    // TF z = 1e308 at 4.25 s, a flipper at 1e39 rad at 5.25 s, a map of
    // heights 3e38 at 2 s (and a TF z = -1e38 at 6.25 s).
    let mut m = good_messages(6);
    m.push((TF, 4.25, tf(4.25, &[("odom", "base_link", [0.0, 0.0, 1e308])])));
    m.push((TF, 6.25, tf(6.25, &[("odom", "base_link", [0.0, 0.0, -1e38])])));
    m.push((JOINTS, 5.25, joints(5.25, [1e39, 0.2, 0.3, 0.4])));
    for x in m.iter_mut().filter(|x| x.0 == MAP && x.1 == 2.0) {
        x.2 = Map { height: 3e38, ..Map::at(2.0) }.bytes();
    }
    m.sort_by(|a, b| a.1.total_cmp(&b.1));
    let p = write(d, "values.bag", &bag(&bag_records(&m)));
    let o = import(&d.join("o"), &[], &[&p]);
    no_panic(&o, "values");
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("values.bag: topic /tf, message 9: transform odom -> base_link: translation z = 1e308 m is not a position"), "{e}");
    assert!(e.contains("values.bag: topic /tf, message 14: transform odom -> base_link: translation z = -1e38 m is not a position"), "{e}");
    assert!(
        e.contains("values.bag: topic /joint_states, message 11: flipper joint front_left_flipper_j at 1e39 rad is not an angle"),
        "{e}"
    );
    assert!(e.contains("values.bag: topic /elevation_mapping/elevation_map, message 1: height 3e38 m at DEM row"), "{e}");
    assert!(e.contains("6 maps -> 5 DEMs") && e.contains("4 skipped: 4 damaged"), "{e}");
    assert_eq!(dems(&d.join("o/values.npy")), 5);
    // --keep-going: the same, exit 0, the summary printed.
    let o = import(&d.join("o2"), &["--keep-going"], &[&p]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stderr(&o).contains("6 maps -> 5 DEMs"), "{}", stderr(&o));
}

#[test]
fn damaged_map_geometry_is_named_as_what_it_is() {
    let dir = tempdir();
    let d = dir.path();
    let mut m = good_messages(6);
    let nan_map = |k: usize, f: &dyn Fn(&mut Map)| {
        let mut map = Map::at(k as f64);
        f(&mut map);
        map.bytes()
    };
    for x in m.iter_mut().filter(|x| x.0 == MAP) {
        match x.1 as usize {
            2 => x.2 = nan_map(2, &|m| m.orientation[2] = f64::NAN),
            3 => x.2 = nan_map(3, &|m| m.centre[0] = f64::NAN),
            4 => x.2 = nan_map(4, &|m| m.length_x = 1e300),
            5 => x.2 = nan_map(5, &|m| m.data_offset = 5),
            _ => {}
        }
    }
    let p = write(d, "maps.bag", &bag(&bag_records(&m)));
    let o = import(&d.join("o"), &[], &[&p]);
    no_panic(&o, "maps");
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    let at = |k: usize| format!("maps.bag: topic /elevation_mapping/elevation_map, message {k}: ");
    assert!(e.contains(&format!("{}info.pose.orientation (0, 0, NaN, 1) is not a rotation", at(1))), "{e}");
    assert!(e.contains(&format!("{}info.pose.position x = NaN m is not a position", at(2))), "{e}");
    assert!(
        e.contains(&format!("{}info: lengths 1e300 x 3 m at resolution 0.05 m are ", at(3)))
            && e.contains("e301 x 60 cells (1 to 65536 a side)"),
        "{e}"
    );
    assert!(
        e.contains(&format!(
            "{}layer elevation: layout.data_offset 5 is out of range: 3600 cells from there need 3605 floats, the layer has 3600",
            at(4)
        )),
        "{e}"
    );
    assert!(e.lines().all(|l| l.len() < 300), "{e}");
    assert!(e.contains("6 maps -> 2 DEMs") && e.contains("4 skipped: 4 damaged"), "{e}");
}

#[test]
fn a_deep_tf_chain_is_followed_and_a_loop_is_named() {
    let dir = tempdir();
    let d = dir.path();
    // odom -> f0 -> ... -> f299 -> base_link, static; no loop.
    let names: Vec<String> = (0..300).map(|k| format!("f{k}")).collect();
    let mut links: Vec<(&str, &str, [f64; 3])> = vec![("odom", "f0", [0.0; 3])];
    for k in 1..300 {
        links.push((&names[k - 1], &names[k], [0.0; 3]));
    }
    links.push(("f299", "base_link", [0.0, 0.0, 0.1]));
    let mut m: Vec<_> = (1..=3).map(|k| (MAP, k as f64, Map::at(k as f64).bytes())).collect();
    m.insert(0, (TF_STATIC, 0.0, tf(0.0, &links)));
    let p = write(d, "chain.bag", &bag(&bag_records(&m)));
    let o = import(&d.join("o"), &[], &[&p]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{e}");
    assert!(e.contains("3 maps -> 3 DEMs") && !e.contains("loop"), "{e}");
    // A loop: odom -> a -> b -> a.
    let mut m: Vec<_> = (1..=2).map(|k| (MAP, k as f64, Map::at(k as f64).bytes())).collect();
    m.insert(0, (TF_STATIC, 0.0, tf(0.0, &[("a", "b", [0.0; 3]), ("b", "a", [0.0; 3]), ("b", "base_link", [0.0; 3])])));
    let p = write(d, "loop.bag", &bag(&bag_records(&m)));
    let o = import(&d.join("o2"), &[], &[&p]);
    no_panic(&o, "loop");
    assert!(stderr(&o).contains("message 0: the TF tree has a loop through b"), "{}", stderr(&o));
}
