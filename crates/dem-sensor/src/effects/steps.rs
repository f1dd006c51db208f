//! Heights moved at steps, where a cell holds points of two surfaces:
//! `riser-blend`, `drop-blend`, `mixed-cells`, `floor-lift`,
//! `step-jitter`, `smoothing`.

use dem_core::format::{row_center_x, Dem, DemCells, COLS, GRID_ROWS};

use super::heights::step_under_tracks;
use super::{cell_heights, probability, EffectSpec, Family, Limit, ParamSpec, Range, Stage, HALF, MIXED_JUMP};
use crate::draws::Draws;

/// A cell between two jumps (`drop-blend`, `riser-blend`) takes the one
/// behind only when its step is larger by more than this (m): a cell made
/// the mean of its neighbours (`mixed-cells`, `smoothing`) lies exactly
/// between two equal steps, where rounding alone would choose.
pub const TIE_MARGIN: f64 = 1e-5;

/// A share from 0 to 1 whose both ends are natural (none, or all of it).
const SHARE: (Range, Limit) = (Range::lin(0.0, 1.0), Limit::new(0.0, 1.0).natural_lo().natural_hi());

/// `smoothing`: fusion blurs edges.
pub const SMOOTHING: EffectSpec = EffectSpec {
    name: "smoothing",
    family: Family::Steps,
    emulator: &["smoothing"],
    formula: "h = (w h + (1-w)/8 sum of valid 3x3 neighbours) / (w + (1-w)/8 n_valid)",
    params: &[ParamSpec {
        name: "w",
        doc: "Centre weight in (0, 1]; 1 is no smoothing.",
        fit: Range::lin(0.05, 1.0),
        limit: Limit::new(0.01, 1.0).natural_hi(),
    }],
    stage: Stage::Smoothing,
    draws: 0,
};

/// `mixed-cells`: cells that straddle a step read part of the way up or down.
pub const MIXED_CELLS: EffectSpec = EffectSpec {
    name: "mixed-cells",
    family: Family::Steps,
    emulator: &["occlusion", "smoothing"],
    formula: "a cell is the mean of its two half cells along x; at a jump of more than MIXED_JUMP between valid x-neighbours the step \
        lies at s, uniform over the 10 cm between their centres (one draw per row boundary), and the higher surface reaches e = \
        u r past it into the lower cell (u uniform per cell; r = `up` when the higher cell lies ahead, `down` when it lies \
        behind, i.e. beyond a drop): a half of the lower cell whose centre the higher surface reaches reads the higher height, a \
        half of the higher cell the lower surface reaches (the step lies in it, deeper than e) reads the lower height",
    // Reaches from none (the halves' mean alone) to a whole cell. Past
    // 0.2 m the surface reaches past the far half of the lower cell
    // whatever the step's place: larger reaches change nothing.
    params: &[
        ParamSpec {
            name: "up",
            doc: "How far (m, at most) a riser's top reaches back into the lower cell in front of it.",
            fit: Range::lin(0.0, 0.15),
            limit: Limit::new(0.0, 0.2).natural_lo().natural_hi(),
        },
        ParamSpec {
            name: "down",
            doc: "How far (m, at most) a drop edge's top reaches on into the lower cell beyond it.",
            fit: Range::lin(0.0, 0.15),
            limit: Limit::new(0.0, 0.2).natural_lo().natural_hi(),
        },
    ],
    stage: Stage::MixedCells,
    // Per row boundary a step position, then a reach per column.
    draws: (GRID_ROWS - 1) * (1 + COLS),
};

/// `drop-blend`: cells on both sides of a drop edge read part of the way across.
pub const DROP_BLEND: EffectSpec = EffectSpec {
    name: "drop-blend",
    family: Family::Steps,
    emulator: &["smoothing"],
    formula: "at a drop along x (valid cells of rows r and r + 1, row r + 1 lower by more than MIXED_JUMP), each of the two cells \
        reads, with probability p, h + u a (h_n - h), u uniform, h_n the other cell (a cell between two drops takes the larger; \
        the one behind only when larger by more than TIE_MARGIN): the stereo window straddles the jump in range at a drop edge \
        and its mean range puts the cell's points part of the way to the other surface",
    // Every cell beside a drop blended, or moved all the way: natural ends.
    params: &[
        ParamSpec { name: "p", doc: "Probability that a cell beside a drop is blended.", fit: SHARE.0, limit: SHARE.1 },
        ParamSpec { name: "a", doc: "Largest share of the drop it moves across.", fit: SHARE.0, limit: SHARE.1 },
    ],
    stage: Stage::DropMoves,
    // Two per cell: whether it is blended, and how far.
    draws: 2 * GRID_ROWS * COLS,
};

/// `floor-lift`: the ground just beyond a drop edge reads part of the way up to it.
pub const FLOOR_LIFT: EffectSpec = EffectSpec {
    name: "floor-lift",
    family: Family::Steps,
    emulator: &["fov", "occlusion", "smoothing"],
    formula: "in rows whose centre x < `x`, a valid cell whose valid neighbour behind (row r - 1) is higher by more than MIXED_JUMP \
        (the ground just beyond a drop edge) reads, with probability p, h + min(1, u a) (h_n - h), u uniform, h_n that \
        neighbour: the edge hides the floor nearest it, and the cell keeps points lifted toward the edge (x past the grid: every \
        row; x at the cone's lowest ray: the rows where the map keeps that grazing view)",
    // x from the rows behind the robot (where a camera whose lowest ray
    // meets the ground ahead keeps its grazing view) to past the grid
    // (every row: occlusion alone); a up to 3 (two in three moved cells
    // read the edge's height). No rows (x behind the grid) or all of them,
    // no cell or every one, none moved or (a large) all the way: natural ends.
    params: &[
        ParamSpec {
            name: "x",
            doc: "Only rows whose centre lies behind this x (m) (past the grid: all).",
            fit: Range::lin(-0.3, 1.45),
            limit: Limit::new(-0.6, 1.45).natural_lo().natural_hi(),
        },
        ParamSpec { name: "p", doc: "Probability that a cell beyond a drop there reads higher.", fit: SHARE.0, limit: SHARE.1 },
        ParamSpec {
            name: "a",
            doc: "Reach: the share moved is min(1, u a), u uniform (a > 1: some cells read the edge's height).",
            fit: Range::lin(0.0, 3.0),
            limit: Limit::new(0.0, 5.0).natural_lo().natural_hi(),
        },
    ],
    stage: Stage::DropMoves,
    // Two per cell: whether it is lifted, and how far.
    draws: 2 * GRID_ROWS * COLS,
};

/// `riser-blend`: cells beside a riser read part of the way up or down the step.
pub const RISER_BLEND: EffectSpec = EffectSpec {
    name: "riser-blend",
    family: Family::Steps,
    emulator: &["fov", "smoothing"],
    formula: "at a riser along x (valid cells of rows r and r + 1, row r + 1 higher by more than MIXED_JUMP), the cell at its foot \
        reads h + u `foot` (h_n - h) and the cell on its top h + u `top` (h_n - h), u uniform per cell, h_n the other cell (a \
        cell beside two risers takes the larger step; the one behind only when larger by more than TIE_MARGIN); `foot`, `top` in \
        [-1, 1], negative: away from the other surface: the stereo window over a riser's corners moves the points there along \
        their rays, up or down the step as the view angle gives",
    // Either way across the step; 0 (no move) on the grid. Moved all the
    // way to the other surface: a natural end; the other end (away from
    // it) is not.
    params: &[
        ParamSpec {
            name: "foot",
            doc: "Largest share of the step the cell at the riser's foot moves toward the top (negative: down, away from it).",
            fit: Range::lin(-0.6, 1.0),
            limit: Limit::new(-1.0, 1.0).natural_hi(),
        },
        ParamSpec {
            name: "top",
            doc: "Largest share of the step the cell on the riser's top moves toward the foot (negative: up, away from it).",
            fit: Range::lin(-0.6, 1.0),
            limit: Limit::new(-1.0, 1.0).natural_hi(),
        },
    ],
    stage: Stage::RiserMoves,
    // One per cell.
    draws: GRID_ROWS * COLS,
};

/// `step-jitter`: vibration seen at steps.
pub const STEP_JITTER: EffectSpec = EffectSpec {
    name: "step-jitter",
    family: Family::Steps,
    emulator: &["vibration"],
    formula: "per record s = `sigma` + `edge` J (J as in `shake`); each valid cell reads dx = clamp(s z, +-0.1 m) off along x, z a \
        standard normal per cell (as `noise` draws them): h += dx (h(r + 1) - h(r - 1)) / 0.2, a neighbour missing or outside \
        the grid read as the cell's own height (jitter_steps): each map cell beside a step keeps the points of the few frames \
        whose heights agree, so one frame's horizontal misregistration (the body's vibration) stays in it, a different one in \
        each cell; even ground averages it out and reads nothing",
    // A frame misregistered by up to 3 cm sd on even ground, 0.3 m per
    // metre of step under the tracks (a 0.2 m stair edge: 6 cm more). A
    // cell read more than 0.1 m off is clamped there: 0.1 is no edge.
    params: &[
        ParamSpec {
            name: "sigma",
            doc: "Sd (m) of the misregistration on even ground.",
            fit: Range::lin(0.0, 0.03),
            limit: Limit::new(0.0, 0.1).natural_lo(),
        },
        ParamSpec {
            name: "edge",
            doc: "Extra sd per metre of step under the tracks (m per m).",
            fit: Range::lin(0.0, 0.3),
            limit: Limit::new(0.0, 1.0).natural_lo(),
        },
    ],
    stage: Stage::Registration,
    // One normal per cell, as `noise` draws them.
    draws: GRID_ROWS * COLS,
};

pub(super) fn check_smoothing(w: f64) -> Result<(), String> {
    if !(w > 0.0 && w <= 1.0) {
        return Err(format!("w = {w} must be in (0, 1]"));
    }
    Ok(())
}

pub(super) fn check_mixed_cells(up: f64, down: f64) -> Result<(), String> {
    if up < 0.0 || down < 0.0 {
        return Err(format!("up = {up} and down = {down} must be >= 0"));
    }
    Ok(())
}

pub(super) fn check_drop_blend(p: f64, a: f64) -> Result<(), String> {
    probability(p)?;
    if !(0.0..=1.0).contains(&a) {
        return Err(format!("a = {a} must be in [0, 1]"));
    }
    Ok(())
}

pub(super) fn check_floor_lift(p: f64, a: f64) -> Result<(), String> {
    probability(p)?;
    if a < 0.0 {
        return Err(format!("a = {a} must be >= 0"));
    }
    Ok(())
}

pub(super) fn check_riser_blend(foot: f64, top: f64) -> Result<(), String> {
    if !(-1.0..=1.0).contains(&foot) || !(-1.0..=1.0).contains(&top) {
        return Err(format!("foot = {foot} and top = {top} must be in [-1, 1]"));
    }
    Ok(())
}

pub(super) fn check_step_jitter(sigma: f64, edge: f64) -> Result<(), String> {
    if sigma < 0.0 || edge < 0.0 {
        return Err(format!("sigma = {sigma} and edge = {edge} must be >= 0"));
    }
    Ok(())
}

/// `drop-blend`: heights are read on the DEM as it comes in, so a cell
/// between two drops blends toward one of them only. Risers (the higher
/// cell ahead) are left alone: the surface seen is continuous there (a
/// corner, not a jump in range), and the emulator moves their cells by a
/// fifth of the step at most.
pub(super) fn blend_drops(d: &mut Dem, rng: &mut Draws, p: f64, a: f64) {
    let z = cell_heights(d);
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let (u, v): (f64, f64) = (rng.gen(), rng.gen());
            let Some(zc) = z[r][c] else { continue };
            // The other cell across a drop: ahead and lower, or behind and higher.
            let across = |rr: usize, ahead: bool| {
                let zn = z.get(rr).and_then(|row| row[c])?;
                ((if ahead { zc - zn } else { zn - zc }) > MIXED_JUMP).then_some(zn - zc)
            };
            let step = match (across(r + 1, true), across(r.wrapping_sub(1), false)) {
                (Some(f), Some(b)) => Some(if b.abs() > f.abs() + TIE_MARGIN { b } else { f }),
                (f, b) => f.or(b),
            };
            if let (Some(s), true) = (step, u < p) {
                d.set_valid(r, c, (zc + v * a * s) as f32);
            }
        }
    }
}

/// `floor-lift` (formula in its spec): heights are read on the DEM as it
/// comes in, so a cell beyond two drops (a one-cell tread) moves toward
/// the edge just behind it only.
pub(super) fn lift_floors(d: &mut Dem, rng: &mut Draws, x: f64, p: f64, a: f64) {
    let z = cell_heights(d);
    for (r, row) in z.iter().enumerate() {
        for (c, &zc) in row.iter().enumerate() {
            let (u, v): (f64, f64) = (rng.gen(), rng.gen());
            let (Some(zc), true) = (zc, r > 0 && row_center_x(r) < x) else { continue };
            let Some(edge) = z[r - 1][c] else { continue };
            if edge - zc > MIXED_JUMP && u < p {
                d.set_valid(r, c, (zc + (v * a).min(1.0) * (edge - zc)) as f32);
            }
        }
    }
}

/// `riser-blend`: heights are read on the DEM as it comes in; a cell beside
/// two risers (a one-cell tread) moves across the larger step only.
pub(super) fn blend_risers(d: &mut Dem, rng: &mut Draws, foot: f64, top: f64) {
    let z = cell_heights(d);
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let u: f64 = rng.gen();
            let Some(zc) = z[r][c] else { continue };
            // (step to the other cell, share): the riser ahead (this cell
            // at its foot) or behind (this cell on its top).
            let across = |rr: usize, share: f64| {
                let zn = z.get(rr).and_then(|row| row[c])?;
                let step = zn - zc;
                let riser = if rr > r { step > MIXED_JUMP } else { -step > MIXED_JUMP };
                riser.then_some((step, share))
            };
            let moved = match (across(r + 1, foot), across(r.wrapping_sub(1), top)) {
                (Some(f), Some(b)) => Some(if b.0.abs() > f.0.abs() + TIE_MARGIN { b } else { f }),
                (f, b) => f.or(b),
            };
            if let Some((step, share)) = moved {
                d.set_valid(r, c, (zc + u * share * step) as f32);
            }
        }
    }
}

/// `mixed-cells` (formula in its spec). Each cell is two halves along x,
/// back (toward row r - 1) and front; a half's centre lies [`HALF`] / 2
/// from its cell's boundary, the other half's 3/2 [`HALF`]. Where
/// neighbours both reach a half, the higher surface wins, as in a map cell
/// that keeps the higher of two heights.
pub(super) fn mix_cells(d: &mut Dem, rng: &mut Draws, up: f64, down: f64) {
    let z = cell_heights(d);
    // Per half: the height the higher neighbour spills in, the lower one's.
    let mut raise = [[[f64::NEG_INFINITY; 2]; COLS]; GRID_ROWS];
    let mut lower = [[[f64::INFINITY; 2]; COLS]; GRID_ROWS];
    let (near, far) = (0.5 * HALF, 1.5 * HALF);
    for b in 0..GRID_ROWS - 1 {
        // The step's distance past the boundary into row b (negative: into b + 1).
        let s = (1.0 - 2.0 * rng.gen()) * HALF;
        for c in 0..COLS {
            let u: f64 = rng.gen();
            let (Some(z0), Some(z1)) = (z[b][c], z[b + 1][c]) else { continue };
            if (z1 - z0).abs() <= MIXED_JUMP {
                continue;
            }
            // (lower row, its half at the boundary, higher row, its half, step depth into the lower row)
            let (lo, lo_half, hi, hi_half, depth, reach) = if z1 > z0 { (b, 1, b + 1, 0, s, up) } else { (b + 1, 0, b, 1, -s, down) };
            let (zlo, zhi) = (z0.min(z1), z0.max(z1));
            let into_low = depth + u * reach;
            for (dist, h) in [(near, lo_half), (far, 1 - lo_half)] {
                if into_low > dist {
                    raise[lo][c][h] = raise[lo][c][h].max(zhi);
                }
            }
            for (dist, h) in [(near, hi_half), (far, 1 - hi_half)] {
                if -into_low > dist {
                    lower[hi][c][h] = lower[hi][c][h].min(zlo);
                }
            }
        }
    }
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let Some(zc) = z[r][c] else { continue };
            let half = |h: usize| {
                if raise[r][c][h].is_finite() {
                    raise[r][c][h]
                } else if lower[r][c][h].is_finite() {
                    lower[r][c][h]
                } else {
                    zc
                }
            };
            let m = 0.5 * (half(0) + half(1));
            if m != zc {
                d.set_valid(r, c, m as f32);
            }
        }
    }
}

/// `step-jitter` (formula in its spec): the record's sd from the step
/// under the tracks, then [`jitter_steps`].
pub(super) fn jitter(d: &mut Dem, rng: &mut Draws, sigma: f64, edge: f64) {
    let normals: [f64; GRID_ROWS * COLS] = rng.normals();
    jitter_steps(d, &normals, sigma + edge * step_under_tracks(d));
}

/// `step-jitter` with sd `s`: each valid cell reads dx = clamp(s z, +-0.1
/// m) off along x (`z` its normal, row-major):
/// h += dx (src(r + 1) - src(r - 1)) / 0.2, where src(k) is row k's height
/// where row k lies in the grid and is valid, else the cell's own (a
/// one-sided slope at an edge of what was seen, none on even ground).
pub fn jitter_steps(d: &mut Dem, z: &[f64; GRID_ROWS * COLS], s: f64) {
    let h = cell_heights(d);
    let cell = dem_core::format::CELL;
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let Some(own) = h[r][c] else { continue };
            let src = |k: Option<usize>| k.filter(|&k| k < GRID_ROWS).and_then(|k| h[k][c]).unwrap_or(own);
            let slope = (src(Some(r + 1)) - src(r.checked_sub(1))) / (2.0 * cell);
            let dx = (s * z[r * COLS + c]).clamp(-cell, cell);
            d.set_valid(r, c, (own + dx * slope) as f32);
        }
    }
}

/// `smoothing` (formula in its spec), on the DEM as it comes in.
pub(super) fn smooth(d: &mut Dem, w: f64) {
    let z = cell_heights(d);
    let wn = (1.0 - w) / 8.0;
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let Some(zc) = z[r][c] else { continue };
            let (mut sum, mut weight) = (w * zc, w);
            let (r0, c0) = (r.saturating_sub(1), c.saturating_sub(1));
            for (rr, row) in z.iter().enumerate().take(r + 2).skip(r0) {
                for (cc, zn) in row.iter().enumerate().take(c + 2).skip(c0) {
                    if let (true, Some(zn)) = ((rr, cc) != (r, c), zn) {
                        sum += wn * zn;
                        weight += wn;
                    }
                }
            }
            d.set_valid(r, c, (sum / weight) as f32);
        }
    }
}
