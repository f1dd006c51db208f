//! Evidence for the effects of dem-sensor's `holes` family: cells lost or filled where the map is thin.

use super::*;

/// The evidence for `dropout`.
pub(crate) fn dropout(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let removed = c.removed();
    let effect = c.effect;
    let (gap_before, gap_after) = (c.gap_before, c.gap_after);
    let body = {
        let extra = per_rec(real, "missing") - per_rec(before, "missing");
        let rows = 5.0 * (per_rec(real, "row-missing") - per_rec(before, "row-missing"));
        let shadow = per_rec(real, "shadow") - per_rec(before, "shadow");
        if extra <= 0.0 {
            return format!(
                "missing cells real {} vs model {}: no extra missing cells, the fitted {effect} trades where cells are missing; it removes {} of the gap ({gap_before:.3} -> {gap_after:.3})",
                pct(real.mean_over("missing", 0..20)),
                pct(before.mean_over("missing", 0..20)),
                pct(removed)
            );
        }
        format!(
            "missing cells real {} vs model {}; of the {:.1} extra missing cells per record only {} are whole rows and {} lie in shadows: scattered single cells",
            pct(real.mean_over("missing", 0..20)),
            pct(before.mean_over("missing", 0..20)),
            extra,
            pct((rows / extra.max(1e-9)).clamp(0.0, 1.0)),
            pct((shadow / extra.max(1e-9)).clamp(0.0, 1.0)),
        )
    };
    c.fitted(body)
}

/// The evidence for `row-dropout`.
pub(crate) fn row_dropout(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let extra = per_rec(real, "missing") - per_rec(before, "missing");
        let rows = 5.0 * (per_rec(real, "row-missing") - per_rec(before, "row-missing"));
        format!(
            "whole rows missing: real {} of rows vs model {}; {} of the extra missing cells come as whole rows, spread over all ranges",
            pct(real.mean_over("row-missing", 0..20)),
            pct(before.mean_over("row-missing", 0..20)),
            pct((rows / extra.max(1e-9)).clamp(0.0, 1.0)),
        )
    };
    c.fitted(body)
}

/// The evidence for `patch-dropout`.
pub(crate) fn patch_dropout(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = paired_misses(
        real,
        before,
        "missing cells come in blobs",
        "no more blobs in real than in the model: blobs are the closest effect, not a clear one",
    );
    c.fitted(body)
}

/// The evidence for `edge-holes`.
pub(crate) fn edge_holes(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let (r, b) = (real.mean_over("jump-missing", 0..20), before.mean_over("jump-missing", 0..20));
        format!(
            "missing cells between valid cells of their column that differ by 5 cm or more: real {} vs model {}: {}",
            pct(r),
            pct(b),
            if r > b { "holes at height jumps" } else { "no more of them in real: the holes are the closest effect, not a clear one" }
        )
    };
    c.fitted(body)
}

/// The evidence for `drop-holes`.
pub(crate) fn drop_holes(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let (rs, bs) = (real.mean_over("shadow", 0..20), before.mean_over("shadow", 0..20));
        let (rj, bj) = (real.mean_over("jump-missing", 0..20), before.mean_over("jump-missing", 0..20));
        format!(
            "missing cells behind cells at least 0.08 m taller: real {} vs model {}; between valid cells of their column that differ by 5 cm or more: real {} vs model {}: {}",
            pct(rs),
            pct(bs),
            pct(rj),
            pct(bj),
            if rs > bs && rj > bj {
                "holes where the terrain drops away, one cell at its edge"
            } else {
                "no more holes at drops in real: holes at drop edges are the closest effect, not a clear one"
            }
        )
    };
    c.fitted(body)
}

/// The evidence for `hole-growth`.
pub(crate) fn hole_growth(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = paired_misses(
        real,
        before,
        "holes are wider in real: cells at their edges are lost",
        "no more paired misses in real: grown holes are the closest effect, not a clear one",
    );
    c.fitted(body)
}

/// The evidence for `rim-holes`.
pub(crate) fn rim_holes(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let (r, b) = (real.mean_over("jump-missing", 0..20), before.mean_over("jump-missing", 0..20));
        format!(
            "missing cells between valid cells of their column that differ by 5 cm or more: real {} vs model {}; missing cells real {} vs model {}: {}",
            pct(r),
            pct(b),
            pct(real.mean_over("missing", 0..20)),
            pct(before.mean_over("missing", 0..20)),
            if r > b { "holes at height jumps, on their upper side too" } else { "no more holes at jumps in real: the rim holes are the closest effect, not a clear one" }
        )
    };
    c.fitted(body)
}

/// The evidence for `pit-fill`.
pub(crate) fn pit_fill(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let (r2, b2) = (real.mean_over("edge-2cm", 0..19), before.mean_over("edge-2cm", 0..19));
        format!(
            "steps between neighbouring rows above 0.02 m: real {} vs model {}: {}",
            pct(r2),
            pct(b2),
            if r2 < b2 {
                "narrow pits read as their rims"
            } else {
                "real has as many steps: the filled pits are the closest effect, not a clear one"
            }
        )
    };
    c.fitted(body)
}
