//! Adam over one flat parameter vector, exactly PyTorch's update:
//!
//! ```text
//! m = b1 m + (1 - b1) g;   v = b2 v + (1 - b2) g^2
//! p -= lr / (1 - b1^t) * m / (sqrt(v) / sqrt(1 - b2^t) + eps)
//! ```
//!
//! Layer 5 (train), the top: may use net, layers, weights and gemm.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Hyper-parameters (the spec's: lr 2e-4, betas 0.5 / 0.999).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AdamConfig {
    /// Learning rate.
    pub lr: f32,
    /// First-moment decay.
    pub beta1: f32,
    /// Second-moment decay.
    pub beta2: f32,
    /// Denominator guard.
    pub eps: f32,
}

impl Default for AdamConfig {
    fn default() -> Self {
        AdamConfig { lr: 2e-4, beta1: 0.5, beta2: 0.999, eps: 1e-8 }
    }
}

/// Moments and step count of one optimiser.
#[derive(Clone, Debug, PartialEq)]
pub struct Adam {
    /// Settings.
    pub cfg: AdamConfig,
    /// Steps taken.
    pub t: u64,
    /// First moments.
    pub m: Vec<f32>,
    /// Second moments.
    pub v: Vec<f32>,
}

impl Adam {
    /// A fresh optimiser over `n` parameters.
    pub fn new(cfg: AdamConfig, n: usize) -> Self {
        Adam { cfg, t: 0, m: vec![0.0; n], v: vec![0.0; n] }
    }

    /// One update of `p` from gradient `g`.
    pub fn step(&mut self, p: &mut [f32], g: &[f32]) {
        self.t += 1;
        let c = self.cfg;
        let b1t = 1.0 - c.beta1.powi(self.t as i32);
        let b2t = (1.0 - c.beta2.powi(self.t as i32)).sqrt();
        let step = c.lr / b1t;
        p.par_chunks_mut(4096).zip(g.par_chunks(4096)).zip(self.m.par_chunks_mut(4096).zip(self.v.par_chunks_mut(4096))).for_each(
            |((p, g), (m, v))| {
                for i in 0..p.len() {
                    m[i] = c.beta1 * m[i] + (1.0 - c.beta1) * g[i];
                    v[i] = c.beta2 * v[i] + (1.0 - c.beta2) * g[i] * g[i];
                    p[i] -= step * m[i] / (v[i].sqrt() / b2t + c.eps);
                }
            },
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_steps_move_by_lr_in_the_gradient_sign() {
        // With bias correction the first step is lr * g / (|g| + eps').
        let mut a = Adam::new(AdamConfig::default(), 3);
        let mut p = vec![1.0, 1.0, 1.0];
        a.step(&mut p, &[0.5, -2.0, 0.0]);
        assert!((p[0] - (1.0 - 2e-4)).abs() < 1e-7);
        assert!((p[1] - (1.0 + 2e-4)).abs() < 1e-7);
        assert_eq!(p[2], 1.0);
    }
}
