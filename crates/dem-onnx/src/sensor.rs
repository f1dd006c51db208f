//! The virtual sensor as one ONNX graph: a generator, then what dem-apply
//! does to its output, as operators any runtime runs.
//!
//! ```text
//! dem (N,21,5,2) -> generator (docs/network.md) -> network_out (N,21,5,2)
//!   -> masks thresholded at 0: a cell is valid where its mask is > 0
//!   -> heights: `network` (the height head's) or `input` (dem's height where
//!      dem has the cell valid, the network's elsewhere)
//!   -> the residual sensor model's effects (dem-sensor's graph), with
//!      uniform (N,K) and time (N) as inputs
//!   -> dem_out (N,21,5,2): masks +-1, missing cells height 0, row 20 the
//!      network's (the input's, passed through)
//! ```
//!
//! A generator without a residual model and with the network's heights is
//! exported as the network alone ([`crate::generator::generator_model`]).
//! [`Stored::finish`] is the same tail in native code: dem-apply runs the
//! network on its fast path, then this, and a runtime fed the uniforms
//! dem-apply drew (`dem-apply --emit-uniform`) computes the same DEMs.
//!
//! The file says what it is: `dem.graph` = [`GRAPH_SENSOR`], the residual's
//! JSON (`dem.residual`), `dem.heights`, `dem.uniform_count` (K) and
//! `dem.inputs`, and a one-line `doc_string`. A loader takes the network
//! part ([`network_part`]) only after checking that the rest of the graph is
//! exactly what the metadata builds.

use dem_core::format::Dem;
use dem_core::DemError;
use dem_graph::Builder;
use dem_nn::weights::GeneratorWeights;
use dem_sensor::graph::{self as sensor_graph, Cells};
use dem_sensor::SensorModel;
use tract_onnx::pb;

use crate::generator::{generator_nodes, model_proto, ModelInfo, INPUT, OUTPUT, RESIDUAL_KEY};
use crate::heights::{Heights, HEIGHTS_KEY};

pub use dem_sensor::graph::{GRAPH_KEY, GRAPH_NETWORK_SENSOR as GRAPH_SENSOR, GRAPH_SENSOR_ONLY};
/// The tensor between the generator and the tail.
pub const NETWORK_OUT: &str = "network_out";

/// What an exported generator says dem-apply runs around its network.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stored {
    /// The residual sensor model (`dem-train export --residual`), if any.
    pub residual: Option<SensorModel>,
    /// Where its valid cells take their heights from (`dem-train export
    /// --heights`; a model without the key: the network's).
    pub heights: Heights,
}

impl Stored {
    /// Read the residual model and heights source from a model's metadata
    /// (`path` names the file in errors). Two entries of one key are refused.
    pub fn from_info(info: &ModelInfo, path: &str) -> Result<Stored, DemError> {
        let value = |key: &str| -> Result<Option<&String>, DemError> {
            let mut found = info.metadata.iter().filter(|(k, _)| k == key).map(|(_, v)| v);
            let first = found.next();
            if found.next().is_some() {
                return Err(DemError::input(path, format!("its metadata has {key} twice: which one runs is ambiguous")));
            }
            Ok(first)
        };
        let residual = value(RESIDUAL_KEY)?
            .map(|json| {
                SensorModel::from_json(json)
                    .map_err(|e| DemError::input(path, format!("its residual sensor model ({RESIDUAL_KEY}) is not valid: {e}")))
            })
            .transpose()?;
        let heights = match value(HEIGHTS_KEY)? {
            None => Heights::Network,
            Some(v) => v.parse().map_err(|e| DemError::input(path, format!("its {HEIGHTS_KEY} is not valid: {e}")))?,
        };
        Ok(Stored { residual, heights })
    }

    /// True when the graph holds more than the network: a residual model or
    /// the input's heights.
    pub fn has_tail(&self) -> bool {
        self.residual.is_some() || self.heights == Heights::Input
    }

    /// The residual model, or an empty one.
    pub fn residual_or_empty(&self) -> SensorModel {
        self.residual.clone().unwrap_or_default()
    }

    /// Uniforms per record (K).
    pub fn draws(&self) -> usize {
        self.residual.as_ref().map_or(0, SensorModel::draws)
    }

    /// What the graph does after the network, on one record: `out` the
    /// network's output for `input`, `u` the record's uniforms, `time` its
    /// time in its run (finite) when known. Does nothing without a tail.
    pub fn finish(&self, input: &Dem, out: &mut Dem, u: &[f32], time: Option<f64>) {
        if self.heights == Heights::Input {
            crate::heights::input_heights(input, out);
        }
        // The residual thresholds the masks first (SensorModel::apply_drawn).
        if let Some(r) = &self.residual {
            r.apply_drawn(out, u, time);
        }
    }

    /// One line each: what a runtime that loads the file gets, and its inputs.
    pub fn describe(&self, w_desc: &str) -> String {
        let model = self.residual_or_empty();
        let heights = match self.heights {
            Heights::Input => "the input's heights under its holes (the network's where the input has none)",
            Heights::Network => "the network's heights",
        };
        let residual = self
            .residual
            .as_ref()
            .map_or("no residual sensor model".to_string(), |r| format!("then the residual sensor model {}", r.summary()));
        format!(
            "dem-tools virtual sensor, one graph: {w_desc}, masks thresholded at 0 (missing: height 0, mask -1), {heights}, {residual}. \
             Inputs: {}. Output: dem_out float32 (N,21,5,2), the same DEMs as dem-apply given the same uniforms and times.",
            sensor_graph::input_list(&model)
        )
    }

    /// The metadata keys of a file with this tail: the residual's JSON,
    /// the heights source, what the graph holds and its inputs.
    pub fn metadata(&self) -> Vec<(String, String)> {
        let mut m = Vec::new();
        if let Some(r) = &self.residual {
            m.push((RESIDUAL_KEY.to_string(), serde_json::to_string(r).expect("a model serialises")));
            m.extend(sensor_graph::warning_metadata(r));
        }
        if self.heights != Heights::Network {
            m.push((HEIGHTS_KEY.to_string(), self.heights.to_string()));
        }
        m.push((GRAPH_KEY.to_string(), GRAPH_SENSOR.to_string()));
        m.extend(sensor_graph::io_metadata(&self.residual_or_empty()));
        m
    }
}

/// The tail's nodes on `g`, from [`NETWORK_OUT`] and [`INPUT`] to [`OUTPUT`].
fn tail_nodes(g: &mut Builder, stored: &Stored) {
    let (net, row20) = sensor_graph::split_dem(g, NETWORK_OUT);
    let cells = match stored.heights {
        Heights::Network => net,
        Heights::Input => {
            let (input, _) = sensor_graph::split_dem(g, INPUT);
            let both = g.bin("Mul", &net.v, &input.v);
            let both = g.gt_const(&both, 0.5);
            Cells { h: g.select(&both, &input.h, &net.h), v: net.v }
        }
    };
    let model = stored.residual_or_empty();
    let k = model.draws();
    let cells =
        sensor_graph::apply(g, &model, cells, (k > 0).then_some(sensor_graph::UNIFORM), model.uses_time().then_some(sensor_graph::TIME));
    sensor_graph::join_dem(g, &cells, &row20, OUTPUT);
}

/// The virtual sensor's ONNX model: generator `w` and the tail `stored`
/// describes (module docs); `stored` must have a tail.
pub fn sensor_model(w: &GeneratorWeights, name: &str, stored: &Stored) -> pb::ModelProto {
    assert!(stored.has_tail(), "a generator without a tail is exported as the network alone");
    let mut g = Builder::new();
    generator_nodes(&mut g, w, NETWORK_OUT);
    g.set_prefix("tail");
    tail_nodes(&mut g, stored);
    let desc = format!("G_Y ({} head, width {})", w.arch.name(), w.width);
    let model = stored.residual_or_empty();
    model_proto(g, name, stored.describe(&desc), sensor_graph::graph_inputs(&model), sensor_graph::graph_outputs(&model))
}

/// The network part of a virtual sensor file ([`network_part`]).
pub struct NetworkPart {
    /// The nodes up to [`NETWORK_OUT`], as a model of their own.
    pub network: pb::ModelProto,
    /// What the rest of the graph does.
    pub stored: Stored,
    /// A sensor model alone (`dem-sensor export`): its network is the identity.
    pub sensor_alone: bool,
}

/// The network part of a file whose graph is a virtual sensor: the nodes up
/// to [`NETWORK_OUT`] as a model of their own (input `dem`, output
/// `network_out`), after checking that the nodes and constants after it are
/// exactly those its metadata builds. `None` for a graph that is not one
/// (`dem.graph` absent).
pub fn network_part(proto: &pb::ModelProto, name: &str) -> Result<Option<NetworkPart>, DemError> {
    let info = ModelInfo::of(proto);
    let marked: Vec<&str> = info.metadata.iter().filter(|(k, _)| k == GRAPH_KEY).map(|(_, v)| v.as_str()).collect();
    match marked.as_slice() {
        [] => return Ok(None),
        [GRAPH_SENSOR] => {}
        [GRAPH_SENSOR_ONLY] => {
            let (network, stored) = sensor_alone(proto, &info, name)?;
            return Ok(Some(NetworkPart { network, stored, sensor_alone: true }));
        }
        other => {
            return Err(DemError::input(
                name,
                format!("its {GRAPH_KEY} is {other:?}; this version reads \"{GRAPH_SENSOR}\" and \"{GRAPH_SENSOR_ONLY}\""),
            ))
        }
    }
    let stored = Stored::from_info(&info, name)?;
    let graph = proto.graph.as_ref().ok_or_else(|| DemError::input(name, "not an ONNX model (no graph)"))?;
    let cut =
        graph.node.iter().position(|n| n.output.iter().any(|o| o == NETWORK_OUT)).ok_or_else(|| {
            DemError::input(name, format!("its graph has no {NETWORK_OUT}, though {GRAPH_KEY} says it is a virtual sensor"))
        })?;
    let mut tail = Builder::new();
    tail.set_prefix("tail");
    tail_nodes(&mut tail, &stored);
    let (head_nodes, tail_file) = graph.node.split_at(cut + 1);
    let tail_inits: Vec<&pb::TensorProto> = graph.initializer.iter().filter(|t| t.name.starts_with("tail.")).collect();
    let same = tail_file == tail.nodes.as_slice()
        && tail_inits.len() == tail.inits.len()
        && tail_inits.iter().zip(&tail.inits).all(|(a, b)| *a == b);
    if !same || !stored.has_tail() {
        return Err(DemError::input(
            name,
            "its graph after the network is not what its metadata (dem.residual, dem.heights) builds: the file was changed after export; re-export it with dem-train export",
        ));
    }
    let head_inits = graph.initializer.iter().filter(|t| !t.name.starts_with("tail.")).cloned().collect();
    let network = pb::ModelProto {
        graph: Some(pb::GraphProto {
            node: head_nodes.to_vec(),
            initializer: head_inits,
            input: graph.input.iter().filter(|i| i.name == INPUT).cloned().collect(),
            output: vec![dem_graph::batch_value(NETWORK_OUT, &[21, 5, 2])],
            name: graph.name.clone(),
            ..Default::default()
        }),
        ..proto.clone()
    };
    Ok(Some(NetworkPart { network, stored, sensor_alone: false }))
}

/// A sensor model alone (`dem-sensor export`): checked to be exactly the
/// graph its `dem.residual` builds, it runs as an identity network followed
/// by that model (masks thresholded, the input's heights).
fn sensor_alone(proto: &pb::ModelProto, info: &ModelInfo, name: &str) -> Result<(pb::ModelProto, Stored), DemError> {
    let stored = Stored::from_info(info, name)?;
    let model = stored
        .residual
        .clone()
        .ok_or_else(|| DemError::input(name, format!("its {GRAPH_KEY} says a sensor model, but it has no {RESIDUAL_KEY}")))?;
    let rebuilt = sensor_graph::sensor_model(&model, "check", &[]).graph.expect("a graph");
    let graph = proto.graph.as_ref().ok_or_else(|| DemError::input(name, "not an ONNX model (no graph)"))?;
    if graph.node != rebuilt.node || graph.initializer != rebuilt.initializer {
        return Err(DemError::input(
            name,
            "its graph is not what its metadata (dem.residual) builds: the file was changed after export; re-export it with dem-sensor export",
        ));
    }
    let mut g = Builder::new();
    g.node("Identity", &[INPUT], vec![], NETWORK_OUT);
    let identity = model_proto(
        g,
        &graph.name,
        String::new(),
        vec![dem_graph::batch_value(INPUT, &[21, 5, 2])],
        vec![dem_graph::batch_value(OUTPUT, &[21, 5, 2])],
    );
    let mut identity = identity;
    identity.graph.as_mut().expect("a graph").output = vec![dem_graph::batch_value(NETWORK_OUT, &[21, 5, 2])];
    Ok((identity, Stored { residual: Some(model), heights: Heights::Network }))
}
