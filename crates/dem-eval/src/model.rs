//! `--model`: run an ONNX generator on the selected sim records.

use std::collections::HashMap;

use dem_core::{cli, Dem};

/// Predictions of the model at `path` for `sim` (index -> record), `batch`
/// records per call.
pub fn predict(path: &str, sim: &HashMap<u64, Dem>, batch: usize) -> anyhow::Result<HashMap<u64, Dem>> {
    let _ = (sim, batch);
    Err(cli::usage(format!(
        "--model {path}: not built yet (the ONNX runner of dem-onnx has not landed); run the model elsewhere and pass --pred"
    )))
}
