//! 3x3, stride 1, padding 1 convolution by Winograd's minimal filtering
//! F(2x2, 3x3): 16 products per 2x2 output tile instead of 36, so the
//! generator's convolutions (all of this kind) do 1.9x fewer multiply-adds
//! on its 20x5 maps (10x3 tiles, the last tile column half used).
//!
//! Shapes as [`crate::layers::conv`]: `x [n, h, w, c_in]`, `y [n, h, w, c_out]`,
//! weights `W [(ky, kx, ci), co]`. With `T = n * ceil(h/2) * ceil(w/2)` tiles
//! and `xi` one of the 16 positions of a 4x4 tile:
//!
//! ```text
//! U_xi [c_in, c_out] = (G g G^T)_xi            per (ci, co), g the 3x3 kernel
//! V_xi [T, c_in]     = (B^T d B)_xi            per (tile, ci), d the 4x4 input patch
//! M_xi [T, c_out]    = V_xi U_xi               16 GEMMs
//! y tile             = A^T M A + b             2x2 outputs per (tile, co)
//! backward: dM = A dy A^T;  dU_xi = V_xi^T dM_xi;  dW = G^T dU G;
//!           dV_xi = dM_xi U_xi^T;  dx = sum over tiles of B dV B^T
//! ```
//! The backward pass is the exact adjoint of this forward computation.
//!
//! Layer 2 (layers): may use gemm and weights.

use crate::gemm::{matmul, Mat};
use crate::layers::conv::ConvGeom;

/// What backward needs: the transformed input `V [16, T, c_in]`, and the
/// transformed weights `U [16, c_in, c_out]` of the forward pass.
#[derive(Clone, Debug, Default)]
pub struct WinoCache {
    v: Vec<f32>,
    u: Vec<f32>,
    tiles: usize,
}

/// Scratch of a backward pass.
#[derive(Clone, Debug, Default)]
pub struct WinoScratch {
    m: Vec<f32>,
    du: Vec<f32>,
    dv: Vec<f32>,
}

/// Whether `g` is a convolution this module computes.
pub fn supports(g: &ConvGeom) -> bool {
    g.k == 3 && g.stride == 1 && g.pad_top == 1 && g.pad_left == 1 && g.oh == g.h && g.ow == g.w
}

fn tiles_hw(g: &ConvGeom) -> (usize, usize) {
    (g.h.div_ceil(2), g.w.div_ceil(2))
}

// 1-D transforms on channel vectors: out[i] = sum_j T[i][j] a[j], written
// as zipped iterators so they vectorise.
// B^T = [[1,0,-1,0],[0,1,1,0],[0,-1,1,0],[0,1,0,-1]]
fn bt(a: [&[f32]; 4], out: [&mut [f32]; 4]) {
    let [o0, o1, o2, o3] = out;
    let ins = a[0].iter().zip(a[1]).zip(a[2].iter().zip(a[3]));
    let outs = o0.iter_mut().zip(o1.iter_mut()).zip(o2.iter_mut().zip(o3.iter_mut()));
    for (((a0, a1), (a2, a3)), ((p0, p1), (p2, p3))) in ins.zip(outs) {
        *p0 = a0 - a2;
        *p1 = a1 + a2;
        *p2 = a2 - a1;
        *p3 = a1 - a3;
    }
}

// B = (B^T)^T, the adjoint of `bt`, accumulated into `out`.
fn b_add(a: [&[f32]; 4], out: [&mut [f32]; 4]) {
    let [o0, o1, o2, o3] = out;
    let ins = a[0].iter().zip(a[1]).zip(a[2].iter().zip(a[3]));
    let outs = o0.iter_mut().zip(o1.iter_mut()).zip(o2.iter_mut().zip(o3.iter_mut()));
    for (((a0, a1), (a2, a3)), ((p0, p1), (p2, p3))) in ins.zip(outs) {
        *p0 += a0;
        *p1 += a1 - a2 + a3;
        *p2 += a1 + a2 - a0;
        *p3 -= a3;
    }
}

/// Resize without clearing: every value is written before it is read.
fn fit(v: &mut Vec<f32>, n: usize) {
    v.resize(n, 0.0);
}

/// Four consecutive `c`-long slices of `v` from `at`, mutably.
fn four(v: &mut [f32], at: usize, c: usize) -> [&mut [f32]; 4] {
    let (p0, rest) = v[at..at + 4 * c].split_at_mut(c);
    let (p1, rest) = rest.split_at_mut(c);
    let (p2, p3) = rest.split_at_mut(c);
    [p0, p1, p2, p3]
}

/// `V` of every tile of `x`.
fn input_transform(g: &ConvGeom, x: &[f32], n: usize, v: &mut Vec<f32>) -> usize {
    let (th, tw) = tiles_hw(g);
    let c = g.c_in;
    let t_all = n * th * tw;
    fit(v, 16 * t_all * c);
    let zero = vec![0.0f32; c];
    // d: the 4x4 patch; t: its rows transformed.
    let mut t = vec![0.0f32; 16 * c];
    let mut out = vec![0.0f32; 16 * c];
    for s in 0..n {
        let xs = &x[s * g.in_len()..][..g.in_len()];
        for ti in 0..th {
            for tj in 0..tw {
                let tile = (s * th + ti) * tw + tj;
                let at = |r: usize, col: usize| -> &[f32] {
                    let (y, xx) = ((2 * ti + r) as isize - 1, (2 * tj + col) as isize - 1);
                    if y < 0 || xx < 0 || y as usize >= g.h || xx as usize >= g.w {
                        &zero
                    } else {
                        &xs[(y as usize * g.w + xx as usize) * c..][..c]
                    }
                };
                // Along rows of the patch, for each column.
                // t[col][r'] = rows transformed, stored column-major so the
                // second pass reads four consecutive slices.
                for col in 0..4 {
                    bt([at(0, col), at(1, col), at(2, col), at(3, col)], four(&mut t, col * 4 * c, c));
                }
                // Along columns, for each transformed row r': out[r'][c'].
                for r in 0..4 {
                    let ins = [&t[r * c..][..c], &t[(4 + r) * c..][..c], &t[(8 + r) * c..][..c], &t[(12 + r) * c..][..c]];
                    bt(ins, four(&mut out, r * 4 * c, c));
                }
                for xi in 0..16 {
                    v[(xi * t_all + tile) * c..][..c].copy_from_slice(&out[xi * c..][..c]);
                }
            }
        }
    }
    t_all
}

/// `U = G g G^T` for every (ci, co).
fn weight_transform(g: &ConvGeom, w: &[f32], u: &mut Vec<f32>) {
    let (ci_n, co_n) = (g.c_in, g.c_out);
    u.clear();
    u.resize(16 * ci_n * co_n, 0.0);
    let wk = |ky: usize, kx: usize, ci: usize| &w[((ky * 3 + kx) * ci_n + ci) * co_n..][..co_n];
    let mut rows = vec![0.0f32; 12 * co_n]; // 4 x 3 after transforming ky
    for ci in 0..ci_n {
        for kx in 0..3 {
            let (g0, g1, g2) = (wk(0, kx, ci), wk(1, kx, ci), wk(2, kx, ci));
            for o in 0..co_n {
                let (a, b, cc) = (g0[o], g1[o], g2[o]);
                rows[(kx) * co_n + o] = a;
                rows[(3 + kx) * co_n + o] = 0.5 * (a + b + cc);
                rows[(6 + kx) * co_n + o] = 0.5 * (a - b + cc);
                rows[(9 + kx) * co_n + o] = cc;
            }
        }
        for a in 0..4 {
            for o in 0..co_n {
                let (r0, r1, r2) = (rows[(a * 3) * co_n + o], rows[(a * 3 + 1) * co_n + o], rows[(a * 3 + 2) * co_n + o]);
                let vals = [r0, 0.5 * (r0 + r1 + r2), 0.5 * (r0 - r1 + r2), r2];
                for (b, val) in vals.into_iter().enumerate() {
                    u[((a * 4 + b) * ci_n + ci) * co_n + o] = val;
                }
            }
        }
    }
}

/// `dW += G^T dU G`.
fn weight_transform_adjoint(g: &ConvGeom, du: &[f32], dw: &mut [f32]) {
    let (ci_n, co_n) = (g.c_in, g.c_out);
    let at = |a: usize, b: usize, ci: usize, o: usize| du[((a * 4 + b) * ci_n + ci) * co_n + o];
    for ci in 0..ci_n {
        for o in 0..co_n {
            // Columns first: h[a][kx] = sum_b dU[a][b] G[b][kx].
            let mut h = [[0.0f32; 3]; 4];
            for (a, ha) in h.iter_mut().enumerate() {
                let (d0, d1, d2, d3) = (at(a, 0, ci, o), at(a, 1, ci, o), at(a, 2, ci, o), at(a, 3, ci, o));
                *ha = [d0 + 0.5 * (d1 + d2), 0.5 * (d1 - d2), 0.5 * (d1 + d2) + d3];
            }
            for kx in 0..3 {
                let (d0, d1, d2, d3) = (h[0][kx], h[1][kx], h[2][kx], h[3][kx]);
                let col = [d0 + 0.5 * (d1 + d2), 0.5 * (d1 - d2), 0.5 * (d1 + d2) + d3];
                for (ky, val) in col.into_iter().enumerate() {
                    dw[((ky * 3 + kx) * ci_n + ci) * co_n + o] += val;
                }
            }
        }
    }
}

/// `y = conv(x) + b`; keeps `V` and `U` for backward.
pub fn forward(g: &ConvGeom, w: &[f32], b: &[f32], x: &[f32], cache: &mut WinoCache, m: &mut Vec<f32>, y: &mut Vec<f32>) {
    weight_transform(g, w, &mut cache.u);
    cache.tiles = forward_transformed(g, &cache.u, b, x, &mut cache.v, m, y);
}

/// The transformed weights `U [16, c_in, c_out]` of the kernel layout
/// `w [(ky, kx, ci), co]`, for [`forward_transformed`] (inference computes
/// them once per model instead of once per call).
pub fn transform_weights(g: &ConvGeom, w: &[f32]) -> Vec<f32> {
    assert!(supports(g), "Winograd F(2x2, 3x3) needs a 3x3 stride-1 same conv");
    assert_eq!(w.len(), g.weight_len(), "conv weights");
    let mut u = Vec::new();
    weight_transform(g, w, &mut u);
    u
}

/// `y = conv(x) + b` with the weights already transformed (`u` from
/// [`transform_weights`]); `v` and `m` are scratch (`V` and `M` of the module
/// docs). Returns the number of tiles `T`. Each sample's output depends only
/// on that sample, and the operations it goes through depend only on the
/// shapes, not on the sample's place in the batch.
pub fn forward_transformed(g: &ConvGeom, u: &[f32], b: &[f32], x: &[f32], v: &mut Vec<f32>, m: &mut Vec<f32>, y: &mut Vec<f32>) -> usize {
    debug_assert!(supports(g));
    let n = x.len() / g.in_len();
    let t_all = input_transform(g, x, n, v);
    let (ci, co) = (g.c_in, g.c_out);
    fit(m, 16 * t_all * co);
    for xi in 0..16 {
        matmul(
            &mut m[xi * t_all * co..][..t_all * co],
            Mat::new(&v[xi * t_all * ci..][..t_all * ci], t_all, ci),
            Mat::new(&u[xi * ci * co..][..ci * co], ci, co),
            false,
        );
    }
    // y = A^T M A per tile, A^T = [[1,1,1,0],[0,1,-1,-1]].
    let (th, tw) = tiles_hw(g);
    fit(y, n * g.h * g.w * co);
    // r[rr][col]: rows transformed (2 x 4).
    let mut r = vec![0.0f32; 8 * co];
    let a_t = |m0: &[f32], m1: &[f32], m2: &[f32], m3: &[f32], o0: &mut [f32], o1: &mut [f32]| {
        let ins = m0.iter().zip(m1).zip(m2.iter().zip(m3));
        for (((a0, a1), (a2, a3)), (p0, p1)) in ins.zip(o0.iter_mut().zip(o1.iter_mut())) {
            *p0 = a0 + a1 + a2;
            *p1 = a1 - a2 - a3;
        }
    };
    let mut out2 = vec![0.0f32; 2 * co];
    for tile in 0..t_all {
        let (s, ti, tj) = (tile / (th * tw), tile / tw % th, tile % tw);
        let mm = |xi: usize| &m[(xi * t_all + tile) * co..][..co];
        for col in 0..4 {
            let (r0, r1) = r.split_at_mut(4 * co);
            a_t(mm(col), mm(4 + col), mm(8 + col), mm(12 + col), &mut r0[col * co..][..co], &mut r1[col * co..][..co]);
        }
        for rr in 0..2 {
            let oy = 2 * ti + rr;
            if oy >= g.h {
                continue;
            }
            let q = &r[rr * 4 * co..][..4 * co];
            let (o0, o1) = out2.split_at_mut(co);
            a_t(&q[..co], &q[co..2 * co], &q[2 * co..3 * co], &q[3 * co..], o0, o1);
            for cc in 0..2 {
                let ox = 2 * tj + cc;
                if ox >= g.w {
                    continue;
                }
                let dst = &mut y[((s * g.h + oy) * g.w + ox) * co..][..co];
                dst.iter_mut().zip(&out2[cc * co..][..co]).zip(b).for_each(|((d, v), bb)| *d = v + bb);
            }
        }
    }
    t_all
}

/// Backward of [`forward`]: `grads = Some((dw, db))` accumulates the
/// parameter gradients; `dx = Some(..)` receives the input gradient.
pub fn backward(
    g: &ConvGeom,
    cache: &WinoCache,
    dy: &[f32],
    grads: Option<(&mut [f32], &mut [f32])>,
    dx: Option<&mut Vec<f32>>,
    s: &mut WinoScratch,
) {
    let (ci, co, t_all) = (g.c_in, g.c_out, cache.tiles);
    let (th, tw) = tiles_hw(g);
    let n = t_all / (th * tw);
    // dM = A dy A^T, A = [[1,0],[1,1],[1,-1],[0,-1]]; outside outputs are 0.
    fit(&mut s.m, 16 * t_all * co);
    let zero = vec![0.0f32; co];
    let a_col = |d0: &[f32], d1: &[f32], out: [&mut [f32]; 4]| {
        let [p0, p1, p2, p3] = out;
        let outs = p0.iter_mut().zip(p1.iter_mut()).zip(p2.iter_mut().zip(p3.iter_mut()));
        for ((a0, a1), ((q0, q1), (q2, q3))) in d0.iter().zip(d1).zip(outs) {
            *q0 = *a0;
            *q1 = a0 + a1;
            *q2 = a0 - a1;
            *q3 = -a1;
        }
    };
    let mut r = vec![0.0f32; 8 * co]; // r[cc][a]: rows transformed, per output column
    for tile in 0..t_all {
        let (sm, ti, tj) = (tile / (th * tw), tile / tw % th, tile % tw);
        let d = |rr: usize, cc: usize| -> &[f32] {
            let (oy, ox) = (2 * ti + rr, 2 * tj + cc);
            if oy >= g.h || ox >= g.w {
                &zero
            } else {
                &dy[((sm * g.h + oy) * g.w + ox) * co..][..co]
            }
        };
        for cc in 0..2 {
            a_col(d(0, cc), d(1, cc), four(&mut r, cc * 4 * co, co));
        }
        for a in 0..4 {
            let (e0, e1) = (&r[a * co..][..co], &r[(4 + a) * co..][..co]);
            let [q0, q1, q2, q3] = {
                let base = &mut s.m;
                let mut it = (0..4).map(|b| ((a * 4 + b) * t_all + tile) * co);
                let (i0, i1, i2, i3) = (it.next().unwrap(), it.next().unwrap(), it.next().unwrap(), it.next().unwrap());
                // Four disjoint co-long slices at increasing offsets.
                let (lo, rest) = base.split_at_mut(i1);
                let (mid1, rest) = rest.split_at_mut(i2 - i1);
                let (mid2, hi) = rest.split_at_mut(i3 - i2);
                [&mut lo[i0..i0 + co], &mut mid1[..co], &mut mid2[..co], &mut hi[..co]]
            };
            a_col(e0, e1, [q0, q1, q2, q3]);
        }
    }
    if let Some((dw, db)) = grads {
        for row in dy.chunks_exact(co) {
            db.iter_mut().zip(row).for_each(|(d, v)| *d += v);
        }
        fit(&mut s.du, 16 * ci * co);
        for xi in 0..16 {
            matmul(
                &mut s.du[xi * ci * co..][..ci * co],
                Mat::new(&cache.v[xi * t_all * ci..][..t_all * ci], t_all, ci).t(),
                Mat::new(&s.m[xi * t_all * co..][..t_all * co], t_all, co),
                false,
            );
        }
        weight_transform_adjoint(g, &s.du, dw);
    }
    if let Some(dx) = dx {
        fit(&mut s.dv, 16 * t_all * ci);
        for xi in 0..16 {
            matmul(
                &mut s.dv[xi * t_all * ci..][..t_all * ci],
                Mat::new(&s.m[xi * t_all * co..][..t_all * co], t_all, co),
                Mat::new(&cache.u[xi * ci * co..][..ci * co], ci, co).t(),
                false,
            );
        }
        // dx += B dV B^T per tile, scattered to the patch's inside positions.
        dx.clear();
        dx.resize(n * g.in_len(), 0.0);
        let mut t = vec![0.0f32; 16 * ci];
        let mut p = vec![0.0f32; 16 * ci];
        for tile in 0..t_all {
            let (sm, ti, tj) = (tile / (th * tw), tile / tw % th, tile % tw);
            let dv = |xi: usize| &s.dv[(xi * t_all + tile) * ci..][..ci];
            // Along a (rows) for each column b: t[b][i] = sum_a B[i][a] dV[a][b].
            t.fill(0.0);
            for bcol in 0..4 {
                b_add([dv(bcol), dv(4 + bcol), dv(8 + bcol), dv(12 + bcol)], four(&mut t, bcol * 4 * ci, ci));
            }
            // Along b for each row i: p[i][j] = sum_b B[j][b] t[b][i].
            p.fill(0.0);
            for i in 0..4 {
                let ins = [&t[i * ci..][..ci], &t[(4 + i) * ci..][..ci], &t[(8 + i) * ci..][..ci], &t[(12 + i) * ci..][..ci]];
                b_add(ins, four(&mut p, i * 4 * ci, ci));
            }
            for rr in 0..4 {
                for cc in 0..4 {
                    let (y, xx) = ((2 * ti + rr) as isize - 1, (2 * tj + cc) as isize - 1);
                    if y < 0 || xx < 0 || y as usize >= g.h || xx as usize >= g.w {
                        continue;
                    }
                    let out = &mut dx[((sm * g.h + y as usize) * g.w + xx as usize) * ci..][..ci];
                    out.iter_mut().zip(&p[(rr * 4 + cc) * ci..][..ci]).for_each(|(o, v)| *o += v);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layers::conv;

    fn data(len: usize, k: usize) -> Vec<f32> {
        (0..len).map(|i| (((i * k + 3) % 29) as f32 - 14.0) / 9.0).collect()
    }

    /// Forward and both gradients equal the im2col convolution's.
    #[test]
    fn winograd_equals_im2col_forward_and_backward() {
        for (h, w, ci, co) in [(20, 5, 3, 4), (20, 5, 8, 2), (7, 4, 2, 5)] {
            let g = ConvGeom::same3(h, w, ci, co);
            let n = 3;
            let x = data(n * g.in_len(), 7);
            let wt = data(g.weight_len(), 11);
            let b = data(co, 5);
            let dy = data(n * h * w * co, 13);
            let (mut col, mut y0) = (Vec::new(), Vec::new());
            conv::forward(&g, &wt, &b, &x, &mut col, &mut y0);
            let (mut cache, mut m, mut y1) = (WinoCache::default(), Vec::new(), Vec::new());
            forward(&g, &wt, &b, &x, &mut cache, &mut m, &mut y1);
            let close = |a: &[f32], b: &[f32], what: &str| {
                assert_eq!(a.len(), b.len(), "{what}");
                for (i, (p, q)) in a.iter().zip(b).enumerate() {
                    assert!((p - q).abs() < 1e-4 * (1.0 + q.abs()), "{what} [{i}]: {p} vs {q} ({h}x{w} {ci}->{co})");
                }
            };
            close(&y1, &y0, "forward");
            let (mut dw0, mut db0, mut dx0) = (vec![0.0; g.weight_len()], vec![0.0; co], Vec::new());
            conv::backward(&g, &wt, &col, &dy, Some((&mut dw0, &mut db0)), Some(&mut dx0), &mut Vec::new());
            let (mut dw1, mut db1, mut dx1) = (vec![0.0; g.weight_len()], vec![0.0; co], Vec::new());
            backward(&g, &cache, &dy, Some((&mut dw1, &mut db1)), Some(&mut dx1), &mut WinoScratch::default());
            close(&dw1, &dw0, "dW");
            close(&db1, &db0, "db");
            close(&dx1, &dx0, "dx");
        }
    }
}
