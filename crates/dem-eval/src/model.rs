//! `--model`: run an ONNX generator on the selected sim records only, in
//! batches of `--batch` records spread over threads with rayon (the model
//! is shared; each batch is independent, so the result does not depend on
//! the number of threads).

use dem_core::{Dem, DemError};
use dem_onnx::apply::{check_outputs, AttitudeCheck};
use dem_onnx::OnnxModel;
use rayon::prelude::*;

/// Predictions of `model` (loaded from `path`) for the sim records
/// `inputs` (stream indices `keys`, of `sim_path`), `batch` records per
/// model call. A NaN or infinite output is refused naming the record (never
/// scored as a missing cell); a model that changes row 20 is counted in
/// `attitude`, and refused when `strict`.
#[allow(clippy::too_many_arguments)]
pub fn predict(
    model: &OnnxModel,
    path: &str,
    keys: &[u64],
    inputs: &[Dem],
    sim_path: &str,
    batch: usize,
    strict: bool,
    attitude: &mut AttitudeCheck,
) -> anyhow::Result<Vec<Dem>> {
    let outputs: Vec<Vec<Dem>> = inputs.par_chunks(batch).map(|c| model.run(c)).collect::<Result<_, DemError>>()?;
    let outputs: Vec<Dem> = outputs.into_iter().flatten().collect();
    if outputs.len() != keys.len() {
        return Err(DemError::input(path, format!("gave {} outputs for {} inputs", outputs.len(), keys.len())).into());
    }
    for (k, (x, y)) in keys.iter().zip(inputs.iter().zip(&outputs)) {
        check_outputs(std::slice::from_ref(x), std::slice::from_ref(y), *k, sim_path, path, strict, attitude)?;
    }
    Ok(outputs)
}
