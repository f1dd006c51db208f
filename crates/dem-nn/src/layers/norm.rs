//! Affine instance norm fused with the activation that follows it, on
//! channels-last maps `[n, p, c]` (p spatial positions).
//!
//! ```text
//! xhat = (x - mean_p x) / sqrt(var_p x + eps)      per sample and channel, biased variance
//! z    = act(gamma * xhat + beta)
//! backward, with u = dz * act'(z):
//!   dgamma += sum_{n,p} u * xhat,   dbeta += sum_{n,p} u
//!   dx = inv_std * (gamma u - mean_p(gamma u) - xhat * mean_p(gamma u * xhat))
//! ```
//! The activation's derivative is read off its output: leaky ReLU and ReLU
//! keep the sign of their input (a zero output of ReLU means "was <= 0").
//!
//! Layer 2 (layers): may use gemm and weights.

use rayon::prelude::*;

use crate::weights::{LEAK, NORM_EPS};

/// What follows the norm.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Act {
    /// Nothing (the second norm of a residual block).
    None,
    /// max(x, 0).
    Relu,
    /// x for x > 0, 0.2 x otherwise.
    Leaky,
}

impl Act {
    /// Apply to one value.
    #[inline]
    pub fn apply(self, v: f32) -> f32 {
        match self {
            Act::None => v,
            Act::Relu => v.max(0.0),
            Act::Leaky => {
                if v > 0.0 {
                    v
                } else {
                    LEAK * v
                }
            }
        }
    }

    /// Derivative, from the activation's output.
    #[inline]
    pub fn slope(self, out: f32) -> f32 {
        match self {
            Act::None => 1.0,
            Act::Relu => {
                if out > 0.0 {
                    1.0
                } else {
                    0.0
                }
            }
            Act::Leaky => {
                if out > 0.0 {
                    1.0
                } else {
                    LEAK
                }
            }
        }
    }
}

/// What backward needs: the normalized input and 1/std per sample and channel.
#[derive(Clone, Debug, Default)]
pub struct NormCache {
    /// `xhat [n, p, c]`.
    pub xhat: Vec<f32>,
    /// `inv_std [n, c]`.
    pub inv_std: Vec<f32>,
}

/// `z = act(gamma * xhat + beta)`; `x` is `[n, p, c]` with `c = gamma.len()`.
pub fn forward(x: &[f32], p: usize, gamma: &[f32], beta: &[f32], act: Act, cache: &mut NormCache, z: &mut Vec<f32>) {
    // One monomorphic loop per activation, so the inner loops vectorise.
    match act {
        Act::None => forward_with(x, p, gamma, beta, |v| v, cache, z),
        Act::Relu => forward_with(x, p, gamma, beta, |v| v.max(0.0), cache, z),
        Act::Leaky => forward_with(x, p, gamma, beta, |v| v.max(LEAK * v), cache, z),
    }
}

fn forward_with(
    x: &[f32],
    p: usize,
    gamma: &[f32],
    beta: &[f32],
    act: impl Fn(f32) -> f32 + Sync,
    cache: &mut NormCache,
    z: &mut Vec<f32>,
) {
    let c = gamma.len();
    let n = x.len() / (p * c);
    cache.xhat.resize(x.len(), 0.0);
    cache.inv_std.resize(n * c, 0.0);
    z.resize(x.len(), 0.0);
    x.par_chunks(p * c).zip(cache.xhat.par_chunks_mut(p * c)).zip(z.par_chunks_mut(p * c)).zip(cache.inv_std.par_chunks_mut(c)).for_each(
        |(((xs, hs), zs), inv)| {
            let mut mean = vec![0.0f32; c];
            for row in xs.chunks_exact(c) {
                mean.iter_mut().zip(row).for_each(|(m, v)| *m += v);
            }
            mean.iter_mut().for_each(|m| *m /= p as f32);
            let mut var = vec![0.0f32; c];
            for row in xs.chunks_exact(c) {
                var.iter_mut().zip(row).zip(&mean).for_each(|((s, v), m)| *s += (v - m) * (v - m));
            }
            inv.iter_mut().zip(&var).for_each(|(i, v)| *i = 1.0 / (v / p as f32 + NORM_EPS).sqrt());
            let inv = &*inv;
            for ((row, hrow), zrow) in xs.chunks_exact(c).zip(hs.chunks_exact_mut(c)).zip(zs.chunks_exact_mut(c)) {
                for ((((h, zv), x), (m, i)), (g, b)) in
                    hrow.iter_mut().zip(zrow.iter_mut()).zip(row).zip(mean.iter().zip(inv)).zip(gamma.iter().zip(beta))
                {
                    *h = (x - m) * i;
                    *zv = act(g * *h + b);
                }
            }
        },
    );
}

/// Inference: `x <- act(gamma * xhat + beta)` in place on `x [n, p, c]`
/// (`c = gamma.len()`), the formula of [`forward`] with nothing kept for a
/// backward pass, one sample after another on the calling thread. Computed
/// as `act(x * s + t)` with `s = gamma / sqrt(var + eps)` and
/// `t = beta - mean * s` per sample and channel.
#[inline(always)]
pub fn forward_inplace(x: &mut [f32], p: usize, gamma: &[f32], beta: &[f32], act: Act) {
    match act {
        Act::None => inplace_with(x, p, gamma, beta, |v| v),
        Act::Relu => inplace_with(x, p, gamma, beta, |v| v.max(0.0)),
        Act::Leaky => inplace_with(x, p, gamma, beta, |v| v.max(LEAK * v)),
    }
}

#[inline(always)]
fn inplace_with(x: &mut [f32], p: usize, gamma: &[f32], beta: &[f32], act: impl Fn(f32) -> f32) {
    let c = gamma.len();
    assert_eq!(beta.len(), c, "gamma and beta");
    assert_eq!(x.len() % (p * c), 0, "x is [n, p, c]");
    let (mut mean, mut var) = (vec![0.0f32; c], vec![0.0f32; c]);
    let (mut scale, mut shift) = (vec![0.0f32; c], vec![0.0f32; c]);
    for xs in x.chunks_exact_mut(p * c) {
        mean.fill(0.0);
        var.fill(0.0);
        for row in xs.chunks_exact(c) {
            mean.iter_mut().zip(row).for_each(|(m, v)| *m += v);
        }
        mean.iter_mut().for_each(|m| *m /= p as f32);
        for row in xs.chunks_exact(c) {
            var.iter_mut().zip(row).zip(&mean).for_each(|((s, v), m)| *s += (v - m) * (v - m));
        }
        for ((((s, t), v), m), (g, b)) in scale.iter_mut().zip(shift.iter_mut()).zip(&var).zip(&mean).zip(gamma.iter().zip(beta)) {
            *s = g / (v / p as f32 + NORM_EPS).sqrt();
            *t = b - m * *s;
        }
        for row in xs.chunks_exact_mut(c) {
            row.iter_mut().zip(scale.iter().zip(&shift)).for_each(|(v, (s, t))| *v = act(*v * s + t));
        }
    }
}

/// Backward of [`forward`]: accumulates `dgamma`, `dbeta`; returns `dx` in
/// place of `dz` (which must hold the gradient of `z`).
#[allow(clippy::too_many_arguments)]
pub fn backward(cache: &NormCache, z: &[f32], p: usize, gamma: &[f32], act: Act, dz: &mut [f32], dgamma: &mut [f32], dbeta: &mut [f32]) {
    match act {
        Act::None => backward_with(cache, z, p, gamma, |_| 1.0, dz, dgamma, dbeta),
        Act::Relu => backward_with(cache, z, p, gamma, |o| if o > 0.0 { 1.0 } else { 0.0 }, dz, dgamma, dbeta),
        Act::Leaky => backward_with(cache, z, p, gamma, |o| if o > 0.0 { 1.0 } else { LEAK }, dz, dgamma, dbeta),
    }
}

#[allow(clippy::too_many_arguments)]
fn backward_with(
    cache: &NormCache,
    z: &[f32],
    p: usize,
    gamma: &[f32],
    slope: impl Fn(f32) -> f32 + Sync,
    dz: &mut [f32],
    dgamma: &mut [f32],
    dbeta: &mut [f32],
) {
    let c = gamma.len();
    let inv_p = 1.0 / p as f32;
    let partial: Vec<Vec<f32>> = dz
        .par_chunks_mut(p * c)
        .zip(cache.xhat.par_chunks(p * c))
        .zip(z.par_chunks(p * c))
        .zip(cache.inv_std.par_chunks(c))
        .map(|(((ds, hs), zs), inv)| {
            // su: sum u (dbeta), sux: sum u*xhat (dgamma), u = dz * act'(z).
            let mut su = vec![0.0f32; c];
            let mut sux = vec![0.0f32; c];
            for ((drow, hrow), zrow) in ds.chunks_exact_mut(c).zip(hs.chunks_exact(c)).zip(zs.chunks_exact(c)) {
                for ((((d, h), zv), a), b) in drow.iter_mut().zip(hrow).zip(zrow).zip(su.iter_mut()).zip(sux.iter_mut()) {
                    let u = *d * slope(*zv);
                    *d = u;
                    *a += u;
                    *b += u * h;
                }
            }
            // dx = inv * gamma * (u - mean u - xhat * mean(u xhat)).
            let k: Vec<f32> = inv.iter().zip(gamma).map(|(i, g)| i * g).collect();
            let mu: Vec<f32> = su.iter().map(|v| v * inv_p).collect();
            let mux: Vec<f32> = sux.iter().map(|v| v * inv_p).collect();
            for (drow, hrow) in ds.chunks_exact_mut(c).zip(hs.chunks_exact(c)) {
                for ((((d, h), k), m), mx) in drow.iter_mut().zip(hrow).zip(&k).zip(&mu).zip(&mux) {
                    *d = k * (*d - m - h * mx);
                }
            }
            sux.extend_from_slice(&su);
            sux
        })
        .collect();
    for s in partial {
        dgamma.iter_mut().zip(&s[..c]).for_each(|(d, v)| *d += v);
        dbeta.iter_mut().zip(&s[c..]).for_each(|(d, v)| *d += v);
    }
}
