//! Fully connected layer on a batch: `y [n, out] = x [n, in] W [in, out] + b`.
//!
//! Backward: `dW += x^T dy`, `db += sum_n dy`, `dx = dy W^T`.
//!
//! Layer 2 (layers): may use gemm and weights.

use crate::gemm::{matmul, Mat};

/// `y = x W + b`.
pub fn forward(w: &[f32], b: &[f32], x: &[f32], n_in: usize, y: &mut Vec<f32>) {
    let n_out = b.len();
    let n = x.len() / n_in;
    y.clear();
    y.reserve(n * n_out);
    for _ in 0..n {
        y.extend_from_slice(b);
    }
    matmul(y, Mat::new(x, n, n_in), Mat::new(w, n_in, n_out), true);
}

/// Backward of [`forward`]; `grads = Some((dw, db))` accumulates the
/// parameter gradients, `dx = Some(..)` receives the input gradient.
pub fn backward(w: &[f32], x: &[f32], n_in: usize, dy: &[f32], grads: Option<(&mut [f32], &mut [f32])>, dx: Option<&mut Vec<f32>>) {
    let n = x.len() / n_in;
    if let Some((dw, db)) = grads {
        let n_out = db.len();
        matmul(dw, Mat::new(x, n, n_in).t(), Mat::new(dy, n, n_out), true);
        for row in dy.chunks_exact(n_out) {
            db.iter_mut().zip(row).for_each(|(d, v)| *d += v);
        }
    }
    if let Some(dx) = dx {
        let n_out = dy.len() / n;
        dx.resize(n * n_in, 0.0);
        matmul(dx, Mat::new(dy, n, n_out), Mat::new(w, n_in, n_out).t(), false);
    }
}
