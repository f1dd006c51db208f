//! 3x3, stride 1, padding 1 convolution by Winograd's minimal filtering with
//! rectangular tiles F(m_r x m_c, 3x3), forward only (inference).
//!
//! The 20x5 maps of the generator tile exactly with F(4, 3) along rows (5
//! tiles of 4) and F(3, 3) along columns (2 tiles of 3, the last column of the
//! second dropped): 6 x 5 = 30 products per 4 x 3 output tile, 300 per
//! channel pair and record, where F(2x2, 3x3) ([`crate::layers::winograd`])
//! needs 480 and the direct convolution 900.
//!
//! One axis, `a = m + 2` points `p_0 .. p_{a-2}` and infinity (Toom-Cook; the
//! correlation `y_i = sum_k g_k d_{i+k}` is the transpose of the polynomial
//! product `h(x) g(x)`):
//!
//! ```text
//! A^T [m, a]:  A^T[i][j] = p_j^i,                  column a-1 = e_{m-1}
//! G   [a, 3]:  G[j][k]   = p_j^k / prod_{l != j} (p_j - p_l),   row a-1 = e_2
//! B^T [a, a]:  B^T[j]    = coefficients of prod_{l != j} (x - p_l),  row a-1: of prod_l (x - p_l)
//! y = A^T [(G g) . (B^T d)]                        (. elementwise)
//! ```
//!
//! Two axes, per tile `d [a_r, a_c]` of the padded input and channel pair:
//! `U = G_r g G_c^T`, `V = B_r^T d B_c`, `M_xi [T, c_out] = V_xi [T, c_in] U_xi [c_in, c_out]`
//! for each of the `a_r a_c` positions `xi` (one matrix product each over the
//! `T` tiles of the batch), `y tile = A_r^T M A_c + b`. Shapes as
//! [`crate::layers::conv`]: `x [n, h, w, c_in]`, `y [n, h, w, c_out]`.
//!
//! The transforms are built in f64 from the points and rounded once to f32;
//! the points `0, +-1, +-2` (rows) and `0, +-1, 2` (columns) keep every
//! transform entry a small dyadic fraction or 1/3, 1/6, 1/12, 1/24, so the
//! f32 error stays of the order of the direct convolution's (tested).
//!
//! Layer 2 (layers): may use gemm and weights.

use crate::gemm::{matmul, Mat};
use crate::layers::conv::ConvGeom;

/// Coefficients (lowest degree first) of `prod (x - r)` over `roots`.
fn poly(roots: impl Iterator<Item = f64>) -> Vec<f64> {
    let mut c = vec![1.0];
    for r in roots {
        let mut next = vec![0.0; c.len() + 1];
        for (k, v) in c.iter().enumerate() {
            next[k + 1] += v;
            next[k] -= r * v;
        }
        c = next;
    }
    c
}

/// The transforms of one axis, `F(m, 3)` over the `a = m + 2` points
/// `points` and infinity: `(B^T [a, a], G [a, 3], A^T [m, a])`, row-major.
fn axis(points: &[f64]) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let a = points.len() + 1;
    let m = a - 2;
    let (mut bt, mut g, mut at) = (vec![0.0; a * a], vec![0.0; a * 3], vec![0.0; m * a]);
    for (j, &p) in points.iter().enumerate() {
        let others = || points.iter().enumerate().filter(move |(l, _)| *l != j).map(|(_, &q)| q);
        for (t, c) in poly(others()).into_iter().enumerate() {
            bt[j * a + t] = c;
        }
        let denom: f64 = others().map(|q| p - q).product();
        for k in 0..3 {
            g[j * 3 + k] = p.powi(k as i32) / denom;
        }
        for i in 0..m {
            at[i * a + j] = p.powi(i as i32);
        }
    }
    for (t, c) in poly(points.iter().copied()).into_iter().enumerate() {
        bt[(a - 1) * a + t] = c;
    }
    g[(a - 1) * 3 + 2] = 1.0;
    at[(m - 1) * a + a - 1] = 1.0;
    (bt, g, at)
}

/// A 3x3 same convolution of one geometry, its weights transformed.
#[derive(Clone, Debug)]
pub struct RectConv {
    g: ConvGeom,
    /// `U [30, c_in, c_out]`.
    u: Vec<f32>,
    b: Vec<f32>,
}

/// Scratch of [`RectConv::forward`]: `V` and `M`.
#[derive(Clone, Debug, Default)]
pub struct RectScratch {
    v: Vec<f32>,
    m: Vec<f32>,
}

/// Points of F(4, 3) (rows).
pub const ROW_POINTS: [f64; 5] = [0.0, 1.0, -1.0, 2.0, -2.0];
/// Points of F(3, 3) (columns).
pub const COL_POINTS: [f64; 4] = [0.0, 1.0, -1.0, 2.0];

impl RectConv {
    /// Prepare conv `g` (3x3, stride 1, pad 1) with weights in kernel layout
    /// `w [(ky, kx, ci), co]` and biases `b [co]`: `U = G_r g G_c^T`, in f64.
    pub fn new(g: ConvGeom, w: &[f32], b: &[f32]) -> Self {
        assert!(crate::layers::winograd::supports(&g), "a 3x3 stride-1 same conv");
        assert_eq!((w.len(), b.len()), (g.weight_len(), g.c_out), "conv weights and biases");
        let (gr, gc) = (axis(&ROW_POINTS).1, axis(&COL_POINTS).1);
        let (ci_n, co_n) = (g.c_in, g.c_out);
        let mut u = vec![0.0f32; XIS * ci_n * co_n];
        for ci in 0..ci_n {
            for co in 0..co_n {
                let k = |ky: usize, kx: usize| w[((ky * 3 + kx) * ci_n + ci) * co_n + co] as f64;
                for p in 0..ROW_A {
                    // (G_r g)[p][kx]
                    let r: [f64; 3] = std::array::from_fn(|kx| (0..3).map(|ky| gr[p * 3 + ky] * k(ky, kx)).sum());
                    for q in 0..COL_A {
                        let v: f64 = (0..3).map(|kx| r[kx] * gc[q * 3 + kx]).sum();
                        u[((p * COL_A + q) * ci_n + ci) * co_n + co] = v as f32;
                    }
                }
            }
        }
        RectConv { g, u, b: b.to_vec() }
    }

    fn tiles(&self) -> (usize, usize) {
        (self.g.h.div_ceil(ROW_M), self.g.w.div_ceil(COL_M))
    }

    /// `y [n, h, w, c_out] = conv(x) + b` for `x [n, h, w, c_in]`.
    ///
    /// `V` is kept as `[T, 30, c_in]` (a tile's transform written in place)
    /// and read by the 30 matrix products as strided `[T, c_in]` blocks; `M`
    /// is `[30, T, c_out]`.
    #[inline(always)]
    pub fn forward(&self, x: &[f32], s: &mut RectScratch, y: &mut Vec<f32>) {
        let g = &self.g;
        let (ci, co) = (g.c_in, g.c_out);
        let n = x.len() / g.in_len();
        let (th, tw) = self.tiles();
        let t_all = n * th * tw;
        s.v.resize(t_all * XIS * ci, 0.0);
        s.m.resize(XIS * t_all * co, 0.0);
        let zero = vec![0.0f32; ci];
        // Input transform: per column c of the 6x5 patch, t[.][c] = B_r^T d[.][c];
        // then per row p, V[p][.] = B_c^T t[p][.] (written to the tile's V).
        let mut t = vec![0.0f32; COL_A * ROW_A * ci]; // [c][p][ci]
        for (tile, vt) in s.v.chunks_exact_mut(XIS * ci).enumerate() {
            let (smp, ti, tj) = (tile / (th * tw), tile / tw % th, tile % tw);
            let xs = &x[smp * g.in_len()..][..g.in_len()];
            let y0 = (ROW_M * ti) as isize - 1;
            let x0 = (COL_M * tj) as isize - 1;
            for (c, tc) in t.chunks_exact_mut(ROW_A * ci).enumerate() {
                let xx = x0 + c as isize;
                let at = |r: usize| -> &[f32] {
                    let yy = y0 + r as isize;
                    if yy < 0 || xx < 0 || yy as usize >= g.h || xx as usize >= g.w {
                        &zero
                    } else {
                        &xs[(yy as usize * g.w + xx as usize) * ci..][..ci]
                    }
                };
                bt6([at(0), at(1), at(2), at(3), at(4), at(5)], tc, ci);
            }
            for p in 0..ROW_A {
                let ins: [&[f32]; 5] = std::array::from_fn(|c| &t[(c * ROW_A + p) * ci..][..ci]);
                bt5(ins, &mut vt[p * COL_A * ci..][..COL_A * ci], ci);
            }
        }
        for xi in 0..XIS {
            matmul(
                &mut s.m[xi * t_all * co..][..t_all * co],
                Mat::strided(&s.v[xi * ci..], t_all, ci, XIS * ci),
                Mat::new(&self.u[xi * ci * co..][..ci * co], ci, co),
                false,
            );
        }
        // Output transform: per column v, q[.][v] = A_r^T M[.][v]; then per
        // output row i, y[i][.] = A_c^T q[i][.] + b.
        y.resize(n * g.h * g.w * co, 0.0);
        let mut q = vec![0.0f32; COL_A * ROW_M * co]; // [v][i][co]
        let mut row = vec![0.0f32; COL_M * co];
        for tile in 0..t_all {
            let (smp, ti, tj) = (tile / (th * tw), tile / tw % th, tile % tw);
            for (v, qv) in q.chunks_exact_mut(ROW_M * co).enumerate() {
                let mm: [&[f32]; 6] = std::array::from_fn(|u| &s.m[((u * COL_A + v) * t_all + tile) * co..][..co]);
                at6(mm, qv, co);
            }
            let cols = COL_M.min(g.w - COL_M * tj);
            for i in 0..ROW_M {
                let oy = ROW_M * ti + i;
                if oy >= g.h {
                    break;
                }
                let ins: [&[f32]; 5] = std::array::from_fn(|v| &q[(v * ROW_M + i) * co..][..co]);
                at5(ins, &mut row, &self.b, co);
                let at = ((smp * g.h + oy) * g.w + COL_M * tj) * co;
                y[at..at + cols * co].copy_from_slice(&row[..cols * co]);
            }
        }
    }
}

/// Rows: F(4, 3).
const ROW_M: usize = 4;
const ROW_A: usize = 6;
/// Columns: F(3, 3).
const COL_M: usize = 3;
const COL_A: usize = 5;
/// Winograd positions of a tile.
const XIS: usize = ROW_A * COL_A;

// The transforms of ROW_POINTS and COL_POINTS written out (the tests check
// them against the matrices `Axis::new` builds), one channel vector at a time.

/// `out[p] = sum_r B_r^T[p][r] d[r]`, B_r^T of points 0, +-1, +-2:
/// `[4 0 -5 0 1 0; 0 -4 -4 1 1 0; 0 4 -4 -1 1 0; 0 -2 -1 2 1 0; 0 2 -1 -2 1 0; 0 4 0 -5 0 1]`;
/// `out` is `[6, c]`.
#[inline(always)]
fn bt6(d: [&[f32]; 6], out: &mut [f32], c: usize) {
    let [d0, d1, d2, d3, d4, d5] = d.map(|s| &s[..c]);
    let (o0, rest) = out.split_at_mut(c);
    let (o1, rest) = rest.split_at_mut(c);
    let (o2, rest) = rest.split_at_mut(c);
    let (o3, rest) = rest.split_at_mut(c);
    let (o4, o5) = rest.split_at_mut(c);
    let (o5, o4) = (&mut o5[..c], &mut o4[..c]);
    for j in 0..c {
        let (a0, a1, a2, a3, a4, a5) = (d0[j], d1[j], d2[j], d3[j], d4[j], d5[j]);
        let s14 = a4 - 4.0 * a2;
        let s23 = a3 - 4.0 * a1;
        o0[j] = 4.0 * a0 - 5.0 * a2 + a4;
        o1[j] = s14 + s23;
        o2[j] = s14 - s23;
        let t14 = a4 - a2;
        let t23 = 2.0 * (a3 - a1);
        o3[j] = t14 + t23;
        o4[j] = t14 - t23;
        o5[j] = 4.0 * a1 - 5.0 * a3 + a5;
    }
}

/// `out[q] = sum_c B_c^T[q][c] t[c]`, B_c^T of points 0, +-1, 2:
/// `[2 -1 -2 1 0; 0 -2 -1 1 0; 0 2 -3 1 0; 0 -1 0 1 0; 0 2 -1 -2 1]`; `out` is `[5, c]`.
#[inline(always)]
fn bt5(t: [&[f32]; 5], out: &mut [f32], c: usize) {
    let [d0, d1, d2, d3, d4] = t.map(|s| &s[..c]);
    let (o0, rest) = out.split_at_mut(c);
    let (o1, rest) = rest.split_at_mut(c);
    let (o2, rest) = rest.split_at_mut(c);
    let (o3, o4) = rest.split_at_mut(c);
    let (o3, o4) = (&mut o3[..c], &mut o4[..c]);
    for j in 0..c {
        let (a0, a1, a2, a3, a4) = (d0[j], d1[j], d2[j], d3[j], d4[j]);
        o0[j] = 2.0 * a0 - a1 - 2.0 * a2 + a3;
        o1[j] = a3 - 2.0 * a1 - a2;
        o2[j] = a3 + 2.0 * a1 - 3.0 * a2;
        o3[j] = a3 - a1;
        o4[j] = a4 + 2.0 * a1 - a2 - 2.0 * a3;
    }
}

/// `out[i] = sum_u A_r^T[i][u] m[u]`, A_r^T = `[1 1 1 1 1 0; 0 1 -1 2 -2 0; 0 1 1 4 4 0; 0 1 -1 8 -8 1]`;
/// `out` is `[4, c]`.
#[inline(always)]
fn at6(m: [&[f32]; 6], out: &mut [f32], c: usize) {
    let [m0, m1, m2, m3, m4, m5] = m.map(|s| &s[..c]);
    let (o0, rest) = out.split_at_mut(c);
    let (o1, rest) = rest.split_at_mut(c);
    let (o2, o3) = rest.split_at_mut(c);
    let (o2, o3) = (&mut o2[..c], &mut o3[..c]);
    for j in 0..c {
        let (a12, s12) = (m1[j] + m2[j], m1[j] - m2[j]);
        let (a34, s34) = (m3[j] + m4[j], m3[j] - m4[j]);
        o0[j] = m0[j] + a12 + a34;
        o1[j] = s12 + 2.0 * s34;
        o2[j] = a12 + 4.0 * a34;
        o3[j] = s12 + 8.0 * s34 + m5[j];
    }
}

/// `out[j] = b + sum_v A_c^T[j][v] q[v]`, A_c^T = `[1 1 1 1 0; 0 1 -1 2 0; 0 1 1 4 1]`;
/// `out` is `[3, c]`.
#[inline(always)]
fn at5(q: [&[f32]; 5], out: &mut [f32], b: &[f32], c: usize) {
    let [q0, q1, q2, q3, q4] = q.map(|s| &s[..c]);
    let b = &b[..c];
    let (o0, rest) = out.split_at_mut(c);
    let (o1, o2) = rest.split_at_mut(c);
    let o2 = &mut o2[..c];
    for j in 0..c {
        let (a12, s12) = (q1[j] + q2[j], q1[j] - q2[j]);
        o0[j] = b[j] + q0[j] + a12 + q3[j];
        o1[j] = b[j] + s12 + 2.0 * q3[j];
        o2[j] = b[j] + a12 + 4.0 * q3[j] + q4[j];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layers::conv;

    fn data(len: usize, k: usize) -> Vec<f32> {
        (0..len).map(|i| (((i * k + 3) % 29) as f32 - 14.0) / 9.0).collect()
    }

    /// F(4x3) equals the im2col convolution.
    #[test]
    fn rectangular_winograd_equals_im2col() {
        for (h, w, ci, co) in [(20, 5, 3, 4), (20, 5, 64, 16), (20, 5, 2, 8), (7, 4, 2, 5)] {
            let g = ConvGeom::same3(h, w, ci, co);
            let n = 3;
            let x = data(n * g.in_len(), 7);
            let wt: Vec<f32> = data(g.weight_len(), 11).iter().map(|v| v / (ci as f32).sqrt()).collect();
            let b = data(co, 5);
            let (mut col, mut want) = (Vec::new(), Vec::new());
            conv::forward(&g, &wt, &b, &x, &mut col, &mut want);
            let mut got = Vec::new();
            RectConv::new(g, &wt, &b).forward(&x, &mut RectScratch::default(), &mut got);
            assert_eq!(got.len(), want.len());
            for (i, (p, q)) in got.iter().zip(&want).enumerate() {
                assert!((p - q).abs() < 2e-5 * (1.0 + q.abs()), "[{i}]: {p} vs {q} ({h}x{w} {ci}->{co})");
            }
        }
    }

    /// The written-out transforms are the matrices built from the points.
    #[test]
    fn written_out_transforms_are_the_points_matrices() {
        let basis = |k: usize, a: usize| -> Vec<Vec<f32>> { (0..a).map(|r| vec![if r == k { 1.0 } else { 0.0 }]).collect() };
        let check = |got: &[f32], want: &[f64], rows: usize, a: usize, k: usize, what: &str| {
            for r in 0..rows {
                assert_eq!(got[r] as f64, want[r * a + k], "{what}[{r}][{k}]");
            }
        };
        let (bt_r, _, at_r) = axis(&ROW_POINTS);
        let (bt_c, _, at_c) = axis(&COL_POINTS);
        for k in 0..6 {
            let e = basis(k, 6);
            let ins: [&[f32]; 6] = std::array::from_fn(|r| &e[r][..]);
            let mut out = vec![0.0; 6];
            bt6(ins, &mut out, 1);
            check(&out, &bt_r, 6, 6, k, "B_r^T");
            let mut out = vec![0.0; 4];
            at6(ins, &mut out, 1);
            check(&out, &at_r, 4, 6, k, "A_r^T");
        }
        for k in 0..5 {
            let e = basis(k, 5);
            let ins: [&[f32]; 5] = std::array::from_fn(|r| &e[r][..]);
            let mut out = vec![0.0; 5];
            bt5(ins, &mut out, 1);
            check(&out, &bt_c, 5, 5, k, "B_c^T");
            let mut out = vec![0.0; 3];
            at5(ins, &mut out, &[0.0], 1);
            check(&out, &at_c, 3, 5, k, "A_c^T");
        }
    }
}
