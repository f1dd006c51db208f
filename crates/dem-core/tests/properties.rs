//! Property tests of everything that parses user input: the NPY stream
//! reader and the CSV readers. Whatever the bytes,
//! a reader returns records or an error naming the file; it never panics,
//! never allocates by what a header claims, and what it accepts follows the
//! contract. `make test` runs a fixed budget of cases (PROPTEST_CASES,
//! default 256 a property); `make fuzz` runs many more, plus cargo-fuzz.

use std::io::Cursor;

use dem_core::format::RECORD_LEN;
use dem_core::npy::header::f32_header;
use dem_core::npy::NpyReader;
use dem_core::{table, Dem, DemCells};
use proptest::prelude::*;

fn config() -> ProptestConfig {
    let cases = std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(256);
    // A fixed seed unless PROPTEST_RNG_SEED names one: `make test` draws the
    // same cases on every machine, `make fuzz` draws new ones.
    let rng_seed = match std::env::var_os("PROPTEST_RNG_SEED") {
        Some(_) => ProptestConfig::default().rng_seed,
        None => proptest::test_runner::RngSeed::Fixed(0),
    };
    ProptestConfig { cases, rng_seed, failure_persistence: None, ..ProptestConfig::default() }
}

/// Read a whole stream from bytes; the error as text.
fn read(bytes: &[u8]) -> Result<Vec<Dem>, String> {
    let mut r = NpyReader::new(Cursor::new(bytes.to_vec()), "x.npy", Some(bytes.len() as u64));
    r.read_to_end().map_err(|e| e.to_string())
}

/// A valid NPY array of `n` records built from `values` (cycled).
fn npy(n: usize, values: &[f32]) -> Vec<u8> {
    let mut b = f32_header(n as u64);
    for i in 0..n * RECORD_LEN {
        b.extend_from_slice(&values[i % values.len()].to_le_bytes());
    }
    b
}

fn finite() -> impl Strategy<Value = f32> {
    prop_oneof![-10.0f32..10.0, Just(-0.0f32), Just(f32::MAX), Just(f32::MIN_POSITIVE / 2.0)]
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn any_bytes_give_records_or_an_error_naming_the_file(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
        if let Err(e) = read(&bytes) {
            prop_assert!(e.starts_with("x.npy: "), "{e}");
        }
    }

    #[test]
    fn a_mutated_stream_is_read_or_refused_never_misread(
        n in 1usize..6,
        values in proptest::collection::vec(finite(), 1..32),
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..4),
        cut in any::<usize>(),
    ) {
        let good = [npy(n, &values), npy(2, &values)].concat();
        let mut bad = good.clone();
        for (at, x) in flips {
            let at = at % bad.len();
            bad[at] ^= x;
        }
        bad.truncate(cut % (bad.len() + 1));
        match read(&bad) {
            Ok(records) => {
                // Whatever was accepted follows the contract's value rule.
                for d in &records {
                    prop_assert!(d.iter().all(|v| v.is_finite()));
                    prop_assert!((0..20).all(|r| (0..5).all(|c| d.mask(r, c).is_finite())));
                }
                prop_assert!(records.len() <= n + 2 + bad.len() / (RECORD_LEN * 4));
            }
            Err(e) => prop_assert!(e.starts_with("x.npy: "), "{e}"),
        }
    }

    #[test]
    fn finite_records_round_trip_bit_for_bit(n in 0usize..300, values in proptest::collection::vec(finite(), 1..64)) {
        let bytes = npy(n, &values);
        let records = read(&bytes).unwrap();
        prop_assert_eq!(records.len(), n);
        let back: Vec<u8> = records.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
        prop_assert_eq!(&back[..], &bytes[128..]);
    }

    #[test]
    fn csv_readers_never_panic_and_name_the_file(text in "[a-z_,0-9.\\-\n\" ]{0,300}") {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.csv");
        std::fs::write(&p, &text).unwrap();
        let p = p.to_string_lossy().into_owned();
        for e in [table::read_labels(&p).err(), table::read_pairs(&p).err(), table::read_index(&p).err()].into_iter().flatten() {
            prop_assert!(e.to_string().starts_with(&p), "{e}");
        }
    }

    #[test]
    fn csv_with_a_valid_header_and_junk_rows_names_a_line(rows in proptest::collection::vec("[0-9a-z\\-.]{0,6},[0-9a-z\\-.]{0,6}", 1..20)) {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("p.csv");
        std::fs::write(&p, format!("sim_index,real_index\n{}\n", rows.join("\n"))).unwrap();
        let p = p.to_string_lossy().into_owned();
        match table::read_pairs(&p) {
            Ok(pairs) => prop_assert_eq!(pairs.len(), rows.len()),
            Err(e) => prop_assert!(e.to_string().contains(": line "), "{e}"),
        }
    }
}
