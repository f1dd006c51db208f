//! The two networks on batches: layouts of their flat parameter vectors,
//! forward passes that keep a tape, and backward passes over it; and the
//! generator's inference-only forward pass ([`infer`]).
//!
//! Layer 4 (net): may use layers, weights and gemm.

pub mod discriminator;
pub mod generator;
pub mod infer;
pub mod params;

pub use discriminator::{DiscScratch, DiscTape, Discriminator};
pub use generator::{GenScratch, GenTape, Generator};
pub use infer::{GeneratorInference, InferScratch};
