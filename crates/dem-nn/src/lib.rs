//! The Cycle GAN with paired data of `spec/network.md`, trained on the CPU
//! with kernels of our own over rayon and a packed GEMM.
//!
//! - [`weights`]: the parameters, in PyTorch's layout (checkpoints, export).
//! - [`reference`]: a slow f64 forward pass the fast code is tested against.
#![deny(missing_docs)]

pub mod reference;
pub mod weights;
