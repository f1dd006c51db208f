//! `mixed-cells`: cells that straddle a step read part of the way up or down.

use crate::draws::Draws;
use crate::effects::{cell_heights, params, EffectKind, EffectSpec, Family, Limit, Range, Stage, MIXED_JUMP};
use crate::evidence::{mid, pct, Context};
use crate::graph::ops::{is_valid, set_heights, Cells, FAR, HALF};
use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Cells that straddle a step read part of the way up or down: a DEM
    /// cell is the mean of finer map cells, and a map cell holding a step
    /// keeps the higher surface (lower points hide under tops; the ground
    /// just beyond a drop edge is hidden by the edge).
    #[serde(expecting = "struct variant Effect::MixedCells")]
    MixedCells {
        // Reaches from none (the halves' mean alone) to a whole cell. Past
        // 0.2 m the surface reaches past the far half of the lower cell
        // whatever the step's place: larger reaches change nothing.
        /// How far (m, at most) a riser's top reaches back into the lower cell in front of it.
        up: fit Range::lin(0.0, 0.15), limit Limit::new(0.0, 0.2).natural_lo().natural_hi();
        /// How far (m, at most) a drop edge's top reaches on into the lower cell beyond it.
        down: fit Range::lin(0.0, 0.15), limit Limit::new(0.0, 0.2).natural_lo().natural_hi();
    }
}

impl EffectKind for MixedCells {
    const SPEC: EffectSpec = EffectSpec {
        name: "mixed-cells",
        family: Family::Steps,
        emulator: &["occlusion", "smoothing"],
        formula: "a cell is the mean of its two half cells along x; at a jump of more than MIXED_JUMP between valid x-neighbours the step \
            lies at s, uniform over the 10 cm between their centres (one draw per row boundary), and the higher surface reaches e = \
            u r past it into the lower cell (u uniform per cell; r = `up` when the higher cell lies ahead, `down` when it lies \
            behind, i.e. beyond a drop): a half of the lower cell whose centre the higher surface reaches reads the higher height, a \
            half of the higher cell the lower surface reaches (the step lies in it, deeper than e) reads the lower height",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::MixedCells,
        // Per row boundary a step position, then a reach per column.
        draws: (GRID_ROWS - 1) * (1 + COLS),
    };

    fn check(&self) -> Result<(), String> {
        let Self { up, down } = *self;
        check_mixed_cells(up, down)
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, _time: Option<f64>) {
        let Self { up, down } = *self;
        mix_cells(d, rng, up, down)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, _time: Option<&str>) -> Cells {
        let Self { up, down } = *self;
        operators(b, c, u, up, down)
    }

    fn evidence(&self, c: &Context) -> String {
        sentence(c)
    }

    fn examples() -> Vec<Self> {
        vec![MixedCells { up: 0.04, down: 0.06 }]
    }
}

fn check_mixed_cells(up: f64, down: f64) -> Result<(), String> {
    if up < 0.0 || down < 0.0 {
        return Err(format!("up = {up} and down = {down} must be >= 0"));
    }
    Ok(())
}

/// `mixed-cells` (formula in its spec). Each cell is two halves along x,
/// back (toward row r - 1) and front; a half's centre lies [`HALF`] / 2
/// from its cell's boundary, the other half's 3/2 [`HALF`]. Where
/// neighbours both reach a half, the higher surface wins, as in a map cell
/// that keeps the higher of two heights.
fn mix_cells(d: &mut Dem, rng: &mut Draws, up: f64, down: f64) {
    let z = cell_heights(d);
    // Per half: the height the higher neighbour spills in, the lower one's.
    let mut raise = [[[f64::NEG_INFINITY; 2]; COLS]; GRID_ROWS];
    let mut lower = [[[f64::INFINITY; 2]; COLS]; GRID_ROWS];
    let (near, far) = (0.5 * HALF, 1.5 * HALF);
    // Every decision (the jump, the reach past each half's centre) in
    // float32, operation for operation as the graph takes it, so that a
    // jump of exactly MIXED_JUMP or a reach exactly at a centre is decided
    // alike in every runtime; the heights moved are the same either way.
    let (near, far) = (near as f32, far as f32);
    for b in 0..GRID_ROWS - 1 {
        // The step's distance past the boundary into row b (negative: into b + 1).
        let s = rng.gen() as f32 * (-2.0 * HALF) as f32 + HALF as f32;
        for c in 0..COLS {
            let u = rng.gen() as f32;
            let (Some(z0), Some(z1)) = (z[b][c], z[b + 1][c]) else { continue };
            let dz = z1 as f32 - z0 as f32;
            if dz.abs() <= MIXED_JUMP as f32 {
                continue;
            }
            // (lower row, its half at the boundary, higher row, its half, step depth into the lower row)
            let (lo, lo_half, hi, hi_half, depth, reach) =
                if dz > 0.0 { (b, 1, b + 1, 0, s, up as f32) } else { (b + 1, 0, b, 1, -s, down as f32) };
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

/// `mixed-cells`: per row boundary a step position s and per column a
/// reach; each half cell takes the higher surface that reaches it, else the
/// lower one, else its own height; the cell is the mean of its halves.
fn operators(b: &mut Builder, c: &Cells, u: &str, up: f64, down: f64) -> Cells {
    let (rows, cols) = (GRID_ROWS as i64, COLS as i64);
    let bounds = rows - 1;
    let u = b.reshape(u, &[-1, bounds, 1 + cols]);
    let s = b.take(&u, 2, 0, 1);
    let reach_u = b.take(&u, 2, 1, 1 + cols);
    // s = (1 - 2 u) HALF, the step's distance past the boundary into row b.
    let s = b.mul_const(&s, (-2.0 * HALF) as f32);
    let s = b.add_const(&s, HALF as f32);
    let z0 = b.take(&c.h, 1, 0, bounds);
    let z1 = b.take(&c.h, 1, 1, rows);
    let v0 = b.take(&c.v, 1, 0, bounds);
    let v1 = b.take(&c.v, 1, 1, rows);
    let v0 = is_valid(b, &v0);
    let v1 = is_valid(b, &v1);
    let dz = b.bin("Sub", &z1, &z0);
    let adz = b.un("Abs", &dz);
    let big = b.gt_const(&adz, MIXED_JUMP as f32);
    let jump = b.all(&[&v0, &v1, &big]);
    let riser = b.gt_const(&dz, 0.0);
    let drop = b.un("Not", &riser);
    let minus_s = b.un("Neg", &s);
    let depth = b.select(&riser, &s, &minus_s);
    let (upc, downc) = (b.scalar(up as f32), b.scalar(down as f32));
    let reach = b.select(&riser, &upc, &downc);
    let into = b.bin("Mul", &reach_u, &reach);
    let into = b.bin("Add", &depth, &into);
    let out_of = b.un("Neg", &into);
    let zhi = b.bin("Max", &z0, &z1);
    let zlo = b.bin("Min", &z0, &z1);
    let (near, far) = ((0.5 * HALF) as f32, (1.5 * HALF) as f32);
    let a_near = b.gt_const(&into, near);
    let a_far = b.gt_const(&into, far);
    let b_near = b.gt_const(&out_of, near);
    let b_far = b.gt_const(&out_of, far);
    let cond = |b: &mut Builder, kind: &str, reach: &str| b.all(&[&jump, kind, reach]);
    // Boundary b's upper row is b (its half 1 is near), its lower row b + 1
    // (its half 0 is near). (raise, lower) conditions per half.
    let top = [
        // half 0 of row b: far from boundary b
        (cond(b, &riser, &a_far), cond(b, &drop, &b_far)),
        // half 1 of row b: near
        (cond(b, &riser, &a_near), cond(b, &drop, &b_near)),
    ];
    let bottom = [
        // half 0 of row b + 1: near
        (cond(b, &drop, &a_near), cond(b, &riser, &b_near)),
        // half 1 of row b + 1: far
        (cond(b, &drop, &a_far), cond(b, &riser, &b_far)),
    ];
    let (lowest, highest) = (b.scalar(-FAR), b.scalar(FAR));
    // Place a boundary's (N, 19, 5) tensor on the grid's rows: as the upper
    // row (pad at the end) or the lower row (pad at the start).
    let place = |b: &mut Builder, x: &str, upper: bool, fill: f32| {
        let pads = if upper { [0, 0, 0, 0, 1, 0] } else { [0, 1, 0, 0, 0, 0] };
        let pads = b.ints(&pads);
        let fill = b.scalar(fill);
        b.op("Pad", &[x, &pads, &fill], vec![])
    };
    let mut halves = Vec::new();
    for half in 0..2 {
        let mut raise = Vec::new();
        let mut lower = Vec::new();
        for (upper, (r_cond, l_cond)) in [(true, &top[half]), (false, &bottom[half])] {
            let r = b.select(r_cond, &zhi, &lowest);
            raise.push(place(b, &r, upper, -FAR));
            let l = b.select(l_cond, &zlo, &highest);
            lower.push(place(b, &l, upper, FAR));
        }
        let raise = b.bin("Max", &raise[0], &raise[1]);
        let lower = b.bin("Min", &lower[0], &lower[1]);
        let raised = b.gt_const(&raise, -FAR / 2.0);
        let lowered = b.lt_const(&lower, FAR / 2.0);
        let x = b.select(&lowered, &lower, &c.h);
        halves.push(b.select(&raised, &raise, &x));
    }
    let sum = b.bin("Add", &halves[0], &halves[1]);
    let mean = b.mul_const(&sum, 0.5);
    let valid = is_valid(b, &c.v);
    set_heights(b, c, &valid, &mean)
}

/// The evidence for `mixed-cells`.
fn sentence(c: &Context) -> String {
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
