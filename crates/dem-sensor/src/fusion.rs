//! A fused map from one frame to the next (`map-memory`): the output keeps
//! each cell's previous estimate and hole, moved with the robot, and blends
//! each new frame in, as a Kalman elevation map does.
//!
//! ```text
//! state     per cell: the last output's height and validity, and the last input's (N, 20, 5, 4)
//! moved     new cell (r, c) lay at (fr, fc) in the last frame's cells, from the motion (dx, dy, dyaw):
//!           X = r - 5.5, Y = 2 - c;  X' = (cos X - sin Y) + 10 dx,  Y' = (sin X + cos Y) + 10 dy
//!           fr = X' + 5.5, fc = 2 - Y'
//!           valid iff the nearest cell (floor(fr + 1/2), floor(fc + 1/2)) is in the grid and valid;
//!           its height bilinear over the valid cells of the four around (fr, fc)
//! climb     dz = mean over cells whose input is valid now and was (moved): last input - input
//! weights   dt seconds after the last frame: rate = 1 - e^(-dt/tau), kept = e^(-dt/keep)
//! new       frame valid, map valid:  h = (m - dz) + rate (f - (m - dz))
//!           frame valid, map missing: h = f
//!           frame missing, map valid: h = m - dz when u < kept (the map keeps it), else missing
//!           a run's first frame (reset): the frame
//! ```
//!
//! Heights are relative to the robot centre C, so the map's heights move by
//! the robot's climb between frames; the labels give no height, and the
//! climb is what the input (sim) DEMs show of the ground both frames see.
//! Everything is float32, operation for operation as the graph computes it
//! ([`operators`]), so dem-sensor, dem-apply and any runtime that steps the
//! graph through the same run agree.

use std::collections::HashMap;

use dem_core::error::{DemError, Result};
use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::{attr_int, Builder};

use crate::effects::MapMemory;
use crate::graph::ops::{is_valid, Cells};
use crate::memory::Pose;
use crate::Moment;

/// Channels of a cell's state: output height, output validity (1/0), input
/// height, input validity.
pub const CHANNELS: usize = 4;
/// Cells of the grid (rows 0..20), one uniform each for the memory.
pub const CELLS: usize = GRID_ROWS * COLS;
/// The memory's uniforms among a record's (`SensorModel::uniforms`, the
/// memory last): their last [`CELLS`].
pub fn memory_draws(record: &[f32]) -> &[f32] {
    &record[record.len() - CELLS..]
}

/// Floats of one record's state: `(20, 5, 4)`, row-major.
pub const STATE_LEN: usize = GRID_ROWS * COLS * CHANNELS;
/// One record's state ([`CHANNELS`] per cell).
pub type State = [f32; STATE_LEN];
/// Floats of one record's motion: dx, dy (m), dyaw (rad), dt (s).
pub const MOTION_LEN: usize = 4;
/// Stands in for a time constant of 0 (the frame alone) in a division.
const TINY: f32 = 1e-30;

/// Name of the graph's state input `(N, 20, 5, 4)` (zeros at a reset).
pub const STATE: &str = "state";
/// Name of the graph's motion input `(N, 4)`: the robot's move since the
/// last frame, in the last frame's axes (x forward, y left, yaw
/// counter-clockwise), and the seconds since it.
pub const MOTION: &str = "motion";
/// Name of the graph's reset input `(N,)`: 1 at a run's first frame, 0 after.
pub const RESET: &str = "reset";
/// Name of the graph's new state `(N, 20, 5, 4)`, the next frame's [`STATE`].
pub const STATE_OUT: &str = "state_out";

/// Row centre x, in cells, of row 0 (x = -0.55 m = -5.5 cells).
const ROW0: f32 = 5.5;
/// Column whose centre is on the robot's axis (y = 0).
const COL_MID: f32 = 2.0;
/// Cells per metre.
const PER_METRE: f32 = 10.0;

/// The robot's move from one frame to the next, in the earlier frame's axes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Motion {
    /// Forward (m).
    pub dx: f32,
    /// Left (m).
    pub dy: f32,
    /// Turn (rad, counter-clockwise), in (-pi, pi].
    pub dyaw: f32,
    /// Seconds since the last frame.
    pub dt: f32,
}

impl Motion {
    /// The move from pose `a` at time `ta` to pose `b` at `tb` (world
    /// poses of the labels, seconds in the run).
    pub fn between(a: Pose, ta: f64, b: Pose, tb: f64) -> Motion {
        let (s, c) = a.yaw.sin_cos();
        let (ex, ey) = (b.x - a.x, b.y - a.y);
        let turn = (b.yaw - a.yaw).rem_euclid(std::f64::consts::TAU);
        let turn = if turn > std::f64::consts::PI { turn - std::f64::consts::TAU } else { turn };
        Motion { dx: (c * ex + s * ey) as f32, dy: (-s * ex + c * ey) as f32, dyaw: turn as f32, dt: (tb - ta) as f32 }
    }

    /// The four numbers of the graph's [`MOTION`] input.
    pub fn to_array(self) -> [f32; MOTION_LEN] {
        [self.dx, self.dy, self.dyaw, self.dt]
    }
}

/// The weight of a frame `dt` seconds after the last, and the chance that
/// a cell it misses keeps the map's estimate: `(1 - e^(-dt/tau), e^(-dt/keep))`.
pub fn weights(m: MapMemory, dt: f32) -> (f32, f32) {
    let decay = |t: f64| (-dt / (t as f32).max(TINY)).exp();
    (1.0 - decay(m.tau), decay(m.keep))
}

/// The state after a frame: `output` (the map) and `input` (the DEM the
/// model was given), each cell's height (0 where missing) and validity.
pub fn state_of(input: &Dem, output: &Dem) -> State {
    let mut s = [0.0f32; STATE_LEN];
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let at = (r * COLS + c) * CHANNELS;
            for (k, d) in [output, input].into_iter().enumerate() {
                if d.is_valid(r, c) {
                    s[at + 2 * k] = d.height(r, c);
                    s[at + 2 * k + 1] = 1.0;
                }
            }
        }
    }
    s
}

/// Where cell (r, c) of the new frame lay in the last one, in (fractional)
/// rows and columns.
fn source(m: Motion, r: usize, c: usize) -> (f32, f32) {
    let (s, co) = (m.dyaw.sin(), m.dyaw.cos());
    let (x, y) = (r as f32 - ROW0, COL_MID - c as f32);
    let xp = (co * x - s * y) + m.dx * PER_METRE;
    let yp = (s * x + co * y) + m.dy * PER_METRE;
    (xp + ROW0, COL_MID - yp)
}

/// The cell at (row, col) of `state`'s channel pair `ch` (0: output, 2:
/// input): its height when it is in the grid and valid.
fn cell(state: &State, ch: usize, row: f32, col: f32) -> Option<f32> {
    let inside = row > -0.5 && row < GRID_ROWS as f32 - 0.5 && col > -0.5 && col < COLS as f32 - 0.5;
    if !inside {
        return None;
    }
    let at = (row as usize * COLS + col as usize) * CHANNELS + ch;
    (state[at + 1] > 0.5).then_some(state[at])
}

/// Channel pair `ch` of `state` at (fr, fc): valid where the nearest cell
/// is, its height bilinear over the valid cells of the four around.
fn moved(state: &State, ch: usize, fr: f32, fc: f32) -> Option<f32> {
    cell(state, ch, (fr + 0.5).floor(), (fc + 0.5).floor())?;
    let (r0, c0) = (fr.floor(), fc.floor());
    let (ar, ac) = (fr - r0, fc - c0);
    let (wr, wc) = ([1.0 - ar, ar], [1.0 - ac, ac]);
    let (mut num, mut den) = (0.0f32, 0.0f32);
    for (i, w_row) in wr.into_iter().enumerate() {
        for (j, w_col) in wc.into_iter().enumerate() {
            if let Some(h) = cell(state, ch, r0 + i as f32, c0 + j as f32) {
                let w = w_row * w_col;
                num += w * h;
                den += w;
            }
        }
    }
    Some(num / den)
}

/// One frame of the map: `out` holds the frame (the model's output of this
/// record before its memory) and becomes the map; `input` is the record the
/// model was given; `prev` the state after the run's last frame; `u` the
/// effect's uniforms (one per cell).
pub fn step(m: MapMemory, prev: &State, motion: Motion, input: &Dem, out: &mut Dem, u: &[f32]) {
    assert_eq!(u.len(), GRID_ROWS * COLS, "map-memory: one uniform per cell");
    let sources: Vec<(f32, f32)> = (0..GRID_ROWS * COLS).map(|i| source(motion, i / COLS, i % COLS)).collect();
    let (mut climb, mut seen) = (0.0f32, 0.0f32);
    for (i, &(fr, fc)) in sources.iter().enumerate() {
        let (r, c) = (i / COLS, i % COLS);
        if let (Some(was), true) = (moved(prev, 2, fr, fc), input.is_valid(r, c)) {
            climb += was - input.height(r, c);
            seen += 1.0;
        }
    }
    let dz = climb / seen.max(1.0);
    let (rate, kept) = weights(m, motion.dt);
    for (i, &(fr, fc)) in sources.iter().enumerate() {
        let (r, c) = (i / COLS, i % COLS);
        let map = moved(prev, 0, fr, fc).map(|h| h - dz);
        match (out.is_valid(r, c), map) {
            (true, Some(h)) => out.set_valid(r, c, h + rate * (out.height(r, c) - h)),
            (true, None) => {}
            (false, Some(h)) if u[i] < kept => out.set_valid(r, c, h),
            (false, _) => out.set_missing(r, c),
        }
    }
}

/// What a run's last frame left: its time, pose and state.
#[derive(Clone)]
struct Last {
    time: f64,
    pose: Pose,
    state: State,
}

/// The map's memory over a stream, record after record in stream order:
/// each run's last state, carried across chunks (and so across a stream's
/// whole length). A record of a run continues that run's map; one of no
/// known run, time or pose is a frame of its own.
pub struct Runs {
    memory: MapMemory,
    last: HashMap<u64, Last>,
    /// Index in the whole data set of the stream's first record (a shard's
    /// runs must start in it).
    first_index: u64,
}

impl Runs {
    /// A stream's runs for `memory`, the stream starting at record
    /// `first_index` of the whole data set.
    pub fn new(memory: MapMemory, first_index: u64) -> Self {
        Runs { memory, last: HashMap::new(), first_index }
    }

    /// Step the records `first..first + outs.len()` of the stream (their
    /// frames in `outs`, the model's inputs in `inputs`, their moments and
    /// the memory's uniforms `u`, one slice per record) in order. Refused
    /// (`path` names the labels): a record earlier in its run than the one
    /// before it, a shard whose run started in an earlier shard.
    pub fn step_chunk(
        &mut self,
        path: &str,
        first: u64,
        outs: &mut [Dem],
        inputs: &[Dem],
        moments: &[Moment],
        u: impl Fn(usize) -> Vec<f32>,
    ) -> Result<()> {
        let records: Vec<u64> = (first..first + outs.len() as u64).collect();
        self.step_records(path, &records, outs, inputs, moments, u)
    }

    /// [`Runs::step_chunk`] for records of the stream that need not be
    /// consecutive (`records[i]` the index of `outs[i]`, ascending): those
    /// a tool scores, stepped as a run of their own.
    pub fn step_records(
        &mut self,
        path: &str,
        records: &[u64],
        outs: &mut [Dem],
        inputs: &[Dem],
        moments: &[Moment],
        u: impl Fn(usize) -> Vec<f32>,
    ) -> Result<()> {
        for (i, out) in outs.iter_mut().enumerate() {
            let Some((run, time, pose)) = moments[i].in_run() else { continue };
            let record = records[i];
            match self.last.get(&run) {
                Some(last) if time <= last.time => {
                    return Err(DemError::input(
                        path,
                        format!(
                            "record {record} (run {run}) is at {time} s, not after the run's frame before it ({} s): \
                             a map's memory steps each run's records in time order; sort the stream by run and time",
                            last.time
                        ),
                    ))
                }
                Some(last) => step(self.memory, &last.state, Motion::between(last.pose, last.time, pose, time), &inputs[i], out, &u(i)),
                None if self.first_index > 0 && time > 0.0 => {
                    return Err(DemError::input(
                        path,
                        format!(
                            "record {record} (record {} of the whole) continues run {run} at {time} s, whose earlier frames \
                             are in an earlier shard: a map's memory needs them; split the data at run boundaries",
                            self.first_index + record
                        ),
                    ))
                }
                None => {}
            }
            self.last.insert(run, Last { time, pose, state: state_of(&inputs[i], out) });
        }
        Ok(())
    }
}

/// The map's memory over a set of records in any order (`outs` their
/// frames, `inputs` the model's inputs): each run stepped in time order,
/// runs in parallel; `u(i)` the memory's uniforms of record `i`. Records of
/// no known run, time or pose, and each run's first, are frames of their own.
pub fn step_set(memory: MapMemory, outs: &mut [Dem], inputs: &[Dem], moments: &[Moment], u: impl Fn(usize) -> Vec<f32> + Sync) {
    use rayon::prelude::*;
    let mut runs: HashMap<u64, Vec<usize>> = HashMap::new();
    for (i, m) in moments.iter().enumerate().take(outs.len()) {
        if let Some((run, _, _)) = m.in_run() {
            runs.entry(run).or_default().push(i);
        }
    }
    let mut runs: Vec<Vec<usize>> = runs.into_values().collect();
    let time = |i: usize| moments[i].time;
    runs.par_iter_mut().for_each(|r| r.sort_by(|&a, &b| time(a).total_cmp(&time(b)).then(a.cmp(&b))));
    let frames: &[Dem] = outs;
    let stepped: Vec<Vec<(usize, Dem)>> = runs
        .par_iter()
        .map(|run| {
            let mut done = Vec::with_capacity(run.len());
            let mut last: Option<(Pose, f64, State)> = None;
            for &i in run {
                let (_, time, pose) = moments[i].in_run().expect("a run's records are in their run");
                let mut out = frames[i];
                if let Some((was, then, state)) = &last {
                    // Two records of one time: the later one is a frame of its own.
                    if time > *then {
                        step(memory, state, Motion::between(*was, *then, pose, time), &inputs[i], &mut out, &u(i));
                    }
                }
                last = Some((pose, time, state_of(&inputs[i], &out)));
                done.push((i, out));
            }
            done
        })
        .collect();
    for (i, d) in stepped.into_iter().flatten() {
        outs[i] = d;
    }
}

/// `GatherElements` on axis 1.
fn gather(b: &mut Builder, data: &str, index: &str) -> String {
    b.op("GatherElements", &[data, index], vec![attr_int("axis", 1)])
}

/// `x` clamped to `[lo, hi]`.
fn clamp(b: &mut Builder, x: &str, lo: f32, hi: f32) -> String {
    let (lo, hi) = (b.scalar(lo), b.scalar(hi));
    let x = b.bin("Max", x, &lo);
    b.bin("Min", &x, &hi)
}

/// The cell at float rows and columns `(N, 100)`: (inside and valid as
/// 1/0, height) of `channel` pair `ch` of the state, flattened `(N, 100)`
/// each.
fn cell_at(b: &mut Builder, flat: &[String; CHANNELS], ch: usize, row: &str, col: &str) -> (String, String) {
    let above = b.gt_const(row, -0.5);
    let below = b.lt_const(row, GRID_ROWS as f32 - 0.5);
    let right = b.gt_const(col, -0.5);
    let left = b.lt_const(col, COLS as f32 - 0.5);
    let inside = b.all(&[&above, &below, &right, &left]);
    let r = clamp(b, row, 0.0, GRID_ROWS as f32 - 1.0);
    let c = clamp(b, col, 0.0, COLS as f32 - 1.0);
    let r = b.mul_const(&r, COLS as f32);
    let at = b.bin("Add", &r, &c);
    let at = b.op("Cast", &[&at], vec![attr_int("to", dem_graph::proto::tensor_proto::DataType::Int64 as i64)]);
    let v = gather(b, &flat[ch + 1], &at);
    let inside = b.to_float(&inside);
    let v = b.bin("Mul", &v, &inside);
    (v, gather(b, &flat[ch], &at))
}

/// [`moved`] as operators: (valid 1/0, height), `(N, 100)` each.
fn moved_ops(b: &mut Builder, flat: &[String; CHANNELS], ch: usize, fr: &str, fc: &str) -> (String, String) {
    let half = b.scalar(0.5);
    let rn = b.bin("Add", fr, &half);
    let rn = b.un("Floor", &rn);
    let cn = b.bin("Add", fc, &half);
    let cn = b.un("Floor", &cn);
    let (valid, _) = cell_at(b, flat, ch, &rn, &cn);
    let (r0, c0) = (b.un("Floor", fr), b.un("Floor", fc));
    let (ar, ac) = (b.bin("Sub", fr, &r0), b.bin("Sub", fc, &c0));
    let one = b.scalar(1.0);
    let (r1, c1) = (b.bin("Add", &r0, &one), b.bin("Add", &c0, &one));
    let (wr0, wc0) = (b.bin("Sub", &one, &ar), b.bin("Sub", &one, &ac));
    let (mut num, mut den) = (None::<String>, None::<String>);
    for (row, w_row) in [(&r0, &wr0), (&r1, &ar)] {
        for (col, w_col) in [(&c0, &wc0), (&c1, &ac)] {
            let (v, h) = cell_at(b, flat, ch, row, col);
            let w = b.bin("Mul", w_row, w_col);
            let w = b.bin("Mul", &w, &v);
            let wh = b.bin("Mul", &w, &h);
            num = Some(match num {
                None => wh,
                Some(n) => b.bin("Add", &n, &wh),
            });
            den = Some(match den {
                None => w,
                Some(d) => b.bin("Add", &d, &w),
            });
        }
    }
    let tiny = b.scalar(1e-6);
    let den = b.bin("Max", &den.expect("four cells"), &tiny);
    (valid, b.bin("Div", &num.expect("four cells"), &den))
}

/// The memory's step as operators on `frame` (the model's output before
/// it) and `input` (the model's input cells), `u` its uniforms `(N, 100)`,
/// reading the graph inputs [`STATE`], [`MOTION`] and [`RESET`]: the map's
/// cells and the new state (named [`STATE_OUT`]).
pub fn operators(b: &mut Builder, m: MapMemory, frame: &Cells, input: &Cells, u: &str) -> Cells {
    let (cells, rows, cols) = ((GRID_ROWS * COLS) as i64, GRID_ROWS as i64, COLS as i64);
    let state = b.reshape(STATE, &[-1, cells, CHANNELS as i64]);
    let flat: [String; CHANNELS] = std::array::from_fn(|k| {
        let s = b.take(&state, 2, k as i64, k as i64 + 1);
        b.reshape(&s, &[-1, cells])
    });
    let part = |b: &mut Builder, k: i64| b.take(MOTION, 1, k, k + 1);
    let (dx, dy, dyaw) = (part(b, 0), part(b, 1), part(b, 2));
    let (s, co) = (b.un("Sin", &dyaw), b.un("Cos", &dyaw));
    let x = b.constant(&[1, cells as usize], &(0..GRID_ROWS * COLS).map(|i| (i / COLS) as f32 - ROW0).collect::<Vec<_>>());
    let y = b.constant(&[1, cells as usize], &(0..GRID_ROWS * COLS).map(|i| COL_MID - (i % COLS) as f32).collect::<Vec<_>>());
    let (cx, sy) = (b.bin("Mul", &co, &x), b.bin("Mul", &s, &y));
    let xp = b.bin("Sub", &cx, &sy);
    let mx = b.mul_const(&dx, PER_METRE);
    let xp = b.bin("Add", &xp, &mx);
    let (sx, cy) = (b.bin("Mul", &s, &x), b.bin("Mul", &co, &y));
    let yp = b.bin("Add", &sx, &cy);
    let my = b.mul_const(&dy, PER_METRE);
    let yp = b.bin("Add", &yp, &my);
    let fr = b.add_const(&xp, ROW0);
    let mid = b.scalar(COL_MID);
    let fc = b.bin("Sub", &mid, &yp);
    let flat_of = |b: &mut Builder, t: &str| b.reshape(t, &[-1, cells]);
    let (in_h, in_v) = (flat_of(b, &input.h), flat_of(b, &input.v));
    let (f_h, f_v) = (flat_of(b, &frame.h), flat_of(b, &frame.v));
    // The climb: last input minus input over the ground both frames see.
    let (was_v, was_h) = moved_ops(b, &flat, 2, &fr, &fc);
    let both = b.bin("Mul", &was_v, &in_v);
    let diff = b.bin("Sub", &was_h, &in_h);
    let diff = b.bin("Mul", &diff, &both);
    let climb = b.reduce("ReduceSum", &diff, &[1]);
    let seen = b.reduce("ReduceSum", &both, &[1]);
    let one = b.scalar(1.0);
    let seen = b.bin("Max", &seen, &one);
    let dz = b.bin("Div", &climb, &seen);
    let (map_v, map_h) = moved_ops(b, &flat, 0, &fr, &fc);
    let map_h = b.bin("Sub", &map_h, &dz);
    let (fv, mv) = (is_valid(b, &f_v), is_valid(b, &map_v));
    let change = b.bin("Sub", &f_h, &map_h);
    let dt = part(b, 3);
    let dt = b.un("Neg", &dt);
    let decay = |b: &mut Builder, t: f64| {
        let t = b.scalar((t as f32).max(TINY));
        let x = b.bin("Div", &dt, &t);
        b.un("Exp", &x)
    };
    let (forget, kept) = (decay(b, m.tau), decay(b, m.keep));
    let one = b.scalar(1.0);
    let rate = b.bin("Sub", &one, &forget);
    let change = b.bin("Mul", &change, &rate);
    let blend = b.bin("Add", &map_h, &change);
    let kept = b.bin("Less", u, &kept);
    let missing = b.un("Not", &fv);
    let kept = b.all(&[&missing, &mv, &kept]);
    let both = b.all(&[&fv, &mv]);
    let zero = b.scalar(0.0);
    let h = b.select(&kept, &map_h, &zero);
    let h = b.select(&fv, &f_h, &h);
    let h = b.select(&both, &blend, &h);
    let v = b.any(&[&fv, &kept]);
    let v = b.to_float(&v);
    let reset = b.reshape(RESET, &[-1, 1]);
    let reset = b.gt_const(&reset, 0.5);
    let h = b.select(&reset, &f_h, &h);
    let v = b.select(&reset, &f_v, &v);
    let grid = [-1, rows, cols];
    let out = Cells { h: b.reshape(&h, &grid), v: b.reshape(&v, &grid) };
    let cell = [-1, rows, cols, 1];
    let parts: Vec<String> = [&out.h, &out.v, &input.h, &input.v].iter().map(|t| b.reshape(t, &cell)).collect();
    let refs: Vec<&str> = parts.iter().map(String::as_str).collect();
    b.node("Concat", &refs, vec![attr_int("axis", 3)], STATE_OUT);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::format::empty_dem;

    const STILL: Motion = Motion { dx: 0.0, dy: 0.0, dyaw: 0.0, dt: 0.1 };
    /// tau and keep for a weight `rate` and a keep probability `p` 0.1 s after the last frame.
    fn memory(rate: f64, p: f64) -> MapMemory {
        let t = |q: f64| if q <= 0.0 { 0.0 } else { -0.1 / q.ln() };
        MapMemory { tau: t(1.0 - rate), keep: t(p) }
    }

    fn ramp() -> Dem {
        let mut d = empty_dem();
        (0..GRID_ROWS * COLS).for_each(|i| d.set_valid(i / COLS, i % COLS, -0.07 + 0.01 * (i / COLS) as f32 + 0.001 * (i % COLS) as f32));
        d
    }

    #[test]
    fn motion_is_in_the_last_frame_s_axes() {
        let a = Pose { x: 1.0, y: 2.0, yaw: std::f64::consts::FRAC_PI_2, travelled: f64::NAN };
        let b = Pose { x: 1.0, y: 2.3, yaw: -3.0, travelled: f64::NAN };
        let m = Motion::between(a, 2.0, b, 2.25);
        assert!((m.dx - 0.3).abs() < 1e-6 && m.dy.abs() < 1e-6 && m.dt == 0.25, "{m:?}: ahead of a robot facing +y");
        // From +pi/2 to -3 rad is a turn of -4.57 rad, i.e. +1.71 rad.
        assert!((f64::from(m.dyaw) - (-3.0 - std::f64::consts::FRAC_PI_2 + std::f64::consts::TAU)).abs() < 1e-6, "{m:?}");
    }

    /// Still, a rate of 1 and no hold is the frame; a hold of 1 keeps what
    /// the frame misses; a small rate keeps the map's heights.
    #[test]
    fn the_map_blends_and_keeps_what_the_frame_misses() {
        let input = ramp();
        let prev = state_of(&input, &input);
        let u = vec![0.5f32; CELLS];
        let mut frame = ramp();
        frame.set_missing(4, 1);
        (0..COLS).for_each(|c| frame.set_valid(10, c, frame.height(10, c) + 0.1));
        let mut d = frame;
        step(memory(1.0, 0.0), &prev, STILL, &input, &mut d, &u);
        assert_eq!(d, frame, "no memory: the frame");
        let mut d = frame;
        step(MapMemory { tau: memory(0.25, 0.0).tau, keep: 10.0 }, &prev, STILL, &input, &mut d, &u);
        assert_eq!(d.height(4, 1), input.height(4, 1), "the map keeps the cell the frame missed");
        assert!((d.height(10, 2) - (input.height(10, 2) + 0.025)).abs() < 1e-6, "a quarter of the new frame's change");
        let mut d = frame;
        step(memory(0.25, 0.4), &prev, STILL, &input, &mut d, &u);
        assert!(!d.is_valid(4, 1), "u = 0.5 is not below a keep probability of 0.4");
    }

    /// A whole cell forward, the map's rows move back by one; a climb seen
    /// in the input is taken out of the map's heights.
    #[test]
    fn the_map_moves_with_the_robot_and_its_climb() {
        let prev_in = ramp();
        let mut prev_out = ramp();
        prev_out.set_valid(8, 3, 0.5);
        let prev = state_of(&prev_in, &prev_out);
        // One row ahead, 4 cm up: the new input is the old one a row on, 4 cm lower.
        let mut input = empty_dem();
        for r in 0..GRID_ROWS - 1 {
            (0..COLS).for_each(|c| input.set_valid(r, c, prev_in.height(r + 1, c) - 0.04));
        }
        let mut d = input;
        step(memory(0.02, 0.0), &prev, Motion { dx: 0.1, ..STILL }, &input, &mut d, &vec![0.9; CELLS]);
        let want = 0.5 - 0.04 + 0.02 * (input.height(7, 3) - (0.5 - 0.04));
        assert!((d.height(7, 3) - want).abs() < 1e-5, "{} vs {want}: the high cell one row back, lowered by the climb", d.height(7, 3));
        assert!((d.height(2, 0) - input.height(2, 0)).abs() < 1e-6, "the ground both see agrees once the climb is out");
        assert!(!d.is_valid(19, 0), "the new row ahead: the frame misses it and the map never saw it");
    }

    /// A run's records out of time order, and a shard that starts inside a
    /// run, are refused naming the record.
    #[test]
    fn a_stream_steps_runs_in_time_order_only() {
        let pose = |x: f64| Some(Pose { x, y: 0.0, yaw: 0.0, travelled: f64::NAN });
        let at = |t: f64| Moment { run: Some(2), time: t, pose: pose(t) };
        let m = memory(0.5, 0.5);
        let mut outs = vec![ramp(); 3];
        let inputs = outs.clone();
        let u = |_: usize| vec![0.1f32; CELLS];
        let e = Runs::new(m, 0).step_chunk("l.csv", 0, &mut outs, &inputs, &[at(0.0), at(0.2), at(0.1)], u).unwrap_err().to_string();
        assert!(e.contains("l.csv") && e.contains("record 2 (run 2) is at 0.1 s") && e.contains("time order"), "{e}");
        let e = Runs::new(m, 40).step_chunk("l.csv", 0, &mut outs, &inputs, &[at(0.3), at(0.4), at(0.5)], u).unwrap_err().to_string();
        assert!(e.contains("record 0 (record 40 of the whole) continues run 2 at 0.3 s"), "{e}");
        assert!(Runs::new(m, 40).step_chunk("l.csv", 0, &mut outs, &inputs, &[at(0.0), at(0.1), at(0.2)], u).is_ok());
    }
}
