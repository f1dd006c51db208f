//! Every effect of the vocabulary has every part, and the parts agree: a
//! spec in the vocabulary's order, parameters that round-trip through
//! [`Effect::from_values`], [`Effect::params`] and JSON, a fit box inside
//! its limits whose corners pass the effect's check, draws the effect
//! reads, a row in docs/dem-sensor.md's table of effects, and the emulator
//! stages it models as that page's table of stages says. dem-gap's tests
//! check the evidence sentence.

use dem_core::format::{empty_dem, Dem, DemCells, COLS, GRID_ROWS};
use dem_sensor::effects::{modelling, spec_named, EffectSpec, EMULATOR_STAGES, NAMES, SPECS};
use dem_sensor::{Effect, SensorModel};

/// The effect of `spec` at `u` (0 to 1) of its fit box in each parameter.
fn at(spec: &EffectSpec, u: f64) -> Effect {
    let values: Vec<f64> = spec.params.iter().map(|p| p.fit.at(u)).collect();
    Effect::from_values(spec.name, &values).unwrap_or_else(|| panic!("{}: no effect from {} values", spec.name, values.len()))
}

/// The effect of `spec` at the middle of its fit box.
fn middle(spec: &EffectSpec) -> Effect {
    at(spec, 0.5)
}

#[test]
fn names_are_the_specs_names_in_order_and_unique() {
    assert_eq!(NAMES.len(), SPECS.len());
    for (i, (name, spec)) in NAMES.iter().zip(SPECS).enumerate() {
        assert_eq!(*name, spec.name);
        assert!(!NAMES[..i].contains(name), "{name} twice");
        assert_eq!(spec_named(name), Some(spec), "{name}");
    }
    assert!(spec_named("blur").is_none());
}

#[test]
fn every_spec_is_its_variants_and_documented() {
    for spec in SPECS {
        let e = middle(spec);
        assert_eq!(e.name(), spec.name);
        assert_eq!(e.spec(), spec, "{}: the variant points at another spec", spec.name);
        assert_eq!((e.stage(), e.draws()), (spec.stage, spec.draws), "{}", spec.name);
        assert!(!spec.formula.is_empty() && !spec.params.is_empty(), "{}", spec.name);
        for p in spec.params {
            assert!(p.doc.ends_with('.') && p.doc.len() > 5, "{}.{}: a doc line", spec.name, p.name);
        }
    }
}

#[test]
fn parameters_round_trip_through_values_params_and_json() {
    for spec in SPECS {
        let e = middle(spec);
        let names: Vec<&str> = spec.params.iter().map(|p| p.name).collect();
        let params = e.params();
        assert_eq!(params.iter().map(|p| p.0).collect::<Vec<_>>(), names, "{}: params() against the spec", spec.name);
        let values: Vec<f64> = params.iter().map(|p| p.1).collect();
        assert_eq!(Effect::from_values(spec.name, &values), Some(e), "{}", spec.name);
        assert_eq!(Effect::from_values(spec.name, &values[..values.len() - 1]), None, "{}: one value short", spec.name);
        let model = SensorModel::new(vec![e]);
        let json = model.to_json();
        assert_eq!(SensorModel::from_json(&json), Ok(model), "{}", spec.name);
        let parsed: serde_json::Value = serde_json::from_str(&json).unwrap();
        let keys: Vec<&str> = parsed["effects"][0]["params"].as_object().unwrap().keys().map(String::as_str).collect();
        let mut sorted = names.clone();
        sorted.sort_unstable();
        assert_eq!(keys, sorted, "{}: JSON keys against the spec", spec.name);
        assert_eq!(parsed["effects"][0]["effect"], spec.name);
    }
}

#[test]
fn every_fit_box_lies_inside_its_limits_and_passes_the_check() {
    for spec in SPECS {
        for p in spec.params {
            let (b, l) = (p.fit, p.limit);
            assert!(l.lo <= b.lo && b.lo < b.hi && b.hi <= l.hi, "{}.{}: box {b:?} outside its limits {l:?}", spec.name, p.name);
            assert!(!b.log || b.lo > 0.0, "{}.{}: a log box starts above 0", spec.name, p.name);
        }
        assert_eq!(middle(spec).check(), Ok(()), "{}", spec.name);
        for corner in [0.0, 1.0] {
            let v: Vec<f64> = spec.params.iter().map(|p| p.fit.at(corner)).collect();
            let e = Effect::from_values(spec.name, &v).unwrap();
            // fov's corners may cross (x_min >= x_max); dem-gap's fit scores such a point infinite.
            assert!(e.check().is_ok() || spec.name == "fov", "{} at {v:?}: {:?}", spec.name, e.check());
        }
    }
}

/// Terrain where every effect acts: a 0.2 m drop under the tracks (rows
/// 5/6), a 0.1 m drop (12/13) and a 0.3 m riser (16/17) ahead, a 0.2 m pit
/// and a missing cell.
fn terrain() -> Dem {
    let mut d = empty_dem();
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let h = match r {
                0..=5 | 17.. => 0.13,
                6..=12 => -0.07,
                _ => -0.17,
            };
            d.set_valid(r, c, h as f32);
        }
    }
    d.set_valid(15, 2, -0.37);
    d.set_missing(9, 3);
    d
}

/// A random effect reads its draws: two sets of uniforms give two DEMs.
/// A deterministic one reads none. (Not at the middle of the boxes, where
/// `bias` is the identity.)
#[test]
fn every_effect_reads_its_draws() {
    for spec in SPECS {
        let e = at(spec, 0.3);
        if let Effect::MapMemory(m) = e {
            memory_reads_its_draws(m);
            continue;
        }
        // Uniforms spread over [0, 1), from `start` on.
        let out = |start: f32| {
            let u: Vec<f32> = (0..spec.draws).map(|i| (start + 0.618 * i as f32).fract()).collect();
            let mut d = terrain();
            e.apply_drawn(&mut d, &u, None);
            d
        };
        if spec.draws == 0 {
            assert_ne!(out(0.0), terrain(), "{}: a deterministic effect that does nothing here", spec.name);
        } else {
            assert_ne!(out(0.0), out(0.5), "{}: {} uniforms that change nothing", spec.name, spec.draws);
        }
    }
}

/// A map's memory reads its draws on a run's later frame: where the frame
/// misses cells the map holds, whether each keeps the map's estimate.
fn memory_reads_its_draws(m: dem_sensor::effects::MapMemory) {
    use dem_sensor::fusion::{state_of, step, Motion};
    let prev = state_of(&terrain(), &terrain());
    let out = |start: f32| {
        let u: Vec<f32> = (0..100).map(|i| (start + 0.618 * i as f32).fract()).collect();
        let mut d = terrain();
        (0..20).for_each(|r| d.set_missing(r, r % 5));
        step(m, &prev, Motion { dx: 0.03, dy: 0.0, dyaw: 0.0, dt: 0.1 }, &terrain(), &mut d, &u);
        d
    };
    assert_ne!(out(0.0), out(0.5), "map-memory: 100 uniforms that change nothing");
}

/// docs/dem-sensor.md's table of effects lists exactly the vocabulary,
/// each with its parameters in order.
#[test]
fn the_docs_table_lists_every_effect_with_its_parameters() {
    let doc = std::fs::read_to_string(dem_testkit::workspace_root().join("docs/dem-sensor.md")).unwrap();
    let table = doc.split("| effect | parameters | what it does |").nth(1).expect("the effects table");
    let mut rows: Vec<(String, Vec<String>)> = Vec::new();
    for line in table.lines().skip(2).take_while(|l| l.starts_with('|')) {
        let cells: Vec<&str> = line.split(" | ").collect();
        let name = cells[0].trim_start_matches("| ").trim_matches('`').to_string();
        rows.push((name, cells[1].split(", ").map(|p| p.trim_matches('`').to_string()).collect()));
    }
    let mut listed: Vec<&str> = rows.iter().map(|r| r.0.as_str()).collect();
    listed.sort_unstable();
    let mut names = NAMES.to_vec();
    names.sort_unstable();
    assert_eq!(listed, names, "docs/dem-sensor.md's effects against the vocabulary");
    for (name, params) in &rows {
        let spec = spec_named(name).unwrap();
        assert_eq!(params, &spec.params.iter().map(|p| p.name).collect::<Vec<_>>(), "{name}'s parameters in the docs");
    }
}

/// The items of a table cell separated by commas outside parentheses.
fn items(cell: &str) -> Vec<&str> {
    let (mut out, mut depth, mut start) = (Vec::new(), 0, 0);
    for (i, ch) in cell.char_indices() {
        match ch {
            '(' => depth += 1,
            ')' => depth -= 1,
            ',' if depth == 0 => {
                out.push(cell[start..i].trim());
                start = i + 1;
            }
            _ => {}
        }
    }
    out.push(cell[start..].trim());
    out
}

/// docs/dem-sensor.md's table of emulator stages names, first in each
/// item of its last column, exactly the effects whose spec lists the
/// stage; every stage is modelled, and `dem-sensor effects` prints them.
#[test]
fn the_emulator_stages_are_the_specs_and_the_docs_table() {
    let doc = std::fs::read_to_string(dem_testkit::workspace_root().join("docs/dem-sensor.md")).unwrap();
    let table =
        doc.split("| emulator stage (`--no-<stage>`) | what it does to the DEMs | effects that model it |").nth(1).expect("the table");
    let mut stages = Vec::new();
    for line in table.lines().skip(2).take_while(|l| l.starts_with("| `")) {
        let stage = line[3..].split('`').next().unwrap();
        let cells: Vec<&str> = line.trim_end_matches(" |").split(" | ").collect();
        let mut listed: Vec<&str> = items(cells[2]).iter().map(|i| i.split('`').nth(1).unwrap_or(i)).collect();
        listed.sort_unstable();
        let mut registry = modelling(stage);
        registry.sort_unstable();
        assert_eq!(listed, registry, "--no-{stage}: the docs against the specs");
        stages.push(stage);
    }
    assert_eq!(stages, EMULATOR_STAGES, "the docs' stages");
    for spec in SPECS {
        assert!(spec.emulator.iter().all(|s| EMULATOR_STAGES.contains(s)), "{}: {:?}", spec.name, spec.emulator);
    }
    let csv = dem_sensor::effects::csv();
    assert_eq!(csv.lines().count(), SPECS.len() + 1);
    assert!(csv.contains("\nstep-jitter,steps,registration,100,0,sigma edge,vibration,sigma=0..0.1 edge=0..1\n"), "{csv}");
    assert!(
        csv.contains("\ntilt,heights,registration,2,2,pitch roll x0 range,extrinsic,pitch=0..0.2 roll=0..0.2 x0=-0.6..1.45 range=0..3\n"),
        "{csv}"
    );
}

/// `params` of the wrong type gets serde's wording for a struct variant,
/// naming the effect's own variant (the `expecting` of its `params!`).
#[test]
fn a_mistyped_params_names_the_effect_s_variant() {
    for spec in SPECS {
        let variant = format!("{:?}", middle(spec));
        let variant = &variant[..variant.find('(').unwrap()];
        let json = format!(r#"{{"effect": "{}", "params": 3}}"#, spec.name);
        let err = serde_json::from_str::<Effect>(&json).unwrap_err().to_string();
        assert!(err.contains(&format!("expected struct variant Effect::{variant} ")), "{}: {err}", spec.name);
    }
}

/// Every effect has its independent numpy formula in the test peer
/// (`tests/peers/hidden_effects.py`, whose `EFFECTS` table dem-sensor's and
/// dem-gap's tests run), and the peer has no effect the vocabulary lacks.
#[test]
fn every_effect_has_its_numpy_peer() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/peers/hidden_effects.py");
    let text = std::fs::read_to_string(path).unwrap();
    let table = text.split("\nEFFECTS = {").nth(1).and_then(|t| t.split('}').next()).expect("the peer's EFFECTS table");
    let mut peer: Vec<&str> = table.split(',').filter_map(|entry| entry.split('"').nth(1)).collect();
    peer.sort_unstable();
    let mut names = NAMES.to_vec();
    names.sort_unstable();
    assert_eq!(peer, names, "hidden_effects.py's EFFECTS against the vocabulary");
}
