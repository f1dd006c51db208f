//! The layers' forward and backward kernels on channels-last batches.
//! Each documents its formula and shapes; the networks in [`crate::net`]
//! chain them and keep what backward needs.
//!
//! Layer 2 (layers): may use gemm and weights.

pub mod conv;
pub mod dense;
pub mod norm;
pub mod winograd;
pub mod winograd_rect;
