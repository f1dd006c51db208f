//! The Cycle GAN with paired data of `docs/network.md`, trained on the CPU
//! with kernels of our own over rayon and a packed GEMM.
//!
//! - [`weights`]: the parameters, in PyTorch's layout (checkpoints, export).
//! - [`reference`](mod@reference): a slow f64 forward pass the fast code is tested against.
//! - [`layers`]: Winograd 3x3 conv, im2col conv over GEMM, instance norm +
//!   activation, dense.
//! - [`net`]: generator and discriminator on batches, forward and backward.
//! - [`train`]: losses, Adam and the Cycle GAN step.
//! - [`gemm`]: the one bounds-checked wrapper over the GEMM kernel.
#![deny(missing_docs)]

pub mod gemm;
pub mod layers;
pub mod net;
pub mod reference;
pub mod train;
pub mod weights;
