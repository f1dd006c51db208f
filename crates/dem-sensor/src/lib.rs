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
pub mod graph;

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
    let name_key = effect.name().bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ b as u64).wrapping_mul(0x100_0000_01b3));
    let mut rng = ChaCha8Rng::seed_from_u64(mix(seed ^ mix(name_key ^ mix(occurrence))));
    rng.set_stream(record);
    rng
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
        self.apply_at(d, seed, index, None)
    }

    /// Uniforms per record of the whole model ([`Effect::draws`] summed):
    /// the width `K` of its ONNX graph's `uniform` input.
    pub fn draws(&self) -> usize {
        self.effects.iter().map(Effect::draws).sum()
    }

    /// The uniforms of record `index` under `seed`, effect after effect in
    /// the model's order, into `out` ([`SensorModel::draws`] long). Each
    /// effect's come from its own stream ([`effect_rng`]).
    pub fn uniforms(&self, seed: u64, index: u64, out: &mut [f32]) {
        assert_eq!(out.len(), self.draws(), "uniforms: wrong length");
        let mut at = 0;
        for (i, e) in self.effects.iter().enumerate() {
            let n = e.draws();
            if n > 0 {
                let occurrence = self.effects[..i].iter().filter(|x| x.name() == e.name()).count() as u64;
                let mut rng = effect_rng(seed, e, occurrence, index);
                draws::fill_uniform(&mut rng, &mut out[at..at + n]);
            }
            at += n;
        }
    }

    /// The uniforms of records `first..first + n` under `seed`, record after
    /// record ([`SensorModel::uniforms`] each), drawn in parallel: `n x K`.
    pub fn uniforms_of(&self, seed: u64, first: u64, n: usize) -> Vec<f32> {
        let k = self.draws();
        let mut u = vec![0.0f32; n * k];
        if k > 0 {
            u.par_chunks_mut(k).enumerate().for_each(|(i, u)| self.uniforms(seed, first + i as u64, u));
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

    /// [`SensorModel::apply`] for a record `time` seconds into its run, when
    /// known (labels' `time`; `startup` uses it).
    pub fn apply_at(&self, d: &mut Dem, seed: u64, index: u64, time: Option<f64>) {
        let mut u = vec![0.0f32; self.draws()];
        self.uniforms(seed, index, &mut u);
        self.apply_drawn(d, &u, time);
    }

    /// Apply the model to records whose stream indices start at `first`, in
    /// parallel (the result does not depend on the thread count).
    pub fn apply_all(&self, records: &mut [Dem], seed: u64, first: u64) {
        self.apply_all_at(records, seed, first, None)
    }

    /// [`SensorModel::apply_all`] with each record's time in its run
    /// (`times[i]` for `records[i]`; NaN where unknown).
    pub fn apply_all_at(&self, records: &mut [Dem], seed: u64, first: u64, times: Option<&[f64]>) {
        records
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, d)| self.apply_at(d, seed, first + i as u64, times.and_then(|t| t.get(i).copied()).filter(|t| t.is_finite())));
    }

    /// [`SensorModel::apply_all_at`] on `records`, records `first..` of a
    /// stream whose first record is record `first_index` of the whole data
    /// set; `times` (the labels file and its times) index the stream's own
    /// records, and a stream longer than them is refused naming the file.
    pub fn apply_chunk(&self, records: &mut [Dem], seed: u64, first_index: u64, first: u64, times: Option<(&str, &[f64])>) -> Result<()> {
        let t = chunk_times(times, first, records.len())?;
        self.apply_all_at(records, seed, first_index + first, t);
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

/// The times of records `first..first + n` of a stream from its labels
/// (`(path, times)`); a stream longer than its labels is refused.
pub fn chunk_times<'a>(times: Option<(&str, &'a [f64])>, first: u64, n: usize) -> Result<Option<&'a [f64]>> {
    match times {
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

/// [`apply_stream`] with the time of each record in its run (`times[i]` for
/// record i of the stream; from a labels CSV). A stream longer than
/// `times` is refused.
pub fn apply_stream_at(
    model: &SensorModel,
    input: &str,
    output: &str,
    seed: u64,
    times: Option<(&str, &[f64])>,
    progress: impl Fn(u64),
) -> Result<u64> {
    apply_shard(model, input, output, seed, 0, times, progress)
}

/// [`apply_stream_at`] on a shard of a larger data set whose first record is
/// record `first_index` of the whole: each record's random draws come from
/// its index in the whole, so shards joined equal one run on the whole,
/// byte for byte. `times` index the shard's own records.
pub fn apply_shard(
    model: &SensorModel,
    input: &str,
    output: &str,
    seed: u64,
    first_index: u64,
    times: Option<(&str, &[f64])>,
    progress: impl Fn(u64),
) -> Result<u64> {
    apply_shard_emit(model, input, output, seed, first_index, times, None, progress)
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
    times: Option<(&str, &[f64])>,
    emit_uniform: Option<&str>,
    progress: impl Fn(u64),
) -> Result<u64> {
    let k = model.draws();
    let mut emit = emit_uniform.map(|p| dem_core::npy::F32ArrayWriter::create(p, &[k as u64])).transpose()?;
    let (_, written) = transform_checked(
        input,
        output,
        |first, chunk| {
            match &mut emit {
                None => model.apply_chunk(chunk, seed, first_index, first, times)?,
                Some(w) => {
                    let t = chunk_times(times, first, chunk.len())?;
                    let u = model.uniforms_of(seed, first_index + first, chunk.len());
                    chunk.par_iter_mut().enumerate().for_each(|(i, d)| {
                        model.apply_drawn(d, &u[i * k..(i + 1) * k], t.and_then(|t| t.get(i).copied()));
                    });
                    if k > 0 {
                        w.write(&u)?;
                    } else {
                        w.write_empty(chunk.len() as u64);
                    }
                }
            }
            progress(chunk.len() as u64);
            Ok(())
        },
        |read| labels_cover(times.map(|(p, t)| (p, t.len())), read),
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
                Effect::Noise(Noise { sigma0: 0.003, k: 0.01 }),
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
        let m = m.with(Effect::Noise(Noise { sigma0: 0.01, k: 0.0 }));
        assert_eq!(m.effects.iter().map(|e| e.name()).collect::<Vec<_>>(), ["occlusion", "noise", "dropout"]);
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
                Effect::Noise(Noise { sigma0: 0.01, k: 0.01 }),
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
