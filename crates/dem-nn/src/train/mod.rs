//! Training: losses, Adam, the Cycle GAN step, batches, checkpoints and the
//! run loop.

pub mod adam;
pub mod checkpoint;
pub mod cyclegan;
pub mod data;
pub mod loss;
pub mod session;

pub use adam::{Adam, AdamConfig};
pub use cyclegan::{Batch, CycleGan, GanConfig, Losses};
pub use data::{Sampler, TrainData};
