//! A sensor model of named effects: an ordered list of measurement effects
//! from the vocabulary of `docs/format.md`, each with its parameters,
//! stored as JSON and applied to DEM streams.
//!
//! ```text
//! {"effects": [{"effect": "occlusion", "params": {"h": 0.45, "x0": 0.15}},
//!              {"effect": "noise", "params": {"sigma0": 0.003, "k": 0.01}}]}
//! ```
//!
//! - [`effects`]: what each effect does to one DEM (formulas there).
//! - [`SensorModel::apply`]: one record, its random streams derived from the
//!   seed, the record index and the effect, never from a thread, so the
//!   output is identical for any thread count or chunking.
//! - [`apply_stream`]: a whole NPY stream, chunk by chunk, in parallel.

pub mod draws;
pub mod effects;
pub mod evidence;
pub mod export;
pub mod fusion;
pub mod graph;
pub mod memory;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use dem_core::error::{DemError, Result};
use dem_core::format::Dem;
use dem_core::npy::transform_checked;
use dem_core::seeded::mix;

pub use effects::Effect;

/// Most effects a model may have: a few of each of the vocabulary's, and
/// a bound on the work per record and on how far heights can move.
pub const MAX_EFFECTS: usize = 64;

/// An ordered list of effects; applied first to last.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorModel {
    /// The effects, in the order they act on a DEM.
    pub effects: Vec<Effect>,
    /// Why the model may not be the sensor's, one sentence each (dem-gap
    /// writes them: a fit at the edge of its box, sets of different
    /// terrain); an export carries them into the file's metadata, so
    /// `dem-apply --info` shows them. Not part of what the model does.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// The random stream of one effect on one record: keyed by the seed, the
/// effect's name and its occurrence among effects of that name, with the
/// record index as the ChaCha stream. Adding or reordering other effects
/// leaves it unchanged, and every effect draws a fixed number of values per
/// record whatever its parameters (common random numbers for the fitter).
pub fn effect_rng(seed: u64, effect: &Effect, occurrence: u64, record: u64) -> ChaCha8Rng {
    let mut rng = effect_seed_rng(seed, effect, occurrence);
    rng.set_stream(record);
    rng
}

/// The random stream of one effect in one run (labels' `sequence`): as
/// [`effect_rng`], on a ChaCha stream no record index reaches (the top bit
/// set), so the draws a run keeps ([`EffectSpec::run_draws`](effects::EffectSpec::run_draws))
/// are the same in each of its frames, and other runs' differ.
pub fn effect_run_rng(seed: u64, effect: &Effect, occurrence: u64, run: u64) -> ChaCha8Rng {
    let mut rng = effect_seed_rng(seed, effect, occurrence);
    rng.set_stream(RUN_STREAMS | run);
    rng
}

/// The top bit of a ChaCha stream number: set for runs' streams, clear for
/// records' (a stream holds fewer than 2^63 records).
const RUN_STREAMS: u64 = 1 << 63;

fn effect_seed_rng(seed: u64, effect: &Effect, occurrence: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(effect_seed_key(seed, effect, occurrence))
}

/// The key of an effect's streams: the seed, its name and its occurrence.
fn effect_seed_key(seed: u64, effect: &Effect, occurrence: u64) -> u64 {
    let name_key = effect.name().bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ b as u64).wrapping_mul(0x100_0000_01b3));
    mix(seed ^ mix(name_key ^ mix(occurrence)))
}

/// Where a record sits in time, from its labels: its run (`sequence`), its
/// time in the run (`time`; NaN where unknown) and the robot's pose (`x`,
/// `y`, `yaw`). The draws a run keeps read the run; `startup` reads the
/// time; a map's memory ([`memory`]) all three.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Moment {
    /// The run the record belongs to, when its labels say.
    pub run: Option<u64>,
    /// Seconds since the run's start; NaN where unknown.
    pub time: f64,
    /// The robot's pose in the world, when its labels give x, y and yaw.
    pub pose: Option<memory::Pose>,
}

impl Moment {
    /// A record of no known run or time: every draw is its own.
    pub const UNKNOWN: Moment = Moment { run: None, time: f64::NAN, pose: None };

    /// The time when known (finite).
    pub fn known_time(&self) -> Option<f64> {
        Some(self.time).filter(|t| t.is_finite())
    }

    /// Run, time and pose, when all three are known: what a map's memory reads.
    pub fn in_run(&self) -> Option<(u64, f64, memory::Pose)> {
        Some((self.run?, self.known_time()?, self.pose?))
    }

    /// The metres the robot travelled in its run, when known: what
    /// `drift`'s walk reads.
    pub fn travelled(&self) -> Option<f64> {
        self.run?;
        Some(self.pose?.travelled).filter(|t| t.is_finite())
    }
}

/// True when some of `moments` know their run, time and pose (a map's
/// memory can be fitted and applied).
pub fn any_in_run(moments: Option<&[Moment]>) -> bool {
    moments.is_some_and(|m| m.iter().any(|m| m.in_run().is_some()))
}

/// True when some of `moments` know their time (`startup` can read it).
pub fn any_time(moments: Option<&[Moment]>) -> bool {
    moments.is_some_and(|m| m.iter().any(|m| m.known_time().is_some()))
}

/// Each label's [`Moment`], in the labels' order; a pose's `travelled`
/// is the path its run's poses make in time order, up to it.
pub fn moments(labels: &[dem_core::table::Label]) -> Vec<Moment> {
    let mut out: Vec<Moment> = labels
        .iter()
        .map(|l| Moment {
            run: l.sequence,
            time: l.time.unwrap_or(f64::NAN),
            pose: match (l.x, l.y, l.yaw) {
                (Some(x), Some(y), Some(yaw)) => Some(memory::Pose { x, y, yaw, travelled: f64::NAN }),
                _ => None,
            },
        })
        .collect();
    let mut in_runs: Vec<usize> = (0..out.len()).filter(|&i| out[i].run.is_some() && out[i].known_time().is_some()).collect();
    in_runs.sort_by(|&a, &b| out[a].run.cmp(&out[b].run).then(out[a].time.total_cmp(&out[b].time)));
    let mut last: Option<(u64, f64, f64, f64)> = None;
    for i in in_runs {
        let (Some(run), Some(pose)) = (out[i].run, out[i].pose.as_mut()) else { continue };
        let travelled = match last {
            Some((r, x, y, t)) if r == run => t + (pose.x - x).hypot(pose.y - y),
            _ => 0.0,
        };
        pose.travelled = travelled;
        last = Some((run, pose.x, pose.y, travelled));
    }
    out
}

/// Why `model`'s run draws are drawn per record over records of
/// `moments` (none given, or none naming its run), or None when they are
/// the runs': one line for the tool's log.
pub fn runs_unknown(model: &SensorModel, moments: Option<&[Moment]>) -> Option<String> {
    let keeping: Vec<&str> = model.effects.iter().filter(|e| e.spec().run_draws > 0).map(Effect::name).collect();
    let mut lines = Vec::new();
    if !keeping.is_empty() && !moments.is_some_and(|m| m.iter().any(|m| m.run.is_some())) {
        let why = if moments.is_some() { "the labels name no run (`sequence`)" } else { "no --labels gave the records' runs" };
        lines.push(format!("{} keep draws for a run, but {why}: they are drawn afresh for every record", keeping.join(", ")));
    }
    if model.map_memory().is_some() && !any_in_run(moments) {
        lines.push(
            "map-memory steps each run's frames, but no record has a run, time and pose (labels' sequence, time, x, y, yaw): \
             every frame is a run's first"
                .to_string(),
        );
    }
    (!lines.is_empty()).then(|| lines.join("; "))
}

/// The moment of record `i` of `moments`, [`Moment::UNKNOWN`] past their end
/// or without them.
pub fn moment_at(moments: Option<&[Moment]>, i: usize) -> Moment {
    moments.and_then(|m| m.get(i).copied()).unwrap_or(Moment::UNKNOWN)
}

impl SensorModel {
    /// The model of `effects`, in that order, without warnings.
    pub fn new(effects: Vec<Effect>) -> Self {
        SensorModel { effects, warnings: Vec::new() }
    }

    /// Read a model from a JSON file, checking every parameter.
    pub fn read(path: &str) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|source| DemError::Open { path: path.into(), source })?;
        Self::from_json(&text).map_err(|reason| DemError::input(path, reason))
    }

    /// Parse and check a model from JSON text.
    pub fn from_json(text: &str) -> std::result::Result<Self, String> {
        let m: SensorModel = serde_json::from_str(text).map_err(|e| format!("not a sensor model: {e}"))?;
        if m.effects.len() > MAX_EFFECTS {
            return Err(format!(
                "{} effects: a sensor model has at most {MAX_EFFECTS} (the vocabulary has {}; more is a generated file gone wrong)",
                m.effects.len(),
                effects::NAMES.len()
            ));
        }
        for (i, e) in m.effects.iter().enumerate() {
            e.check().map_err(|r| format!("effect {i} ({}): {r}", e.name()))?;
            if matches!(e, Effect::MapMemory(_)) && i + 1 != m.effects.len() {
                return Err(format!(
                    "effect {i} (map-memory): a map's memory is a model's last effect, on the frame all the others made, and a model has one"
                ));
            }
        }
        Ok(m)
    }

    /// Pretty JSON text of the model.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a model serialises")
    }

    /// Write the model as JSON, atomically.
    pub fn write(&self, path: &str) -> Result<()> {
        let text = self.to_json();
        dem_core::output::write_atomic(path, |w| {
            use std::io::Write;
            writeln!(w, "{text}")
        })
    }

    /// The model with `e` inserted at its place in the physical order
    /// ([`Effect::stage`]): after every effect of an earlier or equal stage.
    pub fn with(&self, e: Effect) -> Self {
        let mut effects = self.effects.clone();
        let at = effects.iter().position(|x| x.stage() > e.stage()).unwrap_or(effects.len());
        effects.insert(at, e);
        SensorModel { effects, warnings: self.warnings.clone() }
    }

    /// The model with only the effects named in `names` (in the model's
    /// order). Their random draws are the same as in the whole model (the
    /// streams are keyed by name and occurrence). Err names an effect the
    /// model does not have.
    pub fn only(&self, names: &[String]) -> std::result::Result<Self, String> {
        for n in names {
            if !self.effects.iter().any(|e| e.name() == n) {
                let have: Vec<&str> = self.effects.iter().map(Effect::name).collect();
                return Err(format!("the model has no {n} effect (it has: {})", have.join(", ")));
            }
        }
        let effects = self.effects.iter().filter(|e| names.iter().any(|n| n == e.name())).cloned().collect();
        Ok(SensorModel { effects, warnings: self.warnings.clone() })
    }

    /// Apply every effect to record number `index` of a stream, in order.
    pub fn apply(&self, d: &mut Dem, seed: u64, index: u64) {
        self.apply_at(d, seed, index, Moment::UNKNOWN)
    }

    /// Uniforms per record of the whole model ([`Effect::draws`] summed):
    /// the width `K` of its ONNX graph's `uniform` input.
    pub fn draws(&self) -> usize {
        self.effects.iter().map(Effect::draws).sum()
    }

    /// The uniforms of record `index` at `moment` under `seed`, effect after
    /// effect in the model's order, into `out` ([`SensorModel::draws`]
    /// long). Each effect's come from its own stream ([`effect_rng`]); the
    /// first [`EffectSpec::run_draws`](effects::EffectSpec::run_draws) of
    /// an effect from its run's ([`effect_run_rng`]) when the run is known.
    pub fn uniforms(&self, seed: u64, index: u64, moment: Moment, out: &mut [f32]) {
        assert_eq!(out.len(), self.draws(), "uniforms: wrong length");
        let mut at = 0;
        for (i, e) in self.effects.iter().enumerate() {
            let n = e.draws();
            if n > 0 {
                let occurrence = self.effects[..i].iter().filter(|x| x.name() == e.name()).count() as u64;
                let mut rng = effect_rng(seed, e, occurrence, index);
                draws::fill_uniform(&mut rng, &mut out[at..at + n]);
                let kept = e.spec().run_draws;
                if let (Some(run), true) = (moment.run, kept > 0) {
                    draws::fill_uniform(&mut effect_run_rng(seed, e, occurrence, run), &mut out[at..at + kept]);
                }
                if let Some(run) = moment.run {
                    let key = mix(effect_seed_key(seed, e, occurrence) ^ mix(RUN_STREAMS | run));
                    if let Some(z) = e.normals_in_run(key, moment) {
                        memory::uniforms_of_normals(&z, &mut out[at..at + n]);
                    }
                }
            }
            at += n;
        }
    }

    /// The uniforms of records `first..first + n` under `seed`, record after
    /// record ([`SensorModel::uniforms`] each, `moments[i]` the moment of
    /// record `first + i`), drawn in parallel: `n x K`.
    pub fn uniforms_of(&self, seed: u64, first: u64, n: usize, moments: Option<&[Moment]>) -> Vec<f32> {
        let k = self.draws();
        let mut u = vec![0.0f32; n * k];
        if k > 0 {
            u.par_chunks_mut(k).enumerate().for_each(|(i, u)| self.uniforms(seed, first + i as u64, moment_at(moments, i), u));
        }
        u
    }

    /// Apply every effect to `d` with the record's uniforms `u` (laid out
    /// as [`SensorModel::uniforms`] writes them) and its time in its run
    /// when known (finite; `startup` uses it): what the ONNX graph computes.
    /// The masks are first made the contract's ([`threshold`]; a contract
    /// DEM is left as it is), so a generator's raw masks come out +-1.
    pub fn apply_drawn(&self, d: &mut Dem, u: &[f32], time: Option<f64>) {
        assert_eq!(u.len(), self.draws(), "apply_drawn: wrong number of uniforms");
        threshold(d);
        let time = time.filter(|t| t.is_finite());
        let mut at = 0;
        for e in &self.effects {
            let n = e.draws();
            e.apply_drawn(d, &u[at..at + n], time);
            at += n;
        }
    }

    /// [`SensorModel::apply`] for a record at `moment` in its run (from its
    /// labels: the run's draws, `startup`'s time).
    pub fn apply_at(&self, d: &mut Dem, seed: u64, index: u64, moment: Moment) {
        let mut u = vec![0.0f32; self.draws()];
        self.uniforms(seed, index, moment, &mut u);
        self.apply_drawn(d, &u, moment.known_time());
    }

    /// Apply the model to records whose stream indices start at `first`, in
    /// parallel (the result does not depend on the thread count).
    pub fn apply_all(&self, records: &mut [Dem], seed: u64, first: u64) {
        self.apply_all_at(records, seed, first, None)
    }

    /// [`SensorModel::apply_all`] with each record's moment in its run
    /// (`moments[i]` for `records[i]`); a map's memory steps each run of
    /// the records in time order ([`fusion::step_set`]).
    pub fn apply_all_at(&self, records: &mut [Dem], seed: u64, first: u64, moments: Option<&[Moment]>) {
        let memory = self.map_memory().zip(moments.filter(|m| any_in_run(Some(m))));
        let inputs = memory.map(|_| records.to_vec());
        self.apply_frames(records, seed, first, moments);
        if let (Some((memory, moments)), Some(inputs)) = (memory, inputs) {
            fusion::step_set(memory, records, &inputs, moments, |i| self.memory_uniforms(seed, first + i as u64));
        }
    }

    /// Every record's frame: the model with its map's memory as a run's
    /// first frame (`moments[i]` for `records[i]`), in parallel.
    pub fn apply_frames(&self, records: &mut [Dem], seed: u64, first: u64, moments: Option<&[Moment]>) {
        records.par_iter_mut().enumerate().for_each(|(i, d)| self.apply_at(d, seed, first + i as u64, moment_at(moments, i)));
    }

    /// The model's map memory (`map-memory`, a model's last effect), if it has one.
    pub fn map_memory(&self) -> Option<effects::MapMemory> {
        match self.effects.last() {
            Some(Effect::MapMemory(m)) => Some(*m),
            _ => None,
        }
    }

    /// The uniforms of the model's map memory for record `index`: the last
    /// slice of [`SensorModel::uniforms`] (it keeps none for a run).
    pub fn memory_uniforms(&self, seed: u64, index: u64) -> Vec<f32> {
        let e = self.effects.last().expect("a model with a map memory");
        let mut u = vec![0.0f32; e.draws()];
        draws::fill_uniform(&mut effect_rng(seed, e, 0, index), &mut u);
        u
    }

    /// [`SensorModel::apply_frames`] on `records`, records `first..` of a
    /// stream whose first record is record `first_index` of the whole data
    /// set; `moments` (the labels file and its moments) index the stream's
    /// own records, and a stream longer than them is refused naming the file.
    /// A map's memory is stepped by the stream's [`fusion::Runs`].
    pub fn apply_chunk(
        &self,
        records: &mut [Dem],
        seed: u64,
        first_index: u64,
        first: u64,
        moments: Option<(&str, &[Moment])>,
    ) -> Result<()> {
        let m = chunk_moments(moments, first, records.len())?;
        self.apply_frames(records, seed, first_index + first, m);
        Ok(())
    }

    /// True when an effect reads each record's time (`startup`): without
    /// times it falls back to a per-record rate.
    pub fn uses_time(&self) -> bool {
        self.effects.iter().any(|e| matches!(e, Effect::Startup(_)))
    }

    /// Names of the effects, comma-separated (`none` when empty).
    pub fn summary(&self) -> String {
        if self.effects.is_empty() {
            return "none".into();
        }
        self.effects.iter().map(|e| e.to_string()).collect::<Vec<_>>().join(", ")
    }
}

/// Masks to the contract: a cell with mask > 0 becomes valid (mask +1, its
/// height kept), any other missing (height 0, mask -1). Row 20 untouched.
pub fn threshold(d: &mut Dem) {
    use dem_core::format::{DemCells, COLS, GRID_ROWS};
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            if d.is_valid(r, c) {
                d.set_valid(r, c, d.height(r, c));
            } else {
                d.set_missing(r, c);
            }
        }
    }
}

/// The moments of records `first..first + n` of a stream from its labels
/// (`(path, moments)`); a stream longer than its labels is refused.
pub fn chunk_moments<'a>(moments: Option<(&str, &'a [Moment])>, first: u64, n: usize) -> Result<Option<&'a [Moment]>> {
    match moments {
        Some((path, t)) => {
            let (a, b) = (first as usize, first as usize + n);
            if b > t.len() {
                return Err(DemError::input(path, format!("{} labels, but the stream has more records ({b} so far)", t.len())));
            }
            Ok(Some(&t[a..b]))
        }
        None => Ok(None),
    }
}

/// Refuse labels (`(path, rows)`) that do not have exactly one row per
/// record of a stream of `records`: one row more is as wrong as one less.
pub fn labels_cover(labels: Option<(&str, usize)>, records: u64) -> Result<()> {
    match labels {
        Some((path, rows)) if rows as u64 != records => {
            Err(DemError::input(path, format!("{rows} labels for a stream of {records} records (one row per record, in stream order)")))
        }
        _ => Ok(()),
    }
}

/// Apply `model` to the NPY stream `input`, writing `output` (`-` for
/// stdin/stdout), one chunk at a time. Returns the records written.
pub fn apply_stream(model: &SensorModel, input: &str, output: &str, seed: u64, progress: impl Fn(u64)) -> Result<u64> {
    apply_stream_at(model, input, output, seed, None, progress)
}

/// [`apply_stream`] with the moment of each record in its run
/// (`moments[i]` for record i of the stream; from a labels CSV). A stream
/// longer than `moments` is refused.
pub fn apply_stream_at(
    model: &SensorModel,
    input: &str,
    output: &str,
    seed: u64,
    moments: Option<(&str, &[Moment])>,
    progress: impl Fn(u64),
) -> Result<u64> {
    apply_shard(model, input, output, seed, 0, moments, progress)
}

/// [`apply_stream_at`] on a shard of a larger data set whose first record is
/// record `first_index` of the whole: each record's random draws come from
/// its index in the whole and its run, so shards joined equal one run on
/// the whole, byte for byte. `moments` index the shard's own records.
pub fn apply_shard(
    model: &SensorModel,
    input: &str,
    output: &str,
    seed: u64,
    first_index: u64,
    moments: Option<(&str, &[Moment])>,
    progress: impl Fn(u64),
) -> Result<u64> {
    apply_shard_emit(model, input, output, seed, first_index, moments, None, progress)
}

/// [`apply_shard`], writing each record's uniforms (float32 `(N, K)`, the
/// `uniform` input of the model's graph) to `emit_uniform` when given.
#[allow(clippy::too_many_arguments)]
pub fn apply_shard_emit(
    model: &SensorModel,
    input: &str,
    output: &str,
    seed: u64,
    first_index: u64,
    moments: Option<(&str, &[Moment])>,
    emit_uniform: Option<&str>,
    progress: impl Fn(u64),
) -> Result<u64> {
    let k = model.draws();
    let mut emit = emit_uniform.map(|p| dem_core::npy::F32ArrayWriter::create(p, &[k as u64])).transpose()?;
    let mut runs = model.map_memory().zip(moments).map(|(m, (path, _))| (fusion::Runs::new(m, first_index), path));
    let (_, written) = transform_checked(
        input,
        output,
        |first, chunk| {
            let inputs = runs.as_ref().map(|_| chunk.to_vec());
            let drawn = match &mut emit {
                None => {
                    model.apply_chunk(chunk, seed, first_index, first, moments)?;
                    None
                }
                Some(w) => {
                    let m = chunk_moments(moments, first, chunk.len())?;
                    let u = model.uniforms_of(seed, first_index + first, chunk.len(), m);
                    chunk.par_iter_mut().enumerate().for_each(|(i, d)| {
                        model.apply_drawn(d, &u[i * k..(i + 1) * k], moment_at(m, i).known_time());
                    });
                    if k > 0 {
                        w.write(&u)?;
                    } else {
                        w.write_empty(chunk.len() as u64);
                    }
                    Some(u)
                }
            };
            if let (Some((runs, path)), Some(inputs)) = (&mut runs, inputs) {
                let m = chunk_moments(moments, first, chunk.len())?.expect("a map's memory steps runs from labels");
                let memory_uniforms = |i: usize| match &drawn {
                    Some(u) => fusion::memory_draws(&u[i * k..(i + 1) * k]).to_vec(),
                    None => model.memory_uniforms(seed, first_index + first + i as u64),
                };
                runs.step_chunk(path, first, chunk, &inputs, m, memory_uniforms)?;
            }
            progress(chunk.len() as u64);
            Ok(())
        },
        |read| labels_cover(moments.map(|(p, m)| (p, m.len())), read),
    )?;
    if let Some(w) = emit {
        w.finish()?;
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::{Dropout, Noise, Occlusion, RowDropout};

    /// A pose's path travelled is its run's, in time order, whatever the
    /// labels' order; without a run or a time it is unknown.
    #[test]
    fn the_path_travelled_follows_each_run_in_time() {
        use dem_core::{format::Terrain, table::Label};
        let label = |sequence: Option<u64>, time: Option<f64>, x: f64, y: f64| Label {
            index: 0,
            terrain: Terrain::Flat,
            x: Some(x),
            y: Some(y),
            yaw: Some(0.0),
            sequence,
            time,
        };
        let m = moments(&[
            label(Some(1), Some(0.2), 3.0, 4.0),
            label(Some(2), Some(0.0), 9.0, 9.0),
            label(Some(1), Some(0.0), 0.0, 0.0),
            label(Some(1), Some(0.4), 3.0, 5.0),
            label(None, Some(0.1), 1.0, 1.0),
            label(Some(2), None, 1.0, 1.0),
        ]);
        let travelled: Vec<Option<f64>> = m.iter().map(Moment::travelled).collect();
        assert_eq!(travelled, [Some(5.0), Some(0.0), Some(0.0), Some(6.0), None, None]);
    }

    #[test]
    fn only_keeps_the_named_effects_and_their_draws() {
        use dem_core::format::{empty_dem, DemCells};
        let m = SensorModel::from_json(
            r#"{"effects": [{"effect": "startup", "params": {"x0": 0.4, "v": 0.2, "p": 0.25}},
                            {"effect": "dropout", "params": {"p": 0.3}}, {"effect": "noise", "params": {"sigma0": 0.01, "k": 0.0}}]}"#,
        )
        .unwrap();
        let only = m.only(&["dropout".to_string()]).unwrap();
        assert_eq!(only.effects.iter().map(Effect::name).collect::<Vec<_>>(), ["dropout"]);
        let mut flat = empty_dem();
        (0..100).for_each(|i| flat.set_valid(i / 5, i % 5, -0.07));
        let dropout_alone = SensorModel::from_json(r#"{"effects": [{"effect": "dropout", "params": {"p": 0.3}}]}"#).unwrap();
        for index in 0..20 {
            let (mut a, mut b) = (flat, flat);
            only.apply(&mut a, 7, index);
            dropout_alone.apply(&mut b, 7, index);
            assert_eq!(a, b);
        }
        let e = m.only(&["occlusion".to_string()]).unwrap_err();
        assert!(e.contains("no occlusion effect") && e.contains("startup, dropout, noise"), "{e}");
    }

    #[test]
    fn json_round_trip_and_check() {
        let m = SensorModel {
            effects: vec![
                Effect::Occlusion(Occlusion { h: 0.45, x0: 0.15 }),
                Effect::Noise(Noise { sigma0: 0.003, k: 0.01, tau: 0.0 }),
                Effect::Dropout(Dropout { p: 0.1 }),
            ],
            warnings: vec!["fitted at the edge of its box: noise (k)".into()],
        };
        let back = SensorModel::from_json(&m.to_json()).unwrap();
        assert_eq!(back, m);
        assert!(m.to_json().contains("\"effect\": \"occlusion\""));
        // Without warnings the file is what it was before models had them.
        let plain = SensorModel::new(m.effects.clone());
        assert!(!plain.to_json().contains("warnings"), "{}", plain.to_json());
        // Inside MAX_PARAM and the effect's own rule, outside its physical box.
        let e = SensorModel::from_json(r#"{"effects":[{"effect":"tilt","params":{"pitch":0.01,"roll":0.01,"x0":0.2,"range":10.0}}]}"#)
            .unwrap_err();
        assert!(e.contains("effect 0 (tilt): range = 10 must be in [0, 3] m"), "{e}");
        let e = SensorModel::from_json(r#"{"effects":[{"effect":"drift","params":{"rate":2.0,"zrate":0.0,"x0":0.4}}]}"#).unwrap_err();
        assert!(e.contains("effect 0 (drift): rate = 2 is outside its physical box 0..=1"), "{e}");
        let e = SensorModel::from_json(r#"{"effects":[{"effect":"occlusion","params":{"h":1.15,"x0":-1.0}}]}"#).unwrap_err();
        assert!(e.contains("x0 = -1 is outside its physical box -0.6..=1.4"), "{e}");
        assert!(SensorModel::from_json(r#"{"effects":[{"effect":"dropout","params":{"p":1.5}}]}"#).is_err());
        assert!(SensorModel::from_json(r#"{"effects":[{"effect":"blur","params":{}}]}"#).is_err());
        assert!(SensorModel::from_json(r#"{"effects":[{"effect":"fov","params":{"x_min":1.0,"x_max":0.0}}]}"#).is_err());
    }

    #[test]
    fn insertion_follows_the_physical_order() {
        let m = SensorModel::default().with(Effect::Dropout(Dropout { p: 0.1 })).with(Effect::Occlusion(Occlusion { h: 0.5, x0: 0.1 }));
        assert_eq!(m.effects[0].name(), "occlusion");
        let m = m.with(Effect::Noise(Noise { sigma0: 0.01, k: 0.0, tau: 0.0 }));
        assert_eq!(m.effects.iter().map(|e| e.name()).collect::<Vec<_>>(), ["occlusion", "noise", "dropout"]);
    }

    #[test]
    fn a_run_keeps_its_run_draws_and_each_frame_draws_the_rest_afresh() {
        use crate::effects::{Lag, Tilt, SPECS};
        assert!(SPECS.iter().all(|s| s.run_draws <= s.draws), "run draws are some of an effect's draws");
        let m = SensorModel::new(vec![
            Effect::Lag(Lag { s: 0.05, spread: 0.5 }),
            Effect::Tilt(Tilt { pitch: 0.01, roll: 0.01, x0: 0.2, range: 1.0 }),
            Effect::Noise(Noise { sigma0: 0.01, k: 0.0, tau: 0.0 }),
        ]);
        let k = m.draws();
        let at = |index: u64, run: Option<u64>| {
            let mut u = vec![0.0f32; k];
            m.uniforms(7, index, Moment { run, time: f64::NAN, pose: None }, &mut u);
            u
        };
        // lag's one draw and tilt's two are the run's; noise's 100 the record's.
        let kept = |u: &[f32]| [u[0], u[1], u[2]];
        let (a, b, c) = (at(10, Some(3)), at(11, Some(3)), at(12, Some(4)));
        assert_eq!(kept(&a), kept(&b), "one run, one mount angle and one lag");
        assert_ne!(kept(&a), kept(&c), "another run, another draw");
        assert_ne!(a[3..], b[3..], "the noise is new every frame");
        // Without a run every draw is the record's, as before runs were known,
        // and the frame's draws do not depend on the run.
        let alone = at(10, None);
        assert_eq!(alone[3..], a[3..]);
        assert_ne!(kept(&alone), kept(&a));
        assert_ne!(kept(&alone), kept(&at(11, None)));
        let runs = [Moment { run: Some(3), time: 0.1, pose: None }, Moment { run: Some(3), time: 0.2, pose: None }];
        assert_eq!(m.uniforms_of(7, 10, 2, Some(&runs)), [a, b].concat(), "the batch draws as one record at a time");
        assert!(runs_unknown(&m, None).unwrap().contains("lag, tilt keep draws for a run"));
        assert!(runs_unknown(&m, Some(&runs)).is_none());
        assert!(runs_unknown(&SensorModel::new(vec![Effect::Noise(Noise { sigma0: 0.01, k: 0.0, tau: 0.0 })]), None).is_none());
    }

    #[test]
    fn output_does_not_depend_on_chunking() {
        let flat = {
            let mut d = dem_core::format::empty_dem();
            for r in 0..20 {
                for c in 0..5 {
                    dem_core::format::DemCells::set_valid(&mut d, r, c, -0.07 + 0.01 * r as f32);
                }
            }
            d
        };
        let m = SensorModel {
            effects: vec![
                Effect::Noise(Noise { sigma0: 0.01, k: 0.01, tau: 0.0 }),
                Effect::Dropout(Dropout { p: 0.3 }),
                Effect::RowDropout(RowDropout { p: 0.2 }),
            ],
            warnings: Vec::new(),
        };
        let mut all = vec![flat; 50];
        m.apply_all(&mut all, 7, 0);
        let mut parts = vec![flat; 50];
        let (a, b) = parts.split_at_mut(17);
        m.apply_all(a, 7, 0);
        m.apply_all(b, 7, 17);
        assert!(all == parts);
        assert!(all[0] != all[1], "records get different draws");
    }
}
