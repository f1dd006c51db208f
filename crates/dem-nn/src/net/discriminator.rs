//! The discriminator of `docs/network.md` on a batch, forward and backward.
//!
//! Grid `[n, 20, 5, 2]` -> conv 4x4/2 (64, leaky) -> `[n, 10, 3, 64]` ->
//! conv 4x4/2 + IN + leaky -> `[n, 5, 2, 128]` -> conv 4x4/1 + IN + leaky ->
//! `[n, 5, 2, 128]`; attitude `[n, 10]` -> dense 64 + leaky; both -> dense
//! 1344 -> 10 logits. The sigmoid lives in the loss (BCE on logits).
//!
//! Layer 4 (net): may use layers, weights and gemm.

use dem_core::format::GRID_LEN;

use super::generator::{split2, ATT};
use super::params::{channels_first, same_order, Alloc, ConvLayer, DenseLayer, NormLayer};
use crate::layers::conv::{self, ConvGeom};
use crate::layers::dense;
use crate::layers::norm::{self, Act, NormCache};
use crate::weights::DiscriminatorWeights;

/// Decisions per record (a 5x2 grid).
pub const OUT: usize = 10;
const FEAT: usize = 128 * 10 + 64;

/// Layer layout of a discriminator.
#[derive(Clone, Debug)]
pub struct Discriminator {
    convs: [ConvLayer; 3],
    norms: [NormLayer; 2],
    fa: DenseLayer,
    fo: DenseLayer,
    /// Total parameters.
    pub len: usize,
}

/// What a forward pass keeps for backward.
#[derive(Debug, Default)]
pub struct DiscTape {
    cols: [Vec<f32>; 3],
    ys: [Vec<f32>; 3],
    /// Outputs of the three conv stages (after activation).
    zs: [Vec<f32>; 3],
    norms: [NormCache; 2],
    att: Vec<f32>,
    za: Vec<f32>,
    feat: Vec<f32>,
    /// Logits `[n, 10]`.
    pub logits: Vec<f32>,
}

/// Scratch buffers of a backward pass.
#[derive(Debug, Default)]
pub struct DiscScratch {
    dfeat: Vec<f32>,
    d: [Vec<f32>; 3],
    dcol: Vec<f32>,
    da: Vec<f32>,
    unused: Vec<f32>,
}

impl Default for Discriminator {
    fn default() -> Self {
        Self::new()
    }
}

impl Discriminator {
    /// The layout.
    pub fn new() -> Self {
        let mut a = Alloc::default();
        let c1 = ConvLayer::new(&mut a, ConvGeom::same(20, 5, 2, 64, 4, 2));
        let c2 = ConvLayer::new(&mut a, ConvGeom::same(10, 3, 64, 128, 4, 2));
        let c3 = ConvLayer::new(&mut a, ConvGeom::same(5, 2, 128, 128, 4, 1));
        let n2 = NormLayer::new(&mut a, 128);
        let n3 = NormLayer::new(&mut a, 128);
        let fa = DenseLayer::new(&mut a, channels_first(5, 2).collect(), same_order(64));
        let torch_in = channels_first(10, 128).chain(1280..FEAT).collect();
        let fo = DenseLayer::new(&mut a, torch_in, same_order(OUT));
        Discriminator { convs: [c1, c2, c3], norms: [n2, n3], fa, fo, len: a.len() }
    }

    /// Flat parameters from PyTorch-layout weights.
    pub fn load(&self, t: &DiscriminatorWeights) -> Vec<f32> {
        let mut p = vec![0.0; self.len];
        for (l, c) in self.convs.iter().zip([&t.c1, &t.c2, &t.c3]) {
            l.load(&mut p, c);
        }
        self.norms[0].load(&mut p, &t.n2);
        self.norms[1].load(&mut p, &t.n3);
        self.fa.load(&mut p, &t.fa);
        self.fo.load(&mut p, &t.fo);
        p
    }

    /// PyTorch-layout weights from flat parameters.
    pub fn save(&self, p: &[f32]) -> DiscriminatorWeights {
        DiscriminatorWeights {
            c1: self.convs[0].save(p),
            c2: self.convs[1].save(p),
            c3: self.convs[2].save(p),
            n2: self.norms[0].save(p),
            n3: self.norms[1].save(p),
            fa: self.fa.save(p),
            fo: self.fo.save(p),
        }
    }

    /// Forward pass: `grid [n, 200]`, `att [n, 10]`; logits in `tape.logits`.
    pub fn forward(&self, p: &[f32], grid: &[f32], att: &[f32], t: &mut DiscTape) {
        let [c1, c2, c3] = &self.convs;
        conv::forward(&c1.g, &p[c1.w.clone()], &p[c1.b.clone()], grid, &mut t.cols[0], &mut t.ys[0]);
        t.zs[0].clear();
        t.zs[0].extend(t.ys[0].iter().map(|&v| Act::Leaky.apply(v)));
        for (i, c) in [(1, c2), (2, c3)] {
            let (x, rest) = t.zs.split_at_mut(i);
            conv::forward(&c.g, &p[c.w.clone()], &p[c.b.clone()], &x[i - 1], &mut t.cols[i], &mut t.ys[i]);
            let nl = &self.norms[i - 1];
            let pos = c.g.out_pos();
            norm::forward(&t.ys[i], pos, &p[nl.gamma.clone()], &p[nl.beta.clone()], Act::Leaky, &mut t.norms[i - 1], &mut rest[0]);
        }
        t.att.clear();
        t.att.extend_from_slice(att);
        dense::forward(&p[self.fa.w.clone()], &p[self.fa.b.clone()], att, ATT, &mut t.za);
        t.za.iter_mut().for_each(|v| *v = Act::Leaky.apply(*v));
        t.feat.clear();
        for (row, a) in t.zs[2].chunks_exact(1280).zip(t.za.chunks_exact(64)) {
            t.feat.extend_from_slice(row);
            t.feat.extend_from_slice(a);
        }
        dense::forward(&p[self.fo.w.clone()], &p[self.fo.b.clone()], &t.feat, FEAT, &mut t.logits);
    }

    /// Backward of the last [`forward`](Self::forward) on `t` from `dlogits [n, 10]`.
    /// `grads = Some(..)` accumulates parameter gradients (the discriminator's
    /// own step); `want_input` returns the gradient of the input grid (the
    /// generators' step, which needs no discriminator gradients).
    pub fn backward(
        &self,
        p: &[f32],
        t: &DiscTape,
        dlogits: &[f32],
        mut grads: Option<&mut [f32]>,
        want_input: bool,
        s: &mut DiscScratch,
    ) -> Option<Vec<f32>> {
        let fo = grads.as_deref_mut().map(|g| split2(g, &self.fo.w, &self.fo.b));
        dense::backward(&p[self.fo.w.clone()], &t.feat, FEAT, dlogits, fo, Some(&mut s.dfeat));
        if let Some(g) = grads.as_deref_mut() {
            // The attitude branch only matters for the discriminator's own
            // parameters (its input is data).
            s.da.clear();
            for (row, z) in s.dfeat.chunks_exact(FEAT).zip(t.za.chunks_exact(64)) {
                s.da.extend(row[1280..].iter().zip(z).map(|(d, z)| d * Act::Leaky.slope(*z)));
            }
            let fa = split2(g, &self.fa.w, &self.fa.b);
            dense::backward(&p[self.fa.w.clone()], &t.att, ATT, &s.da, Some(fa), None);
        }
        let mut d = std::mem::take(&mut s.d);
        d[2].clear();
        for row in s.dfeat.chunks_exact(FEAT) {
            d[2].extend_from_slice(&row[..1280]);
        }
        for i in (1..3).rev() {
            let (c, nl) = (&self.convs[i], &self.norms[i - 1]);
            let pos = c.g.out_pos();
            let (gamma, act) = (&p[nl.gamma.clone()], Act::Leaky);
            match grads.as_deref_mut() {
                Some(g) => {
                    let (gg, gb) = split2(g, &nl.gamma, &nl.beta);
                    norm::backward(&t.norms[i - 1], &t.zs[i], pos, gamma, act, &mut d[i], gg, gb);
                }
                None => {
                    // The generators' step: norm gradients go to scratch.
                    s.unused.resize(256, 0.0);
                    let (gg, gb) = s.unused.split_at_mut(128);
                    norm::backward(&t.norms[i - 1], &t.zs[i], pos, gamma, act, &mut d[i], gg, gb);
                }
            }
            let cg = grads.as_deref_mut().map(|g| split2(g, &c.w, &c.b));
            let (lo, hi) = d.split_at_mut(i);
            conv::backward(&c.g, &p[c.w.clone()], &t.cols[i], &hi[0], cg, Some(&mut lo[i - 1]), &mut s.dcol);
        }
        d[0].iter_mut().zip(&t.zs[0]).for_each(|(g, z)| *g *= Act::Leaky.slope(*z));
        let c1 = &self.convs[0];
        let cg = grads.map(|g| split2(g, &c1.w, &c1.b));
        let mut dx = Vec::new();
        conv::backward(&c1.g, &p[c1.w.clone()], &t.cols[0], &d[0], cg, want_input.then_some(&mut dx), &mut s.dcol);
        s.d = d;
        debug_assert!(!want_input || dx.len() == t.att.len() / ATT * GRID_LEN);
        want_input.then_some(dx)
    }
}
