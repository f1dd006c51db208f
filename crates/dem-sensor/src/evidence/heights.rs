//! Evidence for the effects of dem-sensor's `heights` family: heights moved everywhere (range, calibration, pose).

use super::*;

/// The evidence for `noise`.
pub(crate) fn noise(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let spread = c.spread();
    let body = {
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
    };
    c.fitted(body)
}

/// The evidence for `tilt`.
pub(crate) fn tilt(c: &Context, pitch: f64, roll: f64, x0: f64, range: f64) -> String {
    let real = c.real;
    let before = c.before;
    let spread = c.spread();
    if !real.paired {
        return c.fitted(tilted_unpaired(
            real,
            before,
            &format!(
                "a camera angle that differs from record to record (sd pitch {:.2}, roll {:.2} degrees)",
                pitch.to_degrees(),
                roll.to_degrees()
            ),
        ));
    }
    let body = {
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
    };
    c.fitted(body)
}

/// The evidence for `shake`.
pub(crate) fn shake(c: &Context, sigma: f64, edge: f64) -> String {
    let real = c.real;
    let before = c.before;
    let spread = c.spread();
    if !real.paired {
        return c.fitted(tilted_unpaired(
            real,
            before,
            &format!(
                "the body rocks about its centre, with sd {:.2} degrees plus {:.2} degrees per 10 cm of step under the tracks",
                sigma.to_degrees(),
                (0.1 * edge).to_degrees()
            ),
        ));
    }
    let body = {
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
    };
    c.fitted(body)
}

/// The evidence for `drift`.
pub(crate) fn drift(c: &Context, rate: f64, zrate: f64, x0: f64) -> String {
    let real = c.real;
    let before = c.before;
    let spread = c.spread();
    if !real.paired {
        return c.fitted(
{
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
        );
    }
    let body = {
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
    };
    c.fitted(body)
}

/// The evidence for `lag`.
pub(crate) fn lag(c: &Context, s: f64) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
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
                "real moves no more cells on that side of steps than the other: the lag is the closest effect, not a clear one".to_string()
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
            let fitted =
                format!("steps read part of the way across where a shift {ahead} of {:.1} cm puts a cell on both sides", 100.0 * s.abs());
            part_way_steps(real, before, fitted, "the lag is")
        }
    };
    c.fitted(body)
}

/// The evidence for `bias`.
pub(crate) fn bias(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
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
    };
    c.fitted(body)
}

/// The evidence for `quantization`.
pub(crate) fn quantization(c: &Context, q: f64) -> String {
    let real = c.real;
    let before = c.before;
    let body = format!(
        "neighbour differences of 0.1-10 mm: real {} vs model {}; equal neighbours real {} vs model {}: heights come in steps of {}",
        pct(small_steps(real)),
        pct(small_steps(before)),
        pct(real.mean_over("level-pairs", 0..20)),
        pct(before.mean_over("level-pairs", 0..20)),
        mm(q),
    );
    c.fitted(body)
}
