//! Checkpoints: everything a run needs to continue exactly (the four
//! networks, their Adam moments and step counts, the settings and the step
//! reached), in one file written atomically.
//!
//! Layout: the 8 bytes `DEMCKPT1`, a little-endian u64 length, that many
//! bytes of JSON ([`Meta`]), then for G_X, G_Y, D_X, D_Y in turn the
//! parameters, Adam's first and second moments as little-endian f32.
//!
//! Layer 5 (train), the top: may use net, layers, weights and gemm.

use std::io::{Read, Write};

use dem_core::output;
use dem_core::DemError;
use serde::{Deserialize, Serialize};

use super::adam::Adam;
use super::cyclegan::{CycleGan, GanConfig, NAMES};

const MAGIC: &[u8; 8] = b"DEMCKPT1";

/// Settings and progress stored beside the numbers.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Meta {
    /// The model and optimiser settings.
    pub config: GanConfig,
    /// Seed of initialisation and sampling.
    pub seed: u64,
    /// Records per batch.
    pub batch: usize,
    /// Share of each batch drawn from train pairs.
    pub paired_fraction: f64,
    /// Steps done.
    pub step: u64,
    /// Steps per epoch of the data trained on.
    pub steps_per_epoch: u64,
    /// Parameters of G_X, G_Y, D_X, D_Y.
    pub sizes: [usize; 4],
    /// Adam steps of each.
    pub adam_steps: [u64; 4],
    /// Networks in order.
    pub networks: [String; 4],
    /// Sensor model applied to the sims before training, if any (JSON).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor: Option<serde_json::Value>,
    /// The files the run was started on (empty for checkpoints written
    /// before they were recorded).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub data: Vec<DataFile>,
}

/// One input file of a run: what it was, where, how many records, and a
/// hash of its bytes, so an exported model says what it was trained on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DataFile {
    /// `sim`, `real`, `pairs` or `sensor`.
    pub role: String,
    /// The path given (`-` for stdin).
    pub path: String,
    /// Records (NPY) or rows (CSV), when counted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub records: Option<usize>,
    /// SHA-256 of the file's bytes, hex (none for stdin).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sha256: Option<String>,
}

/// Write `gan` and `meta` to `path` atomically.
pub fn save(path: &str, gan: &CycleGan, meta: &Meta) -> Result<(), DemError> {
    let json = serde_json::to_vec(meta).expect("meta serialises");
    output::write_atomic(path, |w| {
        w.write_all(MAGIC)?;
        w.write_all(&(json.len() as u64).to_le_bytes())?;
        w.write_all(&json)?;
        for (p, o) in gan.params.iter().zip(&gan.opts) {
            for v in [p, &o.m, &o.v] {
                let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
                w.write_all(&bytes)?;
            }
        }
        Ok(())
    })
}

fn bad(path: &str, reason: impl Into<String>) -> DemError {
    DemError::Input { path: path.into(), reason: reason.into() }
}

/// Read a checkpoint written by [`save`].
pub fn load(path: &str) -> Result<(Meta, CycleGan), DemError> {
    let mut f = std::fs::File::open(path).map_err(|e| DemError::Open { path: path.into(), source: e })?;
    let mut bytes = Vec::new();
    f.read_to_end(&mut bytes).map_err(|e| DemError::io(path, e))?;
    if bytes.len() < 16 || &bytes[..8] != MAGIC {
        return Err(bad(path, "not a dem-train checkpoint (bad magic)"));
    }
    let len = u64::from_le_bytes(bytes[8..16].try_into().expect("8 bytes")) as usize;
    let json = bytes.get(16..16 + len).ok_or_else(|| bad(path, "truncated header"))?;
    let meta: Meta = serde_json::from_slice(json).map_err(|e| bad(path, format!("header: {e}")))?;
    let mut gan = CycleGan::new(meta.config, meta.seed);
    if gan.sizes() != meta.sizes {
        return Err(bad(path, format!("network sizes {:?} do not match width {}", meta.sizes, meta.config.width)));
    }
    let need = 16 + len + 3 * 4 * meta.sizes.iter().sum::<usize>();
    if bytes.len() != need {
        return Err(bad(path, format!("{} bytes, expected {need}", bytes.len())));
    }
    let mut floats = bytes[16 + len..].chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")));
    for k in 0..4 {
        let n = meta.sizes[k];
        let mut take = || -> Vec<f32> { floats.by_ref().take(n).collect() };
        let (p, m, v) = (take(), take(), take());
        gan.params[k] = p;
        gan.opts[k] = Adam { cfg: meta.config.adam, t: meta.adam_steps[k], m, v };
    }
    Ok((meta, gan))
}

/// The metadata a run at `step` would store.
pub fn meta(gan: &CycleGan, seed: u64, batch: usize, paired_fraction: f64, step: u64, steps_per_epoch: u64) -> Meta {
    Meta {
        config: gan.cfg,
        seed,
        batch,
        paired_fraction,
        step,
        steps_per_epoch,
        sizes: gan.sizes(),
        adam_steps: gan.opts.each_ref().map(|o| o.t),
        networks: NAMES.map(String::from),
        sensor: None,
        data: Vec::new(),
    }
}
