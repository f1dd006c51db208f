//! Evidence in words and numbers for a named effect: what in the data
//! points at it, before (model) against real, and what the fit achieved
//! (each effect's sentence is in its dem-sensor module).

use dem_core::distribution::Stats;
use dem_sensor::Effect;

/// One sentence of evidence for `effect`, from the statistics of the model
/// before it was added, after, and of real ([`Effect::evidence`]).
pub fn evidence(effect: &Effect, before: &Stats, after: &Stats, real: &Stats, gap_before: f64, gap_after: f64) -> String {
    let _ = after;
    effect.evidence(before, real, gap_before, gap_after)
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::distribution::stats;
    use dem_core::format::{empty_dem, DemCells, COLS, GRID_ROWS};
    use dem_sensor::effects::{Bias, Drift, Lag, RiserBlend, Shake, StepJitter, Tilt};

    /// Every effect of the vocabulary has its evidence, paired and
    /// unpaired: a sentence that names the fitted effect and ends with what
    /// it removed.
    #[test]
    fn every_effect_has_evidence() {
        let mut stairs = empty_dem();
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                stairs.set_valid(r, c, -0.07 + 0.15 * (r / 3) as f32);
            }
        }
        let sim = vec![stairs; 20];
        for paired in [Some(sim.as_slice()), None] {
            let s = stats(&sim, paired);
            for spec in dem_sensor::effects::SPECS {
                let values: Vec<f64> = spec.params.iter().map(|p| p.fit.at(0.5)).collect();
                let e = Effect::from_values(spec.name, &values).unwrap();
                let sentence = evidence(&e, &s, &s, &s, 2.0, 1.0);
                let fitted =
                    sentence.contains(&format!("the fitted {e} ")) && sentence.ends_with("removes 50.0% of the gap (2.000 -> 1.000)");
                assert!(fitted, "{}: {sentence}", spec.name);
                assert!(sentence.len() > 80, "{}: {sentence}", spec.name);
            }
        }
    }

    /// Paired, `riser-blend`'s sentence gives the step-side shares: every
    /// foot cell of a riser moved 3 cm up in real, none in the model; and
    /// with nothing moved in real it says the effect is not a clear one.
    #[test]
    fn riser_blend_evidence_reads_the_step_sides() {
        let mut sim = empty_dem();
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                sim.set_valid(r, c, if r >= 10 { 0.1 } else { -0.07 });
            }
        }
        let mut real = sim;
        (0..COLS).for_each(|c| real.set_valid(9, c, -0.04));
        let (sims, reals) = (vec![sim; 10], vec![real; 10]);
        let (model, measured) = (stats(&sims, Some(&sims)), stats(&reals, Some(&sims)));
        let e = Effect::RiserBlend(RiserBlend { foot: 0.3, top: 0.0 });
        let s = evidence(&e, &model, &model, &measured, 2.0, 1.0);
        assert!(
            s.contains("at the foot real 100.0% vs model 0.0%") && s.contains("read part of the way across the step: the foot up"),
            "{s}"
        );
        let s = evidence(&e, &model, &model, &model, 2.0, 1.0);
        assert!(s.contains("not a clear one"), "{s}");
    }

    /// Paired, each of tilt, shake, lag and drift hidden in "real" (the
    /// sim records through the effect) is read as itself from the per-row
    /// spreads and the step sides; with real equal to the model, it is
    /// not a clear one.
    #[test]
    fn pose_effects_are_read_from_the_spread_by_row_and_the_steps() {
        use dem_sensor::SensorModel;
        // Stairs going up: a 0.15 m riser every third row.
        let mut stairs = empty_dem();
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                stairs.set_valid(r, c, -0.07 + 0.15 * (r / 3) as f32);
            }
        }
        let mut flat = empty_dem();
        (0..GRID_ROWS * COLS).for_each(|i| flat.set_valid(i / COLS, i % COLS, -0.07));
        let cases = [
            (Effect::Tilt(Tilt { pitch: 0.02, roll: 0.0, x0: 0.45, range: 0.0 }), flat, "farther ahead of x0"),
            (Effect::Shake(Shake { sigma: 0.01, edge: 0.0 }), flat, "rocks about its centre"),
            (Effect::Lag(Lag { s: 0.08, spread: 0.5 }), stairs, "steps read 8.0 cm ahead"),
            (Effect::StepJitter(StepJitter { sigma: 0.04, edge: 0.0 }), stairs, "both toward and away"),
            (Effect::Drift(Drift { rate: 0.05, zrate: 0.02, x0: 0.45 }), flat, "grows going back from x0"),
        ];
        for (e, terrain, says) in cases {
            let sim = vec![terrain; 400];
            let mut real = sim.clone();
            SensorModel::new(vec![e]).apply_all(&mut real, 5, 0);
            let (model, measured) = (stats(&sim, Some(&sim)), stats(&real, Some(&sim)));
            let s = evidence(&e, &model, &model, &measured, 2.0, 1.0);
            assert!(s.contains(says), "{e}: {s}");
            let s = evidence(&e, &model, &model, &model, 2.0, 1.0);
            assert!(s.contains("not a clear one"), "{e}: {s}");
        }
        // Unpaired, on flat ground: tilted records leave fewer level
        // neighbours; drift's rows behind x0 step against each other.
        let sim = vec![flat; 400];
        for (e, says) in [
            (Effect::Tilt(Tilt { pitch: 0.02, roll: 0.02, x0: 0.45, range: 1.0 }), "level ground reads tilted"),
            (Effect::Shake(Shake { sigma: 0.02, edge: 0.0 }), "level ground reads tilted"),
            (Effect::Drift(Drift { rate: 0.05, zrate: 0.1, x0: 0.45 }), "rows behind x0 step against each other"),
        ] {
            let mut real = sim.clone();
            SensorModel::new(vec![e]).apply_all(&mut real, 5, 0);
            let (model, measured) = (stats(&sim, None), stats(&real, None));
            let s = evidence(&e, &model, &model, &measured, 2.0, 1.0);
            assert!(s.contains(says), "{e}: {s}");
            assert!(evidence(&e, &model, &model, &model, 2.0, 1.0).contains("not a clear one"), "{e}");
        }
    }

    /// Unpaired, `bias`'s sentence says an offset when real is higher (or
    /// lower) behind and ahead alike, and points at the terrain mix when
    /// real is higher on one side and lower on the other.
    #[test]
    fn bias_evidence_tells_an_offset_from_other_terrain() {
        let set = |behind: f32, ahead: f32| {
            let mut d = empty_dem();
            for r in 0..GRID_ROWS {
                for c in 0..COLS {
                    d.set_valid(r, c, if r < 10 { behind } else { ahead });
                }
            }
            stats(&vec![d; 10], None)
        };
        let model = set(0.0, 0.0);
        let e = Effect::Bias(Bias { b: 0.02, t: 0.0 });
        let s = evidence(&e, &model, &model, &set(0.02, 0.02), 2.0, 1.0);
        assert!(s.contains("an offset and a tilt") && !s.contains("terrain"), "{s}");
        let s = evidence(&e, &model, &model, &set(-0.02, 0.09), 2.0, 1.0);
        assert!(s.contains("more like two sets of different terrain") && s.contains("both label files"), "{s}");
    }
}
