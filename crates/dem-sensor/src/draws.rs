//! The random numbers of a sensor model: each effect reads a fixed number
//! of uniforms per record ([`Effect::draws`](crate::Effect::draws)), float32
//! in [0, 1), and nothing else. A record's uniforms, effect after effect in
//! the model's order, are the `uniform` input of the model's ONNX graph
//! (`dem-sensor export`), so any runtime fed the same uniforms computes the
//! same DEM.
//!
//! - A uniform is `(x >> 8) 2^-24` for a 32-bit draw `x` of the effect's
//!   ChaCha8 stream ([`crate::effect_rng`]): 24 bits, exact in float32.
//! - A normal is Box-Muller of two uniforms `(u1, u2)`:
//!   `z1 = sqrt(-2 ln(1 - u1)) cos(2 pi u2)`, `z2 = sqrt(-2 ln(1 - u1)) sin(2 pi u2)`;
//!   `1 - u1` lies in (0, 1], so `|z| <= sqrt(2 ln 2^24) = 5.77`.

use rand::RngCore;

/// One uniform in [0, 1) from a 32-bit draw: its top 24 bits.
pub fn uniform(rng: &mut impl RngCore) -> f32 {
    (rng.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Fill `out` with uniforms from `rng`.
pub fn fill_uniform(rng: &mut impl RngCore, out: &mut [f32]) {
    out.iter_mut().for_each(|u| *u = uniform(rng));
}

/// The two normals of Box-Muller from the uniforms `(u1, u2)` (module docs).
pub fn box_muller(u1: f32, u2: f32) -> (f64, f64) {
    let r = (-2.0 * (1.0 - f64::from(u1)).ln()).sqrt();
    let t = 2.0 * std::f64::consts::PI * f64::from(u2);
    (r * t.cos(), r * t.sin())
}

/// A cursor over one effect's uniforms for one record, read in order.
pub struct Draws<'a> {
    u: &'a [f32],
    at: usize,
}

impl<'a> Draws<'a> {
    /// The cursor at the first of `u`.
    pub fn new(u: &'a [f32]) -> Self {
        Draws { u, at: 0 }
    }

    /// The next uniform, as f64 (exact).
    pub fn gen(&mut self) -> f64 {
        let u = self.u[self.at];
        self.at += 1;
        f64::from(u)
    }

    /// The next `2 n` uniforms as `2 n` normals (Box-Muller pairs, in order).
    pub fn normals<const N: usize>(&mut self) -> [f64; N] {
        let mut z = [0.0; N];
        for pair in z.chunks_mut(2) {
            let (u1, u2) = (self.u[self.at], self.u[self.at + 1]);
            self.at += 2;
            let (a, b) = box_muller(u1, u2);
            pair[0] = a;
            if pair.len() > 1 {
                pair[1] = b;
            }
        }
        z
    }

    /// Uniforms read so far.
    pub fn used(&self) -> usize {
        self.at
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn uniforms_are_exact_float32_in_the_unit_interval() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut u = vec![0.0f32; 100_000];
        fill_uniform(&mut rng, &mut u);
        assert!(u.iter().all(|&x| (0.0..1.0).contains(&x) && (x * 16_777_216.0).fract() == 0.0));
        let mean = u.iter().map(|&x| f64::from(x)).sum::<f64>() / u.len() as f64;
        assert!((mean - 0.5).abs() < 0.005, "{mean}");
    }

    #[test]
    fn box_muller_gives_standard_normals_and_is_bounded() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let mut u = vec![0.0f32; 200_000];
        fill_uniform(&mut rng, &mut u);
        let z: Vec<f64> = u
            .chunks(2)
            .flat_map(|p| {
                let (a, b) = box_muller(p[0], p[1]);
                [a, b]
            })
            .collect();
        let n = z.len() as f64;
        let mean = z.iter().sum::<f64>() / n;
        let var = z.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
        assert!(mean.abs() < 0.01 && (var - 1.0).abs() < 0.02, "{mean} {var}");
        let tail = z.iter().filter(|x| x.abs() > 1.96).count() as f64 / n;
        assert!((tail - 0.05).abs() < 0.003, "{tail}");
        // The largest |z| a 24-bit uniform allows.
        let (a, _) = box_muller(1.0 - 1.0 / 16_777_216.0, 0.0);
        assert!((a - (2.0 * 24.0 * std::f64::consts::LN_2).sqrt()).abs() < 1e-9 && a < 5.8);
    }
}
