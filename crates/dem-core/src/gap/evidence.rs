//! Evidence in words and numbers for a named effect: what in the data
//! points at it, before (model) against real, and what the fit achieved.

use crate::sensor::Effect;

use super::stats::Stats;

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

/// Share of neighbour pairs that differ by 0.1 to 10 mm.
fn small_steps(s: &Stats) -> f64 {
    s.term("steps").map_or(0.0, |t| t.values.iter().take(3).sum())
}

/// One sentence of evidence for `effect`, from the statistics of the model
/// before it was added, after, and of real.
pub fn evidence(effect: &Effect, before: &Stats, after: &Stats, real: &Stats, gap_before: f64, gap_after: f64) -> String {
    let removed = if gap_before > 0.0 { 1.0 - gap_after / gap_before } else { 0.0 };
    let per_rec = |s: &Stats, name: &str| total(s, name) / s.records.max(1) as f64;
    let spread = if real.paired { "residual (real - sim) sd" } else { "across-robot height difference sd / sqrt 2" };
    let body = match *effect {
        Effect::Noise { .. } => format!(
            "neighbouring cells of equal height real {} vs model {}; height spread ({spread}) near (rows 6-9) real {} vs model {}, far (rows 15-19) real {} vs model {}",
            pct(real.mean_over("level-pairs", 0..20)),
            pct(before.mean_over("level-pairs", 0..20)),
            mm(real.mean_over("spread-sd", 6..10)),
            mm(before.mean_over("spread-sd", 6..10)),
            mm(real.mean_over("spread-sd", 15..20)),
            mm(before.mean_over("spread-sd", 15..20)),
        ),
        Effect::Dropout { .. } => {
            let extra = per_rec(real, "missing") - per_rec(before, "missing");
            let rows = 5.0 * (per_rec(real, "row-missing") - per_rec(before, "row-missing"));
            let shadow = per_rec(real, "shadow") - per_rec(before, "shadow");
            format!(
                "missing cells real {} vs model {}; of the {:.1} extra missing cells per record only {} are whole rows and {} lie in shadows: scattered single cells",
                pct(real.mean_over("missing", 0..20)),
                pct(before.mean_over("missing", 0..20)),
                extra,
                pct((rows / extra.max(1e-9)).clamp(0.0, 1.0)),
                pct((shadow / extra.max(1e-9)).clamp(0.0, 1.0)),
            )
        }
        Effect::RowDropout { .. } => {
            let extra = per_rec(real, "missing") - per_rec(before, "missing");
            let rows = 5.0 * (per_rec(real, "row-missing") - per_rec(before, "row-missing"));
            format!(
                "whole rows missing: real {} of rows vs model {}; {} of the extra missing cells come as whole rows, spread over all ranges",
                pct(real.mean_over("row-missing", 0..20)),
                pct(before.mean_over("row-missing", 0..20)),
                pct((rows / extra.max(1e-9)).clamp(0.0, 1.0)),
            )
        }
        Effect::Occlusion { .. } => {
            let extra = per_rec(real, "missing") - per_rec(before, "missing");
            let shadow = per_rec(real, "shadow") - per_rec(before, "shadow");
            format!(
                "{} of the extra missing cells lie behind cells at least 0.08 m taller, in the sensor's line of sight (shadowed cells real {} vs model {})",
                pct((shadow / extra.max(1e-9)).clamp(0.0, 1.0)),
                pct(real.mean_over("shadow", 0..20)),
                pct(before.mean_over("shadow", 0..20)),
            )
        }
        Effect::Fov { x_min, x_max } => {
            let outside: Vec<usize> =
                (0..20).filter(|&r| !(x_min..=x_max).contains(&crate::format::row_center_x(r))).collect();
            let m = |s: &Stats| {
                let t = s.term("missing").map(|t| t.values.clone()).unwrap_or_default();
                outside.iter().map(|&r| t.get(r).copied().unwrap_or(0.0)).sum::<f64>() / outside.len().max(1) as f64
            };
            format!(
                "rows outside x in [{x_min:.2}, {x_max:.2}] m ({} rows) are missing in {} of real cells vs {} of model cells: never in the field of view",
                outside.len(),
                pct(m(real)),
                pct(m(before)),
            )
        }
        Effect::Smoothing { .. } => format!(
            "steps between neighbouring rows above 0.1 m: real {} vs model {}; above 0.02 m: real {} vs model {}: sharp edges become ramps",
            pct(real.mean_over("edge-10cm", 0..19)),
            pct(before.mean_over("edge-10cm", 0..19)),
            pct(real.mean_over("edge-2cm", 0..19)),
            pct(before.mean_over("edge-2cm", 0..19)),
        ),
        Effect::Bias { .. } => format!(
            "mean {} behind (rows 0-5) real {} vs model {}, far ahead (rows 15-19) real {} vs model {}: an offset and a tilt",
            if real.paired { "residual" } else { "height" },
            mm(real.mean_over("height", 0..6)),
            mm(before.mean_over("height", 0..6)),
            mm(real.mean_over("height", 15..20)),
            mm(before.mean_over("height", 15..20)),
        ),
        Effect::Quantization { q } => format!(
            "neighbour differences of 0.1-10 mm: real {} vs model {}; equal neighbours real {} vs model {}: heights come in steps of {}",
            pct(small_steps(real)),
            pct(small_steps(before)),
            pct(real.mean_over("level-pairs", 0..20)),
            pct(before.mean_over("level-pairs", 0..20)),
            mm(q),
        ),
    };
    let _ = after;
    format!("{body}; the fitted {effect} removes {} of the gap ({gap_before:.3} -> {gap_after:.3})", pct(removed))
}
