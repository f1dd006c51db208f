//! 2-D convolution on channels-last maps, as im2col + one GEMM.
//!
//! Shapes: input `x` is `[n, h, w, c_in]`, output `y` is `[n, oh, ow, c_out]`
//! (row-major, so `M = n*oh*ow` rows of `c_out`). The weights are the matrix
//! `W [K, c_out]` with `K = k*k*c_in` ordered `(ky, kx, ci)`, the order of the
//! im2col columns:
//!
//! ```text
//! col[m, (ky*k + kx)*c_in + ci] = x[n, oy*s + ky - pad_top, ox*s + kx - pad_left, ci]  (0 outside)
//! y   = col W + b
//! dW += col^T dy,   db += sum_m dy,   dx = col2im(dy W^T)
//! ```
//!
//! Layer 2 (layers): may use gemm and weights.

use rayon::prelude::*;

use crate::gemm::{matmul, Mat};

/// Where a convolution reads and writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ConvGeom {
    /// Input rows.
    pub h: usize,
    /// Input columns.
    pub w: usize,
    /// Input channels.
    pub c_in: usize,
    /// Output channels.
    pub c_out: usize,
    /// Kernel size (square).
    pub k: usize,
    /// Stride (both axes).
    pub stride: usize,
    /// Zero rows above.
    pub pad_top: usize,
    /// Zero columns to the left.
    pub pad_left: usize,
    /// Output rows.
    pub oh: usize,
    /// Output columns.
    pub ow: usize,
}

impl ConvGeom {
    /// 3x3, stride 1, padding 1: the generator's convs.
    pub fn same3(h: usize, w: usize, c_in: usize, c_out: usize) -> Self {
        ConvGeom { h, w, c_in, c_out, k: 3, stride: 1, pad_top: 1, pad_left: 1, oh: h, ow: w }
    }

    /// PyTorch-style "same" padding ([`same_pad`]), the discriminator's.
    pub fn same(h: usize, w: usize, c_in: usize, c_out: usize, k: usize, stride: usize) -> Self {
        let (oh, pad_top, _) = same_pad(h, k, stride);
        let (ow, pad_left, _) = same_pad(w, k, stride);
        ConvGeom { h, w, c_in, c_out, k, stride, pad_top, pad_left, oh, ow }
    }

    /// Columns of the im2col matrix (rows of W).
    pub fn kdim(&self) -> usize {
        self.k * self.k * self.c_in
    }

    /// Values of one sample's input map.
    pub fn in_len(&self) -> usize {
        self.h * self.w * self.c_in
    }

    /// Output positions of one sample.
    pub fn out_pos(&self) -> usize {
        self.oh * self.ow
    }

    /// Number of weights (`K * c_out`).
    pub fn weight_len(&self) -> usize {
        self.kdim() * self.c_out
    }

    /// Input position of output `(oy, ox)` and tap `(ky, kx)`, if inside.
    #[inline]
    fn source(&self, oy: usize, ox: usize, ky: usize, kx: usize) -> Option<usize> {
        let iy = (oy * self.stride + ky).checked_sub(self.pad_top)?;
        let ix = (ox * self.stride + kx).checked_sub(self.pad_left)?;
        (iy < self.h && ix < self.w).then_some(iy * self.w + ix)
    }
}

/// PyTorch-style "same" padding of one axis of length `n` for kernel size `k`
/// and stride `s`: `(output length, zeros before, zeros after)`, the odd zero
/// after. The kernels and the f64 reference both take it from here, so they
/// cannot disagree on the discriminator's shapes.
pub fn same_pad(n: usize, k: usize, s: usize) -> (usize, usize, usize) {
    let out = n.div_ceil(s);
    let total = ((out - 1) * s + k).saturating_sub(n);
    (out, total / 2, total - total / 2)
}

/// `col [n*oh*ow, K]` from `x [n, h, w, c_in]`.
pub fn im2col(g: &ConvGeom, x: &[f32], col: &mut Vec<f32>) {
    let (kd, c) = (g.kdim(), g.c_in);
    let n = x.len() / g.in_len();
    col.clear();
    col.resize(n * g.out_pos() * kd, 0.0);
    col.par_chunks_mut(g.out_pos() * kd).zip(x.par_chunks(g.in_len())).for_each(|(cs, xs)| {
        for oy in 0..g.oh {
            for ox in 0..g.ow {
                let row = &mut cs[(oy * g.ow + ox) * kd..][..kd];
                for ky in 0..g.k {
                    for kx in 0..g.k {
                        if let Some(p) = g.source(oy, ox, ky, kx) {
                            row[(ky * g.k + kx) * c..][..c].copy_from_slice(&xs[p * c..][..c]);
                        }
                    }
                }
            }
        }
    });
}

/// The adjoint of [`im2col`]: `dx [n, h, w, c_in] = sum of dcol over taps`.
pub fn col2im(g: &ConvGeom, dcol: &[f32], dx: &mut Vec<f32>) {
    let (kd, c) = (g.kdim(), g.c_in);
    let n = dcol.len() / (g.out_pos() * kd);
    dx.clear();
    dx.resize(n * g.in_len(), 0.0);
    dx.par_chunks_mut(g.in_len()).zip(dcol.par_chunks(g.out_pos() * kd)).for_each(|(xs, cs)| {
        for oy in 0..g.oh {
            for ox in 0..g.ow {
                let row = &cs[(oy * g.ow + ox) * kd..][..kd];
                for ky in 0..g.k {
                    for kx in 0..g.k {
                        if let Some(p) = g.source(oy, ox, ky, kx) {
                            let src = &row[(ky * g.k + kx) * c..][..c];
                            xs[p * c..][..c].iter_mut().zip(src).for_each(|(d, s)| *d += s);
                        }
                    }
                }
            }
        }
    });
}

/// `y = col W + b` for a batch; `col` is filled from `x` and kept for backward.
pub fn forward(g: &ConvGeom, w: &[f32], b: &[f32], x: &[f32], col: &mut Vec<f32>, y: &mut Vec<f32>) {
    im2col(g, x, col);
    let m = col.len() / g.kdim();
    y.clear();
    y.reserve(m * g.c_out);
    for _ in 0..m {
        y.extend_from_slice(b);
    }
    matmul(y, Mat::new(col, m, g.kdim()), Mat::new(w, g.kdim(), g.c_out), true);
}

/// Backward of [`forward`]: with `grads = Some((dw, db))` accumulate
/// `dW += col^T dy` and `db += sum dy`; with `dx = Some(..)` set
/// `dx = col2im(dy W^T)`, using `scratch` for `dy W^T`. `col` is left intact,
/// so a forward pass can be back-propagated more than once.
#[allow(clippy::too_many_arguments)]
pub fn backward(
    g: &ConvGeom,
    w: &[f32],
    col: &[f32],
    dy: &[f32],
    grads: Option<(&mut [f32], &mut [f32])>,
    dx: Option<&mut Vec<f32>>,
    scratch: &mut Vec<f32>,
) {
    let kd = g.kdim();
    let m = col.len() / kd;
    if let Some((dw, db)) = grads {
        matmul(dw, Mat::new(col, m, kd).t(), Mat::new(dy, m, g.c_out), true);
        for row in dy.chunks_exact(g.c_out) {
            db.iter_mut().zip(row).for_each(|(d, v)| *d += v);
        }
    }
    if let Some(dx) = dx {
        scratch.resize(m * kd, 0.0);
        matmul(scratch, Mat::new(dy, m, g.c_out), Mat::new(w, kd, g.c_out).t(), false);
        col2im(g, scratch, dx);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_padding_gives_the_discriminators_shapes() {
        // 20x5 -> 10x3 -> 5x2 -> 5x2, as the discriminator's head expects.
        assert_eq!(same_pad(20, 4, 2), (10, 1, 1));
        assert_eq!(same_pad(5, 4, 2), (3, 1, 2));
        assert_eq!(same_pad(10, 4, 2), (5, 1, 1));
        assert_eq!(same_pad(3, 4, 2), (2, 1, 2));
        assert_eq!(same_pad(5, 4, 1), (5, 1, 2));
        assert_eq!(same_pad(2, 4, 1), (2, 1, 2));
    }

    /// im2col and col2im are adjoint: <im2col(x), c> = <x, col2im(c)>.
    #[test]
    fn col2im_is_the_adjoint_of_im2col() {
        for g in [ConvGeom::same3(20, 5, 3, 4), ConvGeom::same(20, 5, 2, 4, 4, 2), ConvGeom::same(5, 2, 3, 3, 4, 1)] {
            let n = 2;
            let x: Vec<f32> = (0..n * g.in_len()).map(|i| ((i * 37 % 17) as f32 - 8.0) / 7.0).collect();
            let c: Vec<f32> = (0..n * g.out_pos() * g.kdim()).map(|i| ((i * 11 % 13) as f32 - 6.0) / 5.0).collect();
            let mut col = Vec::new();
            im2col(&g, &x, &mut col);
            let mut dx = Vec::new();
            col2im(&g, &c, &mut dx);
            let lhs: f64 = col.iter().zip(&c).map(|(a, b)| (*a as f64) * (*b as f64)).sum();
            let rhs: f64 = x.iter().zip(&dx).map(|(a, b)| (*a as f64) * (*b as f64)).sum();
            assert!((lhs - rhs).abs() < 1e-3 * lhs.abs().max(1.0), "{g:?}: {lhs} vs {rhs}");
        }
    }
}
