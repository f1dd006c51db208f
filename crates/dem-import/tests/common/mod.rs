//! Recordings built byte by byte for the tests: ROS 1 serialization of
//! the three message types dem-import reads, a small ROS 1 bag writer and
//! a small MCAP writer (records, chunks in each compression), so a test
//! can put a lying length or a bomb anywhere.
#![allow(dead_code)]

// ---------------------------------------------------------------- ROS 1 serialization

#[derive(Default)]
pub struct W(pub Vec<u8>);

impl W {
    pub fn u16(&mut self, v: u16) -> &mut Self {
        self.0.extend(v.to_le_bytes());
        self
    }
    pub fn u32(&mut self, v: u32) -> &mut Self {
        self.0.extend(v.to_le_bytes());
        self
    }
    pub fn f64(&mut self, v: f64) -> &mut Self {
        self.0.extend(v.to_le_bytes());
        self
    }
    pub fn str(&mut self, s: &str) -> &mut Self {
        self.u32(s.len() as u32);
        self.0.extend(s.as_bytes());
        self
    }
    pub fn header(&mut self, t: f64, frame: &str) -> &mut Self {
        let ns = (t * 1e9).round() as u64;
        self.u32(0).u32((ns / 1_000_000_000) as u32).u32((ns % 1_000_000_000) as u32).str(frame)
    }
}

pub const SEC0: f64 = 100.0;

/// A map at time `t`, what is changed from a good map in `m`.
#[derive(Clone)]
pub struct Map {
    pub t: f64,
    pub centre: [f64; 3],
    pub orientation: [f64; 4],
    pub length_x: f64,
    pub data_offset: u32,
    pub height: f32,
}

impl Map {
    pub fn at(t: f64) -> Map {
        Map { t: SEC0 + t, centre: [0.4, 0.0, 0.0], orientation: [0.0, 0.0, 0.0, 1.0], length_x: 3.0, data_offset: 0, height: 0.0 }
    }
    /// ROS 1 grid_map_msgs/GridMap: 60 x 60 cells of 5 cm, one layer "elevation".
    pub fn bytes(&self) -> Vec<u8> {
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
pub fn tf(t: f64, links: &[(&str, &str, [f64; 3])]) -> Vec<u8> {
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

pub const FLIPPERS: [&str; 4] = ["front_left_flipper_j", "front_right_flipper_j", "rear_left_flipper_j", "rear_right_flipper_j"];

/// ROS 1 sensor_msgs/JointState of the four flippers at `t`.
pub fn joints(t: f64, positions: [f64; 4]) -> Vec<u8> {
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

pub const MAP: (&str, &str) = ("/elevation_mapping/elevation_map", "grid_map_msgs/GridMap");
pub const TF: (&str, &str) = ("/tf", "tf2_msgs/TFMessage");
pub const TF_STATIC: (&str, &str) = ("/tf_static", "tf2_msgs/TFMessage");
pub const JOINTS: (&str, &str) = ("/joint_states", "sensor_msgs/JointState");

/// The messages of a good recording: TF odom -> base_link every 0.5 s
/// from 0 to 10 s, flipper joints as often, maps at 1, 2, ... `maps` s.
pub fn good_messages(maps: usize) -> Vec<((&'static str, &'static str), f64, Vec<u8>)> {
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

pub fn ros1_fields(fields: &[(&str, &[u8])]) -> Vec<u8> {
    let mut h = Vec::new();
    for (n, v) in fields {
        h.extend(((n.len() + 1 + v.len()) as u32).to_le_bytes());
        h.extend(n.as_bytes());
        h.push(b'=');
        h.extend(*v);
    }
    h
}

pub fn ros1_record(fields: &[(&str, &[u8])], data: &[u8]) -> Vec<u8> {
    let h = ros1_fields(fields);
    let mut out = (h.len() as u32).to_le_bytes().to_vec();
    out.extend(h);
    out.extend((data.len() as u32).to_le_bytes());
    out.extend(data);
    out
}

pub const BAG_MAGIC: &[u8] = b"#ROSBAG V2.0\n";

/// A bag (unindexed, its records at top level) of `messages`, and the
/// records as a list so a test can put its own between them.
pub fn bag_records(messages: &[((&str, &str), f64, Vec<u8>)]) -> Vec<Vec<u8>> {
    let mut recs = vec![ros1_record(&[("op", &[0x03]), ("index_pos", &0u64.to_le_bytes())], &[b' '; 16])];
    let mut conns: Vec<(&str, &str)> = Vec::new();
    for (topic, t, data) in messages {
        let conn = match conns.iter().position(|c| c == topic) {
            Some(k) => k as u32,
            None => {
                conns.push(*topic);
                let k = conns.len() as u32 - 1;
                let d = ros1_fields(&[
                    ("topic", topic.0.as_bytes()),
                    ("type", topic.1.as_bytes()),
                    ("md5sum", b"*"),
                    ("message_definition", b""),
                ]);
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

pub fn bag(recs: &[Vec<u8>]) -> Vec<u8> {
    let mut b = BAG_MAGIC.to_vec();
    for r in recs {
        b.extend(r);
    }
    b
}

/// A ROS 1 chunk record that says it holds `size` bytes of `compression`.
pub fn ros1_chunk(compression: &str, size: u32, data: &[u8]) -> Vec<u8> {
    ros1_record(&[("op", &[0x05]), ("compression", compression.as_bytes()), ("size", &size.to_le_bytes())], data)
}

// ---------------------------------------------------------------- MCAP files

pub const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

pub fn mcap_record(op: u8, body: &[u8]) -> Vec<u8> {
    let mut r = vec![op];
    r.extend((body.len() as u64).to_le_bytes());
    r.extend(body);
    r
}

pub fn mcap_str(w: &mut Vec<u8>, s: &str) {
    w.extend((s.len() as u32).to_le_bytes());
    w.extend(s.as_bytes());
}

/// Schema, Channel and Message records (ROS 1 encoding) of `messages`.
pub fn mcap_message_records(messages: &[((&str, &str), f64, Vec<u8>)]) -> Vec<Vec<u8>> {
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
pub fn mcap_chunk(compression: &str, records: &[u8], size: Option<u64>, crc: u32) -> Vec<u8> {
    let data = match compression {
        "" => records.to_vec(),
        "zstd" => zstd::bulk::compress(records, 3).unwrap(),
        "lz4" => lz4_frame(records),
        _ => panic!("{compression}"),
    };
    mcap_chunk_raw(compression, size.unwrap_or(records.len() as u64), crc, &data)
}

/// A Chunk record holding `data` as its (compressed) records.
pub fn mcap_chunk_raw(compression: &str, size: u64, crc: u32, data: &[u8]) -> Vec<u8> {
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

pub fn lz4_frame(data: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = lz4::EncoderBuilder::new().build(Vec::new()).unwrap();
    e.write_all(data).unwrap();
    let (out, r) = e.finish();
    r.unwrap();
    out
}

/// An MCAP file: magic, Header, `recs`, Footer, magic.
pub fn mcap(recs: &[Vec<u8>]) -> Vec<u8> {
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

/// A ROS 1 chunk record holding `records`, compressed with `compression`
/// (`none`, `bz2`, `lz4`), its size the true one.
pub fn ros1_chunk_of(compression: &str, records: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let data = match compression {
        "none" => records.to_vec(),
        "bz2" => {
            let mut e = bzip2::write::BzEncoder::new(Vec::new(), bzip2::Compression::fast());
            e.write_all(records).unwrap();
            e.finish().unwrap()
        }
        "lz4" => lz4_frame(records),
        _ => panic!("{compression}"),
    };
    ros1_chunk(compression, records.len() as u32, &data)
}

/// A bag of `messages` in three chunks (`none`, `bz2`, `lz4`) after the
/// bag header record.
pub fn chunked_bag(messages: &[((&str, &str), f64, Vec<u8>)]) -> Vec<u8> {
    let recs = bag_records(messages);
    let (header, body) = recs.split_first().unwrap();
    let third = body.len().div_ceil(3);
    let mut out = vec![header.clone()];
    for (part, codec) in body.chunks(third).zip(["none", "bz2", "lz4"]) {
        out.push(ros1_chunk_of(codec, &part.concat()));
    }
    bag(&out)
}

/// An MCAP file of `messages` in three chunks (`zstd`, `lz4`, none) with
/// their CRCs.
pub fn chunked_mcap(messages: &[((&str, &str), f64, Vec<u8>)]) -> Vec<u8> {
    let recs = mcap_message_records(messages);
    let third = recs.len().div_ceil(3);
    let chunks: Vec<Vec<u8>> = recs
        .chunks(third)
        .zip(["zstd", "lz4", ""])
        .map(|(part, codec)| {
            let records = part.concat();
            mcap_chunk(codec, &records, None, crc32fast::hash(&records))
        })
        .collect();
    mcap(&chunks)
}

/// The same recording written by the `mcap` crate's writer (Foxglove's
/// reference implementation: message indexes, a summary section with
/// chunk indexes and statistics), chunks of `chunk_size` bytes in
/// `compression` (None: uncompressed).
pub fn reference_mcap(messages: &[((&str, &str), f64, Vec<u8>)], compression: Option<mcap::Compression>, chunk_size: u64) -> Vec<u8> {
    let mut cursor = std::io::Cursor::new(Vec::new());
    {
        let opts = mcap::WriteOptions::new().compression(compression).chunk_size(Some(chunk_size)).profile("ros1");
        let mut w = opts.create(&mut cursor).unwrap();
        let mut channels: Vec<((&str, &str), u16)> = Vec::new();
        for (seq, (topic, t, data)) in messages.iter().enumerate() {
            let id = match channels.iter().find(|c| c.0 == *topic) {
                Some(c) => c.1,
                None => {
                    let schema = w.add_schema(topic.1, "ros1msg", b"").unwrap();
                    let id = w.add_channel(schema, topic.0, "ros1", &Default::default()).unwrap();
                    channels.push((*topic, id));
                    id
                }
            };
            let ns = ((SEC0 + t) * 1e9).round() as u64;
            let header = mcap::records::MessageHeader { channel_id: id, sequence: seq as u32, log_time: ns, publish_time: ns };
            w.write_to_known_channel(&header, data).unwrap();
        }
        w.finish().unwrap();
    }
    cursor.into_inner()
}
