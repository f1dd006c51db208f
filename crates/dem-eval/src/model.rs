//! `--model`: run an ONNX generator on the selected sim records only, in
//! batches of `--batch` records spread over threads with rayon (the model
//! is shared; each batch is independent, so the result does not depend on
//! the number of threads).

use std::collections::HashMap;

use dem_core::{Dem, DemError};
use dem_onnx::OnnxModel;
use rayon::prelude::*;

/// Predictions of the model at `path` for `sim` (index -> record), `batch`
/// records per model call.
pub fn predict(path: &str, sim: &HashMap<u64, Dem>, batch: usize) -> anyhow::Result<HashMap<u64, Dem>> {
    let model = OnnxModel::load(path)?;
    let mut keys: Vec<u64> = sim.keys().copied().collect();
    keys.sort_unstable();
    let inputs: Vec<Dem> = keys.iter().map(|k| sim[k]).collect();
    let outputs: Vec<Vec<Dem>> = inputs.par_chunks(batch).map(|c| model.run(c)).collect::<Result<_, DemError>>()?;
    let outputs: Vec<Dem> = outputs.into_iter().flatten().collect();
    if outputs.len() != keys.len() {
        return Err(DemError::input(path, format!("gave {} outputs for {} inputs", outputs.len(), keys.len())).into());
    }
    // The contract's input rule applies to what a model hands back too.
    Ok(keys.into_iter().zip(outputs).map(|(k, mut d)| (k, {
        dem_core::format::canonicalize(&mut d);
        d
    })).collect())
}
