//! A fused map's memory: the noise a cell shows follows the ground it sees.
//!
//! A Kalman elevation map keeps each cell's estimate and moves it with the
//! robot, and a new frame only nudges it, so over the same ground the map's
//! error changes slowly. `noise` with `tau > 0` models that: the normal of
//! a cell is no longer the record's own draw but a value of the ground cell
//! under it (the 10 cm world cell of its centre, from the labels' pose), an
//! Ornstein-Uhlenbeck process in the run's time (unit variance,
//! correlation `exp(-|dt| / tau)` at lag `dt`), as an AR(1) map update gives.
//!
//! Its value at any time is computed from hashed normals alone, so it is the
//! same whichever record, shard or order asks for it:
//!
//! ```text
//! lattice     v(k) = c sum_{j < TERMS} e^-j n(k - j)          values at t = k tau, corr(v(k), v(k+1)) = e^-1
//! bisection   x(mid) | x(lo), x(hi) ~ N(r1 (x(lo) + x(hi)) / (1 + r2), (1 - r2) / (1 + r2)),
//!             r1 = exp(-L / 2 tau), r2 = r1^2, L = hi - lo        LEVELS times towards t
//! ```
//!
//! The bisection is the process's exact conditional law (it is Markov), so
//! the value at `t` is exact to `tau / 2^LEVELS`, below which it is
//! interpolated (a variance short by at most `2^-LEVELS / 2`, 0.4 %): exact
//! at every frame rate. The hashed normals are the ziggurat's
//! ([`rand_distr::StandardNormal`]) over a SplitMix64 stream seeded by the
//! hash: a few nanoseconds each, since dem-gap redraws them for every time
//! constant it tries. The normals are handed to the
//! graph as the uniforms its Box-Muller turns back into them
//! ([`uniforms_of_normals`]): the graph is the same with or without memory.

use dem_core::format::{col_center_y, row_center_x, CELL, COLS, GRID_BACK, GRID_ROWS};
use dem_core::seeded::mix;

use rand::RngCore;
use rand_distr::{Distribution, StandardNormal};

/// Terms of a lattice value's moving average: a weight of e^-2 TERMS
/// (0.03 % of the variance) is left out.
const TERMS: usize = 4;
/// Bisections between lattice values: exact to tau / 128.
const LEVELS: usize = 7;

/// A robot's pose in its run, from the labels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Position in the world (m).
    pub x: f64,
    /// Position in the world (m).
    pub y: f64,
    /// Heading in the world (rad).
    pub yaw: f64,
    /// Metres along the run's path since its first record (the labels'
    /// poses in time order); NaN where the run or the times are unknown.
    pub travelled: f64,
}

/// The cell normals (`GRID_ROWS x COLS`, row-major) of a map of memory
/// `tau` (s) at `time` (s) in a run, for a robot at `pose`; `key` keys the
/// effect and run (seed, effect, occurrence, run).
pub fn ground_normals(key: u64, tau: f64, time: f64, pose: Pose) -> [f64; GRID_ROWS * COLS] {
    let s = time / tau;
    let k = s.floor();
    let (k, w) = (k as i64, s - k);
    let (sin, cos) = pose.yaw.sin_cos();
    let mut z = [0.0; GRID_ROWS * COLS];
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let (x, y) = (row_center_x(r), col_center_y(c));
            let gx = ((pose.x + cos * x - sin * y) / CELL).floor() as i64;
            let gy = ((pose.y + sin * x + cos * y) / CELL).floor() as i64;
            let cell = mix(key ^ mix(gx as u64 ^ mix(gy as u64)));
            z[r * COLS + c] = at_time(cell, k, w);
        }
    }
    z
}

/// The process of ground cell `cell` at `(k + w) tau`, `w` in [0, 1).
fn at_time(cell: u64, k: i64, w: f64) -> f64 {
    let a = (-1.0f64).exp();
    let unit = ((1.0 - a * a) / (1.0 - a.powi(2 * TERMS as i32))).sqrt();
    // v(k) reads n(k - j) for j < TERMS, v(k + 1) n(k + 1 - j).
    let (mut lo_x, mut hi_x, mut weight) = (0.0, 0.0, 1.0);
    for j in 0..=TERMS as i64 {
        let n = hashed_normal(cell, k + 1 - j, 0);
        if j < TERMS as i64 {
            hi_x += weight * n;
        }
        if j >= 1 {
            lo_x += weight / a * n;
        }
        weight *= a;
    }
    let (mut lo_x, mut hi_x) = (unit * lo_x, unit * hi_x);
    let (mut lo, mut hi, mut node) = (0.0f64, 1.0f64, 1u64);
    for level in bisection_levels() {
        let mid = 0.5 * (lo + hi);
        let x = level.mean * (lo_x + hi_x) + level.sd * hashed_normal(cell, k, node);
        if w < mid {
            (hi, hi_x, node) = (mid, x, 2 * node);
        } else {
            (lo, lo_x, node) = (mid, x, 2 * node + 1);
        }
    }
    let f = (w - lo) / (hi - lo);
    (1.0 - f) * lo_x + f * hi_x
}

/// The conditional law of a bisection level (an interval of `L = 2^-level`
/// lattice spans): the midpoint's mean is `mean (x(lo) + x(hi))`, its
/// deviation `sd`.
#[derive(Clone, Copy)]
struct Level {
    mean: f64,
    sd: f64,
}

/// The [`Level`]s of the bisection, coarsest first.
fn bisection_levels() -> &'static [Level; LEVELS] {
    static LEVELS_OF: std::sync::OnceLock<[Level; LEVELS]> = std::sync::OnceLock::new();
    LEVELS_OF.get_or_init(|| {
        std::array::from_fn(|level| {
            let r1 = (-0.5 * 0.5f64.powi(level as i32)).exp();
            let r2 = r1 * r1;
            Level { mean: r1 / (1.0 + r2), sd: ((1.0 - r2) / (1.0 + r2)).sqrt() }
        })
    })
}

/// `drift`'s normals for a record `travelled` metres along its run's path
/// (`2 GRID_ROWS`: row `j`'s x step, then its height step): the increments
/// of two Brownian walks in the path travelled, in cells, over the span of
/// path under row `j`. The walk `drift` sums from x0 back to a row is then
/// the walk between the pose of now and the pose the ground under the row
/// was seen from: the same ground keeps its displacement from one frame to
/// the next and it grows as the robot travels on, as a map fused at a
/// drifting believed pose does. `key` keys the effect and run.
pub fn path_steps(key: u64, travelled: f64) -> [f64; 2 * GRID_ROWS] {
    let q = (travelled + GRID_BACK) / CELL;
    let k = q.floor();
    let (k, f) = (k as i64, q - k);
    let mut z = [0.0; 2 * GRID_ROWS];
    for (walk, key) in [mix(key ^ 1), mix(key ^ 2)].into_iter().enumerate() {
        // The walk from lattice point i to i + f: its increment's share plus
        // a Brownian bridge pinned at both ends.
        let partial = |i: i64| f * hashed_normal(key, i, 0) + bridge(key, i, f);
        let mut start = partial(k);
        for j in 0..GRID_ROWS as i64 {
            let end = partial(k + j + 1);
            z[2 * j as usize + walk] = hashed_normal(key, k + j, 0) - start + end;
            start = end;
        }
    }
    z
}

/// A Brownian bridge on [0, 1], pinned at 0 at both ends, at `f`: keyed
/// by `key` and lattice point `i`, exact to 2^-LEVELS by bisection.
fn bridge(key: u64, i: i64, f: f64) -> f64 {
    let (mut lo, mut hi, mut lo_x, mut hi_x, mut node) = (0.0f64, 1.0f64, 0.0, 0.0, 1u64);
    for level in 0..LEVELS {
        let mid = 0.5 * (lo + hi);
        let x = 0.5 * (lo_x + hi_x) + 0.5f64.powi(level as i32 + 2).sqrt() * hashed_normal(key, i, node);
        if f < mid {
            (hi, hi_x, node) = (mid, x, 2 * node);
        } else {
            (lo, lo_x, node) = (mid, x, 2 * node + 1);
        }
    }
    lo_x + (f - lo) / (hi - lo) * (hi_x - lo_x)
}

/// A standard normal keyed by a ground cell, a lattice point and a node of
/// its bisection (0: the lattice value's own).
fn hashed_normal(cell: u64, lattice: i64, node: u64) -> f64 {
    StandardNormal.sample(&mut SplitMix64(mix(cell ^ mix(lattice as u64 ^ mix(node)))))
}

/// SplitMix64 (Steele, Lea and Flood 2014), the stream a hashed normal's
/// ziggurat reads: one or two words almost always.
struct SplitMix64(u64);

impl RngCore for SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        // `mix` is SplitMix64's step and output function.
        let z = mix(self.0);
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z
    }

    fn next_u32(&mut self) -> u32 {
        (self.next_u64() >> 32) as u32
    }

    fn fill_bytes(&mut self, dest: &mut [u8]) {
        for chunk in dest.chunks_mut(8) {
            let bytes = self.next_u64().to_le_bytes();
            chunk.copy_from_slice(&bytes[..chunk.len()]);
        }
    }

    fn try_fill_bytes(&mut self, dest: &mut [u8]) -> Result<(), rand::Error> {
        self.fill_bytes(dest);
        Ok(())
    }
}

/// The uniforms whose Box-Muller pairs ([`crate::draws`]) are `z`, pair
/// after pair: `u1 = 1 - exp(-(z1^2 + z2^2) / 2)`, `u2 = atan2(z2, z1) / 2 pi`
/// (mod 1), each on the 24-bit lattice of a uniform.
pub fn uniforms_of_normals(z: &[f64], out: &mut [f32]) {
    assert_eq!(z.len(), out.len(), "uniforms_of_normals: wrong length");
    const TOP: f64 = 16_777_215.0 / 16_777_216.0;
    let lattice = |u: f64| ((u * 16_777_216.0).round() / 16_777_216.0).clamp(0.0, TOP) as f32;
    for (z, u) in z.chunks(2).zip(out.chunks_mut(2)) {
        let (z1, z2) = (z[0], z.get(1).copied().unwrap_or(0.0));
        u[0] = lattice(-(-(z1 * z1 + z2 * z2) / 2.0).exp_m1());
        if u.len() > 1 {
            u[1] = lattice(z2.atan2(z1).rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::draws::box_muller;

    /// The robot at `x` on the world's x axis, heading along it.
    fn at(x: f64) -> Pose {
        Pose { x, y: 0.0, yaw: 0.0, travelled: x }
    }

    #[test]
    fn normals_come_back_through_box_muller() {
        let z: Vec<f64> = (0..100).map(|i| ((i as f64) * 0.37).sin() * 2.5).collect();
        let mut u = vec![0.0f32; 100];
        uniforms_of_normals(&z, &mut u);
        for (p, u) in z.chunks(2).zip(u.chunks(2)) {
            let (a, b) = box_muller(u[0], u[1]);
            assert!((a - p[0]).abs() < 2e-3 && (b - p[1]).abs() < 2e-3, "{p:?} -> {a} {b}");
        }
        assert!(u.iter().all(|&x| (0.0..1.0).contains(&x) && (x * 16_777_216.0).fract() == 0.0));
    }

    /// Over the same ground the process is unit normal and correlates as a
    /// first-order process, exp(-dt / tau) at lag dt, short lags too, and
    /// its mean change is a normal's of that correlation.
    #[test]
    fn the_ground_s_noise_is_a_first_order_process_in_time() {
        let tau = 0.8;
        let lags = [0.033, 0.1, 0.8, 2.4];
        let (mut s, mut ss, mut lag, mut change) = (0.0, 0.0, [0.0; 4], [0.0; 4]);
        let n = 4000;
        for i in 0..n {
            // Many runs' ground: every tenth sample a new stretch of it.
            let (t, pose) = (i as f64 * 0.37, at((i / 10) as f64 * 5.0));
            let z0 = ground_normals(11, tau, t, pose);
            s += z0.iter().sum::<f64>();
            ss += z0.iter().map(|v| v * v).sum::<f64>();
            for ((l, d), dt) in lag.iter_mut().zip(&mut change).zip(lags) {
                let z1 = ground_normals(11, tau, t + dt, pose);
                *l += z0.iter().zip(&z1).map(|(a, b)| a * b).sum::<f64>();
                *d += z0.iter().zip(&z1).map(|(a, b)| (a - b).abs()).sum::<f64>();
            }
        }
        let m = (n * GRID_ROWS * COLS) as f64;
        assert!((s / m).abs() < 0.02 && (ss / m - 1.0).abs() < 0.03, "mean {} var {}", s / m, ss / m);
        for ((l, d), dt) in lag.iter().zip(change).zip(lags) {
            let want = (-dt / tau).exp();
            assert!((l / m - want).abs() < 0.03, "lag {dt}: {} against {want}", l / m);
            let mean_change = (2.0 * (1.0 - want)).sqrt() * (2.0 / std::f64::consts::PI).sqrt();
            assert!((d / m / mean_change - 1.0).abs() < 0.06, "lag {dt}: mean change {} against {mean_change}", d / m);
        }
    }

    /// The robot moved one cell ahead: a cell sees the ground the cell in
    /// front of it saw, and its noise moves with it.
    #[test]
    fn the_noise_moves_with_the_ground() {
        let z0 = ground_normals(5, 1.0, 3.0, at(0.0));
        let z1 = ground_normals(5, 1.0, 3.0, at(CELL));
        for r in 0..GRID_ROWS - 1 {
            for c in 0..COLS {
                assert_eq!(z1[r * COLS + c], z0[(r + 1) * COLS + c]);
            }
        }
        let other_run = ground_normals(6, 1.0, 3.0, at(0.0));
        assert!(z0.iter().zip(&other_run).filter(|(a, b)| a == b).count() < 2);
    }

    /// drift's steps: unit normals, independent across rows and walks, and
    /// the walk from x0 back to a ground patch is the Brownian walk between
    /// the path points: one cell on, the rows' sums are the same ground's
    /// plus one new step, and part of a cell on, its variance grows by the
    /// part travelled.
    #[test]
    fn drift_s_steps_walk_with_the_path_travelled() {
        let n = 3000u64;
        let (mut ss, mut cross, mut grow) = (0.0, 0.0, 0.0);
        for run in 0..n {
            let key = mix(run);
            let (a, b) = (path_steps(key, 1.234), path_steps(key, 1.234 + 0.04));
            ss += a.iter().map(|v| v * v).sum::<f64>();
            cross += a.chunks(2).map(|p| p[0] * p[1]).sum::<f64>() + a.windows(2).map(|w| w[0] * w[1]).sum::<f64>();
            // Rows 0..=9 summed: the walk over the path under them.
            let sum = |z: &[f64; 2 * GRID_ROWS]| (0..10).map(|j| z[2 * j]).sum::<f64>();
            grow += (sum(&b) - sum(&a)).powi(2);
            let c = path_steps(key, 1.234 + CELL);
            for j in 0..GRID_ROWS - 1 {
                assert!((c[2 * j] - a[2 * j + 2]).abs() < 1e-12, "one cell on, row {j} reads the next row's ground");
            }
        }
        let m = (n as usize * 2 * GRID_ROWS) as f64;
        assert!((ss / m - 1.0).abs() < 0.03, "variance {}", ss / m);
        assert!((cross / m).abs() < 0.03, "correlation {}", cross / m);
        // 0.4 cells more at the front end, 0.4 fewer at the back: var 0.8.
        assert!((grow / n as f64 - 0.8).abs() < 0.06, "{}", grow / n as f64);
    }
}
