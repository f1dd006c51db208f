//! Any text as a sensor model: refused, or a model whose effects write only
//! finite values.
#![no_main]
use dem_core::DemCells;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Ok(m) = dem_sensor::SensorModel::from_json(text) {
        let mut d = dem_core::format::empty_dem();
        for i in 0..100 {
            d.set_valid(i / 5, i % 5, -0.07 + 0.01 * (i % 13) as f32);
        }
        m.apply_at(&mut d, 1, 2, Some(0.5));
        assert!(d.iter().all(|v| v.is_finite()));
    }
});
