//! Cells lost or filled where the map is thin: `dropout`, `row-dropout`,
//! `patch-dropout`, `edge-holes`, `rim-holes`, `pit-fill`, `drop-holes`,
//! `hole-growth`.

use dem_core::format::{col_center_y, row_center_x, Dem, DemCells, COLS, GRID_ROWS};

use super::{cell_heights, neighbours4, probability, EffectSpec, Family, Limit, ParamSpec, Range, Stage, HALF, MIXED_JUMP};
use crate::draws::Draws;

/// Blob slots per record of `patch-dropout`: at most this many blobs.
pub const PATCH_SLOTS: usize = 8;

/// The box and limits of a probability that fades out at 0.
const RATE: (Range, Limit) = (Range::lin(0.0, 0.6), Limit::new(0.0, 1.0).natural_lo());

/// `dropout`: single valid cells missing at random.
pub const DROPOUT: EffectSpec = EffectSpec {
    name: "dropout",
    family: Family::Holes,
    emulator: &["dropout", "holes"],
    formula: "each valid cell missing with probability p",
    params: &[ParamSpec { name: "p", doc: "Probability per valid cell.", fit: RATE.0, limit: RATE.1 }],
    stage: Stage::Dropout,
    // One per cell.
    draws: GRID_ROWS * COLS,
};

/// `row-dropout`: whole grid rows missing at random.
pub const ROW_DROPOUT: EffectSpec = EffectSpec {
    name: "row-dropout",
    family: Family::Holes,
    emulator: &[],
    formula: "each grid row wholly missing with probability p",
    params: &[ParamSpec { name: "p", doc: "Probability per row.", fit: RATE.0, limit: RATE.1 }],
    stage: Stage::RowDropout,
    // One per row.
    draws: GRID_ROWS,
};

/// `patch-dropout`: missing blobs (dark or reflective patches).
pub const PATCH_DROPOUT: EffectSpec = EffectSpec {
    name: "patch-dropout",
    family: Family::Holes,
    emulator: &["dropout", "holes"],
    formula: "blobs: each of PATCH_SLOTS slots holds a blob with probability n / slots, centred uniformly over the grid widened by r; \
        of each cell's four quarter-cell centres (x +- 2.5 cm, y +- 2.5 cm) those within r of a blob centre are covered; three \
        or four covered: the cell is missing (the map needs two of four); one or two: h += a (h_low - h), h_low the lowest of h \
        and its x-neighbours left valid (the points a patch takes from a cell beside a step are those that lifted it)",
    // A blob loses a cell when it covers three of its quarter-cell
    // centres: r from 4 cm (up to four cells around a corner, by the
    // quarters it covers); smaller is `dropout`'s business. a from none
    // (a partly covered cell keeps its height) to the whole way down to
    // the lower x-neighbour: both natural ends.
    params: &[
        ParamSpec {
            name: "n",
            doc: "Expected blobs per record (0..PATCH_SLOTS).",
            fit: Range::lin(0.0, 4.0),
            limit: Limit::new(0.0, 8.0).natural_lo(),
        },
        ParamSpec { name: "r", doc: "Blob radius (m).", fit: Range::lin(0.04, 0.25), limit: Limit::new(0.02, 0.5).natural_lo() },
        ParamSpec {
            name: "a",
            doc: "Share of the way a partly covered cell moves down toward its lower neighbour along x (0: it keeps its height).",
            fit: Range::lin(0.0, 1.0),
            limit: Limit::new(0.0, 1.0).natural_lo().natural_hi(),
        },
    ],
    stage: Stage::Patches,
    // Per slot: whether it holds a blob, the blob's x, its y.
    draws: 3 * PATCH_SLOTS,
};

/// The jump of `edge-holes` and `rim-holes`: a natural end at 1 m, where
/// no jump of a DEM qualifies.
const JUMP: (Range, Limit) = (Range::lin(0.02, 0.3), Limit::new(0.005, 1.0).natural_hi());
/// The probability of `edge-holes` and `rim-holes`.
const LOST: (Range, Limit) = (Range::lin(0.0, 1.0), Limit::new(0.0, 1.0).natural_lo());

/// `edge-holes`: holes at the foot of height jumps.
pub const EDGE_HOLES: EffectSpec = EffectSpec {
    name: "edge-holes",
    family: Family::Holes,
    emulator: &["smoothing", "holes"],
    formula: "a valid cell whose valid 4-neighbour is higher by more than g is missing with probability p (the foot of a height jump)",
    params: &[
        ParamSpec { name: "g", doc: "Jump (m) above which the lower cell may be lost.", fit: JUMP.0, limit: JUMP.1 },
        ParamSpec { name: "p", doc: "Probability that such a cell is lost.", fit: LOST.0, limit: LOST.1 },
    ],
    stage: Stage::JumpHoles,
    // One per cell.
    draws: GRID_ROWS * COLS,
};

/// `rim-holes`: holes at the rim of height jumps.
pub const RIM_HOLES: EffectSpec = EffectSpec {
    name: "rim-holes",
    family: Family::Holes,
    emulator: &["smoothing", "holes"],
    formula: "a valid cell whose valid 4-neighbour is lower by more than g is missing with probability p (the rim of a height jump)",
    params: &[
        ParamSpec { name: "g", doc: "Jump (m) above which the higher cell may be lost.", fit: JUMP.0, limit: JUMP.1 },
        ParamSpec { name: "p", doc: "Probability that such a cell is lost.", fit: LOST.0, limit: LOST.1 },
    ],
    stage: Stage::JumpHoles,
    // One per cell.
    draws: GRID_ROWS * COLS,
};

/// `pit-fill`: narrow pits read as their rims.
pub const PIT_FILL: EffectSpec = EffectSpec {
    name: "pit-fill",
    family: Family::Holes,
    emulator: &["occlusion"],
    formula: "a valid cell lower by more than g than both valid neighbours of a line through it (rows r +- 1, or columns c +- 1) reads \
        the lower of the two with probability p",
    params: &[
        ParamSpec { name: "g", doc: "Depth (m) below both neighbours above which a cell is a pit.", fit: JUMP.0, limit: JUMP.1 },
        // Every pit filled (p = 1) is a natural end: no gap is ever seen.
        ParamSpec {
            name: "p",
            doc: "Probability that a pit is filled.",
            fit: Range::lin(0.0, 1.0),
            limit: Limit::new(0.0, 1.0).natural_lo().natural_hi(),
        },
    ],
    stage: Stage::PitFill,
    // One per cell.
    draws: GRID_ROWS * COLS,
};

/// `drop-holes`: holes at drop edges.
pub const DROP_HOLES: EffectSpec = EffectSpec {
    name: "drop-holes",
    family: Family::Holes,
    emulator: &["smoothing", "holes"],
    formula: "at a drop along x (valid cells of rows r and r + 1, row r + 1 lower by more than MIXED_JUMP), with probability p the \
        cell that holds the edge is missing: the lip (row r) or the floor (row r + 1), one of the two with equal chance (the \
        edge lies anywhere between their centres): the map cells over a drop edge get points from the lip and, as the view \
        moves, from the floor below it, outliers of the older ones; their variance grows past the map's threshold",
    // No drop edge lost, or every one: natural ends.
    params: &[ParamSpec {
        name: "p",
        doc: "Probability that the cell holding a drop's edge is lost.",
        fit: Range::lin(0.0, 1.0),
        limit: Limit::new(0.0, 1.0).natural_lo().natural_hi(),
    }],
    stage: Stage::JumpHoles,
    // Two per cell: whether the edge's cell is lost, and which of the two.
    draws: 2 * GRID_ROWS * COLS,
};

/// `hole-growth`: holes grow by thin cells at their edges.
pub const HOLE_GROWTH: EffectSpec = EffectSpec {
    name: "hole-growth",
    family: Family::Holes,
    emulator: &["smoothing", "holes"],
    formula: "a valid cell with k missing 4-neighbours (inside the grid) is missing with probability 1 - (1 - p)^k (the edge of a \
        hole, where a 10 cm cell holds fewer seen map cells than the two of four the map needs)",
    params: &[ParamSpec { name: "p", doc: "Probability per missing 4-neighbour that the cell is lost.", fit: RATE.0, limit: RATE.1 }],
    stage: Stage::HoleGrowth,
    // One per cell.
    draws: GRID_ROWS * COLS,
};

pub(super) fn check_patch_dropout(n: f64, r: f64, a: f64) -> Result<(), String> {
    if !(0.0..=PATCH_SLOTS as f64).contains(&n) || r < 0.0 || !(0.0..=1.0).contains(&a) {
        return Err(format!("n = {n} must be in [0, {PATCH_SLOTS}], r = {r} >= 0 and a = {a} in [0, 1]"));
    }
    Ok(())
}

/// `edge-holes`, `rim-holes` and `pit-fill`: the probability first.
pub(super) fn check_jump(g: f64, p: f64) -> Result<(), String> {
    probability(p)?;
    if g <= 0.0 {
        return Err(format!("g = {g} must be > 0"));
    }
    Ok(())
}

/// `dropout` (formula in its spec).
pub(super) fn drop_cells(d: &mut Dem, rng: &mut Draws, p: f64) {
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let u: f64 = rng.gen();
            if u < p && d.is_valid(r, c) {
                d.set_missing(r, c);
            }
        }
    }
}

/// `row-dropout` (formula in its spec).
pub(super) fn drop_rows(d: &mut Dem, rng: &mut Draws, p: f64) {
    for r in 0..GRID_ROWS {
        let u: f64 = rng.gen();
        if u < p {
            (0..COLS).for_each(|c| d.set_missing(r, c));
        }
    }
}

/// `pit-fill` (formula in its spec): pits are found on the DEM as it comes
/// in; a pit along both lines reads the higher of the two rims.
pub(super) fn fill_pits(d: &mut Dem, rng: &mut Draws, g: f64, p: f64) {
    let z = cell_heights(d);
    let at = |r: usize, c: usize| if r < GRID_ROWS && c < COLS { z[r][c] } else { None };
    for (r, row) in z.iter().enumerate() {
        for (c, &zc) in row.iter().enumerate() {
            let u: f64 = rng.gen();
            let Some(zc) = zc else { continue };
            let rims = [(at(r.wrapping_sub(1), c), at(r + 1, c)), (at(r, c.wrapping_sub(1)), at(r, c + 1))];
            let fill = rims.into_iter().filter_map(|(a, b)| Some(a?.min(b?))).filter(|&rim| rim - zc > g).reduce(f64::max);
            if let (Some(rim), true) = (fill, u < p) {
                d.set_valid(r, c, rim as f32);
            }
        }
    }
}

/// `patch-dropout` (formula in its spec). A DEM cell is the mean of its
/// four 5 cm map cells and needs two of them seen: a blob that covers three
/// or four quarter-cell centres loses the cell. One that covers one or two
/// leaves it fewer points, and beside a step the points it loses are the
/// ones that lifted it (the map keeps the higher of a frame's points in a
/// map cell, and a patch darkens the riser face and the edge with the
/// ground): the cell reads h + a (h_low - h), h_low its lower neighbour
/// along x that the blobs leave valid. Measured on the emulator
/// (`--no-dropout` against all stages): such cells move down, never up,
/// and only where that lower neighbour was seen.
pub(super) fn drop_patches(d: &mut Dem, rng: &mut Draws, n: f64, radius: f64, a: f64) {
    let (ylo, yhi) = (col_center_y(COLS - 1) - HALF, col_center_y(0) + HALF);
    let (xlo, xhi) = (row_center_x(0) - HALF, row_center_x(GRID_ROWS - 1) + HALF);
    let mut blobs = Vec::with_capacity(PATCH_SLOTS);
    for _ in 0..PATCH_SLOTS {
        let (u, s, t): (f64, f64, f64) = (rng.gen(), rng.gen(), rng.gen());
        if u < n / PATCH_SLOTS as f64 {
            // Centres anywhere a blob can touch the grid.
            blobs.push((xlo - radius + s * (xhi - xlo + 2.0 * radius), ylo - radius + t * (yhi - ylo + 2.0 * radius)));
        }
    }
    if !blobs.is_empty() {
        darken(d, &blobs, radius, a);
    }
}

/// The cells of `d` under dark blobs of `radius` centred at `blobs` (x, y):
/// see [`drop_patches`].
pub(super) fn darken(d: &mut Dem, blobs: &[(f64, f64)], radius: f64, a: f64) {
    let covered = |x: f64, y: f64| blobs.iter().any(|&(px, py)| (x - px).powi(2) + (y - py).powi(2) <= radius * radius);
    let seen: [[usize; COLS]; GRID_ROWS] = std::array::from_fn(|r| {
        std::array::from_fn(|c| {
            let (x, y) = (row_center_x(r), col_center_y(c));
            [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)]
                .into_iter()
                .filter(|&(sx, sy)| !covered(x + sx * HALF / 2.0, y + sy * HALF / 2.0))
                .count()
        })
    });
    // The heights the map still holds once the blobs are dark.
    let z: [[Option<f64>; COLS]; GRID_ROWS] =
        std::array::from_fn(|r| std::array::from_fn(|c| (d.is_valid(r, c) && seen[r][c] >= 2).then(|| d.height(r, c) as f64)));
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            match (z[r][c], seen[r][c]) {
                (None, _) => d.set_missing(r, c),
                (Some(_), 4) => {}
                (Some(h), _) => {
                    let low =
                        [r.checked_sub(1), Some(r + 1).filter(|&n| n < GRID_ROWS)].into_iter().filter_map(|n| z[n?][c]).fold(h, f64::min);
                    d.set_valid(r, c, (h + a * (low - h)) as f32);
                }
            }
        }
    }
}

/// `edge-holes` (`sign` 1: a neighbour higher by more than g) and
/// `rim-holes` (`sign` -1: lower by more than g): the cell is lost with
/// probability p.
pub(super) fn jump_holes(d: &mut Dem, rng: &mut Draws, g: f64, p: f64, sign: f64) {
    let z = cell_heights(d);
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let u: f64 = rng.gen();
            let Some(zc) = z[r][c] else { continue };
            let jump = neighbours4(r, c).any(|(rr, cc)| z[rr][cc].is_some_and(|zn| sign * (zn - zc) > g));
            if jump && u < p {
                d.set_missing(r, c);
            }
        }
    }
}

/// `drop-holes` (formula in its spec): drops are read on the DEM as it
/// comes in, so a lost lip makes no new drop. Two uniforms per row
/// boundary and column (the last row's pair unused): whether the edge's
/// cell is lost, and which of the two holds the edge.
pub(super) fn drop_holes(d: &mut Dem, rng: &mut Draws, p: f64) {
    let z = cell_heights(d);
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let (u, v): (f64, f64) = (rng.gen(), rng.gen());
            let (Some(lip), Some(floor)) = (z[r][c], z.get(r + 1).and_then(|row| row[c])) else { continue };
            if lip - floor > MIXED_JUMP && u < p {
                d.set_missing(if v < 0.5 { r } else { r + 1 }, c);
            }
        }
    }
}

/// `hole-growth`'s probability that a cell with `k` missing 4-neighbours is
/// lost, 1 - (1 - p)^k, as float32: the graph looks it up in the same table.
pub fn growth_threshold(p: f64, k: usize) -> f32 {
    (1.0 - (1.0 - p).powi(k as i32)) as f32
}

/// `hole-growth`: missing neighbours are counted on the DEM as it comes in,
/// so a hole grows by one ring of cells at most.
pub(super) fn grow_holes(d: &mut Dem, rng: &mut Draws, p: f64) {
    let z = cell_heights(d);
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let u: f64 = rng.gen();
            if z[r][c].is_none() {
                continue;
            }
            let k = neighbours4(r, c).filter(|&(rr, cc)| z[rr][cc].is_none()).count();
            if (u as f32) < growth_threshold(p, k) {
                d.set_missing(r, c);
            }
        }
    }
}
