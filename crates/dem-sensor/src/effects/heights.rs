//! Heights moved everywhere, by the range, the calibration or the pose:
//! `noise`, `bias`, `quantization`, `tilt`, `shake`, `lag`, `drift`.

use dem_core::format::{col_center_y, row_center_x, Dem, DemCells, COLS, GRID_ROWS};

use super::{cell_heights, EffectSpec, Family, Limit, ParamSpec, Range, Stage};
use crate::draws::Draws;

/// Where `noise` measures its range from: the nominal depth camera mount,
/// 0.15 m ahead of C and 0.45 m above it (x, z in metres).
pub const NOISE_ORIGIN: (f64, f64) = (0.15, 0.45);
/// The heights (m, either sign) beyond which `noise`'s range stops
/// growing: a cell 2 m above or below the robot is out of any DEM, and the
/// bound keeps every draw finite however many noise effects a model has.
pub const NOISE_RANGE_HEIGHT: f64 = 2.0;
/// Smallest `quantization` step (m): a tenth of a millimetre, finer than
/// any depth camera resolves at a metre, and large enough that h / q stays
/// far from float32's range.
pub const MIN_QUANTUM: f64 = 1e-4;
/// `quantization` rounds h / q up from this fraction of a step, not from
/// exactly a half: sim heights often lie on half steps, and there a
/// rounding error of 1e-7 would decide the step, differently in each
/// runtime. A thousandth of a step is far beyond rounding and far below
/// anything a sensor shows.
pub const ROUND_UP_FROM: f64 = 0.501;
/// Largest sd (rad) of `tilt`'s pitch and roll and of `shake`'s `sigma`:
/// a calibration or a body that far off (29 degrees) is no sensor effect.
pub const MAX_TILT: f64 = 0.5;
/// Largest `range` (m) of `tilt`: a depth camera's useful range.
pub const MAX_TILT_RANGE: f64 = 10.0;
/// The rows under the tracks whose x-neighbour steps `shake` reads: rows
/// 2..=9, centres from x = -0.35 to 0.35 m (tracks 0.7 m long about C).
pub const TRACK_ROWS: (usize, usize) = (2, 9);
/// `shake`'s step under the tracks is capped at this (m): a taller step is
/// no edge the tracks ride, and the cap keeps a stack of shakes finite.
pub const SHAKE_MAX_STEP: f64 = 0.5;
/// Largest `lag` shift `s` (m, either sign): a frame 2 s old at 0.25 m/s.
pub const MAX_LAG: f64 = 0.5;
/// Row shifts (`lag`, `drift`) are clamped to +-this many metres (10
/// rows): with `lag`'s box no shift reaches it; `drift` at absurd rates does.
pub const MAX_SHIFT: f64 = 1.0;
/// `lag` reads the record's pitch clamped to +-this (rad, 57 degrees).
pub const MAX_CLIMB_PITCH: f64 = 1.0;

/// `noise`: height noise growing with range.
pub const NOISE: EffectSpec = EffectSpec {
    name: "noise",
    family: Family::Heights,
    emulator: &["noise"],
    formula: "h += sigma z, z a standard normal (Box-Muller, crate::draws), sigma = sigma0 + k d^2, d = distance from the nominal \
        sensor mount NOISE_ORIGIN to the cell's centre at its height (clamped to +-NOISE_RANGE_HEIGHT)",
    params: &[
        ParamSpec { name: "sigma0", doc: "Noise at the sensor (m).", fit: Range::lin(0.0, 0.03), limit: Limit::new(0.0, 0.1).natural_lo() },
        ParamSpec {
            name: "k",
            doc: "Growth with squared range (1/m).",
            fit: Range::lin(0.0, 0.03),
            limit: Limit::new(0.0, 0.1).natural_lo(),
        },
    ],
    stage: Stage::Noise,
    // 50 Box-Muller pairs: one normal per cell.
    draws: GRID_ROWS * COLS,
};

/// `bias`: calibration offset and tilt.
pub const BIAS: EffectSpec = EffectSpec {
    name: "bias",
    family: Family::Heights,
    emulator: &[],
    formula: "h += b + t x",
    params: &[
        ParamSpec { name: "b", doc: "Offset (m).", fit: Range::lin(-0.1, 0.1), limit: Limit::new(-0.5, 0.5) },
        ParamSpec { name: "t", doc: "Tilt (m per m along x).", fit: Range::lin(-0.1, 0.1), limit: Limit::new(-0.5, 0.5) },
    ],
    stage: Stage::Registration,
    draws: 0,
};

/// `quantization`: heights rounded to multiples of q.
pub const QUANTIZATION: EffectSpec = EffectSpec {
    name: "quantization",
    family: Family::Heights,
    emulator: &[],
    formula: "h = q floor(h / q + ROUND_UP_FROM) (half steps round up, the same in every runtime)",
    params: &[ParamSpec { name: "q", doc: "Step (m).", fit: Range::log(0.002, 0.05), limit: Limit::new(0.0005, 0.2) }],
    stage: Stage::Quantization,
    draws: 0,
};

/// `tilt`: the camera's pitch and roll off their calibration.
pub const TILT: EffectSpec = EffectSpec {
    name: "tilt",
    family: Family::Heights,
    emulator: &["extrinsic"],
    formula: "per record a = `pitch` z1, b = `roll` z2 (z1, z2 standard normals, one Box-Muller pair; radians, used as slopes), h += a \
        (`range` + max(x, x0) - x0) + b y: the camera's pitch and roll off their calibration (the extrinsic error). A point seen \
        at horizontal range d moves by a d in height, and the map fuses each cell over the ranges it was seen from: a cell past \
        x0 was seen from `range` + (x - x0) on average, the cells behind x0 keep the error of their last views, so the whole DEM \
        rises or falls with the angle and tilts about a pivot `range` behind x0",
    // Sds of the camera's pitch and roll errors up to 3 degrees (0.05
    // rad); x0 from behind the grid (every row tilts) to 1 m ahead; the
    // lever at x0 from none to 4 m (a map fused from far views). No error
    // (sd 0) is a natural end; x0 behind the grid (every row tilts) or past
    // it (no row pitches) too, and no lever at x0.
    params: &[
        ParamSpec {
            name: "pitch",
            doc: "Sd (rad) of the pitch error.",
            fit: Range::lin(0.0, 0.05),
            limit: Limit::new(0.0, 0.2).natural_lo(),
        },
        ParamSpec {
            name: "roll",
            doc: "Sd (rad) of the roll error.",
            fit: Range::lin(0.0, 0.05),
            limit: Limit::new(0.0, 0.2).natural_lo(),
        },
        ParamSpec {
            name: "x0",
            doc: "Cells behind this x (m) keep the error of x0.",
            fit: Range::lin(-0.6, 1.0),
            limit: Limit::new(-0.6, 1.45).natural_lo().natural_hi(),
        },
        ParamSpec {
            name: "range",
            doc: "Mean horizontal range (m) from which the map's cells at x0 were seen: the lever of the angle there.",
            fit: Range::lin(0.0, 4.0),
            limit: Limit::new(0.0, 10.0).natural_lo(),
        },
    ],
    stage: Stage::Registration,
    // One Box-Muller pair.
    draws: 2,
};

/// `shake`: vibration, the body's pitch and roll noise, larger on edges.
pub const SHAKE: EffectSpec = EffectSpec {
    name: "shake",
    family: Family::Heights,
    emulator: &["vibration"],
    formula: "per record s = `sigma` + `edge` J, J the largest height step (m, capped at SHAKE_MAX_STEP) between valid x-neighbours of \
        the rows under the tracks (TRACK_ROWS, |x| <= 0.35 m) of the DEM as it comes in; a = s z1, b = s z2 (one Box-Muller \
        pair), h += a x + b y: the body rocks about C, more on edges. Unlike `tilt` it pivots at C (rows behind C move the other \
        way) and its spread follows the terrain under the tracks",
    // On even ground up to 1 degree; per metre of step under the tracks up
    // to 0.3 rad (a 0.2 m stair edge: 3.4 degrees more).
    params: &[
        ParamSpec { name: "sigma", doc: "Sd (rad) on even ground.", fit: Range::lin(0.0, 0.02), limit: Limit::new(0.0, 0.2).natural_lo() },
        ParamSpec {
            name: "edge",
            doc: "Extra sd per metre of step under the tracks (rad per m).",
            fit: Range::lin(0.0, 0.3),
            limit: Limit::new(0.0, 1.0).natural_lo(),
        },
    ],
    stage: Stage::Registration,
    // One Box-Muller pair.
    draws: 2,
};

/// `lag`: latency, the DEM is an older frame's map.
pub const LAG: EffectSpec = EffectSpec {
    name: "lag",
    family: Family::Heights,
    emulator: &["latency"],
    formula: "per record shift s_r = `s` (1 + `spread` (2u - 1)), u uniform; h'(x) = h(x - s_r) + s_r tan(pitch), pitch the record's \
        row 20 column 0 (clamped to +-MAX_CLIMB_PITCH, 0 if not finite): the DEM is the map of a frame s_r / v old, cut at that \
        older pose. See shift_rows for the interpolation; validity is kept",
    // Speed times latency: up to 0.15 m, spread from none to all of it. No
    // shift is a natural end, and a backward one is allowed (a robot
    // reversing); spread none or all: natural ends.
    params: &[
        ParamSpec {
            name: "s",
            doc: "Mean shift ahead (m): speed times latency.",
            fit: Range::lin(0.0, 0.15),
            limit: Limit::new(-0.3, 0.5).natural_lo(),
        },
        ParamSpec {
            name: "spread",
            doc: "Spread of the shift around s, as a share of s (0..1).",
            fit: Range::lin(0.0, 1.0),
            limit: Limit::new(0.0, 1.0).natural_lo().natural_hi(),
        },
    ],
    stage: Stage::Pose,
    draws: 1,
};

/// `drift`: pose drift, older rows displaced by a random walk.
pub const DRIFT: EffectSpec = EffectSpec {
    name: "drift",
    family: Family::Heights,
    emulator: &["drift"],
    formula: "rows whose centre x < `x0` are displaced by a random walk going back from x0: per row r, from the row just behind x0 \
        backward, dx(r) = `rate` sqrt(0.1) sum of xi_j and dz(r) = `zrate` sqrt(0.1) sum of zeta_j over the rows j from r to the \
        last row behind x0 (xi_j, zeta_j the normals of Box-Muller pair j); h'(x) = h(x - dx) + dz by shift_rows; rows from x0 \
        on are left alone: the map registers older frames at a believed pose that walks at random per metre travelled",
    // Walks up to 0.1 m per sqrt(m) along x, 0.05 in height; x0 as tilt's.
    params: &[
        ParamSpec {
            name: "rate",
            doc: "Sd of the x walk (m per sqrt(m) travelled).",
            fit: Range::lin(0.0, 0.1),
            limit: Limit::new(0.0, 1.0).natural_lo(),
        },
        ParamSpec {
            name: "zrate",
            doc: "Sd of the height walk (m per sqrt(m) travelled).",
            fit: Range::lin(0.0, 0.05),
            limit: Limit::new(0.0, 0.5).natural_lo(),
        },
        ParamSpec {
            name: "x0",
            doc: "Rows whose centre lies behind this x (m) are displaced.",
            fit: Range::lin(-0.6, 1.0),
            limit: Limit::new(-0.6, 1.45).natural_lo().natural_hi(),
        },
    ],
    stage: Stage::Pose,
    // A Box-Muller pair per row: its x and its height step.
    draws: 2 * GRID_ROWS,
};

pub(super) fn check_noise(sigma0: f64, k: f64) -> Result<(), String> {
    if sigma0 < 0.0 || k < 0.0 {
        return Err("sigma0 and k must be >= 0".into());
    }
    Ok(())
}

pub(super) fn check_quantization(q: f64) -> Result<(), String> {
    if q < MIN_QUANTUM {
        return Err(format!("q = {q:e} must be >= {MIN_QUANTUM:e} m"));
    }
    Ok(())
}

pub(super) fn check_tilt(pitch: f64, roll: f64, range: f64) -> Result<(), String> {
    if !(0.0..=MAX_TILT).contains(&pitch) || !(0.0..=MAX_TILT).contains(&roll) {
        return Err(format!("pitch = {pitch} and roll = {roll} must be in [0, {MAX_TILT}] rad"));
    }
    if !(0.0..=MAX_TILT_RANGE).contains(&range) {
        return Err(format!("range = {range} must be in [0, {MAX_TILT_RANGE}] m"));
    }
    Ok(())
}

pub(super) fn check_shake(sigma: f64, edge: f64) -> Result<(), String> {
    if !(0.0..=MAX_TILT).contains(&sigma) || edge < 0.0 {
        return Err(format!("sigma = {sigma} must be in [0, {MAX_TILT}] rad and edge = {edge} >= 0"));
    }
    Ok(())
}

pub(super) fn check_lag(s: f64, spread: f64) -> Result<(), String> {
    if s.abs() > MAX_LAG || !(0.0..=1.0).contains(&spread) {
        return Err(format!("s = {s} must be in [-{MAX_LAG}, {MAX_LAG}] m and spread = {spread} in [0, 1]"));
    }
    Ok(())
}

pub(super) fn check_drift(rate: f64, zrate: f64) -> Result<(), String> {
    if rate < 0.0 || zrate < 0.0 {
        return Err(format!("rate = {rate} and zrate = {zrate} must be >= 0"));
    }
    Ok(())
}

/// `noise` (formula in its spec).
pub(super) fn add_noise(d: &mut Dem, rng: &mut Draws, sigma0: f64, k: f64) {
    let (sx, sz) = NOISE_ORIGIN;
    let normals: [f64; GRID_ROWS * COLS] = rng.normals();
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let z = normals[r * COLS + c];
            if d.is_valid(r, c) {
                let h = d.height(r, c) as f64;
                let (dx, dy, dz) = (row_center_x(r) - sx, col_center_y(c), h.clamp(-NOISE_RANGE_HEIGHT, NOISE_RANGE_HEIGHT) - sz);
                let sigma = sigma0 + k * (dx * dx + dy * dy + dz * dz);
                d.set_valid(r, c, (h + sigma * z) as f32);
            }
        }
    }
}

/// `bias` (formula in its spec).
pub(super) fn offset(d: &mut Dem, b: f64, t: f64) {
    for r in 0..GRID_ROWS {
        let off = b + t * row_center_x(r);
        for c in 0..COLS {
            if d.is_valid(r, c) {
                d.set_valid(r, c, (d.height(r, c) as f64 + off) as f32);
            }
        }
    }
}

/// `quantization` (formula in its spec).
pub(super) fn quantize(d: &mut Dem, q: f64) {
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            if d.is_valid(r, c) {
                // In float32, the graph's arithmetic: the same rounding everywhere.
                let (h, q) = (d.height(r, c), q as f32);
                d.set_valid(r, c, q * (h / q + ROUND_UP_FROM as f32).floor());
            }
        }
    }
}

/// `tilt` (formula in its spec).
pub(super) fn tilt(d: &mut Dem, rng: &mut Draws, pitch: f64, roll: f64, x0: f64, range: f64) {
    let [z1, z2]: [f64; 2] = rng.normals();
    tilt_plane(d, pitch * z1, roll * z2, |x| range + x.max(x0) - x0);
}

/// `shake` (formula in its spec).
pub(super) fn shake(d: &mut Dem, rng: &mut Draws, sigma: f64, edge: f64) {
    let [z1, z2]: [f64; 2] = rng.normals();
    let s = sigma + edge * step_under_tracks(d);
    tilt_plane(d, s * z1, s * z2, |x| x);
}

/// `lag` (formula in its spec).
pub(super) fn lag(d: &mut Dem, rng: &mut Draws, s: f64, spread: f64) {
    let shift = s * (1.0 + spread * (2.0 * rng.gen() - 1.0));
    let climb = shift * climb_slope(d);
    shift_rows(d, &[shift; GRID_ROWS], &[climb; GRID_ROWS]);
}

/// `drift` (formula in its spec).
pub(super) fn drift(d: &mut Dem, rng: &mut Draws, rate: f64, zrate: f64, x0: f64) {
    let z: [f64; 2 * GRID_ROWS] = rng.normals();
    let (dx, dz) = drift_walk(&z, rate, zrate, x0);
    shift_rows(d, &dx, &dz);
}

/// h += a lever(x) + b y on the valid cells (`tilt`, `shake`).
fn tilt_plane(d: &mut Dem, a: f64, b: f64, lever: impl Fn(f64) -> f64) {
    for r in 0..GRID_ROWS {
        let ax = a * lever(row_center_x(r));
        for c in 0..COLS {
            if d.is_valid(r, c) {
                d.set_valid(r, c, (d.height(r, c) as f64 + ax + b * col_center_y(c)) as f32);
            }
        }
    }
}

/// `shake`'s J: the largest height step (m) between valid x-neighbours of
/// the rows under the tracks ([`TRACK_ROWS`]), at most [`SHAKE_MAX_STEP`];
/// 0 when no such pair is valid.
pub fn step_under_tracks(d: &Dem) -> f64 {
    let mut j: f64 = 0.0;
    for r in TRACK_ROWS.0..TRACK_ROWS.1 {
        for c in 0..COLS {
            if d.is_valid(r, c) && d.is_valid(r + 1, c) {
                j = j.max((d.height(r + 1, c) as f64 - d.height(r, c) as f64).abs());
            }
        }
    }
    j.min(SHAKE_MAX_STEP)
}

/// `lag`'s climb per metre of shift: tan of the record's pitch (row 20,
/// column 0), clamped to +-[`MAX_CLIMB_PITCH`]; 0 when it is not finite.
pub fn climb_slope(d: &Dem) -> f64 {
    let p = d.attitude()[0] as f64;
    if p.is_finite() {
        p.clamp(-MAX_CLIMB_PITCH, MAX_CLIMB_PITCH).tan()
    } else {
        0.0
    }
}

/// `drift`'s displacements per row from its 40 normals (pair j: `z[2j]`
/// along x, `z[2j + 1]` in height): cumulative sums going back from the
/// last row whose centre lies behind `x0`, one step of sd rate sqrt(0.1)
/// (zrate sqrt(0.1)) per row; 0 for the rows from x0 on.
pub fn drift_walk(z: &[f64; 2 * GRID_ROWS], rate: f64, zrate: f64, x0: f64) -> ([f64; GRID_ROWS], [f64; GRID_ROWS]) {
    let step = dem_core::format::CELL.sqrt();
    let (mut dx, mut dz) = ([0.0; GRID_ROWS], [0.0; GRID_ROWS]);
    let (mut sx, mut sz) = (0.0, 0.0);
    for r in (0..GRID_ROWS).rev().filter(|&r| row_center_x(r) < x0) {
        sx += rate * step * z[2 * r];
        sz += zrate * step * z[2 * r + 1];
        dx[r] = sx;
        dz[r] = sz;
    }
    (dx, dz)
}

/// Row `r` of every column reads the column at x - dx[r], plus dz[r]
/// (`lag`, `drift`), on the valid cells; validity is kept. With q = dx / 0.1
/// (in rows, clamped to +-[`MAX_SHIFT`] / 0.1), m = floor(q), g = q - m:
/// h' = (1 - g) src(r - m) + g src(r - m - 1) + dz, where src(k) is row k's
/// height when row k lies in the grid and is valid there, else the cell's
/// own height (nothing seen there: the cell keeps what it had; row 0 keeps
/// its value when nothing lies behind). The same as weights max(0, 1 - |q -
/// m|) on src(r - m) for every integer m, as the graph computes it:
/// continuous in dx, so no runtime's rounding of q decides a cell.
pub fn shift_rows(d: &mut Dem, dx: &[f64; GRID_ROWS], dz: &[f64; GRID_ROWS]) {
    let z = cell_heights(d);
    let lim = MAX_SHIFT / dem_core::format::CELL;
    for r in 0..GRID_ROWS {
        let q = (dx[r] / dem_core::format::CELL).clamp(-lim, lim);
        let m = q.floor();
        let g = q - m;
        let k = r as i64 - m as i64;
        for (c, own) in z[r].iter().enumerate() {
            let Some(own) = *own else { continue };
            let src = |k: i64| usize::try_from(k).ok().filter(|&k| k < GRID_ROWS).and_then(|k| z[k][c]).unwrap_or(own);
            let h = (1.0 - g) * src(k) + g * src(k - 1);
            d.set_valid(r, c, (h + dz[r]) as f32);
        }
    }
}
