//! Evidence in words and numbers for a named effect: what in the data
//! points at it, before (model) against real, and what the fit achieved.

use dem_core::format::{row_center_x, GRID_ROWS};
use dem_sensor::Effect;

use dem_core::distribution::{Stats, STEP_SIDES};

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

/// One sentence of evidence for `effect`, from the statistics of the model
/// before it was added, after, and of real.
pub fn evidence(effect: &Effect, before: &Stats, after: &Stats, real: &Stats, gap_before: f64, gap_after: f64) -> String {
    let removed = crate::share_removed(gap_before, gap_after);
    let per_rec = |s: &Stats, name: &str| total(s, name) / s.records.max(1) as f64;
    let spread = if real.paired { "residual (real - sim) sd" } else { "across-robot height difference sd / sqrt 2" };
    let body = match *effect {
        Effect::Noise { .. } => {
            let (rn, bn, rf, bf) = (
                real.mean_over("spread-sd", 6..10),
                before.mean_over("spread-sd", 6..10),
                real.mean_over("spread-sd", 15..20),
                before.mean_over("spread-sd", 15..20),
            );
            let verdict = if rn >= bn && rf >= bf {
                "real is the noisier"
            } else {
                "the model's spread is already as large or larger in part (terrain, not noise): the noise is named for the equal neighbours and the small height steps"
            };
            format!(
                "neighbouring cells of equal height real {} vs model {}; height spread ({spread}) near (rows 6-9) real {} vs model {}, far (rows 15-19) real {} vs model {}: {verdict}",
                pct(real.mean_over("level-pairs", 0..20)),
                pct(before.mean_over("level-pairs", 0..20)),
                mm(rn),
                mm(bn),
                mm(rf),
                mm(bf),
            )
        }
        Effect::Dropout { .. } => {
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
        }
        Effect::Fov { x_min, x_max } => {
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
        }
        Effect::Startup { x0, v, p } => {
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
        }
        Effect::PatchDropout { .. } => paired_misses(
            real,
            before,
            "missing cells come in blobs",
            "no more blobs in real than in the model: blobs are the closest effect, not a clear one",
        ),
        Effect::EdgeHoles { .. } => {
            let (r, b) = (real.mean_over("jump-missing", 0..20), before.mean_over("jump-missing", 0..20));
            format!(
                "missing cells between valid cells of their column that differ by 5 cm or more: real {} vs model {}: {}",
                pct(r),
                pct(b),
                if r > b { "holes at height jumps" } else { "no more of them in real: the holes are the closest effect, not a clear one" }
            )
        }
        Effect::DropHoles { .. } => {
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
        }
        Effect::HoleGrowth { .. } => paired_misses(
            real,
            before,
            "holes are wider in real: cells at their edges are lost",
            "no more paired misses in real: grown holes are the closest effect, not a clear one",
        ),
        Effect::ViewTop { h, t } => {
            let far = |s: &Stats| s.mean_over("missing", 15..20);
            format!(
                "cells far ahead (rows 15-19) missing: real {} vs model {}: terrain above a line {} above C falling {} per metre is out of view",
                pct(far(real)),
                pct(far(before)),
                mm(h),
                mm(t),
            )
        }
        Effect::RimHoles { .. } => {
            let (r, b) = (real.mean_over("jump-missing", 0..20), before.mean_over("jump-missing", 0..20));
            format!(
                "missing cells between valid cells of their column that differ by 5 cm or more: real {} vs model {}; missing cells real {} vs model {}: {}",
                pct(r),
                pct(b),
                pct(real.mean_over("missing", 0..20)),
                pct(before.mean_over("missing", 0..20)),
                if r > b { "holes at height jumps, on their upper side too" } else { "no more holes at jumps in real: the rim holes are the closest effect, not a clear one" }
            )
        }
        Effect::PitFill { .. } => {
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
        }
        Effect::MixedCells { .. } => {
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
        }
        Effect::DropBlend { .. } => {
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
        }
        Effect::FloorLift { x, .. } => {
            let rows =
                if x > row_center_x(GRID_ROWS - 1) { "in every row".to_string() } else { format!("in the rows behind x = {x:.2} m") };
            let verdict =
                format!("the ground just beyond a drop edge reads part of the way up ({rows}): the edge hides the floor nearest it");
            if real.paired {
                // The drop floors' share moved > 2 cm toward the edge (component 2).
                let up = |s: &Stats| s.term("drop-floor").map_or(0.0, |t| t.values[2]);
                let v = if up(real) > up(before) {
                    verdict
                } else {
                    "real moves no more cells beyond drops than the model: lifted floors are the closest effect, not a clear one".into()
                };
                format!(
                    "cells beyond a drop read more than 2 cm up toward its edge: real {} vs model {}: {v}",
                    pct(up(real)),
                    pct(up(before))
                )
            } else {
                let v = if mid(real) > mid(before) {
                    verdict
                } else {
                    "no more part-way steps in real: lifted floors are the closest effect, not a clear one".into()
                };
                format!("steps between neighbouring rows of 0.02-0.1 m: real {} vs model {}: {v}", pct(mid(real)), pct(mid(before)))
            }
        }
        Effect::RiserBlend { foot, top } => {
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
        }
        Effect::Tilt { pitch, roll, .. } if !real.paired => tilted_unpaired(
            real,
            before,
            &format!(
                "a camera angle that differs from record to record (sd pitch {:.2}, roll {:.2} degrees)",
                pitch.to_degrees(),
                roll.to_degrees()
            ),
        ),
        Effect::Shake { sigma, edge } if !real.paired => tilted_unpaired(
            real,
            before,
            &format!(
                "the body rocks about its centre, with sd {:.2} degrees plus {:.2} degrees per 10 cm of step under the tracks",
                sigma.to_degrees(),
                (0.1 * edge).to_degrees()
            ),
        ),
        Effect::Drift { rate, zrate, x0 } if !real.paired => {
            // Along-x steps between the rows behind x0 (each row its own
            // height offset) against those ahead of it.
            let behind = (0..GRID_ROWS).filter(|&r| row_center_x(r) < x0).count().clamp(2, 18);
            let e = |s: &Stats, rows: std::ops::Range<usize>| s.mean_over("edge-2cm", rows);
            let (rb, bb, ra, ba) = (e(real, 0..behind - 1), e(before, 0..behind - 1), e(real, behind..19), e(before, behind..19));
            let verdict = if rb - bb > ra - ba && rb > bb {
                format!(
                    "the rows behind x0 step against each other: rows seen earlier are displaced by a pose that walks {:.0} mm along x and {:.0} mm in height per sqrt(m) travelled",
                    1000.0 * rate,
                    1000.0 * zrate
                )
            } else {
                "no more steps behind x0 than ahead of it in real: the drift is the closest effect, not a clear one".to_string()
            };
            format!(
                "steps above 2 cm between neighbouring rows behind x = {x0:.2} m real {} vs model {}, ahead of it real {} vs model {}: {verdict}",
                pct(rb),
                pct(bb),
                pct(ra),
                pct(ba),
            )
        }
        Effect::Tilt { pitch, roll, x0, range } => {
            // Rows just ahead of x0 against the far rows: a tilt's spread
            // grows with the range, range at x0 and more past it.
            let first = (0..GRID_ROWS).find(|&r| row_center_x(r) > x0).unwrap_or(GRID_ROWS).min(12);
            let near = first..first + 3;
            let sd = |s: &Stats, rows: std::ops::Range<usize>| s.mean_over("spread-sd", rows);
            let (rn, bn, rf, bf) = (sd(real, near.clone()), sd(before, near.clone()), sd(real, 15..20), sd(before, 15..20));
            let verdict = if rf > bf && rf - bf > rn - bn {
                format!(
                    "real spreads more the farther ahead of x0: heights tilted by a camera angle that differs from record to record (sd pitch {:.2}, roll {:.2} degrees), seen from {range:.1} m at x0 and farther beyond",
                    pitch.to_degrees(),
                    roll.to_degrees()
                )
            } else {
                "real's extra spread does not grow with range: the tilt is the closest effect, not a clear one".to_string()
            };
            format!(
                "height spread ({spread}) just ahead of x = {x0:.2} m (rows {}-{}) real {} vs model {}, far ahead (rows 15-19) real {} vs model {}: {verdict}",
                near.start,
                near.end - 1,
                mm(rn),
                mm(bn),
                mm(rf),
                mm(bf),
            )
        }
        Effect::Shake { sigma, edge } => {
            // Both ends of the grid against the rows over C: a body rocking
            // about C moves both ends, the middle not at all.
            let sd = |s: &Stats, rows: std::ops::Range<usize>| s.mean_over("spread-sd", rows);
            let (rb, bb, rm, bm, rf, bf) =
                (sd(real, 0..3), sd(before, 0..3), sd(real, 5..7), sd(before, 5..7), sd(real, 16..20), sd(before, 16..20));
            let verdict = if (rb - bb).min(rf - bf) > rm - bm {
                format!(
                    "real spreads more at both ends than over C: the body rocks about its centre, with sd {:.2} degrees plus {:.2} degrees per 10 cm of step under the tracks",
                    sigma.to_degrees(),
                    (0.1 * edge).to_degrees()
                )
            } else {
                "real's extra spread is not larger at both ends than over C: the shake is the closest effect, not a clear one".to_string()
            };
            format!(
                "height spread ({spread}) behind the robot (rows 0-2) real {} vs model {}, over C (rows 5-6) real {} vs model {}, far ahead (rows 16-19) real {} vs model {}: {verdict}",
                mm(rb),
                mm(bb),
                mm(rm),
                mm(bm),
                mm(rf),
                mm(bf),
            )
        }
        Effect::Lag { s, .. } => {
            let ahead = if s >= 0.0 { "ahead" } else { "back" };
            if real.paired {
                // The cells beside steps moved > 2 cm toward the other
                // surface (component 2): a shift ahead moves the far side of
                // each step (riser tops, drop floors), a shift back the near
                // side (riser feet, drop lips).
                let moved = |st: &Stats, sides: [&str; 2]| side_share(st, &sides, 2);
                let (far, near) = (["riser-top", "drop-floor"], ["riser-foot", "drop-lip"]);
                let (lead, trail) = if s >= 0.0 { (far, near) } else { (near, far) };
                let (rl, bl, rt, bt) = (moved(real, lead), moved(before, lead), moved(real, trail), moved(before, trail));
                let verdict = if rl > bl && rl - bl > rt - bt {
                    format!("steps read {:.1} cm {ahead} of where sim has them: the DEM is the map of an older frame", 100.0 * s.abs())
                } else {
                    "real moves no more cells on that side of steps than the other: the lag is the closest effect, not a clear one"
                        .to_string()
                };
                format!(
                    "cells on the {} side of steps (riser {}, drop {}) moved more than 2 cm toward the other surface: real {} vs model {}; on the other side real {} vs model {}: {verdict}",
                    if s >= 0.0 { "far" } else { "near" },
                    if s >= 0.0 { "tops" } else { "feet" },
                    if s >= 0.0 { "floors" } else { "lips" },
                    pct(rl),
                    pct(bl),
                    pct(rt),
                    pct(bt),
                )
            } else {
                let fitted = format!(
                    "steps read part of the way across where a shift {ahead} of {:.1} cm puts a cell on both sides",
                    100.0 * s.abs()
                );
                part_way_steps(real, before, fitted, "the lag is")
            }
        }
        Effect::Drift { rate, zrate, x0 } => {
            // The oldest rows against those just behind x0 and those ahead:
            // a walk back from x0 spreads most in the oldest rows.
            let behind = (0..GRID_ROWS).filter(|&r| row_center_x(r) < x0).count().clamp(4, 17);
            let sd = |s: &Stats, rows: std::ops::Range<usize>| s.mean_over("spread-sd", rows);
            let (old, just, ahead) = (0..2, behind - 2..behind, behind..behind + 3);
            let ex = |rows: std::ops::Range<usize>| sd(real, rows.clone()) - sd(before, rows);
            let verdict = if ex(old.clone()) > ex(just.clone()) && ex(old.clone()) > ex(ahead.clone()) {
                format!(
                    "real's extra spread grows going back from x0: rows seen earlier are displaced by a pose that walks {:.0} mm along x and {:.0} mm in height per sqrt(m) travelled",
                    1000.0 * rate,
                    1000.0 * zrate
                )
            } else {
                "real's extra spread does not grow going back: the drift is the closest effect, not a clear one".to_string()
            };
            format!(
                "height spread ({spread}) in the oldest rows (0-1) real {} vs model {}, just behind x = {x0:.2} m (rows {}-{}) real {} vs model {}, ahead of it (rows {}-{}) real {} vs model {}: {verdict}",
                mm(sd(real, old.clone())),
                mm(sd(before, old)),
                just.start,
                just.end - 1,
                mm(sd(real, just.clone())),
                mm(sd(before, just.clone())),
                ahead.start,
                ahead.end - 1,
                mm(sd(real, ahead.clone())),
                mm(sd(before, ahead.clone())),
            )
        }
        Effect::StepJitter { sigma, edge } => {
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
        }
        Effect::Smoothing { .. } => {
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
        }
        Effect::Bias { .. } => {
            let (rb, mb) = (real.mean_over("height", 0..6), before.mean_over("height", 0..6));
            let (ra, ma) = (real.mean_over("height", 15..20), before.mean_over("height", 15..20));
            // Unpaired, mean heights follow the terrain: real higher than
            // the model on one side of the robot and lower on the other is
            // more like two sets of different terrain than a sensor offset.
            let mixed = !real.paired && (rb - mb).abs() > 0.005 && (ra - ma).abs() > 0.005 && (rb - mb).signum() != (ra - ma).signum();
            format!(
                "mean {} behind (rows 0-5) real {} vs model {}, far ahead (rows 15-19) real {} vs model {}: {}",
                if real.paired { "residual" } else { "height" },
                mm(rb),
                mm(mb),
                mm(ra),
                mm(ma),
                if mixed {
                    "real is higher on one side and lower on the other, more like two sets of different terrain than one offset: \
                     read it as the closest effect, and compare the same terrain mix (--match-terrain-mix with both label files, or --pairs)"
                } else {
                    "an offset and a tilt"
                }
            )
        }
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
