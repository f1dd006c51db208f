//! Evidence for the effects of dem-sensor's `steps` family: heights moved at steps.

use super::*;

/// The evidence for `mixed-cells`.
pub(crate) fn mixed_cells(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let (r10, b10) = (real.mean_over("edge-10cm", 0..19), before.mean_over("edge-10cm", 0..19));
        let verdict = if r10 < b10 && mid(real) > mid(before) {
            "a cell beside a step reads part of the way up: jumps split into two smaller ones"
        } else {
            "no clear split of jumps in real: mixed cells are the closest effect, not a clear one"
        };
        format!(
            "steps between neighbouring rows above 0.1 m: real {} vs model {}; of 0.02-0.1 m: real {} vs model {}: {verdict}",
            pct(r10),
            pct(b10),
            pct(mid(real)),
            pct(mid(before)),
        )
    };
    c.fitted(body)
}

/// The evidence for `drop-blend`.
pub(crate) fn drop_blend(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let (q, spread) = if real.paired {
            ("spread-q99", "99th percentile of the residual (real - sim)")
        } else {
            ("spread-q90", "90th percentile of the across-robot height difference")
        };
        let tail = |s: &Stats| s.mean_over(q, 0..20);
        let verdict = if mid(real) > mid(before) && tail(real) > tail(before) {
            "cells beside drops read part of the way across in some records"
        } else {
            "no more part-way steps or wide tails in real: blended drops are the closest effect, not a clear one"
        };
        format!(
            "steps between neighbouring rows of 0.02-0.1 m: real {} vs model {}; {spread}: real {} vs model {}: {verdict}",
            pct(mid(real)),
            pct(mid(before)),
            mm(tail(real)),
            mm(tail(before)),
        )
    };
    c.fitted(body)
}

/// The evidence for `floor-lift`.
pub(crate) fn floor_lift(c: &Context, x: f64) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let rows = if x > row_center_x(GRID_ROWS - 1) { "in every row".to_string() } else { format!("in the rows behind x = {x:.2} m") };
        let verdict = format!("the ground just beyond a drop edge reads part of the way up ({rows}): the edge hides the floor nearest it");
        if real.paired {
            // The drop floors' share moved > 2 cm toward the edge (component 2).
            let up = |s: &Stats| s.term("drop-floor").map_or(0.0, |t| t.values[2]);
            let v = if up(real) > up(before) {
                verdict
            } else {
                "real moves no more cells beyond drops than the model: lifted floors are the closest effect, not a clear one".into()
            };
            format!("cells beyond a drop read more than 2 cm up toward its edge: real {} vs model {}: {v}", pct(up(real)), pct(up(before)))
        } else {
            let v = if mid(real) > mid(before) {
                verdict
            } else {
                "no more part-way steps in real: lifted floors are the closest effect, not a clear one".into()
            };
            format!("steps between neighbouring rows of 0.02-0.1 m: real {} vs model {}: {v}", pct(mid(real)), pct(mid(before)))
        }
    };
    c.fitted(body)
}

/// The evidence for `riser-blend`.
pub(crate) fn riser_blend(c: &Context, foot: f64, top: f64) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let way = |share: f64, toward: &'static str, away: &'static str| if share >= 0.0 { toward } else { away };
        let fitted = format!("the foot {}, the top {}", way(foot, "up", "down"), way(top, "down", "up"));
        if real.paired {
            // The step-side terms' shares of cells moved > 2 cm toward
            // the other surface and away (components 2 and 3).
            let moved = |s: &Stats, side: &str| s.term(side).map_or(0.0, |t| t.values[2] + t.values[3]);
            let more = |side: &str| moved(real, side) > moved(before, side);
            let verdict = if more("riser-foot") || more("riser-top") {
                format!("cells beside risers read part of the way across the step: {fitted}")
            } else {
                "real moves no more riser cells than the model: blended risers are the closest effect, not a clear one".to_string()
            };
            format!(
                "cells beside risers moved more than 2 cm: at the foot real {} vs model {}, on the top real {} vs model {}: {verdict}",
                pct(moved(real, "riser-foot")),
                pct(moved(before, "riser-foot")),
                pct(moved(real, "riser-top")),
                pct(moved(before, "riser-top")),
            )
        } else {
            part_way_steps(
                real,
                before,
                format!("cells beside risers read part of the way across the step: {fitted}"),
                "blended risers are",
            )
        }
    };
    c.fitted(body)
}

/// The evidence for `step-jitter`.
pub(crate) fn step_jitter(c: &Context, sigma: f64, edge: f64) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let fitted = format!(
            "each cell beside a step reads a random distance off along x (a frame's misregistration kept where fusion does not average), sd {:.0} mm plus {:.0} mm per 10 cm of step under the tracks",
            1000.0 * sigma,
            100.0 * edge
        );
        if real.paired {
            // Both ways across the step: cells moved > 2 cm toward the
            // other surface (component 2) and away from it (3).
            let share = |st: &Stats, k: usize| side_share(st, &STEP_SIDES, k);
            let (rt, bt, ra, ba) = (share(real, 2), share(before, 2), share(real, 3), share(before, 3));
            let verdict = if rt > bt && ra > ba {
                format!("cells beside steps move both toward and away from the other surface: {fitted}")
            } else {
                "real moves no more step cells both ways than the model: the jitter is the closest effect, not a clear one".to_string()
            };
            format!(
                "cells beside steps moved more than 2 cm toward the other surface real {} vs model {}, away from it real {} vs model {}: {verdict}",
                pct(rt),
                pct(bt),
                pct(ra),
                pct(ba),
            )
        } else {
            part_way_steps(real, before, format!("steps read part of the way across: {fitted}"), "the jitter is")
        }
    };
    c.fitted(body)
}

/// The evidence for `smoothing`.
pub(crate) fn smoothing(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let (r10, b10) = (real.mean_over("edge-10cm", 0..19), before.mean_over("edge-10cm", 0..19));
        let verdict = if r10 < b10 {
            "sharp edges become ramps"
        } else {
            "real has as many sharp edges: the smoothing is named for the small steps and spreads, not for ramps"
        };
        format!(
            "steps between neighbouring rows above 0.1 m: real {} vs model {}; above 0.02 m: real {} vs model {}: {verdict}",
            pct(r10),
            pct(b10),
            pct(real.mean_over("edge-2cm", 0..19)),
            pct(before.mean_over("edge-2cm", 0..19)),
        )
    };
    c.fitted(body)
}
