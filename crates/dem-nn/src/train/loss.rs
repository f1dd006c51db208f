//! The losses of `docs/network.md`, each returning its value and writing
//! (adding) its gradient.
//!
//! - BCE on logits with a constant target t, mean over all decisions:
//!   `softplus(l) - t l` (= BCE(sigmoid(l), t)), gradient `(sigmoid(l) - t) / n`.
//! - L1 cycle term, mean over all `n * 210` record values (row 20 passes
//!   through the generators, so it adds nothing but the count):
//!   gradient `sign(a - b) / (n * 210)`.
//! - Paired G_Y term: mean over paired sims of `min_i e(y_i, G_Y(x))`, the
//!   equation 7.1 error of `docs/format.md` (height error only where y_i
//!   is valid, mask error everywhere, sum over the 100 cells / 100).
//! - Paired height term: `H(y, p) = mean over cells valid in y of
//!   |y_h - p_h| / 0.01 m`, the mean absolute height error in centimetres;
//!   subgradient `sign(p_h - y_h) / (valid * 0.01)`. L1, not squared: a
//!   2 cm error must still pull, and a stair edge off by one cell must not
//!   dominate.
//! - Paired G_X term: mean over pairs of the squared error between G_X(y)
//!   and x over both channels (sum over cells / 100, the scale of e).
//!
//! Layer 5 (train), the top: may use net, layers, weights and gemm.

/// Values per record in the loss means (the whole 21x5x2 record).
pub const RECORD: f32 = 210.0;

fn softplus(l: f32) -> f32 {
    // log(1 + e^l) without overflow.
    l.max(0.0) + (-l.abs()).exp().ln_1p()
}

fn sigmoid(l: f32) -> f32 {
    1.0 / (1.0 + (-l).exp())
}

/// BCE(sigmoid(logits), target) summed over `logits` and divided by `n`
/// (the decisions of the whole batch, of which these may be a part); `grad`
/// receives d/dlogits (set, not added).
pub fn bce_logits(logits: &[f32], target: f32, n: f32, grad: &mut Vec<f32>) -> f32 {
    grad.clear();
    grad.extend(logits.iter().map(|&l| (sigmoid(l) - target) / n));
    logits.iter().map(|&l| (softplus(l) - target * l) as f64).sum::<f64>() as f32 / n
}

/// `weight * sum |a - b| / (records * 210)`: the mean over a batch of
/// `records` records (of which `a` may hold a part) of 200 grid values each,
/// row 20 counted as zero; adds `weight * d/da` to `grad`.
pub fn l1_cycle(a: &[f32], b: &[f32], weight: f32, records: usize, grad: &mut [f32]) -> f32 {
    let n = records as f32 * RECORD;
    let mut sum = 0.0f64;
    for ((x, y), g) in a.iter().zip(b).zip(grad.iter_mut()) {
        let d = x - y;
        sum += d.abs() as f64;
        *g += weight * d.signum() * (d != 0.0) as u8 as f32 / n;
    }
    weight * (sum as f32) / n
}

/// Equation 7.1 error of prediction `p` (200 grid values) against measured `y`.
pub fn error71(y: &[f32], p: &[f32]) -> f32 {
    let mut s = 0.0f32;
    for (yc, pc) in y.chunks_exact(2).zip(p.chunks_exact(2)) {
        let v = if yc[1] > 0.0 { 1.0 } else { 0.0 };
        s += (v * (yc[0] - pc[0])).powi(2) + (yc[1] - pc[1]).powi(2);
    }
    s / 100.0
}

/// Paired G_Y term for one sim: `min_i e(y_i, p)`; adds `weight * d/dp` of
/// the best pair to `grad` and returns `(weight * e_min, index of the best)`.
pub fn paired_min(reals: &[&[f32]], p: &[f32], weight: f32, grad: &mut [f32]) -> (f32, usize) {
    let (best, e) =
        reals.iter().enumerate().map(|(i, y)| (i, error71(y, p))).fold((0, f32::INFINITY), |a, b| if b.1 < a.1 { b } else { a });
    let y = reals[best];
    for ((g, yc), pc) in grad.chunks_exact_mut(2).zip(y.chunks_exact(2)).zip(p.chunks_exact(2)) {
        let v = if yc[1] > 0.0 { 1.0 } else { 0.0 };
        g[0] += weight * 2.0 * v * (pc[0] - yc[0]) / 100.0;
        g[1] += weight * 2.0 * (pc[1] - yc[1]) / 100.0;
    }
    (weight * e, best)
}

/// Centimetres per metre: the height term's unit.
pub const HEIGHT_UNIT: f32 = 0.01;

/// Paired height term for one sim: `weight * H(y, p)` (see the module docs);
/// adds `weight * dH/dp` to `grad`. 0 when y has no valid cell.
pub fn height_l1(y: &[f32], p: &[f32], weight: f32, grad: &mut [f32]) -> f32 {
    let valid = y.chunks_exact(2).filter(|c| c[1] > 0.0).count();
    if valid == 0 {
        return 0.0;
    }
    let scale = weight / (valid as f32 * HEIGHT_UNIT);
    let mut s = 0.0f32;
    for ((g, yc), pc) in grad.chunks_exact_mut(2).zip(y.chunks_exact(2)).zip(p.chunks_exact(2)) {
        if yc[1] > 0.0 {
            let d = pc[0] - yc[0];
            s += d.abs();
            g[0] += scale * d.signum() * (d != 0.0) as u8 as f32;
        }
    }
    s * scale
}

/// Paired G_X term for one pair: `weight * sum (p - x)^2 / 100`; adds the gradient.
pub fn paired_sq(x: &[f32], p: &[f32], weight: f32, grad: &mut [f32]) -> f32 {
    let mut s = 0.0f32;
    for ((g, xv), pv) in grad.iter_mut().zip(x).zip(p) {
        let d = pv - xv;
        s += d * d;
        *g += weight * 2.0 * d / 100.0;
    }
    weight * s / 100.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bce_matches_its_definition_and_gradient() {
        let logits = [-3.0f32, -0.2, 0.0, 1.5, 8.0];
        let mut g = Vec::new();
        let l = bce_logits(&logits, 0.9, 5.0, &mut g);
        let want: f32 = logits
            .iter()
            .map(|&x| {
                let s = sigmoid(x);
                -(0.9 * s.ln() + 0.1 * (1.0 - s).ln())
            })
            .sum::<f32>()
            / 5.0;
        assert!((l - want).abs() < 1e-5, "{l} vs {want}");
        for (i, &x) in logits.iter().enumerate() {
            let h = 1e-3;
            let mut a = logits;
            a[i] = x + h;
            let up = bce_logits(&a, 0.9, 5.0, &mut Vec::new());
            a[i] = x - h;
            let down = bce_logits(&a, 0.9, 5.0, &mut Vec::new());
            assert!((g[i] - (up - down) / (2.0 * h)).abs() < 1e-3);
        }
    }

    #[test]
    fn error71_worked_checks() {
        // The spec's worked checks: one cell differs.
        let y: Vec<f32> = (0..100).flat_map(|_| [-0.07, 1.0]).collect();
        let mut p = y.clone();
        p[1] = 0.5;
        assert!((error71(&y, &p) - 0.0025).abs() < 1e-7);
        let mut y2 = y.clone();
        y2[1] = -1.0;
        y2[0] = 0.0;
        let mut p2 = y2.clone();
        p2[1] = 0.5;
        assert!((error71(&y2, &p2) - 0.0225).abs() < 1e-7);
        let mut p3 = y.clone();
        p3[0] = -0.09;
        assert!((error71(&y, &p3) - 0.000004).abs() < 1e-9);
    }

    #[test]
    fn height_l1_is_centimetres_on_valid_cells() {
        let mut y: Vec<f32> = (0..100).flat_map(|_| [-0.07, 1.0]).collect();
        y[2] = 0.0;
        y[3] = -1.0; // cell 1 missing in y: not scored
        let mut p = y.clone();
        p[0] = -0.05; // +2 cm
        p[2] = 0.5; // under a missing cell
        p[4] = -0.08; // -1 cm
        let mut g = vec![0.0; 200];
        let h = height_l1(&y, &p, 2.0, &mut g);
        assert!((h - 2.0 * 3.0 / 99.0).abs() < 1e-5, "{h}");
        let unit = 2.0 / (99.0 * HEIGHT_UNIT);
        assert!((g[0] - unit).abs() < 1e-4 && (g[4] + unit).abs() < 1e-4);
        assert_eq!((g[1], g[2], g[6]), (0.0, 0.0, 0.0));
        let none: Vec<f32> = (0..100).flat_map(|_| [0.0, -1.0]).collect();
        assert_eq!(height_l1(&none, &p, 1.0, &mut g), 0.0);
    }

    #[test]
    fn paired_min_takes_the_closest_real_and_its_gradient() {
        let p: Vec<f32> = (0..200).map(|i| if i % 2 == 1 { 1.0 } else { 0.1 }).collect();
        let far: Vec<f32> = (0..200).map(|i| if i % 2 == 1 { -1.0 } else { 0.0 }).collect();
        let mut near = p.clone();
        near[0] = 0.2;
        let mut g = vec![0.0; 200];
        let (e, best) = paired_min(&[&far, &near], &p, 1.0, &mut g);
        assert_eq!(best, 1);
        assert!((e - 0.0001).abs() < 1e-7);
        assert!((g[0] - 2.0 * (0.1 - 0.2) / 100.0).abs() < 1e-7);
        assert!(g[1..].iter().all(|v| *v == 0.0));
    }
}
