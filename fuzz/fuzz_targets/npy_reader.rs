//! Any bytes as an NPY stream: records or an error naming the file, never a
//! panic; what is accepted holds only finite values.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut r = dem_core::npy::NpyReader::new(std::io::Cursor::new(data), "fuzz.npy", Some(data.len() as u64));
    match r.read_to_end() {
        Ok(records) => assert!(records.iter().flatten().all(|v| v.is_finite())),
        Err(e) => assert!(e.to_string().starts_with("fuzz.npy: ")),
    }
});
