//! A sensor model as ONNX operators: the same effects as [`crate::effects`],
//! on a batch, with the record's uniforms and time as graph inputs.
//!
//! The grid travels through the graph as two float32 tensors `(N, 20, 5)`
//! ([`Cells`]): `v`, 1 where a cell is valid and 0 where it is missing, and
//! `h`, its height (0 where missing, as the contract stores it). Each effect
//! reads the cells as they come in (a snapshot, as the native code reads
//! [`heights`](crate::effects) before it writes) and returns new ones.
//! Neighbours are the grid shifted by one row or column, padded with
//! missing cells ([`dem_graph::Builder::shift`]). Each effect's operators
//! are in its file ([`crate::effects`], [`crate::effects::EffectKind::graph`]),
//! built from [`ops`].
//!
//! The graph computes in float32 where the native code computes in float64
//! from float32 heights: heights agree within ~1e-6 m, and a cell's validity
//! differs only where a comparison lies within float32's rounding of its
//! threshold. Comparisons of a uniform with a probability are exact in both
//! (24-bit uniforms, [`crate::draws`]).

use dem_core::format::{COLS, GRID_ROWS};
use dem_graph::{Builder, Input};

use crate::fusion::{MOTION, MOTION_LEN, RESET, STATE, STATE_OUT};
use crate::{Effect, SensorModel};

pub mod ops;

use ops::*;
pub use ops::{Cells, INPUT};

/// Name of the uniforms input: `(N, K)`, float32 in [0, 1), K =
/// [`SensorModel::draws`], each effect's slice in the model's order.
pub const UNIFORM: &str = "uniform";
/// Name of the time input: `(N,)`, float32 seconds into the run; NaN where
/// unknown (`startup` then draws startup frames at its rate `p`).
pub const TIME: &str = "time";
/// Name of the output DEM (`(N, 21, 5, 2)`).
pub const OUTPUT: &str = "dem_out";

/// The input DEM `(N, 21, 5, 2)` split into [`Cells`] (a cell is valid
/// where its mask is > 0) and row 20 `(N, 1, 5, 2)`.
pub fn split_dem(b: &mut Builder, dem: &str) -> (Cells, String) {
    let grid = b.take(dem, 1, 0, GRID_ROWS as i64);
    let row20 = b.take(dem, 1, GRID_ROWS as i64, GRID_ROWS as i64 + 1);
    let shape = [-1, GRID_ROWS as i64, COLS as i64];
    let h = b.take(&grid, 3, 0, 1);
    let h = b.reshape(&h, &shape);
    let m = b.take(&grid, 3, 1, 2);
    let m = b.reshape(&m, &shape);
    let valid = b.gt_const(&m, 0.0);
    let v = b.to_float(&valid);
    let zero = b.scalar(0.0);
    let h = b.select(&valid, &h, &zero);
    (Cells { h, v }, row20)
}

/// [`Cells`] and row 20 joined into a DEM `(N, 21, 5, 2)` named `out`:
/// valid cells with mask +1, missing ones height 0 and mask -1.
pub fn join_dem(b: &mut Builder, c: &Cells, row20: &str, out: &str) -> String {
    let valid = is_valid(b, &c.v);
    let (one, minus, zero) = (b.scalar(1.0), b.scalar(-1.0), b.scalar(0.0));
    let m = b.select(&valid, &one, &minus);
    let h = b.select(&valid, &c.h, &zero);
    let shape = [-1, GRID_ROWS as i64, COLS as i64, 1];
    let h = b.reshape(&h, &shape);
    let m = b.reshape(&m, &shape);
    let grid = b.concat(&[&h, &m], 3);
    b.node("Concat", &[&grid, row20], vec![dem_graph::attr_int("axis", 1)], out)
}

/// Every effect of `model`, in order, on `cells`; `uniform` is the graph's
/// `(N, K)` uniforms (needed when K > 0), `time` its `(N,)` times (needed
/// when the model has `startup`). A map's memory then steps the frame
/// ([`crate::fusion::operators`]) from the graph's [`INPUT`] and state
/// inputs, and names the new state [`STATE_OUT`].
pub fn apply(b: &mut Builder, model: &SensorModel, cells: Cells, uniform: Option<&str>, time: Option<&str>) -> Cells {
    let mut at = 0;
    let mut c = cells;
    let base = b.prefix().to_string();
    for (i, e) in model.effects.iter().enumerate() {
        let scope = format!("sensor.{i}.{}", e.name());
        b.set_prefix(&if base.is_empty() { scope } else { format!("{base}.{scope}") });
        let n = e.draws();
        let u = (n > 0).then(|| uniforms(b, uniform.expect("a model with draws has a uniform input"), at, n, &[-1, n as i64]));
        // An effect that draws nothing never reads its uniforms.
        c = e.graph(b, &c, u.as_deref().unwrap_or(""), time);
        if let (Effect::MapMemory(m), Some(u)) = (e, &u) {
            let (input, _) = split_dem(b, INPUT);
            c = crate::fusion::operators(b, *m, &c, &input, u);
        }
        at += n;
    }
    b.set_prefix(&base);
    c
}

/// The ONNX model of `model` alone: a virtual sensor without a network.
/// Inputs [`INPUT`] `(N, 21, 5, 2)`, [`UNIFORM`] `(N, K)` when the model
/// draws (K = [`SensorModel::draws`]), [`TIME`] `(N,)` when it has
/// `startup`; output [`OUTPUT`] `(N, 21, 5, 2)`. The metadata says what
/// the inputs are (see [`io_metadata`]).
pub fn sensor_model(model: &SensorModel, name: &str, extra_metadata: &[(String, String)]) -> dem_graph::proto::ModelProto {
    let mut b = Builder::new();
    let (cells, row20) = split_dem(&mut b, INPUT);
    let k = model.draws();
    let uniform = (k > 0).then_some(UNIFORM);
    let time = model.uses_time().then_some(TIME);
    let cells = apply(&mut b, model, cells, uniform, time);
    join_dem(&mut b, &cells, &row20, OUTPUT);
    let mut metadata = vec![(GRAPH_KEY.to_string(), GRAPH_SENSOR_ONLY.to_string())];
    metadata.extend(io_metadata(model));
    metadata.push((RESIDUAL_JSON_KEY.into(), serde_json::to_string(model).expect("a model serialises")));
    metadata.extend(warning_metadata(model));
    metadata.extend_from_slice(extra_metadata);
    let doc = format!(
        "dem-tools virtual sensor of named effects ({}), no network. Inputs: {}. Output: dem_out float32 (N,21,5,2), \
         masks +-1, missing cells height 0, row 20 passed through.",
        model.summary(),
        input_list(model)
    );
    b.model(name, graph_inputs(model), graph_outputs(model), doc, &metadata)
}

/// The graph's outputs for `model`: [`OUTPUT`], and [`STATE_OUT`] with a
/// map's memory.
pub fn graph_outputs(model: &SensorModel) -> Vec<dem_graph::proto::ValueInfoProto> {
    let mut v = vec![dem_graph::batch_value(OUTPUT, &[21, 5, 2])];
    if model.map_memory().is_some() {
        v.push(dem_graph::batch_value(STATE_OUT, &STATE_DIMS));
    }
    v
}

/// A state's shape after the batch axis: `(20, 5, 4)`.
pub const STATE_DIMS: [i64; 3] = [GRID_ROWS as i64, COLS as i64, crate::fusion::CHANNELS as i64];

/// The `metadata_props` key of a model's warnings ([`SensorModel::warnings`]),
/// one a line: `dem-apply --info` prints them under it.
pub const WARNINGS_KEY: &str = "dem.warnings";

/// [`WARNINGS_KEY`] with `model`'s warnings, one a line; nothing when it
/// has none.
pub fn warning_metadata(model: &SensorModel) -> Option<(String, String)> {
    (!model.warnings.is_empty()).then(|| (WARNINGS_KEY.to_string(), model.warnings.join("\n")))
}

/// The `metadata_props` key that says what a dem-tools graph holds.
pub const GRAPH_KEY: &str = "dem.graph";
/// [`GRAPH_KEY`]'s value for a sensor model alone (`dem-sensor export`).
pub const GRAPH_SENSOR_ONLY: &str = "sensor";
/// [`GRAPH_KEY`]'s value for a generator followed by its sensor tail.
pub const GRAPH_NETWORK_SENSOR: &str = "network+sensor";

/// The `metadata_props` key holding the sensor model's JSON.
pub const RESIDUAL_JSON_KEY: &str = "dem.residual";
/// The key stating K, the uniforms per record.
pub const UNIFORM_COUNT_KEY: &str = "dem.uniform_count";
/// The key stating the graph's inputs, comma-separated.
pub const INPUTS_KEY: &str = "dem.inputs";

/// The graph's inputs for `model`: `dem`, then `uniform` and `time` as needed.
pub fn graph_inputs(model: &SensorModel) -> Vec<dem_graph::proto::ValueInfoProto> {
    let mut v = vec![dem_graph::batch_value(INPUT, &[21, 5, 2])];
    if model.draws() > 0 {
        v.push(dem_graph::batch_value(UNIFORM, &[model.draws() as i64]));
    }
    if model.uses_time() {
        v.push(dem_graph::batch_value(TIME, &[]));
    }
    if model.map_memory().is_some() {
        v.push(dem_graph::batch_value(STATE, &STATE_DIMS));
        v.push(dem_graph::batch_value(MOTION, &[MOTION_LEN as i64]));
        v.push(dem_graph::batch_value(RESET, &[]));
    }
    v
}

/// One line naming each input and its meaning.
pub fn input_list(model: &SensorModel) -> String {
    let mut parts = vec!["dem float32 (N,21,5,2)".to_string()];
    if model.draws() > 0 {
        parts.push(format!("uniform float32 (N,{}) in [0,1), drawn fresh per call", model.draws()));
    }
    if model.uses_time() {
        parts.push("time float32 (N) seconds into the run, NaN where unknown".to_string());
    }
    if model.map_memory().is_some() {
        parts.push(
            "state float32 (N,20,5,4) the last frame's state_out (zeros at a reset); motion float32 (N,4) dx, dy (m), dyaw (rad) \
             since the last frame, in its axes, and dt (s); reset float32 (N) 1 at a run's first frame, else 0. Outputs also state_out"
                .to_string(),
        );
    }
    parts.join("; ")
}

/// `metadata_props` that say what the inputs are: K and the input names.
pub fn io_metadata(model: &SensorModel) -> Vec<(String, String)> {
    let mut names = vec![INPUT];
    if model.draws() > 0 {
        names.push(UNIFORM);
    }
    if model.uses_time() {
        names.push(TIME);
    }
    if model.map_memory().is_some() {
        names.extend([STATE, MOTION, RESET]);
    }
    vec![(UNIFORM_COUNT_KEY.into(), model.draws().to_string()), (INPUTS_KEY.into(), names.join(","))]
}

/// Run `proto` (a sensor graph, or any graph with the same inputs) with
/// tract on `records`, with their uniforms (`records.len() x K`, row-major)
/// and times (NaN where unknown); a graph with a map's memory as at each
/// run's first frame.
pub fn run_tract(
    proto: &dem_graph::proto::ModelProto,
    model: &SensorModel,
    records: &[dem_core::Dem],
    uniform: &[f32],
    times: &[f32],
) -> anyhow::Result<Vec<dem_core::Dem>> {
    let n = records.len();
    let first = Step { state: &vec![0.0; n * crate::fusion::STATE_LEN], motion: &vec![0.0; n * MOTION_LEN], reset: &vec![1.0; n] };
    Ok(run_tract_step(proto, model, records, uniform, times, first)?.0)
}

/// The state inputs of one step of a graph with a map's memory, one
/// record after another, row-major.
#[derive(Clone, Copy)]
pub struct Step<'a> {
    /// [`STATE`]: `N x 400`.
    pub state: &'a [f32],
    /// [`MOTION`]: `N x 3`.
    pub motion: &'a [f32],
    /// [`RESET`]: `N`.
    pub reset: &'a [f32],
}

/// [`run_tract`] for one step of a graph: its DEMs and, with a map's
/// memory, its new state (`N x 400`; empty without).
pub fn run_tract_step(
    proto: &dem_graph::proto::ModelProto,
    model: &SensorModel,
    records: &[dem_core::Dem],
    uniform: &[f32],
    times: &[f32],
    step: Step,
) -> anyhow::Result<(Vec<dem_core::Dem>, Vec<f32>)> {
    let n = records.len();
    let flat: Vec<f32> = records.iter().flat_map(|d| d.iter().copied()).collect();
    let mut inputs = vec![Input { name: INPUT, shape: vec![n, 21, 5, 2], data: &flat }];
    if model.draws() > 0 {
        inputs.push(Input { name: UNIFORM, shape: vec![n, model.draws()], data: uniform });
    }
    if model.uses_time() {
        inputs.push(Input { name: TIME, shape: vec![n], data: times });
    }
    if model.map_memory().is_some() {
        inputs.push(Input { name: STATE, shape: vec![n, GRID_ROWS, COLS, crate::fusion::CHANNELS], data: step.state });
        inputs.push(Input { name: MOTION, shape: vec![n, MOTION_LEN], data: step.motion });
        inputs.push(Input { name: RESET, shape: vec![n], data: step.reset });
    }
    let mut out = dem_graph::run_all(proto, &inputs)?;
    let state = if out.len() > 1 { out.swap_remove(1) } else { Vec::new() };
    let dems = out[0].chunks(dem_core::format::RECORD_LEN).map(|c| std::array::from_fn(|i| c[i])).collect();
    Ok((dems, state))
}
