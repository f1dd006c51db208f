//! `dem-sensor export`: a sensor model as an ONNX file ([`crate::graph`]),
//! written only after tract, fed the same uniforms and times, reproduces
//! the native code on check records.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use dem_core::error::{DemError, Result};
use dem_core::format::{empty_dem, Dem, DemCells, COLS, GRID_ROWS};

use crate::{graph, SensorModel};

/// Largest share of cells whose validity tract's graph and the native code
/// may disagree on: a comparison within float32 rounding of its threshold.
pub const VALIDITY_TOLERANCE: f64 = 1e-4;
/// Largest height difference (m) where both are valid.
pub const HEIGHT_TOLERANCE: f32 = 1e-5;

/// What [`export`] checked.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportCheck {
    /// Records checked.
    pub records: usize,
    /// Share of cells whose validity differs.
    pub validity_differ: f64,
    /// Largest height difference where both are valid (m).
    pub max_height_diff: f32,
    /// Bytes written.
    pub bytes: usize,
}

/// Terrain a sensor model acts on: flat ground, risers and drops of 5 to
/// 40 cm, stairs both ways, boxes, one-cell pits, some missing cells and
/// centimetre roughness; `n` records from `seed`.
pub fn probe_records(n: usize, seed: u64) -> Vec<Dem> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|i| {
            let mut d = empty_dem();
            let kind = i % 6;
            let (at, step) = (rng.gen_range(2..18), rng.gen_range(0.05..0.4));
            let len = rng.gen_range(1..5);
            for r in 0..GRID_ROWS {
                let base = match kind {
                    0 => 0.0,
                    1 => {
                        if r >= at {
                            step
                        } else {
                            0.0
                        }
                    }
                    2 => {
                        if r >= at {
                            -step
                        } else {
                            0.0
                        }
                    }
                    3 => step * ((r / len) as f64),
                    4 => -step * ((r / len) as f64),
                    _ => {
                        if (at..at + len).contains(&r) {
                            step
                        } else {
                            0.0
                        }
                    }
                };
                for c in 0..COLS {
                    let pit = kind == 0 && rng.gen_bool(0.05);
                    let h = base - 0.07 + rng.gen_range(-0.01..0.01) - if pit { 0.1 } else { 0.0 };
                    if !rng.gen_bool(0.05) {
                        d.set_valid(r, c, h as f32);
                    }
                }
            }
            d.set_attitude(std::array::from_fn(|_| rng.gen_range(-0.5..0.5)));
            d
        })
        .collect()
}

/// Build the graph of `model`, check it on `records` (uniforms from seed
/// 0, times with every fifth unknown), and write it to `path` atomically.
/// Refused, writing nothing, beyond [`VALIDITY_TOLERANCE`] or
/// [`HEIGHT_TOLERANCE`], or when row 20 changes.
pub fn export(model: &SensorModel, records: &[Dem], path: &str, metadata: &[(String, String)]) -> Result<ExportCheck> {
    let name = std::path::Path::new(path).file_stem().map_or("sensor".into(), |s| s.to_string_lossy().into_owned());
    let proto = graph::sensor_model(model, &name, metadata);
    let (n, k) = (records.len(), model.draws());
    let uniform = model.uniforms_of(0, 0, n, None);
    let times: Vec<f32> = (0..n).map(|i| if i % 5 == 0 { f32::NAN } else { 0.1 * (i % 40) as f32 }).collect();
    let mut native = records.to_vec();
    for (i, d) in native.iter_mut().enumerate() {
        model.apply_drawn(d, &uniform[i * k..(i + 1) * k], Some(f64::from(times[i])));
    }
    let got = graph::run_tract(&proto, model, records, &uniform, &times)
        .map_err(|e| DemError::input(path, format!("export check failed, nothing written: tract cannot run the graph: {e:#}")))?;
    let mut check = Agreement::default();
    check.compare(path, &native, &got)?;
    if let Some(memory) = model.map_memory() {
        let (native, got) = stepped(&proto, model, memory, records, &uniform, &times)
            .map_err(|e| DemError::input(path, format!("export check failed, nothing written: tract cannot step the graph: {e:#}")))?;
        check.compare(path, &native, &got)?;
    }
    let validity_differ = check.differ as f64 / check.cells.max(1) as f64;
    let worst = check.worst;
    if validity_differ > VALIDITY_TOLERANCE || worst > HEIGHT_TOLERANCE {
        return Err(DemError::input(
            path,
            format!(
                "export check failed, nothing written: tract's graph differs from dem-sensor on {:.4} % of the cells' validity \
                 (tolerance {:.4} %) and by {worst:e} m in height (tolerance {HEIGHT_TOLERANCE:e})",
                100.0 * validity_differ,
                100.0 * VALIDITY_TOLERANCE
            ),
        ));
    }
    let bytes = dem_graph::encode(&proto);
    dem_core::output::write_atomic(path, |w| {
        use std::io::Write;
        w.write_all(&bytes)
    })?;
    Ok(ExportCheck { records: n, validity_differ, max_height_diff: worst, bytes: bytes.len() })
}

/// Where the graph and the native code disagree, over the records compared.
#[derive(Default)]
struct Agreement {
    cells: usize,
    differ: usize,
    worst: f32,
}

impl Agreement {
    /// Add `native` against `got`; a graph that changes row 20 is refused.
    fn compare(&mut self, path: &str, native: &[Dem], got: &[Dem]) -> Result<()> {
        for (i, (a, b)) in native.iter().zip(got).enumerate() {
            if a[200..] != b[200..] {
                return Err(DemError::input(
                    path,
                    format!("export check failed, nothing written: the graph changes row 20 of check record {i}"),
                ));
            }
            for r in 0..GRID_ROWS {
                for c in 0..COLS {
                    if a.is_valid(r, c) != b.is_valid(r, c) {
                        self.differ += 1;
                    } else if a.is_valid(r, c) {
                        let d = (a.height(r, c) - b.height(r, c)).abs();
                        self.worst = if d.is_nan() { f32::INFINITY } else { self.worst.max(d) };
                    }
                }
            }
            self.cells += GRID_ROWS * COLS;
        }
        Ok(())
    }
}

/// Frames of each check run: the check records in order, [`RUN_FRAMES`] a run.
const RUN_FRAMES: usize = 6;

/// The check records stepped as runs of [`RUN_FRAMES`] frames (the records
/// in order; a seeded motion of up to 15 cm and 0.2 rad between frames),
/// natively and by tract feeding each step's `state_out` to the next:
/// (native, tract), run after run. `uniform` and `times` are the records'.
pub fn stepped(
    proto: &dem_graph::proto::ModelProto,
    model: &SensorModel,
    memory: crate::effects::MapMemory,
    records: &[Dem],
    uniform: &[f32],
    times: &[f32],
) -> anyhow::Result<(Vec<Dem>, Vec<Dem>)> {
    use crate::fusion::{state_of, step, Motion, CELLS, MOTION_LEN, STATE_LEN};
    let k = model.draws();
    let runs = records.len() / RUN_FRAMES;
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let motions: Vec<Motion> = (0..runs * RUN_FRAMES)
        .map(|_| Motion {
            dx: rng.gen_range(-0.02..0.15),
            dy: rng.gen_range(-0.05..0.05),
            dyaw: rng.gen_range(-0.2..0.2),
            dt: rng.gen_range(0.03..0.5),
        })
        .collect();
    let at = |run: usize, frame: usize| run * RUN_FRAMES + frame;
    let mut native = vec![records[0]; runs * RUN_FRAMES];
    let mut got = native.clone();
    let mut native_state = vec![[0.0f32; STATE_LEN]; runs];
    let mut state = vec![0.0f32; runs * STATE_LEN];
    for frame in 0..RUN_FRAMES {
        let idx: Vec<usize> = (0..runs).map(|r| at(r, frame)).collect();
        let batch: Vec<Dem> = idx.iter().map(|&i| records[i]).collect();
        let u: Vec<f32> = idx.iter().flat_map(|&i| uniform[i * k..(i + 1) * k].iter().copied()).collect();
        let t: Vec<f32> = idx.iter().map(|&i| times[i]).collect();
        let motion: Vec<f32> = idx.iter().flat_map(|&i| motions[i].to_array()).collect();
        let reset = vec![if frame == 0 { 1.0 } else { 0.0 }; runs];
        debug_assert_eq!(motion.len(), runs * MOTION_LEN);
        let (out, next) =
            graph::run_tract_step(proto, model, &batch, &u, &t, graph::Step { state: &state, motion: &motion, reset: &reset })?;
        state = next;
        for (r, &i) in idx.iter().enumerate() {
            got[i] = out[r];
            let mut d = records[i];
            model.apply_drawn(&mut d, &uniform[i * k..(i + 1) * k], Some(f64::from(times[i])));
            if frame > 0 {
                step(memory, &native_state[r], motions[i], &records[i], &mut d, &uniform[(i + 1) * k - CELLS..(i + 1) * k]);
            }
            native_state[r] = state_of(&records[i], &d);
            native[i] = d;
        }
    }
    Ok((native, got))
}
