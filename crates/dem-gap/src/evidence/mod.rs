//! Evidence in words and numbers for a named effect: what in the data
//! points at it, before (model) against real, and what the fit achieved.

use dem_core::format::{row_center_x, GRID_ROWS};
use dem_sensor::Effect;

use dem_core::distribution::{Stats, STEP_SIDES};

mod heights;
mod holes;
mod steps;
mod view;

fn pct(x: f64) -> String {
    format!("{:.1}%", 100.0 * x)
}

fn mm(x: f64) -> String {
    format!("{:.1} mm", 1000.0 * x)
}

/// Sum of term `name` over components weighted by support (a total count
/// when the term is a rate).
fn total(s: &Stats, name: &str) -> f64 {
    s.term(name).map_or(0.0, |t| t.values.iter().zip(&t.support).map(|(v, n)| v * *n as f64).sum())
}

/// Share of steps between neighbouring rows of 0.02-0.1 m: part-way steps.
fn mid(s: &Stats) -> f64 {
    s.mean_over("edge-2cm", 0..19) - s.mean_over("edge-10cm", 0..19)
}

/// Mean over the step `sides` ([`STEP_SIDES`] names) of component `k` of
/// their residuals toward the other surface (2: the share moved more than
/// 2 cm toward it, 3: away from it).
fn side_share(s: &Stats, sides: &[&str], k: usize) -> f64 {
    sides.iter().map(|n| s.term(n).map_or(0.0, |t| t.values[k])).sum::<f64>() / sides.len() as f64
}

/// Unpaired evidence of cells read part of the way across steps: real has
/// more steps of 0.02-0.1 m than the model (`fitted` says why), else
/// `closest` is only the closest effect.
fn part_way_steps(real: &Stats, before: &Stats, fitted: String, closest: &str) -> String {
    let verdict = if mid(real) > mid(before) {
        fitted
    } else {
        format!("no more part-way steps in real: {closest} the closest effect, not a clear one")
    };
    format!("steps between neighbouring rows of 0.02-0.1 m: real {} vs model {}: {verdict}", pct(mid(real)), pct(mid(before)))
}

/// Share of neighbour pairs that differ by 0.1 to 10 mm.
fn small_steps(s: &Stats) -> f64 {
    s.term("steps").map_or(0.0, |t| t.values.iter().take(3).sum())
}

/// Evidence from missing cells that come together (blobs, grown holes): the
/// missing rate and the rate of across-robot neighbour pairs both missing;
/// `more` when real has more such pairs than the model, else `not_more`.
fn paired_misses(real: &Stats, before: &Stats, more: &str, not_more: &str) -> String {
    let (r, b) = (real.mean_over("missing-pair", 0..20), before.mean_over("missing-pair", 0..20));
    format!(
        "missing cells real {} vs model {}; both cells of an across-robot neighbour pair missing (in rows not wholly missing): real {} vs model {}: {}",
        pct(real.mean_over("missing", 0..20)),
        pct(before.mean_over("missing", 0..20)),
        pct(r),
        pct(b),
        if r > b { more } else { not_more }
    )
}

/// Unpaired evidence of a per-record tilt (`tilt`, `shake`): tilted heights
/// leave fewer level neighbours and more small steps than sim's flat cells.
fn tilted_unpaired(real: &Stats, before: &Stats, what: &str) -> String {
    let (rl, bl) = (real.mean_over("level-pairs", 0..20), before.mean_over("level-pairs", 0..20));
    let verdict = if rl < bl && small_steps(real) > small_steps(before) {
        format!("level ground reads tilted in real: {what}")
    } else {
        "real has as many level neighbours and small steps: a tilt is the closest effect, not a clear one".to_string()
    };
    format!(
        "neighbouring cells across the robot of equal height real {} vs model {}; neighbour differences of 0.1-10 mm real {} vs model {}: {verdict}",
        pct(rl),
        pct(bl),
        pct(small_steps(real)),
        pct(small_steps(before)),
    )
}

/// What every sentence is made from: the effect, the statistics of the
/// model before it was added and of real, and the gap before and after.
struct Context<'a> {
    effect: &'a Effect,
    before: &'a Stats,
    real: &'a Stats,
    gap_before: f64,
    gap_after: f64,
}

impl Context<'_> {
    /// The share of the gap the effect removed.
    fn removed(&self) -> f64 {
        crate::share_removed(self.gap_before, self.gap_after)
    }

    /// What a height spread measures: paired, the residual; unpaired, the
    /// difference across the robot.
    fn spread(&self) -> &'static str {
        if self.real.paired {
            "residual (real - sim) sd"
        } else {
            "across-robot height difference sd / sqrt 2"
        }
    }

    /// `body` and what the fit removed: the whole sentence.
    fn fitted(&self, body: String) -> String {
        format!(
            "{body}; the fitted {} removes {} of the gap ({:.3} -> {:.3})",
            self.effect,
            pct(self.removed()),
            self.gap_before,
            self.gap_after
        )
    }
}

/// Total of term `name` per record.
fn per_rec(s: &Stats, name: &str) -> f64 {
    total(s, name) / s.records.max(1) as f64
}

/// One sentence of evidence for `effect`, from the statistics of the model
/// before it was added, after, and of real; one function per effect, in
/// the module of its family.
pub fn evidence(effect: &Effect, before: &Stats, after: &Stats, real: &Stats, gap_before: f64, gap_after: f64) -> String {
    let _ = after;
    let c = Context { effect, before, real, gap_before, gap_after };
    match *effect {
        Effect::Noise { .. } => heights::noise(&c),
        Effect::Dropout { .. } => holes::dropout(&c),
        Effect::RowDropout { .. } => holes::row_dropout(&c),
        Effect::Occlusion { .. } => view::occlusion(&c),
        Effect::Fov { x_min, x_max } => view::fov(&c, x_min, x_max),
        Effect::Startup { x0, v, p } => view::startup(&c, x0, v, p),
        Effect::PatchDropout { .. } => holes::patch_dropout(&c),
        Effect::EdgeHoles { .. } => holes::edge_holes(&c),
        Effect::DropHoles { .. } => holes::drop_holes(&c),
        Effect::HoleGrowth { .. } => holes::hole_growth(&c),
        Effect::ViewTop { h, t } => view::view_top(&c, h, t),
        Effect::RimHoles { .. } => holes::rim_holes(&c),
        Effect::PitFill { .. } => holes::pit_fill(&c),
        Effect::MixedCells { .. } => steps::mixed_cells(&c),
        Effect::DropBlend { .. } => steps::drop_blend(&c),
        Effect::FloorLift { x, .. } => steps::floor_lift(&c, x),
        Effect::RiserBlend { foot, top } => steps::riser_blend(&c, foot, top),
        Effect::Tilt { pitch, roll, x0, range } => heights::tilt(&c, pitch, roll, x0, range),
        Effect::Shake { sigma, edge } => heights::shake(&c, sigma, edge),
        Effect::Drift { rate, zrate, x0 } => heights::drift(&c, rate, zrate, x0),
        Effect::Lag { s, .. } => heights::lag(&c, s),
        Effect::StepJitter { sigma, edge } => steps::step_jitter(&c, sigma, edge),
        Effect::Smoothing { .. } => steps::smoothing(&c),
        Effect::Bias { .. } => heights::bias(&c),
        Effect::Quantization { q } => heights::quantization(&c, q),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::distribution::stats;
    use dem_core::format::{empty_dem, DemCells, COLS, GRID_ROWS};

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
        let e = Effect::RiserBlend { foot: 0.3, top: 0.0 };
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
            (Effect::Tilt { pitch: 0.02, roll: 0.0, x0: 0.45, range: 0.0 }, flat, "farther ahead of x0"),
            (Effect::Shake { sigma: 0.01, edge: 0.0 }, flat, "rocks about its centre"),
            (Effect::Lag { s: 0.08, spread: 0.5 }, stairs, "steps read 8.0 cm ahead"),
            (Effect::StepJitter { sigma: 0.04, edge: 0.0 }, stairs, "both toward and away"),
            (Effect::Drift { rate: 0.05, zrate: 0.02, x0: 0.45 }, flat, "grows going back from x0"),
        ];
        for (e, terrain, says) in cases {
            let sim = vec![terrain; 400];
            let mut real = sim.clone();
            SensorModel { effects: vec![e] }.apply_all(&mut real, 5, 0);
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
            (Effect::Tilt { pitch: 0.02, roll: 0.02, x0: 0.45, range: 1.0 }, "level ground reads tilted"),
            (Effect::Shake { sigma: 0.02, edge: 0.0 }, "level ground reads tilted"),
            (Effect::Drift { rate: 0.05, zrate: 0.1, x0: 0.45 }, "rows behind x0 step against each other"),
        ] {
            let mut real = sim.clone();
            SensorModel { effects: vec![e] }.apply_all(&mut real, 5, 0);
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
        let e = Effect::Bias { b: 0.02, t: 0.0 };
        let s = evidence(&e, &model, &model, &set(0.02, 0.02), 2.0, 1.0);
        assert!(s.contains("an offset and a tilt") && !s.contains("terrain"), "{s}");
        let s = evidence(&e, &model, &model, &set(-0.02, 0.09), 2.0, 1.0);
        assert!(s.contains("more like two sets of different terrain") && s.contains("--match-terrain-mix"), "{s}");
    }
}
