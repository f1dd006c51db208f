//! The generator of `docs/network.md` on a batch, forward and backward.
//!
//! Input: the grid `[n, 20, 5, 2]` (rows 0..19 of each record, which is
//! already channels-last) and the attitude `[n, 10]` (row 20, in record
//! order). Output: the grid `[n, 20, 5, 2]` with tanh on the mask channel
//! and, for [`Arch::Residual`], heights `(x_h + s o_h) sigmoid(k o_m)` (see
//! [`Arch`]); the caller copies row 20 through. Shapes inside: `[n, 100, c]`.
//!
//! Layer 4 (net): may use layers, weights and gemm.

use dem_core::format::{GRID_CELLS, GRID_LEN, RECORD_LEN};

use super::params::{channels_first, Alloc, ConvLayer, DenseLayer, NormLayer};
use crate::layers::conv::ConvGeom;
use crate::layers::dense;
use crate::layers::norm::{self, Act, NormCache};
use crate::layers::winograd::{self, WinoCache, WinoScratch};
use crate::weights::{Arch, GeneratorWeights, ResBlock, CORRECTION_SCALE, GATE_SHARPNESS};

/// Attitude values of one record (row 20).
pub const ATT: usize = RECORD_LEN - GRID_LEN;
/// Cells of the grid: heights come first in the head's output, masks after.
const POS: usize = GRID_CELLS;

/// Layer layout of a generator of width w.
#[derive(Clone, Debug)]
pub struct Generator {
    /// Width w.
    pub width: usize,
    /// The head.
    pub arch: Arch,
    /// 3 encoder, 6 residual (a, b per block), 3 decoder convs, in order.
    convs: Vec<ConvLayer>,
    /// 3 encoder, 6 residual, 2 decoder norms, in order.
    norms: Vec<NormLayer>,
    fc: DenseLayer,
    /// Total parameters.
    pub len: usize,
}

/// What a forward pass keeps for backward. Reused between steps so its
/// buffers keep their capacity.
#[derive(Debug, Default)]
pub struct GenTape {
    n: usize,
    /// Input of each conv, Winograd-transformed.
    convs: Vec<WinoCache>,
    /// Scratch of the Winograd products.
    m: Vec<f32>,
    norms: Vec<NormCache>,
    /// Output of each norm + activation.
    zs: Vec<Vec<f32>>,
    /// Conv outputs before their norm (scratch, kept to reuse capacity).
    ys: Vec<Vec<f32>>,
    /// Head input `[n, 210]`.
    feat: Vec<f32>,
    /// Output grid `[n, 200]` (after tanh on the mask).
    pub out: Vec<f32>,
    /// [`Arch::Residual`]: the ungated height `x_h + s o_h` of each cell `[n, 100]`.
    ungated: Vec<f32>,
    /// [`Arch::Residual`]: the gate `sigmoid(k o_m)` of each cell `[n, 100]`.
    gate: Vec<f32>,
}

/// Scratch buffers of a backward pass.
#[derive(Debug, Default)]
pub struct GenScratch {
    dh: Vec<f32>,
    dres: Vec<f32>,
    dfeat: Vec<f32>,
    wino: WinoScratch,
}

const ENC: usize = 0;
const RES: usize = 3;
const DEC: usize = 9;

impl Generator {
    /// The layout of a generator of width `w` with head `arch`.
    pub fn new(w: usize, arch: Arch) -> Self {
        let mut a = Alloc::default();
        let (h, wd) = (20, 5);
        let enc = [2, w, 2 * w, 2 * w];
        let dec = [2 * w, 2 * w, w, 2];
        let mut convs = Vec::new();
        let mut norms = Vec::new();
        for i in 0..3 {
            convs.push(ConvLayer::new(&mut a, ConvGeom::same3(h, wd, enc[i], enc[i + 1])));
            norms.push(NormLayer::new(&mut a, enc[i + 1]));
        }
        for _ in 0..6 {
            convs.push(ConvLayer::new(&mut a, ConvGeom::same3(h, wd, 2 * w, 2 * w)));
            norms.push(NormLayer::new(&mut a, 2 * w));
        }
        for i in 0..3 {
            convs.push(ConvLayer::new(&mut a, ConvGeom::same3(h, wd, dec[i], dec[i + 1])));
            if i < 2 {
                norms.push(NormLayer::new(&mut a, dec[i + 1]));
            }
        }
        let torch_in = channels_first(POS, 2).chain(channels_first(5, 2).map(|t| GRID_LEN + t)).collect();
        let fc = DenseLayer::new(&mut a, torch_in, channels_first(POS, 2).collect());
        Generator { width: w, arch, convs, norms, fc, len: a.len() }
    }

    /// Flat parameters from PyTorch-layout weights.
    pub fn load(&self, t: &GeneratorWeights) -> Vec<f32> {
        assert_eq!((t.width, t.arch), (self.width, self.arch), "generator width and head");
        let mut p = vec![0.0; self.len];
        let convs = t.enc.iter().chain(t.res.iter().flat_map(|r| [&r.a, &r.b])).chain(&t.dec);
        let norms = t.enc_norm.iter().chain(t.res.iter().flat_map(|r| [&r.na, &r.nb])).chain(&t.dec_norm);
        self.convs.iter().zip(convs).for_each(|(l, c)| l.load(&mut p, c));
        self.norms.iter().zip(norms).for_each(|(l, n)| l.load(&mut p, n));
        self.fc.load(&mut p, &t.fc);
        p
    }

    /// PyTorch-layout weights from flat parameters.
    pub fn save(&self, p: &[f32]) -> GeneratorWeights {
        let c: Vec<_> = self.convs.iter().map(|l| l.save(p)).collect();
        let n: Vec<_> = self.norms.iter().map(|l| l.save(p)).collect();
        let res = (0..3)
            .map(|i| ResBlock {
                a: c[RES + 2 * i].clone(),
                na: n[RES + 2 * i].clone(),
                b: c[RES + 2 * i + 1].clone(),
                nb: n[RES + 2 * i + 1].clone(),
            })
            .collect();
        GeneratorWeights {
            width: self.width,
            arch: self.arch,
            enc: c[ENC..RES].to_vec(),
            enc_norm: n[ENC..RES].to_vec(),
            res,
            dec: c[DEC..].to_vec(),
            dec_norm: n[DEC..].to_vec(),
            fc: self.fc.save(p),
        }
    }

    fn conv_fwd(&self, i: usize, p: &[f32], x: &[f32], t: &mut GenTape) {
        let l = &self.convs[i];
        winograd::forward(&l.g, &p[l.w.clone()], &p[l.b.clone()], x, &mut t.convs[i], &mut t.m, &mut t.ys[i]);
    }

    fn norm_fwd(&self, j: usize, conv: usize, p: &[f32], act: Act, t: &mut GenTape) {
        let l = &self.norms[j];
        norm::forward(&t.ys[conv], POS, &p[l.gamma.clone()], &p[l.beta.clone()], act, &mut t.norms[j], &mut t.zs[j]);
    }

    /// Forward pass of a batch: `grid [n, 200]`, `att [n, 10]`; the output
    /// grid is `tape.out`.
    pub fn forward(&self, p: &[f32], grid: &[f32], att: &[f32], t: &mut GenTape) {
        let n = grid.len() / GRID_LEN;
        assert_eq!(att.len(), n * ATT, "attitude rows");
        t.n = n;
        t.convs.resize_with(12, WinoCache::default);
        t.ys.resize_with(12, Vec::new);
        t.zs.resize_with(11, Vec::new);
        t.norms.resize_with(11, NormCache::default);
        self.conv_fwd(0, p, grid, t);
        self.norm_fwd(0, 0, p, Act::Leaky, t);
        for i in 1..3 {
            let x = std::mem::take(&mut t.zs[i - 1]);
            self.conv_fwd(i, p, &x, t);
            t.zs[i - 1] = x;
            self.norm_fwd(i, i, p, Act::Leaky, t);
        }
        // Residual blocks: h_{b+1} = h_b + nb(b(relu(na(a(h_b))))). Backward
        // needs only the layers' caches, so the running sum lives in `h`.
        let mut h = t.zs[2].clone();
        for b in 0..3 {
            let (ca, cb) = (RES + 2 * b, RES + 2 * b + 1);
            self.conv_fwd(ca, p, &h, t);
            self.norm_fwd(ca, ca, p, Act::Relu, t);
            let z = std::mem::take(&mut t.zs[ca]);
            self.conv_fwd(cb, p, &z, t);
            t.zs[ca] = z;
            self.norm_fwd(cb, cb, p, Act::None, t);
            h.iter_mut().zip(&t.zs[cb]).for_each(|(a, b)| *a += b);
        }
        self.conv_fwd(DEC, p, &h, t);
        self.norm_fwd(DEC, DEC, p, Act::Leaky, t);
        let z = std::mem::take(&mut t.zs[DEC]);
        self.conv_fwd(DEC + 1, p, &z, t);
        t.zs[DEC] = z;
        self.norm_fwd(DEC + 1, DEC + 1, p, Act::Leaky, t);
        let z = std::mem::take(&mut t.zs[DEC + 1]);
        self.conv_fwd(DEC + 2, p, &z, t);
        t.zs[DEC + 1] = z;
        // Head: [decoder output (200), attitude (10)] -> 200, tanh on masks.
        t.feat.clear();
        for (row, a) in t.ys[DEC + 2].chunks_exact(GRID_LEN).zip(att.chunks_exact(ATT)) {
            t.feat.extend_from_slice(row);
            t.feat.extend_from_slice(a);
        }
        dense::forward(&p[self.fc.w.clone()], &p[self.fc.b.clone()], &t.feat, GRID_LEN + ATT, &mut t.out);
        match self.arch {
            Arch::Thesis => t.out.iter_mut().skip(1).step_by(2).for_each(|m| *m = m.tanh()),
            Arch::Residual => {
                t.ungated.clear();
                t.gate.clear();
                for (o, x) in t.out.chunks_exact_mut(2).zip(grid.chunks_exact(2)) {
                    let g = 1.0 / (1.0 + (-GATE_SHARPNESS * o[1]).exp());
                    let a = x[0] + CORRECTION_SCALE * o[0];
                    t.ungated.push(a);
                    t.gate.push(g);
                    o[0] = a * g;
                    o[1] = o[1].tanh();
                }
            }
        }
    }

    /// Backward of the last [`forward`](Self::forward) on `t`: `dout [n, 200]` is the loss
    /// gradient of the output grid. Accumulates into `grads`; returns the
    /// gradient of the input grid when `want_input` (the attitude's is never
    /// needed: it passes through from data).
    pub fn backward(
        &self,
        p: &[f32],
        t: &GenTape,
        dout: &[f32],
        grads: &mut [f32],
        want_input: bool,
        s: &mut GenScratch,
    ) -> Option<Vec<f32>> {
        let mut u = dout.to_vec();
        let mut skip = Vec::new();
        match self.arch {
            Arch::Thesis => u.iter_mut().zip(&t.out).skip(1).step_by(2).for_each(|(d, m)| *d *= 1.0 - m * m),
            Arch::Residual => {
                // h = a g with a = x_h + s o_h, g = sigmoid(k o_m): dL/da = dh g
                // (the input height's gradient, kept in `skip`), dL/do_h = s dL/da,
                // dL/do_m = dm (1 - m^2) + dh a k g (1 - g).
                skip.clear();
                let cells = u.chunks_exact_mut(2).zip(t.out.chunks_exact(2)).zip(t.ungated.iter().zip(&t.gate));
                for ((d, o), (a, g)) in cells {
                    let dh = d[0];
                    let da = dh * g;
                    skip.push(da);
                    d[0] = CORRECTION_SCALE * da;
                    d[1] = d[1] * (1.0 - o[1] * o[1]) + dh * a * GATE_SHARPNESS * g * (1.0 - g);
                }
            }
        }
        let (gw, gb) = split2(grads, &self.fc.w, &self.fc.b);
        dense::backward(&p[self.fc.w.clone()], &t.feat, GRID_LEN + ATT, &u, Some((gw, gb)), Some(&mut s.dfeat));
        s.dh.clear();
        for row in s.dfeat.chunks_exact(GRID_LEN + ATT) {
            s.dh.extend_from_slice(&row[..GRID_LEN]);
        }
        let mut dh = std::mem::take(&mut s.dh);
        let mut next = Vec::new();
        self.conv_bwd(DEC + 2, t, &dh, grads, Some(&mut next), s);
        std::mem::swap(&mut dh, &mut next);
        for j in [DEC + 1, DEC] {
            self.norm_bwd(j, p, t, Act::Leaky, &mut dh, grads);
            self.conv_bwd(j, t, &dh, grads, Some(&mut next), s);
            std::mem::swap(&mut dh, &mut next);
        }
        for b in (0..3).rev() {
            let (ca, cb) = (RES + 2 * b, RES + 2 * b + 1);
            let mut branch = std::mem::take(&mut s.dres);
            branch.clear();
            branch.extend_from_slice(&dh);
            self.norm_bwd(cb, p, t, Act::None, &mut branch, grads);
            self.conv_bwd(cb, t, &branch, grads, Some(&mut next), s);
            self.norm_bwd(ca, p, t, Act::Relu, &mut next, grads);
            self.conv_bwd(ca, t, &next, grads, Some(&mut branch), s);
            dh.iter_mut().zip(&branch).for_each(|(a, b)| *a += b);
            s.dres = branch;
        }
        for j in (0..3).rev() {
            self.norm_bwd(j, p, t, Act::Leaky, &mut dh, grads);
            let wants = j > 0 || want_input;
            self.conv_bwd(j, t, &dh, grads, wants.then_some(&mut next), s);
            std::mem::swap(&mut dh, &mut next);
        }
        let out = want_input.then(|| {
            let mut dx = dh.clone();
            if self.arch == Arch::Residual {
                // The skip connection of the input heights.
                dx.iter_mut().step_by(2).zip(&skip).for_each(|(d, g)| *d += g);
            }
            dx
        });
        s.dh = dh;
        out
    }

    /// Conv `i`'s backward; the weights it needs were transformed and kept
    /// by the forward pass (in the tape).
    fn conv_bwd(&self, i: usize, t: &GenTape, dy: &[f32], grads: &mut [f32], dx: Option<&mut Vec<f32>>, s: &mut GenScratch) {
        let l = &self.convs[i];
        let (gw, gb) = split2(grads, &l.w, &l.b);
        winograd::backward(&l.g, &t.convs[i], dy, Some((gw, gb)), dx, &mut s.wino);
    }

    fn norm_bwd(&self, j: usize, p: &[f32], t: &GenTape, act: Act, dz: &mut [f32], grads: &mut [f32]) {
        let l = &self.norms[j];
        let (gg, gb) = split2(grads, &l.gamma, &l.beta);
        norm::backward(&t.norms[j], &t.zs[j], POS, &p[l.gamma.clone()], act, dz, gg, gb);
    }
}

/// Two disjoint ranges of one slice, mutably (`a` before `b`).
pub(crate) fn split2<'a>(v: &'a mut [f32], a: &std::ops::Range<usize>, b: &std::ops::Range<usize>) -> (&'a mut [f32], &'a mut [f32]) {
    assert!(a.end <= b.start, "ranges in order");
    let (lo, hi) = v.split_at_mut(b.start);
    (&mut lo[a.clone()], &mut hi[..b.len()])
}
