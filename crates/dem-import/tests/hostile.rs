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

// ---------------------------------------------------------------- ROS 1 serialization

#[derive(Default)]
struct W(Vec<u8>);

impl W {
    fn u16(&mut self, v: u16) -> &mut Self {
        self.0.extend(v.to_le_bytes());
        self
    }
    fn u32(&mut self, v: u32) -> &mut Self {
        self.0.extend(v.to_le_bytes());
        self
    }
    fn f64(&mut self, v: f64) -> &mut Self {
        self.0.extend(v.to_le_bytes());
        self
    }
    fn str(&mut self, s: &str) -> &mut Self {
        self.u32(s.len() as u32);
        self.0.extend(s.as_bytes());
        self
    }
    fn header(&mut self, t: f64, frame: &str) -> &mut Self {
        let ns = (t * 1e9).round() as u64;
        self.u32(0).u32((ns / 1_000_000_000) as u32).u32((ns % 1_000_000_000) as u32).str(frame)
    }
}

const SEC0: f64 = 100.0;

/// A map at time `t`, what is changed from a good map in `m`.
#[derive(Clone)]
struct Map {
    t: f64,
    centre: [f64; 3],
    orientation: [f64; 4],
    length_x: f64,
    data_offset: u32,
    height: f32,
}

impl Map {
    fn at(t: f64) -> Map {
        Map { t: SEC0 + t, centre: [0.4, 0.0, 0.0], orientation: [0.0, 0.0, 0.0, 1.0], length_x: 3.0, data_offset: 0, height: 0.0 }
    }
    /// ROS 1 grid_map_msgs/GridMap: 60 x 60 cells of 5 cm, one layer "elevation".
    fn bytes(&self) -> Vec<u8> {
        let n = 60usize;
        let mut w = W::default();
        w.header(self.t, "odom").f64(0.05).f64(self.length_x).f64(3.0);
        for v in self.centre.iter().chain(&self.orientation) {
            w.f64(*v);
        }
        w.u32(1).str("elevation").u32(0).u32(1);
        w.u32(2).str("column_index").u32(n as u32).u32((n * n) as u32).str("row_index").u32(n as u32).u32(n as u32);
        w.u32(self.data_offset).u32((n * n) as u32);
        for _ in 0..n * n {
            w.0.extend(self.height.to_le_bytes());
        }
        w.u16(0).u16(0);
        w.0
    }
}

/// ROS 1 tf2_msgs/TFMessage of (parent, child, translation) at `t`, no rotation.
fn tf(t: f64, links: &[(&str, &str, [f64; 3])]) -> Vec<u8> {
    let mut w = W::default();
    w.u32(links.len() as u32);
    for (parent, child, xyz) in links {
        w.header(SEC0 + t, parent).str(child);
        for v in xyz {
            w.f64(*v);
        }
        w.f64(0.0).f64(0.0).f64(0.0).f64(1.0);
    }
    w.0
}

const FLIPPERS: [&str; 4] = ["front_left_flipper_j", "front_right_flipper_j", "rear_left_flipper_j", "rear_right_flipper_j"];

/// ROS 1 sensor_msgs/JointState of the four flippers at `t`.
fn joints(t: f64, positions: [f64; 4]) -> Vec<u8> {
    let mut w = W::default();
    w.header(SEC0 + t, "").u32(4);
    for n in FLIPPERS {
        w.str(n);
    }
    w.u32(4);
    for p in positions {
        w.f64(p);
    }
    w.u32(0).u32(0);
    w.0
}

const MAP: (&str, &str) = ("/elevation_mapping/elevation_map", "grid_map_msgs/GridMap");
const TF: (&str, &str) = ("/tf", "tf2_msgs/TFMessage");
const TF_STATIC: (&str, &str) = ("/tf_static", "tf2_msgs/TFMessage");
const JOINTS: (&str, &str) = ("/joint_states", "sensor_msgs/JointState");

/// The messages of a good recording: TF odom -> base_link every 0.5 s
/// from 0 to 10 s, flipper joints as often, maps at 1, 2, ... `maps` s.
fn good_messages(maps: usize) -> Vec<((&'static str, &'static str), f64, Vec<u8>)> {
    let mut m = Vec::new();
    for k in 0..=20 {
        let t = k as f64 * 0.5;
        m.push((TF, t, tf(t, &[("odom", "base_link", [0.0, 0.0, 0.1])])));
        m.push((JOINTS, t, joints(t, [0.1, 0.2, 0.3, 0.4])));
    }
    for k in 1..=maps {
        m.push((MAP, k as f64, Map::at(k as f64).bytes()));
    }
    m.sort_by(|a, b| a.1.total_cmp(&b.1));
    m
}

// ---------------------------------------------------------------- ROS 1 bags

fn ros1_fields(fields: &[(&str, &[u8])]) -> Vec<u8> {
    let mut h = Vec::new();
    for (n, v) in fields {
        h.extend(((n.len() + 1 + v.len()) as u32).to_le_bytes());
        h.extend(n.as_bytes());
        h.push(b'=');
        h.extend(*v);
    }
    h
}

fn ros1_record(fields: &[(&str, &[u8])], data: &[u8]) -> Vec<u8> {
    let h = ros1_fields(fields);
    let mut out = (h.len() as u32).to_le_bytes().to_vec();
    out.extend(h);
    out.extend((data.len() as u32).to_le_bytes());
    out.extend(data);
    out
}

const BAG_MAGIC: &[u8] = b"#ROSBAG V2.0\n";

/// A bag (unindexed, its records at top level) of `messages`, and the
/// records as a list so a test can put its own between them.
fn bag_records(messages: &[((&str, &str), f64, Vec<u8>)]) -> Vec<Vec<u8>> {
    let mut recs = vec![ros1_record(&[("op", &[0x03]), ("index_pos", &0u64.to_le_bytes())], &[b' '; 16])];
    let mut conns: Vec<(&str, &str)> = Vec::new();
    for (topic, t, data) in messages {
        let conn = match conns.iter().position(|c| c == topic) {
            Some(k) => k as u32,
            None => {
                conns.push(*topic);
                let k = conns.len() as u32 - 1;
                let d = ros1_fields(&[("topic", topic.0.as_bytes()), ("type", topic.1.as_bytes()), ("md5sum", b"*"), ("message_definition", b"")]);
                recs.push(ros1_record(&[("op", &[0x07]), ("conn", &k.to_le_bytes()), ("topic", topic.0.as_bytes())], &d));
                k
            }
        };
        let ns = ((SEC0 + t) * 1e9).round() as u64;
        let mut time = ((ns / 1_000_000_000) as u32).to_le_bytes().to_vec();
        time.extend(((ns % 1_000_000_000) as u32).to_le_bytes());
        recs.push(ros1_record(&[("op", &[0x02]), ("conn", &conn.to_le_bytes()), ("time", &time)], data));
    }
    recs
}

fn bag(recs: &[Vec<u8>]) -> Vec<u8> {
    let mut b = BAG_MAGIC.to_vec();
    for r in recs {
        b.extend(r);
    }
    b
}

/// A ROS 1 chunk record that says it holds `size` bytes of `compression`.
fn ros1_chunk(compression: &str, size: u32, data: &[u8]) -> Vec<u8> {
    ros1_record(&[("op", &[0x05]), ("compression", compression.as_bytes()), ("size", &size.to_le_bytes())], data)
}

// ---------------------------------------------------------------- MCAP files

const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

fn mcap_record(op: u8, body: &[u8]) -> Vec<u8> {
    let mut r = vec![op];
    r.extend((body.len() as u64).to_le_bytes());
    r.extend(body);
    r
}

fn mcap_str(w: &mut Vec<u8>, s: &str) {
    w.extend((s.len() as u32).to_le_bytes());
    w.extend(s.as_bytes());
}

/// Schema, Channel and Message records (ROS 1 encoding) of `messages`.
fn mcap_message_records(messages: &[((&str, &str), f64, Vec<u8>)]) -> Vec<Vec<u8>> {
    let mut recs = Vec::new();
    let mut topics: Vec<(&str, &str)> = Vec::new();
    for (seq, (topic, t, data)) in messages.iter().enumerate() {
        let id = match topics.iter().position(|c| c == topic) {
            Some(k) => k as u16 + 1,
            None => {
                topics.push(*topic);
                let id = topics.len() as u16;
                let mut s = id.to_le_bytes().to_vec();
                mcap_str(&mut s, topic.1);
                mcap_str(&mut s, "ros1msg");
                s.extend(0u32.to_le_bytes());
                recs.push(mcap_record(0x03, &s));
                let mut c = id.to_le_bytes().to_vec();
                c.extend(id.to_le_bytes());
                mcap_str(&mut c, topic.0);
                mcap_str(&mut c, "ros1");
                c.extend(0u32.to_le_bytes());
                recs.push(mcap_record(0x04, &c));
                id
            }
        };
        let ns = ((SEC0 + t) * 1e9).round() as u64;
        let mut m = id.to_le_bytes().to_vec();
        m.extend((seq as u32).to_le_bytes());
        m.extend(ns.to_le_bytes());
        m.extend(ns.to_le_bytes());
        m.extend(data);
        recs.push(mcap_record(0x05, &m));
    }
    recs
}

/// A Chunk record of `records` compressed with `compression` ("", "zstd",
/// "lz4"), declaring `size` uncompressed bytes (None: the true size) and
/// their CRC (0: none).
fn mcap_chunk(compression: &str, records: &[u8], size: Option<u64>, crc: u32) -> Vec<u8> {
    let data = match compression {
        "" => records.to_vec(),
        "zstd" => zstd::bulk::compress(records, 3).unwrap(),
        "lz4" => lz4_frame(records),
        _ => panic!("{compression}"),
    };
    mcap_chunk_raw(compression, size.unwrap_or(records.len() as u64), crc, &data)
}

/// A Chunk record holding `data` as its (compressed) records.
fn mcap_chunk_raw(compression: &str, size: u64, crc: u32, data: &[u8]) -> Vec<u8> {
    let mut b = Vec::new();
    b.extend(0u64.to_le_bytes());
    b.extend(0u64.to_le_bytes());
    b.extend(size.to_le_bytes());
    b.extend(crc.to_le_bytes());
    mcap_str(&mut b, compression);
    b.extend((data.len() as u64).to_le_bytes());
    b.extend(data);
    mcap_record(0x06, &b)
}

fn lz4_frame(data: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = lz4::EncoderBuilder::new().build(Vec::new()).unwrap();
    e.write_all(data).unwrap();
    let (out, r) = e.finish();
    r.unwrap();
    out
}

/// An MCAP file: magic, Header, `recs`, Footer, magic.
fn mcap(recs: &[Vec<u8>]) -> Vec<u8> {
    let mut b = MCAP_MAGIC.to_vec();
    let mut h = Vec::new();
    mcap_str(&mut h, "ros1");
    mcap_str(&mut h, "hostile.rs");
    b.extend(mcap_record(0x01, &h));
    for r in recs {
        b.extend(r);
    }
    b.extend(mcap_record(0x02, &[0; 20]));
    b.extend(MCAP_MAGIC);
    b
}

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
    assert!(e.contains(&format!("tail.mcap: byte {at}: record op 0x05 declares 18446744073709551607 bytes")) && e.contains("6 maps -> 6 DEMs"), "{e}");
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
    assert!(e.contains("values.bag: topic /joint_states, message 11: flipper joint front_left_flipper_j at 1e39 rad is not an angle"), "{e}");
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
    assert!(e.contains(&format!("{}info: lengths 1e300 x 3 m at resolution 0.05 m are ", at(3))) && e.contains("e301 x 60 cells (1 to 65536 a side)"), "{e}");
    assert!(e.contains(&format!("{}layer elevation: layout.data_offset 5 is out of range: 3600 cells from there need 3605 floats, the layer has 3600", at(4))), "{e}");
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
