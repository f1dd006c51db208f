//! Training: losses, Adam, the Cycle GAN step.

pub mod adam;
pub mod cyclegan;
pub mod loss;

pub use adam::{Adam, AdamConfig};
pub use cyclegan::{Batch, CycleGan, GanConfig, Losses};
