//! Where each layer's parameters live in a network's one flat vector (so the
//! optimiser and checkpoints see one slice), and the conversion between
//! PyTorch's layout ([`crate::weights`]) and the kernels' layout.
//!
//! Kernel layout: a conv's weights are `W [(ky, kx, ci), co]` (see
//! [`crate::layers::conv`]); a dense layer's are `W [in, out]`, with inputs and
//! outputs in the order of the channels-last maps, which differs from
//! PyTorch's flatten order by the permutations each layer carries.
//!
//! Layer 4 (net): may use layers, weights and gemm.

use std::ops::Range;

use crate::layers::conv::ConvGeom;
use crate::weights::{Conv2d, InstanceNorm, Linear};

/// Hands out consecutive ranges of a flat parameter vector.
#[derive(Debug, Default)]
pub struct Alloc {
    len: usize,
}

impl Alloc {
    fn take(&mut self, n: usize) -> Range<usize> {
        let r = self.len..self.len + n;
        self.len += n;
        r
    }

    /// Total parameters handed out.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Nothing handed out yet.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// A convolution's geometry and parameter ranges.
#[derive(Clone, Debug)]
pub struct ConvLayer {
    /// Shapes.
    pub g: ConvGeom,
    /// Weights `[K, c_out]`.
    pub w: Range<usize>,
    /// Biases `[c_out]`.
    pub b: Range<usize>,
}

impl ConvLayer {
    /// Allocate a conv of geometry `g`.
    pub fn new(a: &mut Alloc, g: ConvGeom) -> Self {
        ConvLayer { g, w: a.take(g.weight_len()), b: a.take(g.c_out) }
    }

    /// Write PyTorch-layout weights into `p`.
    pub fn load(&self, p: &mut [f32], t: &Conv2d) {
        let g = &self.g;
        assert_eq!((t.c_out, t.c_in, t.k), (g.c_out, g.c_in, g.k), "conv shape");
        let w = &mut p[self.w.clone()];
        for o in 0..g.c_out {
            for i in 0..g.c_in {
                for ky in 0..g.k {
                    for kx in 0..g.k {
                        w[((ky * g.k + kx) * g.c_in + i) * g.c_out + o] = t.weight[((o * g.c_in + i) * g.k + ky) * g.k + kx];
                    }
                }
            }
        }
        p[self.b.clone()].copy_from_slice(&t.bias);
    }

    /// Read the weights back in PyTorch's layout.
    pub fn save(&self, p: &[f32]) -> Conv2d {
        let g = &self.g;
        let w = &p[self.w.clone()];
        let mut weight = vec![0.0; g.weight_len()];
        for o in 0..g.c_out {
            for i in 0..g.c_in {
                for ky in 0..g.k {
                    for kx in 0..g.k {
                        weight[((o * g.c_in + i) * g.k + ky) * g.k + kx] = w[((ky * g.k + kx) * g.c_in + i) * g.c_out + o];
                    }
                }
            }
        }
        Conv2d { c_out: g.c_out, c_in: g.c_in, k: g.k, stride: g.stride, weight, bias: p[self.b.clone()].to_vec() }
    }
}

/// An instance norm's parameter ranges.
#[derive(Clone, Debug)]
pub struct NormLayer {
    /// Scales `[c]`.
    pub gamma: Range<usize>,
    /// Shifts `[c]`.
    pub beta: Range<usize>,
}

impl NormLayer {
    /// Allocate a norm over `c` channels.
    pub fn new(a: &mut Alloc, c: usize) -> Self {
        NormLayer { gamma: a.take(c), beta: a.take(c) }
    }

    /// Write PyTorch-layout parameters into `p`.
    pub fn load(&self, p: &mut [f32], t: &InstanceNorm) {
        p[self.gamma.clone()].copy_from_slice(&t.gamma);
        p[self.beta.clone()].copy_from_slice(&t.beta);
    }

    /// Read the parameters back.
    pub fn save(&self, p: &[f32]) -> InstanceNorm {
        InstanceNorm { gamma: p[self.gamma.clone()].to_vec(), beta: p[self.beta.clone()].to_vec() }
    }
}

/// A dense layer's ranges and the permutations from kernel order to
/// PyTorch's order: `torch_in[i]` is PyTorch's input index of kernel input `i`.
#[derive(Clone, Debug)]
pub struct DenseLayer {
    /// Inputs.
    pub n_in: usize,
    /// Outputs.
    pub n_out: usize,
    /// Weights `[n_in, n_out]`.
    pub w: Range<usize>,
    /// Biases `[n_out]`.
    pub b: Range<usize>,
    torch_in: Vec<usize>,
    torch_out: Vec<usize>,
}

impl DenseLayer {
    /// Allocate a dense layer with the given index permutations.
    pub fn new(a: &mut Alloc, torch_in: Vec<usize>, torch_out: Vec<usize>) -> Self {
        let (n_in, n_out) = (torch_in.len(), torch_out.len());
        DenseLayer { n_in, n_out, w: a.take(n_in * n_out), b: a.take(n_out), torch_in, torch_out }
    }

    /// Write PyTorch-layout weights into `p`.
    pub fn load(&self, p: &mut [f32], t: &Linear) {
        assert_eq!((t.n_in, t.n_out), (self.n_in, self.n_out), "linear shape");
        let w = &mut p[self.w.clone()];
        for (i, &ti) in self.torch_in.iter().enumerate() {
            for (o, &to) in self.torch_out.iter().enumerate() {
                w[i * self.n_out + o] = t.weight[to * self.n_in + ti];
            }
        }
        let b = &mut p[self.b.clone()];
        for (o, &to) in self.torch_out.iter().enumerate() {
            b[o] = t.bias[to];
        }
    }

    /// Read the weights back in PyTorch's layout.
    pub fn save(&self, p: &[f32]) -> Linear {
        let w = &p[self.w.clone()];
        let mut weight = vec![0.0; self.n_in * self.n_out];
        for (i, &ti) in self.torch_in.iter().enumerate() {
            for (o, &to) in self.torch_out.iter().enumerate() {
                weight[to * self.n_in + ti] = w[i * self.n_out + o];
            }
        }
        let mut bias = vec![0.0; self.n_out];
        for (o, &to) in self.torch_out.iter().enumerate() {
            bias[to] = p[self.b.clone()][o];
        }
        Linear { n_out: self.n_out, n_in: self.n_in, weight, bias }
    }
}

/// PyTorch index (`c * positions + p`) of channels-last index `p * channels + c`.
pub fn channels_first(positions: usize, channels: usize) -> impl Iterator<Item = usize> {
    (0..positions * channels).map(move |q| (q % channels) * positions + q / channels)
}

/// Identity order.
pub fn same_order(n: usize) -> Vec<usize> {
    (0..n).collect()
}
