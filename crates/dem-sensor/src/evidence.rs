//! Evidence in words and numbers for a named effect: what in the data
//! points at it, before (model) against real, and what the fit achieved.
//! Each effect's sentence is in its file ([`crate::effects::EffectKind::evidence`]);
//! the helpers here name no effect. dem-gap prints the sentences.

use dem_core::distribution::Stats;

/// Share of the gap `before` that `after` removes (0 when there was none).
pub fn share_removed(before: f64, after: f64) -> f64 {
    if before > 0.0 {
        1.0 - after / before
    } else {
        0.0
    }
}

/// `x` as a percentage with one decimal.
pub fn pct(x: f64) -> String {
    format!("{:.1}%", 100.0 * x)
}

/// `x` (m) in millimetres with one decimal.
pub fn mm(x: f64) -> String {
    format!("{:.1} mm", 1000.0 * x)
}

/// Sum of term `name` over components weighted by support (a total count
/// when the term is a rate).
pub fn total(s: &Stats, name: &str) -> f64 {
    s.term(name).map_or(0.0, |t| t.values.iter().zip(&t.support).map(|(v, n)| v * *n as f64).sum())
}

/// Share of steps between neighbouring rows of 0.02-0.1 m: part-way steps.
pub fn mid(s: &Stats) -> f64 {
    s.mean_over("edge-2cm", 0..19) - s.mean_over("edge-10cm", 0..19)
}

/// Mean over the step `sides` ([`STEP_SIDES`](dem_core::distribution::STEP_SIDES) names) of component `k` of
/// their residuals toward the other surface (2: the share moved more than
/// 2 cm toward it, 3: away from it).
pub fn side_share(s: &Stats, sides: &[&str], k: usize) -> f64 {
    sides.iter().map(|n| s.term(n).map_or(0.0, |t| t.values[k])).sum::<f64>() / sides.len() as f64
}

/// Unpaired evidence of cells read part of the way across steps: real has
/// more steps of 0.02-0.1 m than the model (`fitted` says why), else
/// `closest` is only the closest effect.
pub fn part_way_steps(real: &Stats, before: &Stats, fitted: String, closest: &str) -> String {
    let verdict = if mid(real) > mid(before) {
        fitted
    } else {
        format!("no more part-way steps in real: {closest} the closest effect, not a clear one")
    };
    format!("steps between neighbouring rows of 0.02-0.1 m: real {} vs model {}: {verdict}", pct(mid(real)), pct(mid(before)))
}

/// `body` and, paired, how together the cells beside a step move in real
/// against the model ([`Stats::step_coherence`]): what tells a pose error,
/// which moves a step's cells as one, from a misregistration per cell,
/// where the gap's terms cannot. `moves_together`: the effect moves a
/// step's cells as one (a pose effect) rather than each on its own.
pub fn with_step_coherence(body: String, real: &Stats, before: &Stats, moves_together: bool) -> String {
    let (Some(r), Some(b)) = (real.step_coherence, before.step_coherence) else { return body };
    let (how, agrees) = match r {
        r if r >= 0.6 => ("together", Some(moves_together)),
        r if r <= 0.2 => ("each on its own", Some(!moves_together)),
        _ => ("partly together", None),
    };
    let note = match agrees {
        Some(true) => "as this effect moves them",
        Some(false) => "unlike this effect: read its ties",
        None => "between a pose error (1) and a misregistration per cell (0)",
    };
    format!("{body}; across the robot, neighbouring cells beside a step move {how} (correlation of their residuals real {r:.2} vs model {b:.2}), {note}")
}

/// Share of neighbour pairs that differ by 0.1 to 10 mm.
pub fn small_steps(s: &Stats) -> f64 {
    s.term("steps").map_or(0.0, |t| t.values.iter().take(3).sum())
}

/// Evidence from missing cells that come together (blobs, grown holes): the
/// missing rate and the rate of across-robot neighbour pairs both missing;
/// `more` when real has more such pairs than the model, else `not_more`.
pub fn paired_misses(real: &Stats, before: &Stats, more: &str, not_more: &str) -> String {
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
pub fn tilted_unpaired(real: &Stats, before: &Stats, what: &str) -> String {
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
pub struct Context<'a> {
    /// The fitted effect, as a sentence names it.
    pub effect: &'a dyn std::fmt::Display,
    /// The statistics of the model before the effect was added.
    pub before: &'a Stats,
    /// The statistics of real.
    pub real: &'a Stats,
    /// The gap before the effect was added.
    pub gap_before: f64,
    /// The gap with the fitted effect.
    pub gap_after: f64,
}

impl Context<'_> {
    /// The share of the gap the effect removed.
    pub fn removed(&self) -> f64 {
        share_removed(self.gap_before, self.gap_after)
    }

    /// What a height spread measures: paired, the residual; unpaired, the
    /// difference across the robot.
    pub fn spread(&self) -> &'static str {
        if self.real.paired {
            "residual (real - sim) sd"
        } else {
            "across-robot height difference sd / sqrt 2"
        }
    }

    /// `body` and what the fit removed: the whole sentence.
    pub fn fitted(&self, body: String) -> String {
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
pub fn per_rec(s: &Stats, name: &str) -> f64 {
    total(s, name) / s.records.max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn coherence(paired: bool, value: f64) -> Stats {
        Stats { records: 100, paired, terms: vec![], step_coherence: paired.then_some(value) }
    }

    /// Paired, the sentence says how together real's step cells move
    /// against the model's; unpaired (no residuals) it is left alone.
    #[test]
    fn the_step_coherence_is_said_where_it_is_measured() {
        let with = |r, b, together| with_step_coherence("body".into(), &coherence(true, r), &coherence(true, b), together);
        assert_eq!(
            with(0.83, 0.0, true),
            "body; across the robot, neighbouring cells beside a step move together (correlation of their residuals real 0.83 vs model 0.00), as this effect moves them"
        );
        assert!(with(0.83, 0.0, false)
            .ends_with("move together (correlation of their residuals real 0.83 vs model 0.00), unlike this effect: read its ties"));
        assert!(with(0.33, 0.01, false).contains("move partly together (correlation of their residuals real 0.33 vs model 0.01), between"));
        assert!(with(0.05, 0.9, false)
            .contains("move each on its own (correlation of their residuals real 0.05 vs model 0.90), as this effect"));
        assert_eq!(with_step_coherence("body".into(), &coherence(false, 0.0), &coherence(false, 0.0), true), "body");
    }
}
