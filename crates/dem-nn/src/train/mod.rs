//! Training: losses, Adam, the Cycle GAN step, batches and checkpoints.
//! The run loop (a run directory, progress, losses.csv) is dem-train's.
//!
//! Layer 5 (train), the top: may use net, layers, weights and gemm.

pub mod adam;
pub mod checkpoint;
pub mod cyclegan;
pub mod data;
pub mod loss;

pub use adam::{Adam, AdamConfig};
pub use cyclegan::{Batch, CycleGan, GanConfig, Losses};
pub use data::{Sampler, TrainData};
