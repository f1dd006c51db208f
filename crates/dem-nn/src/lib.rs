//! The Cycle GAN with paired data of `docs/network.md`, trained on the CPU
//! with kernels of our own over rayon and a packed GEMM.
//!
//! The modules form layers, bottom first; each uses only its own layer and
//! those below, so no two modules import each other in a circle:
//!
//! 0. [`gemm`]: the one bounds-checked wrapper over the GEMM kernel.
//! 1. [`weights`]: the parameters, in PyTorch's layout (checkpoints, export),
//!    and the architecture's constants (activation slope, norm epsilon, the
//!    residual head's scale and gate).
//! 2. [`layers`]: Winograd 3x3 conv, im2col conv over GEMM, instance norm +
//!    activation, dense.
//! 3. [`reference`](mod@reference): a slow f64 forward pass the fast code is
//!    tested against; only tests call it, production code never does.
//! 4. [`net`]: generator and discriminator on batches, forward and backward.
//! 5. [`train`]: losses, Adam and the Cycle GAN step.
//!
//! `tests/layers.rs` reads the sources and fails on an import that points up
//! or on production code that calls the reference.
#![deny(missing_docs)]

pub mod gemm;
pub mod layers;
pub mod net;
pub mod reference;
pub mod train;
pub mod weights;
