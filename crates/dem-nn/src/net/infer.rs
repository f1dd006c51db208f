//! The generator of `docs/network.md` for inference only: no tape, weights
//! prepared once, records run in blocks of a fixed size.
//!
//! Per block of `B` records (`x [B, 100, c]` channels-last, 100 = 20x5
//! positions of rows 0..19):
//!
//! ```text
//! conv (3x3, stride 1, pad 1)   Winograd F(4x3, 3x3), U = G_r g G_c^T computed at load   [B, 100, c_in] -> [B, 100, c_out]
//! norm + act                    act(gamma (x - mean) / sqrt(var + eps) + beta), fused, in place
//! encoder   3 x (conv, norm, leaky 0.2)          2 -> w -> 2w -> 2w
//! residual  3 x h + norm(conv(relu(norm(conv(h)))))                         2w
//! decoder   2 x (conv, norm, leaky 0.2), conv    2w -> 2w -> w -> 2
//! head      [decoder out (200), attitude (10)] W [210, 200] + b ->
//!           thesis:   h = o_h,                   m = tanh(o_m)
//!           residual: h = (x_h + s o_h) sigmoid(k o_m),   m = tanh(o_m)
//! output    rows 0..19 from the head, row 20 the input's (the attitude passes through)
//! ```
//!
//! The same maths as [`crate::net::Generator::forward`], which trains, and
//! as the f64 [`crate::reference::generator`], which the tests compare with.
//!
//! **Determinism.** A call on any number of records runs them in blocks of
//! exactly [`GeneratorInference::block`] records (the last block padded with
//! zero records, whose outputs are dropped), so every matrix product has the
//! same shape whatever the caller's batch, and a record's output does not
//! depend on the batch it came in nor on its place in it (tested).
//!
//! Layer 4 (net): may use layers, weights and gemm.

use dem_core::format::{GRID_CELLS, GRID_LEN, RECORD_LEN};
use dem_core::Dem;

use super::generator::ATT;
use super::params::{channels_first, Alloc, ConvLayer, DenseLayer};
use crate::gemm::{matmul, Mat};
use crate::layers::conv::ConvGeom;
use crate::layers::norm::{self, Act};
use crate::layers::winograd_rect::{RectConv, RectScratch};
use crate::weights::{Arch, Conv2d, GeneratorWeights, InstanceNorm, CORRECTION_SCALE, GATE_SHARPNESS};

/// Positions of the 20x5 grid.
const POS: usize = GRID_CELLS;
/// Records per block when none is given: 16 records are 160 Winograd tiles
/// (rows of each of the 30 matrix products), enough to amortise packing the
/// 2w x 2w weights, few enough that a block's transformed activations
/// (160 x 30 x 2w floats, 1.2 MB at w = 32) stay near the core's L2 cache. On
/// the width-32 generator, one thread: blocks of 8, 16, 32 ran 1,600, 1,740,
/// 1,410 records/s (a shared 2-core machine).
pub const DEFAULT_BLOCK: usize = 16;

/// PyTorch layout -> kernel layout `[(ky, kx, ci), co]` (through the
/// training code's own conversion), then the Winograd weight transform.
fn prepare(c: &Conv2d) -> RectConv {
    assert_eq!((c.k, c.stride), (3, 1), "the generator's convs are 3x3 stride 1");
    let g = ConvGeom::same3(20, 5, c.c_in, c.c_out);
    let mut a = Alloc::default();
    let layer = ConvLayer::new(&mut a, g);
    let mut p = vec![0.0; a.len()];
    layer.load(&mut p, c);
    RectConv::new(g, &p[layer.w.clone()], &c.bias)
}

/// A generator ready for inference (see the module docs).
#[derive(Clone, Debug)]
pub struct GeneratorInference {
    arch: Arch,
    width: usize,
    block: usize,
    /// 3 encoder, 6 residual (a, b per block), 3 decoder convs, in order.
    convs: Vec<RectConv>,
    /// 3 encoder, 6 residual, 2 decoder norms, in order.
    norms: Vec<InstanceNorm>,
    /// Head weights `[210, 200]` in channels-last order, and biases `[200]`.
    fc_w: Vec<f32>,
    fc_b: Vec<f32>,
}

/// Buffers of [`GeneratorInference::run`], reused between calls.
#[derive(Debug, Default)]
pub struct InferScratch {
    grid: Vec<f32>,
    a: Vec<f32>,
    b: Vec<f32>,
    h: Vec<f32>,
    conv: RectScratch,
    feat: Vec<f32>,
    out: Vec<f32>,
}

impl GeneratorInference {
    /// Prepare generator `w` with blocks of [`DEFAULT_BLOCK`] records.
    /// Panics if `w` is not shaped as [`GeneratorWeights::init_arch`] makes it.
    pub fn new(w: &GeneratorWeights) -> Self {
        Self::with_block(w, DEFAULT_BLOCK)
    }

    /// Prepare generator `w`, running `block >= 1` records per block.
    pub fn with_block(w: &GeneratorWeights, block: usize) -> Self {
        assert!(block >= 1, "block of at least one record");
        let wd = w.width;
        let shapes: Vec<(usize, usize)> = [(2, wd), (wd, 2 * wd), (2 * wd, 2 * wd)]
            .into_iter()
            .chain(std::iter::repeat_n((2 * wd, 2 * wd), 6))
            .chain([(2 * wd, 2 * wd), (2 * wd, wd), (wd, 2)])
            .collect();
        let convs: Vec<&Conv2d> = w.enc.iter().chain(w.res.iter().flat_map(|r| [&r.a, &r.b])).chain(&w.dec).collect();
        assert_eq!(convs.len(), 12, "3 encoder, 6 residual and 3 decoder convs");
        for (c, (ci, co)) in convs.iter().zip(&shapes) {
            assert_eq!((c.c_in, c.c_out), (*ci, *co), "conv channels of a width-{wd} generator");
        }
        let norms: Vec<InstanceNorm> =
            w.enc_norm.iter().chain(w.res.iter().flat_map(|r| [&r.na, &r.nb])).chain(&w.dec_norm).cloned().collect();
        assert_eq!(norms.len(), 11, "11 instance norms");
        let mut a = Alloc::default();
        let torch_in = channels_first(POS, 2).chain(channels_first(5, 2).map(|t| GRID_LEN + t)).collect();
        let fc = DenseLayer::new(&mut a, torch_in, channels_first(POS, 2).collect());
        let mut p = vec![0.0; a.len()];
        fc.load(&mut p, &w.fc);
        GeneratorInference {
            arch: w.arch,
            width: wd,
            block,
            convs: convs.into_iter().map(prepare).collect(),
            norms,
            fc_w: p[fc.w.clone()].to_vec(),
            fc_b: p[fc.b.clone()].to_vec(),
        }
    }

    /// The head.
    pub fn arch(&self) -> Arch {
        self.arch
    }

    /// Width w.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Records per block.
    pub fn block(&self) -> usize {
        self.block
    }

    /// The generator's output for every record of `records`, appended to
    /// `out` in order (row 20 copied from the input).
    pub fn run(&self, records: &[Dem], s: &mut InferScratch, out: &mut Vec<Dem>) {
        out.reserve(records.len());
        for chunk in records.chunks(self.block) {
            s.grid.clear();
            for d in chunk {
                s.grid.extend_from_slice(&d[..GRID_LEN]);
            }
            s.grid.resize(self.block * GRID_LEN, 0.0);
            s.feat.clear();
            s.feat.resize(self.block * (GRID_LEN + ATT), 0.0);
            for (f, d) in s.feat.chunks_exact_mut(GRID_LEN + ATT).zip(chunk) {
                f[GRID_LEN..].copy_from_slice(&d[GRID_LEN..]);
            }
            crate::gemm::with_avx2(Block(self, s));
            for (d, o) in chunk.iter().zip(s.out.chunks_exact(GRID_LEN)) {
                let mut r = [0.0f32; RECORD_LEN];
                r[..GRID_LEN].copy_from_slice(o);
                r[GRID_LEN..].copy_from_slice(&d[GRID_LEN..]);
                out.push(r);
            }
        }
    }

    /// One conv into `y`, then its norm and activation in place.
    #[inline(always)]
    fn conv(&self, i: usize, x: &[f32], y: &mut Vec<f32>, s: &mut RectScratch, act: Option<Act>) {
        self.convs[i].forward(x, s, y);
        if let Some(act) = act {
            let n = &self.norms[i];
            norm::forward_inplace(y, POS, &n.gamma, &n.beta, act);
        }
    }

    /// The network on `s.grid [block, 200]` with the attitudes already in
    /// `s.feat [block, 210]` (columns 200..210); the output grid in `s.out`.
    #[inline(always)]
    fn block_forward(&self, s: &mut InferScratch) {
        let InferScratch { grid, a, b, h, conv: v, feat, out } = s;
        self.conv(0, grid, a, v, Some(Act::Leaky));
        self.conv(1, a, b, v, Some(Act::Leaky));
        self.conv(2, b, h, v, Some(Act::Leaky));
        for r in 0..3 {
            let (ca, cb) = (3 + 2 * r, 4 + 2 * r);
            self.conv(ca, h, a, v, Some(Act::Relu));
            self.conv(cb, a, b, v, Some(Act::None));
            h.iter_mut().zip(b.iter()).for_each(|(x, y)| *x += y);
        }
        self.conv(9, h, a, v, Some(Act::Leaky));
        self.conv(10, a, b, v, Some(Act::Leaky));
        self.conv(11, b, a, v, None);
        for (f, y) in feat.chunks_exact_mut(GRID_LEN + ATT).zip(a.chunks_exact(GRID_LEN)) {
            f[..GRID_LEN].copy_from_slice(y);
        }
        out.clear();
        for _ in 0..self.block {
            out.extend_from_slice(&self.fc_b);
        }
        matmul(out, Mat::new(feat, self.block, GRID_LEN + ATT), Mat::new(&self.fc_w, GRID_LEN + ATT, GRID_LEN), true);
        match self.arch {
            Arch::Thesis => out.iter_mut().skip(1).step_by(2).for_each(|m| *m = m.tanh()),
            Arch::Residual => {
                for (o, x) in out.chunks_exact_mut(2).zip(grid.chunks_exact(2)) {
                    let gate = 1.0 / (1.0 + (-GATE_SHARPNESS * o[1]).exp());
                    o[0] = (x[0] + CORRECTION_SCALE * o[0]) * gate;
                    o[1] = o[1].tanh();
                }
            }
        }
    }
}

/// One block's forward pass, as work for [`crate::gemm::with_avx2`].
struct Block<'a>(&'a GeneratorInference, &'a mut InferScratch);

impl crate::gemm::Widened for Block<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self) {
        self.0.block_forward(self.1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn records(n: usize, seed: u64) -> Vec<Dem> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let mut d = [0.0f32; RECORD_LEN];
                for (k, v) in d.iter_mut().enumerate() {
                    *v = if k % 2 == 1 && k < GRID_LEN { rng.gen_range(-1.0f32..1.0).signum() } else { rng.gen_range(-0.5..0.5) };
                }
                d
            })
            .collect()
    }

    /// Both heads equal the f64 reference within 1e-4 (the export's
    /// tolerance: f32 rounding through ~15 layers with norms is ~1e-6).
    #[test]
    fn inference_equals_the_f64_reference() {
        for arch in [Arch::Thesis, Arch::Residual] {
            let mut rng = ChaCha8Rng::seed_from_u64(7);
            let mut w = GeneratorWeights::init_arch(&mut rng, 8, arch);
            // Non-trivial norms and head rows, so every parameter matters.
            for n in w.enc_norm.iter_mut().chain(&mut w.dec_norm) {
                n.gamma.iter_mut().for_each(|g| *g = rng.gen_range(0.5..1.5));
                n.beta.iter_mut().for_each(|b| *b = rng.gen_range(-0.3..0.3));
            }
            w.fc.weight.iter_mut().for_each(|v| *v += rng.gen_range(-0.05..0.05));
            let g = GeneratorInference::with_block(&w, 4);
            let xs = records(7, 3);
            let mut out = Vec::new();
            g.run(&xs, &mut InferScratch::default(), &mut out);
            assert_eq!(out.len(), xs.len());
            for (x, y) in xs.iter().zip(&out) {
                let want = reference::generator(&w, x);
                for (j, (a, b)) in y.iter().zip(want.iter()).enumerate() {
                    assert!((a - b).abs() <= 1e-4, "{arch:?} value {j}: {a} vs {b}");
                }
                assert_eq!(y[GRID_LEN..], x[GRID_LEN..], "row 20 passes through");
            }
        }
    }

    /// A record's output is the same bits whatever the batch it came in and
    /// its place there.
    #[test]
    fn outputs_do_not_depend_on_the_batch() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let w = GeneratorWeights::init_arch(&mut rng, 16, Arch::Residual);
        let g = GeneratorInference::new(&w);
        let xs = records(53, 5);
        let mut s = InferScratch::default();
        let mut whole = Vec::new();
        g.run(&xs, &mut s, &mut whole);
        for batch in [1, 3, 16, 17, 40] {
            let mut got = Vec::new();
            for c in xs.chunks(batch) {
                g.run(c, &mut s, &mut got);
            }
            assert!(got == whole, "batch {batch}");
        }
        let mut rev = Vec::new();
        let back: Vec<Dem> = xs.iter().rev().copied().collect();
        g.run(&back, &mut s, &mut rev);
        rev.reverse();
        assert!(rev == whole, "records in another order");
    }
}
