//! The small models of the transfer test: linear maps from a DEM's grid to
//! what a robot's policy needs, fitted in closed form (no random choices, so
//! a fit depends only on its data).
//!
//! Features of a record (rows 0..19): the 100 heights (0 where missing, as
//! the contract stores them) and the 100 validity indicators (1 valid, 0
//! missing): `x = [h; v]`, 200 numbers. They are standardised with the
//! training set's mean and standard deviation (a constant feature gets
//! sd 1), and a bias is appended.
//!
//! Ridge regression: `W = argmin |X W - Y|^2 + lambda n |W'|^2` (`W'` without
//! the bias row), solved from the normal equations
//! `(X^T X + lambda n I') W = X^T Y` by Cholesky in f64. The terrain
//! classifier is the same fit to one-hot targets, predicting the class of
//! the largest output (a least-squares linear classifier).
//!
//! ```text
//! X: (n, 201)   Y: (n, k)   W: (201, k)
//! ```

use dem_core::Dem;

/// Features per record before the bias.
pub const FEATURES: usize = dem_core::format::GRID_CELLS * dem_core::format::CHANNELS;

/// The raw feature vector of a record: heights then validity, rows 0..19.
pub fn features(d: &Dem) -> [f64; FEATURES] {
    let mut x = [0.0; FEATURES];
    const CELLS: usize = dem_core::format::GRID_CELLS;
    for k in 0..CELLS {
        let valid = d[2 * k + 1] > 0.0;
        x[k] = if valid { d[2 * k] as f64 } else { 0.0 };
        x[CELLS + k] = valid as u8 as f64;
    }
    x
}

/// Standardisation of the features, from a training set.
#[derive(Clone, Debug)]
pub struct Scaler {
    mean: Vec<f64>,
    sd: Vec<f64>,
}

impl Scaler {
    /// Mean and sd (population) of every feature of `xs`.
    pub fn fit(xs: &[[f64; FEATURES]]) -> Self {
        let n = xs.len().max(1) as f64;
        let mut mean = vec![0.0; FEATURES];
        xs.iter().for_each(|x| mean.iter_mut().zip(x).for_each(|(m, v)| *m += v / n));
        let mut var = vec![0.0; FEATURES];
        xs.iter().for_each(|x| var.iter_mut().zip(x).zip(&mean).for_each(|((s, v), m)| *s += (v - m).powi(2) / n));
        let sd = var.into_iter().map(|v| if v > 1e-12 { v.sqrt() } else { 1.0 }).collect();
        Scaler { mean, sd }
    }

    /// The standardised features of `x` with the bias (1) last.
    pub fn row(&self, x: &[f64; FEATURES]) -> Vec<f64> {
        let mut r: Vec<f64> = x.iter().zip(&self.mean).zip(&self.sd).map(|((v, m), s)| (v - m) / s).collect();
        r.push(1.0);
        r
    }
}

/// A fitted linear map: `y = W^T [scaled x; 1]`.
#[derive(Clone, Debug)]
pub struct Linear {
    scaler: Scaler,
    /// `(FEATURES + 1) x k`, row-major.
    w: Vec<f64>,
    k: usize,
}

impl Linear {
    /// Ridge fit of targets `ys` (`k` per record) on `xs`, penalty `lambda`
    /// per record. None when there are no records.
    pub fn fit(xs: &[[f64; FEATURES]], ys: &[Vec<f64>], lambda: f64) -> Option<Linear> {
        let n = xs.len();
        if n == 0 {
            return None;
        }
        let k = ys[0].len();
        let d = FEATURES + 1;
        let scaler = Scaler::fit(xs);
        let mut a = vec![0.0; d * d];
        let mut b = vec![0.0; d * k];
        for (x, y) in xs.iter().zip(ys) {
            let r = scaler.row(x);
            for i in 0..d {
                if r[i] == 0.0 {
                    continue;
                }
                for j in i..d {
                    a[i * d + j] += r[i] * r[j];
                }
                for (t, yt) in y.iter().enumerate() {
                    b[i * k + t] += r[i] * yt;
                }
            }
        }
        for i in 0..d {
            for j in 0..i {
                a[i * d + j] = a[j * d + i];
            }
            if i < FEATURES {
                a[i * d + i] += lambda * n as f64;
            }
        }
        // A tiny ridge on the bias too keeps an all-constant design solvable.
        a[(d - 1) * d + d - 1] += 1e-9 * n as f64;
        let w = cholesky_solve(&mut a, d, &b, k)?;
        Some(Linear { scaler, w, k })
    }

    /// The outputs for `x`.
    pub fn predict(&self, x: &[f64; FEATURES]) -> Vec<f64> {
        let r = self.scaler.row(x);
        (0..self.k).map(|t| r.iter().enumerate().map(|(i, v)| v * self.w[i * self.k + t]).sum()).collect()
    }
}

/// Solve `A X = B` for symmetric positive definite `A` (`d x d`, overwritten
/// by its Cholesky factor) and `B` (`d x k`). None when `A` is not positive
/// definite to working precision.
pub fn cholesky_solve(a: &mut [f64], d: usize, b: &[f64], k: usize) -> Option<Vec<f64>> {
    for j in 0..d {
        let mut s = a[j * d + j];
        for p in 0..j {
            s -= a[j * d + p] * a[j * d + p];
        }
        if s <= 0.0 || !s.is_finite() {
            return None;
        }
        let l = s.sqrt();
        a[j * d + j] = l;
        for i in j + 1..d {
            let mut s = a[i * d + j];
            for p in 0..j {
                s -= a[i * d + p] * a[j * d + p];
            }
            a[i * d + j] = s / l;
        }
    }
    let mut x = b.to_vec();
    for t in 0..k {
        // L z = b, then L^T x = z.
        for i in 0..d {
            let mut s = x[i * k + t];
            for p in 0..i {
                s -= a[i * d + p] * x[p * k + t];
            }
            x[i * k + t] = s / a[i * d + i];
        }
        for i in (0..d).rev() {
            let mut s = x[i * k + t];
            for p in i + 1..d {
                s -= a[p * d + i] * x[p * k + t];
            }
            x[i * k + t] = s / a[i * d + i];
        }
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::format::{at, empty_dem};

    #[test]
    fn cholesky_solves_a_small_system() {
        // A = [[4, 2], [2, 3]], B = A [1, -2; 0.5, 1] = [[5, -6], [3.5, -1]].
        let mut a = vec![4.0, 2.0, 2.0, 3.0];
        let x = cholesky_solve(&mut a, 2, &[5.0, -6.0, 3.5, -1.0], 2).unwrap();
        for (got, want) in x.iter().zip([1.0, -2.0, 0.5, 1.0]) {
            assert!((got - want).abs() < 1e-12, "{x:?}");
        }
        assert!(cholesky_solve(&mut [1.0, 2.0, 2.0, 1.0], 2, &[1.0, 1.0], 1).is_none());
    }

    #[test]
    fn features_zero_missing_heights_and_flag_validity() {
        let mut d = empty_dem();
        d[at(3, 2, 0)] = 0.25;
        d[at(3, 2, 1)] = 1.0;
        d[at(4, 0, 0)] = 9.0; // a stray height under a missing cell is ignored
        let x = features(&d);
        assert_eq!((x[17], x[117]), (0.25, 1.0));
        assert_eq!((x[20], x[120]), (0.0, 0.0));
    }

    #[test]
    fn ridge_recovers_a_linear_law_and_generalises() {
        // y = 2 h(5) - 3 h(40) + 0.1 on random DEMs: a tiny ridge finds it.
        let mut s = 12345u64;
        let mut rnd = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut xs = Vec::new();
        let mut ys = Vec::new();
        for _ in 0..400 {
            let mut d = empty_dem();
            for k in 0..100 {
                d[2 * k] = rnd() as f32;
                d[2 * k + 1] = if rnd() > -0.4 { 1.0 } else { -1.0 };
                if d[2 * k + 1] < 0.0 {
                    d[2 * k] = 0.0;
                }
            }
            let x = features(&d);
            ys.push(vec![2.0 * x[5] - 3.0 * x[40] + 0.1]);
            xs.push(x);
        }
        let m = Linear::fit(&xs[..300], &ys[..300], 1e-6).unwrap();
        let err: f64 = xs[300..].iter().zip(&ys[300..]).map(|(x, y)| (m.predict(x)[0] - y[0]).abs()).sum::<f64>() / 100.0;
        assert!(err < 1e-3, "held-out error {err}");
        assert!(Linear::fit(&[], &[], 1.0).is_none());
    }
}
