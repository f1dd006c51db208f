//! ONNX for the dem-* tools: run any model that maps DEM batches to DEM
//! batches, and export the generator of `docs/network.md` to such a model.
//!
//! - [`model`]: [`OnnxModel`], a tract plan optimised once with a symbolic
//!   batch axis `N`: `(N, 21, 5, 2) float32 -> (N, 21, 5, 2) float32`, any
//!   `N >= 1`, callable from many threads at once (`Send + Sync`).
//! - [`export`]: [`generator_model`] builds the ONNX graph of a generator
//!   from its [`GeneratorWeights`](dem_nn::weights::GeneratorWeights) with
//!   tract's protobuf types; [`export_checked`] writes it only after tract
//!   reproduces the trainer's forward pass within [`TOLERANCE`].
//! - [`native`]: recognise a generator in an ONNX graph and read its
//!   weights, so [`OnnxModel`] runs it on dem-nn's inference kernels (checked
//!   against tract at load; any other model runs on tract).
//! - [`apply`]: stream an NPY stream through a model in parallel batches,
//!   order preserved (the body of `dem-apply`).
//! - [`masks`] and [`heights`]: what dem-apply can do to a generator's
//!   output: holes drawn from its masks, the input's heights under its holes.
//!
//! Both sides of a model use the file layout of `docs/format.md`: input
//! `dem`, output `dem_out`, so a saved NPY goes straight in.
#![deny(missing_docs)]

pub mod apply;
pub mod export;
pub mod generator;
pub mod heights;
pub mod masks;
pub mod model;
pub mod native;
pub mod sensor;

pub use export::{export_checked, export_checked_with, ExportReport};
pub use generator::{generator_model, read_info, ModelInfo, TOLERANCE};
pub use heights::{Heights, HEIGHTS_KEY};
pub use model::{Engine, OnnxModel};

/// The ONNX protobuf types (tract's generated `prost` messages), for callers
/// that build or inspect models.
pub use tract_onnx::pb;
