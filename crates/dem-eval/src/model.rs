//! `--model`: run an ONNX generator on the selected sim records only, in
//! batches of `--batch` records spread over threads with rayon (the model
//! is shared; each batch is independent, so the result does not depend on
//! the number of threads).

use std::collections::HashMap;

use dem_core::{Dem, DemError};
use dem_onnx::apply::{check_outputs, AttitudeCheck};
use dem_onnx::OnnxModel;
use rayon::prelude::*;

/// Predictions of the model at `path` for `sim` (index -> record), `batch`
/// records per model call. A NaN or infinite output is refused naming the
/// record (never scored as a missing cell); a model that changes row 20 gets
/// a warning, and is refused when `strict`.
pub fn predict(path: &str, sim: &HashMap<u64, Dem>, sim_path: &str, batch: usize, strict: bool) -> anyhow::Result<HashMap<u64, Dem>> {
    let model = OnnxModel::load(path)?;
    let mut keys: Vec<u64> = sim.keys().copied().collect();
    keys.sort_unstable();
    let inputs: Vec<Dem> = keys.iter().map(|k| sim[k]).collect();
    let outputs: Vec<Vec<Dem>> = inputs.par_chunks(batch).map(|c| model.run(c)).collect::<Result<_, DemError>>()?;
    let outputs: Vec<Dem> = outputs.into_iter().flatten().collect();
    if outputs.len() != keys.len() {
        return Err(DemError::input(path, format!("gave {} outputs for {} inputs", outputs.len(), keys.len())).into());
    }
    let mut attitude = AttitudeCheck::default();
    for (k, (x, y)) in keys.iter().zip(inputs.iter().zip(&outputs)) {
        check_outputs(std::slice::from_ref(x), std::slice::from_ref(y), *k, sim_path, path, strict, &mut attitude)?;
    }
    if let Some(w) = attitude.warning(path, sim_path) {
        dem_core::cli::log(w);
    }
    Ok(keys.into_iter().zip(outputs).collect())
}
