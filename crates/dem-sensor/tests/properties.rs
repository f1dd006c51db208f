//! Property tests of the sensor model JSON: whatever the text, parsing
//! returns a model or an error, never panics; every model it accepts writes
//! only finite values. `make test` runs a fixed budget of cases
//! (PROPTEST_CASES, default 256 a property); `make fuzz` runs many more.

use dem_core::format::{empty_dem, DemCells};
use dem_sensor::SensorModel;
use proptest::prelude::*;

fn config() -> ProptestConfig {
    let cases = std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(256);
    ProptestConfig { cases, failure_persistence: None, ..ProptestConfig::default() }
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn sensor_json_never_panics(text in "[{}\\[\\]\":,a-z0-9.e\\- ]{0,200}") {
        let _ = SensorModel::from_json(&text);
    }

    #[test]
    fn every_accepted_sensor_model_writes_only_finite_values(
        effect in prop::sample::select(dem_sensor::effects::NAMES.to_vec()),
        a in -20.0f64..20.0,
        b in -20.0f64..20.0,
        c in -1.0f64..2.0,
        seed in any::<u64>(),
        heights in proptest::collection::vec(-3.0f32..3.0, 100),
    ) {
        let params = match effect {
            "noise" => format!(r#"{{"sigma0":{a},"k":{b}}}"#),
            "dropout" | "row-dropout" | "hole-growth" | "drop-holes" => format!(r#"{{"p":{c}}}"#),
            "occlusion" => format!(r#"{{"h":{a},"x0":{b}}}"#),
            "fov" => format!(r#"{{"x_min":{a},"x_max":{b}}}"#),
            "smoothing" => format!(r#"{{"w":{c}}}"#),
            "bias" => format!(r#"{{"b":{a},"t":{b}}}"#),
            "quantization" => format!(r#"{{"q":{a}}}"#),
            "startup" => format!(r#"{{"x0":{a},"v":{b},"p":{c}}}"#),
            "patch-dropout" => format!(r#"{{"n":{a},"r":{b}}}"#),
            "edge-holes" | "rim-holes" | "pit-fill" => format!(r#"{{"g":{a},"p":{c}}}"#),
            "mixed-cells" => format!(r#"{{"up":{a},"down":{b}}}"#),
            "drop-blend" => format!(r#"{{"p":{c},"a":{}}}"#, b / 10.0),
            "riser-blend" => format!(r#"{{"foot":{},"top":{}}}"#, a / 10.0, b / 10.0),
            "floor-lift" => format!(r#"{{"x":{a},"p":{c},"a":{b}}}"#),
            "view-top" => format!(r#"{{"h":{a},"t":{b}}}"#),
            other => unreachable!("{other}"),
        };
        let json = format!(r#"{{"effects":[{{"effect":"{effect}","params":{params}}}]}}"#);
        if let Ok(m) = SensorModel::from_json(&json) {
            let mut d = empty_dem();
            for (i, h) in heights.iter().enumerate() {
                d.set_valid(i / 5, i % 5, *h);
            }
            m.apply_at(&mut d, seed, 7, Some(a.abs()));
            prop_assert!(d.iter().all(|v| v.is_finite()), "{json} wrote a non-finite value");
        }
    }
}
