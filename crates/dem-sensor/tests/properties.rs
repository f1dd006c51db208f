//! Property tests of the sensor model JSON: whatever the text, parsing
//! returns a model or an error, never panics; every model it accepts writes
//! only finite values. `make test` runs a fixed budget of cases
//! (PROPTEST_CASES, default 256 a property); `make fuzz` runs many more.

use dem_core::format::{empty_dem, DemCells};
use dem_sensor::memory::Pose;
use dem_sensor::{Moment, SensorModel};
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
            "tilt" => format!(r#"{{"pitch":{},"roll":{},"x0":{a},"range":{}}}"#, c / 4.0, b / 40.0, 2.0 * c),
            "shake" => format!(r#"{{"sigma":{},"edge":{b}}}"#, c / 4.0),
            "step-jitter" => format!(r#"{{"sigma":{},"edge":{b}}}"#, c / 4.0),
            "lag" => format!(r#"{{"s":{},"spread":{c}}}"#, a / 40.0),
            "drift" => format!(r#"{{"rate":{c},"zrate":{b},"x0":{a}}}"#),
            "map-memory" => format!(r#"{{"tau":{c},"keep":{}}}"#, b / 2.0),
            other => unreachable!("{other}"),
        };
        let json = format!(r#"{{"effects":[{{"effect":"{effect}","params":{params}}}]}}"#);
        if let Ok(m) = SensorModel::from_json(&json) {
            let mut d = empty_dem();
            for (i, h) in heights.iter().enumerate() {
                d.set_valid(i / 5, i % 5, *h);
            }
            m.apply_at(&mut d, seed, 7, Moment { run: None, time: a.abs(), pose: None });
            prop_assert!(d.iter().all(|v| v.is_finite()), "{json} wrote a non-finite value");
        }
    }
}

/// One effect at parameters anywhere in its physical box (the limits of
/// its spec, which every accepted model stays in): each parameter at a
/// (odd ones b) of the way from its low to its high limit, from the high
/// end when `s` < 0; a point its own rule refuses (fov's x_min at or past
/// x_max) moves the second parameter to its high limit, which every own
/// rule accepts.
fn extreme(effect: &str, a: f64, b: f64, s: f64) -> String {
    let spec = dem_sensor::effects::spec_named(effect).expect("a vocabulary name");
    let at = |k: usize, t: f64| {
        let l = spec.params[k].limit;
        let t = if s < 0.0 { 1.0 - t } else { t };
        l.lo + t * (l.hi - l.lo)
    };
    let mut values: Vec<f64> = (0..spec.params.len()).map(|k| at(k, if k % 2 == 0 { a } else { b })).collect();
    let accepted = |v: &[f64]| dem_sensor::Effect::from_values(effect, v).is_some_and(|e| e.check().is_ok());
    if !accepted(&values) && values.len() > 1 {
        values[1] = spec.params[1].limit.hi;
    }
    let e = dem_sensor::Effect::from_values(effect, &values).expect("as many values as parameters");
    serde_json::to_string(&e).expect("an effect serialises")
}

proptest! {
    #![proptest_config(config())]

    /// Stacks of up to 64 effects anywhere in their physical boxes, on heights up to
    /// 1e30 m either way, write only finite values, frame after frame of a run.
    #[test]
    fn every_accepted_stack_writes_only_finite_values(
        picks in proptest::collection::vec((prop::sample::select(dem_sensor::effects::NAMES.to_vec()), 0.0f64..=1.0, 0.0f64..=1.0, any::<bool>()), 1..=64),
        scale in prop::sample::select(vec![1.0f32, 1e10, 1e30]),
        heights in proptest::collection::vec(-3.0f32..3.0, 100),
        seed in any::<u64>(),
    ) {
        // A map's memory is a model's last effect: the first one picked goes there.
        let memory = picks.iter().find(|p| p.0 == "map-memory");
        let mut effects: Vec<String> =
            picks.iter().filter(|p| p.0 != "map-memory").map(|(e, a, b, s)| extreme(e, *a, *b, if *s { 1.0 } else { -1.0 })).collect();
        effects.extend(memory.map(|(e, a, b, s)| extreme(e, *a, *b, if *s { 1.0 } else { -1.0 })));
        let json = format!(r#"{{"effects":[{}]}}"#, effects.join(","));
        let m = SensorModel::from_json(&json).map_err(|e| TestCaseError::fail(format!("{json}: {e}")))?;
        let mut d = empty_dem();
        for (i, h) in heights.iter().enumerate() {
            d.set_valid(i / 5, i % 5, *h * scale);
        }
        // Three frames of one run, the robot moving and turning between them.
        let at = |k: f64| Moment { run: Some(4), time: 1.5 + 0.1 * k, pose: Some(Pose { x: 0.07 * k, y: 0.01 * k, yaw: 0.1 * k, travelled: f64::NAN }) };
        let mut run = [d; 3];
        m.apply_all_at(&mut run, seed, 3, Some(&[at(0.0), at(1.0), at(2.0)]));
        prop_assert!(run.iter().flatten().all(|v| v.is_finite()), "{json} on heights x {scale} wrote a non-finite value");
    }
}

#[test]
fn a_model_of_more_than_64_effects_is_refused() {
    let one = r#"{"effect":"dropout","params":{"p":0.1}}"#;
    let json = format!(r#"{{"effects":[{}]}}"#, vec![one; 65].join(","));
    let e = SensorModel::from_json(&json).unwrap_err();
    assert!(e.contains("65 effects: a sensor model has at most 64"), "{e}");
    assert!(SensorModel::from_json(&format!(r#"{{"effects":[{}]}}"#, vec![one; 64].join(","))).is_ok());
}
