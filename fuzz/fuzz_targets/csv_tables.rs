//! Any bytes as a labels, pairs or index CSV: rows or an error naming the
//! file, never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = std::env::temp_dir().join(format!("dem-fuzz-{}.csv", std::process::id()));
    std::fs::write(&path, data).unwrap();
    let p = path.to_string_lossy().into_owned();
    for e in [
        dem_core::table::read_labels(&p).err(),
        dem_core::table::read_pairs(&p).err(),
        dem_core::table::read_index(&p).err(),
    ]
    .into_iter()
    .flatten()
    {
        assert!(e.to_string().starts_with(&p));
    }
});
