//! Evidence for the effects of dem-sensor's `view` family: what the sensor can see.

use super::*;

/// The evidence for `occlusion`.
pub(crate) fn occlusion(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let removed = c.removed();
    let effect = c.effect;
    let (gap_before, gap_after) = (c.gap_before, c.gap_after);
    let body = {
        let extra = per_rec(real, "missing") - per_rec(before, "missing");
        let shadow = per_rec(real, "shadow") - per_rec(before, "shadow");
        if extra <= 0.0 || shadow <= 0.0 {
            return format!(
                "shadowed cells (missing behind cells at least 0.08 m taller) real {} vs model {}, missing cells real {} vs model {}: the fitted {effect} changes where cells are missing more than how many; it removes {} of the gap ({gap_before:.3} -> {gap_after:.3})",
                pct(real.mean_over("shadow", 0..20)),
                pct(before.mean_over("shadow", 0..20)),
                pct(real.mean_over("missing", 0..20)),
                pct(before.mean_over("missing", 0..20)),
                pct(removed)
            );
        }
        format!(
            "{} of the extra missing cells lie behind cells at least 0.08 m taller, in the sensor's line of sight (shadowed cells real {} vs model {})",
            pct((shadow / extra.max(1e-9)).clamp(0.0, 1.0)),
            pct(real.mean_over("shadow", 0..20)),
            pct(before.mean_over("shadow", 0..20)),
        )
    };
    c.fitted(body)
}

/// The evidence for `fov`.
pub(crate) fn fov(c: &Context, x_min: f64, x_max: f64) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let outside: Vec<usize> = (0..20).filter(|&r| !(x_min..=x_max).contains(&dem_core::format::row_center_x(r))).collect();
        let m = |s: &Stats| {
            let t = s.term("missing").map(|t| t.values.clone()).unwrap_or_default();
            outside.iter().map(|&r| t.get(r).copied().unwrap_or(0.0)).sum::<f64>() / outside.len().max(1) as f64
        };
        let (mr, mb) = (m(real), m(before));
        let verdict = if mr >= 0.9 {
            "never in the field of view"
        } else if mr > mb {
            "seen in some records, not in others: a field of view only in part (startup frames, map memory)"
        } else {
            "no more missing in real than in the model: the field of view does not explain them"
        };
        format!(
            "rows outside x in [{x_min:.2}, {x_max:.2}] m ({} rows) are missing in {} of real cells vs {} of model cells: {verdict}",
            outside.len(),
            pct(mr),
            pct(mb),
        )
    };
    c.fitted(body)
}

/// The evidence for `startup`.
pub(crate) fn startup(c: &Context, x0: f64, v: f64, p: f64) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let back = |s: &Stats| s.mean_over("missing", 0..6);
        let how = if v > 0.0 {
            format!(
                "a blind edge at x = {x0:.2} m at the start of a run that recedes at {v:.2} m/s ({} of records are startup frames)",
                pct(p)
            )
        } else {
            format!("{} of records are startup frames whose blind edge starts at x = {x0:.2} m", pct(p))
        };
        format!(
            "cells behind the robot (rows 0-5) missing: real {} vs model {}, whole rows in some records and none in others: {how}",
            pct(back(real)),
            pct(back(before)),
        )
    };
    c.fitted(body)
}

/// The evidence for `view-top`.
pub(crate) fn view_top(c: &Context, h: f64, t: f64) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let far = |s: &Stats| s.mean_over("missing", 15..20);
        format!(
            "cells far ahead (rows 15-19) missing: real {} vs model {}: terrain above a line {} above C falling {} per metre is out of view",
            pct(far(real)),
            pct(far(before)),
            mm(h),
            mm(t),
        )
    };
    c.fitted(body)
}
