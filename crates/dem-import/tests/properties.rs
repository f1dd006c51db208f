//! Property tests of the container readers (MCAP, ROS 1 bags) and the
//! message decoders behind them: whatever the bytes (random, or a real
//! recording mutated, truncated, or given lying lengths), a reader hands
//! out messages and skipped parts and stops with an error, never panics,
//! and the binary stays in bounded memory. `make test` runs a fixed budget
//! (PROPTEST_CASES, default 256 a property; the runs of the binary an
//! eighth of it); `make fuzz` runs many more, plus cargo-fuzz.

mod common;

use std::io::Cursor;
use std::path::Path;
use std::process::Command;

use common::*;
use dem_import::container::{mcap, ros1, Event, StopError};
use dem_import::msg;
use proptest::prelude::*;

fn cases() -> u32 {
    std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(256)
}

fn config(cases: u32) -> ProptestConfig {
    // A fixed seed unless PROPTEST_RNG_SEED names one: `make test` draws the
    // same cases on every machine, `make fuzz` draws new ones.
    let rng_seed = match std::env::var_os("PROPTEST_RNG_SEED") {
        Some(_) => ProptestConfig::default().rng_seed,
        None => proptest::test_runner::RngSeed::Fixed(0),
    };
    ProptestConfig { cases, rng_seed, failure_persistence: None, ..ProptestConfig::default() }
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    /// MCAP from tests/common's writer.
    Mcap,
    /// MCAP from the `mcap` crate's writer.
    RefMcap,
    Ros1,
}

/// What a reader gave: each message's topic and bytes, the skipped parts'
/// offsets, and how it ended. Every message is decoded as its type says.
#[derive(Debug, Default, PartialEq)]
struct Read {
    messages: Vec<(String, Vec<u8>)>,
    skipped: Vec<u64>,
    end: Option<String>,
}

fn read(kind: Kind, bytes: &[u8]) -> Read {
    let mut out = Read::default();
    let len = bytes.len() as u64;
    let mut last = 0;
    let mut on_event = |e: Event<'_>| match e {
        Event::Message { conn, data } => {
            // The decoders must not panic on whatever a container hands out.
            match conn.msg_type.as_str() {
                "grid_map_msgs/GridMap" => {
                    let _ = msg::GridMap::decode(data, conn.encoding);
                }
                "tf2_msgs/TFMessage" => {
                    let _ = msg::decode_tf(data, conn.encoding);
                }
                "sensor_msgs/JointState" => {
                    let _ = msg::decode_joint_state(data, conn.encoding);
                }
                _ => {}
            }
            out.messages.push((conn.topic.clone(), data.to_vec()));
        }
        Event::Skipped { offset, .. } => {
            assert!(offset <= len, "a skipped part at byte {offset} of {len}");
            out.skipped.push(offset);
        }
    };
    let mut on_bytes = |b: u64| {
        assert!(b >= last && b <= len, "bytes read {b} after {last}, of {len}");
        last = b;
    };
    let r = match kind {
        Kind::Mcap | Kind::RefMcap => mcap::read_from(Cursor::new(bytes), len, &mut on_event, &mut on_bytes),
        Kind::Ros1 => ros1::read_from(Cursor::new(bytes), len, &mut on_event, &mut on_bytes),
    };
    if let Err(e) = &r {
        if let StopError::Broken { offset, .. } = e {
            assert!(*offset <= len, "broken at byte {offset} of {len}");
        }
        out.end = Some(e.to_string());
    }
    out
}

fn seed(kind: Kind) -> Vec<u8> {
    let messages = good_messages(3);
    match kind {
        Kind::Mcap => chunked_mcap(&messages),
        Kind::RefMcap => reference_mcap(&messages, Some(::mcap::Compression::Zstd), 20_000),
        Kind::Ros1 => chunked_bag(&messages),
    }
}

fn kind() -> impl Strategy<Value = Kind> {
    prop_oneof![Just(Kind::Mcap), Just(Kind::RefMcap), Just(Kind::Ros1)]
}

/// Lengths a hostile file declares.
fn length() -> impl Strategy<Value = u64> {
    prop_oneof![
        (0u64..10).prop_map(|k| u64::MAX - k),
        (0u64..10).prop_map(|k| u64::from(u32::MAX) - k),
        (20u32..44).prop_map(|k| 1u64 << k),
        any::<u64>(),
        0u64..100_000,
    ]
}

/// A mutation of a recording.
#[derive(Clone, Debug)]
enum Mutation {
    /// Overwrite a byte.
    Byte(usize, u8),
    /// Overwrite 8 (or, at random, 4) bytes with a length, little-endian.
    Length(usize, u64, bool),
    /// Cut the file here.
    Cut(usize),
    /// Insert bytes here.
    Insert(usize, Vec<u8>),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        4 => (any::<usize>(), any::<u8>()).prop_map(|(at, b)| Mutation::Byte(at, b)),
        3 => (any::<usize>(), length(), any::<bool>()).prop_map(|(at, n, wide)| Mutation::Length(at, n, wide)),
        1 => any::<usize>().prop_map(Mutation::Cut),
        1 => (any::<usize>(), proptest::collection::vec(any::<u8>(), 1..64)).prop_map(|(at, b)| Mutation::Insert(at, b)),
    ]
}

fn mutate(mut b: Vec<u8>, ms: &[Mutation]) -> Vec<u8> {
    for m in ms {
        if b.is_empty() {
            break;
        }
        match m {
            Mutation::Byte(at, x) => {
                let at = at % b.len();
                b[at] = *x;
            }
            Mutation::Length(at, n, wide) => {
                let bytes = if *wide { n.to_le_bytes().to_vec() } else { (*n as u32).to_le_bytes().to_vec() };
                let at = at % b.len();
                let end = (at + bytes.len()).min(b.len());
                b[at..end].copy_from_slice(&bytes[..end - at]);
            }
            Mutation::Cut(at) => b.truncate(at % b.len()),
            Mutation::Insert(at, x) => {
                let at = at % b.len();
                b.splice(at..at, x.iter().copied());
            }
        }
    }
    b
}

proptest! {
    #![proptest_config(config(cases()))]

    #[test]
    fn any_bytes_after_either_magic_are_read_or_refused(k in kind(), bytes in proptest::collection::vec(any::<u8>(), 0..4096)) {
        let magic: &[u8] = match k { Kind::Mcap | Kind::RefMcap => MCAP_MAGIC, Kind::Ros1 => BAG_MAGIC };
        read(k, &[magic, &bytes].concat());
        read(k, &bytes);
    }

    #[test]
    fn a_mutated_recording_is_read_or_refused_never_a_panic(k in kind(), ms in proptest::collection::vec(mutation(), 1..6)) {
        read(k, &mutate(seed(k), &ms));
    }

    #[test]
    fn a_cut_recording_gives_the_messages_before_the_cut(k in kind(), cut in any::<usize>()) {
        let whole = seed(k);
        let all = read(k, &whole);
        prop_assert!(all.end.is_none() && all.skipped.is_empty(), "{:?}", all.end);
        prop_assert_eq!(all.messages.len(), 21 * 2 + 3);
        let cut = &whole[..cut % whole.len()];
        let part = read(k, cut);
        // What a cut file hands out is what the whole file hands out first
        // (a chunk cut short is never read in part); a cut between two
        // records reads as a recording whose writer was killed there.
        prop_assert!(part.messages.len() <= all.messages.len());
        prop_assert_eq!(&part.messages[..], &all.messages[..part.messages.len()]);
    }
}

/// Peak resident memory (kB) of `dem-import` on `file`, and its exit code.
fn run_binary(dir: &Path, file: &Path) -> (Option<u64>, Option<i32>, String) {
    let out = dir.join("out");
    let o = Command::new("/usr/bin/time")
        .arg("-v")
        .arg(dem_testkit::bin("dem-import"))
        .args(["--keep-going", "--out", out.to_str().unwrap(), file.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    let kb = err.lines().find_map(|l| l.trim().strip_prefix("Maximum resident set size (kbytes): ")).and_then(|v| v.parse().ok());
    (kb, o.status.code(), err)
}

proptest! {
    #![proptest_config(config((cases() / 8).max(8)))]

    #[test]
    fn the_binary_on_a_mutated_recording_exits_0_1_or_2_in_bounded_memory(k in kind(), ms in proptest::collection::vec(mutation(), 1..6)) {
        if !Path::new("/usr/bin/time").exists() {
            return Ok(());
        }
        let dir = tempfile::tempdir().unwrap();
        let name = match k { Kind::Mcap | Kind::RefMcap => "m.mcap", Kind::Ros1 => "m.bag" };
        let file = dir.path().join(name);
        std::fs::write(&file, mutate(seed(k), &ms)).unwrap();
        let (kb, code, err) = run_binary(dir.path(), &file);
        prop_assert!(matches!(code, Some(0..=2)), "exit {code:?}\n{err}");
        prop_assert!(!err.contains("panicked"), "{err}");
        let kb = kb.unwrap_or(0);
        prop_assert!(kb < 100 * 1024, "peak {kb} kB\n{err}");
    }
}
