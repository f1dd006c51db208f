//! One training step of the Cycle GAN with paired data (`docs/network.md`).
//!
//! Generators' update, on a batch of sims x and reals y (the first P rows
//! of each may be a pair: x_i is a sim key, y_i one of its reals):
//!
//! ```text
//! fy = G_Y(x), fx = G_X(y)
//! L_G = BCE(D_Y(fy), 0.9) + BCE(D_X(fx), 0.9)
//!     + lambda_cyc (|G_X(fy) - x|_1 + |G_Y(fx) - y|_1)
//!     + lambda_pair (mean_i<P min_k e(y_i,k, fy_i) + mean_i<P |fx_i - x_i|^2 / 100)
//!     + lambda_height mean_i<P H(y_i,k*, fy_i)
//! ```
//! where k* is the real of the minimum and `H` the mean absolute height
//! error in centimetres on the cells valid in y ([`loss::height_l1`]):
//! equation 7.1 prices a 10 cm height error at 1e-4 against 0.04 for a wrong
//! mask, so without `H` nothing holds the generated heights to the terrain.
//! then the discriminators' update `BCE(D(real), 0.9) + BCE(D(fake), 0)`.
//!
//! The paired terms reuse fy and fx (the PyTorch peer runs G_Y(x) a second
//! time for them), and the discriminators' pass over the fakes is taken from
//! the generators' update: between the two the discriminators do not change,
//! so it is the same forward pass. The generators' backward through D asks
//! for input gradients only.
//!
//! Layer 5 (train), the top: may use net, layers, weights and gemm.

use dem_core::format::GRID_LEN;
use dem_core::Dem;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::adam::{Adam, AdamConfig};
use super::loss;
use crate::net::{DiscScratch, DiscTape, Discriminator, GenScratch, GenTape, Generator};
use crate::weights::{Arch, DiscriminatorWeights, GeneratorWeights};

/// What defines a model and its training.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GanConfig {
    /// Generator width w.
    pub width: usize,
    /// Adam settings of all four networks.
    pub adam: AdamConfig,
    /// Weight of the cycle terms.
    pub lambda_cyc: f32,
    /// Weight of the paired terms.
    pub lambda_pair: f32,
    /// The generators' head (runs saved before it existed are the thesis's).
    #[serde(default)]
    pub arch: Arch,
    /// Weight of the paired height term (0 in runs saved before it existed).
    #[serde(default)]
    pub lambda_height: f32,
    /// Share of the run's epochs trained at the full learning rate; over the
    /// rest it falls linearly to 0 (the Cycle GAN paper's schedule). 1: a
    /// constant rate, as the thesis (and runs saved before it existed).
    #[serde(default = "constant_rate")]
    pub decay_from: f32,
}

fn constant_rate() -> f32 {
    1.0
}

impl Default for GanConfig {
    /// The toolkit's default: the residual head with the paired height term
    /// (docs/training.md has the measurements that chose it).
    fn default() -> Self {
        GanConfig { arch: Arch::Residual, lambda_pair: 30.0, lambda_height: 3.0, decay_from: 0.5, ..GanConfig::thesis() }
    }
}

impl GanConfig {
    /// The thesis's network and losses (`docs/network.md`).
    pub fn thesis() -> Self {
        GanConfig {
            width: 32,
            adam: AdamConfig::default(),
            lambda_cyc: 10.0,
            lambda_pair: 10.0,
            arch: Arch::Thesis,
            lambda_height: 0.0,
            decay_from: 1.0,
        }
    }

    /// The learning rate at `step` of a run planned for `total` steps: `lr`
    /// until `decay_from * total`, then falling linearly to 0 at `total`.
    pub fn lr_at(&self, step: u64, total: u64) -> f32 {
        let start = (self.decay_from as f64 * total as f64).floor();
        let lr = self.adam.lr as f64;
        if (step as f64) < start || total as f64 <= start {
            return self.adam.lr;
        }
        (lr * (total as f64 - step as f64) / (total as f64 - start)).max(0.0) as f32
    }
}

/// One batch: grids `[n, 200]` and attitudes `[n, 10]` of sims and reals, and
/// for the first `pairs.len()` rows the grids of every real paired with x_i.
#[derive(Debug)]
pub struct Batch<'a> {
    /// Sim grids.
    pub x_grid: Vec<f32>,
    /// Sim attitudes.
    pub x_att: Vec<f32>,
    /// Real grids.
    pub y_grid: Vec<f32>,
    /// Real attitudes.
    pub y_att: Vec<f32>,
    /// Reals paired with sim row i (row i of y is one of them).
    pub pairs: Vec<Vec<&'a [f32]>>,
}

impl<'a> Batch<'a> {
    /// A batch from records; `pairs[i]` are the reals of sim row i.
    pub fn new(x: &[&Dem], y: &[&Dem], pairs: Vec<Vec<&'a [f32]>>) -> Self {
        let grid = |v: &[&Dem]| v.iter().flat_map(|d| d[..GRID_LEN].iter().copied()).collect();
        let att = |v: &[&Dem]| v.iter().flat_map(|d| d[GRID_LEN..].iter().copied()).collect();
        Batch { x_grid: grid(x), x_att: att(x), y_grid: grid(y), y_att: att(y), pairs }
    }
}

/// Loss values of one step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Losses {
    /// Generators' adversarial terms.
    pub gan: f32,
    /// Weighted cycle terms.
    pub cycle: f32,
    /// Weighted paired G_Y term.
    pub pair_y: f32,
    /// Weighted paired G_X term.
    pub pair_x: f32,
    /// Weighted paired height term of G_Y.
    pub height: f32,
    /// Discriminators' loss.
    pub disc: f32,
}

impl Losses {
    /// The generators' total.
    pub fn generator(&self) -> f32 {
        self.gan + self.cycle + self.pair_y + self.pair_x + self.height
    }
}

/// Records per micro-batch, the unit of parallel work. Every record's
/// passes are independent of the others' (instance norm, per-record losses),
/// so a step runs its micro-batches on any thread and sums their gradients
/// in a fixed order: the result does not depend on the thread count, and
/// each micro-batch's buffers stay small enough for the caches.
pub const MICRO: usize = 8;

/// One micro-batch's tapes, scratch and partial gradients, kept between
/// steps for their capacity.
#[derive(Debug, Default)]
struct Chunk {
    gen: [GenTape; 4],
    disc: [DiscTape; 4],
    gs: GenScratch,
    ds: DiscScratch,
    /// Partial gradients of G_X, G_Y, D_X, D_Y.
    grads: [Vec<f32>; 4],
    drec: Vec<f32>,
    dl: Vec<f32>,
    losses: Losses,
}

/// What every micro-batch reads.
struct Shared<'a> {
    gen: &'a Generator,
    disc: &'a Discriminator,
    cfg: GanConfig,
    params: &'a [Vec<f32>; 4],
    b: &'a Batch<'a>,
    n: usize,
}

impl Chunk {
    /// The generators' passes over rows `r` of the batch.
    fn generators(&mut self, s: &Shared, r: std::ops::Range<usize>) {
        let (gen, disc, cfg, n) = (s.gen, s.disc, s.cfg, s.n);
        let [pgx, pgy, pdx, pdy] = s.params;
        let g = r.start * GRID_LEN..r.end * GRID_LEN;
        let a = r.start * 10..r.end * 10;
        let (xg, xa, yg, ya) = (&s.b.x_grid[g.clone()], &s.b.x_att[a.clone()], &s.b.y_grid[g.clone()], &s.b.y_att[a]);
        let [ta, tb, tc, td] = &mut self.gen;
        let [te, tf, _, _] = &mut self.disc;
        gen.forward(pgy, xg, xa, ta);
        gen.forward(pgx, yg, ya, tb);
        gen.forward(pgx, &ta.out, xa, tc);
        gen.forward(pgy, &tb.out, ya, td);
        disc.forward(pdy, &ta.out, xa, te);
        disc.forward(pdx, &tb.out, ya, tf);

        let mut l = Losses::default();
        for (v, len) in self.grads.iter_mut().zip([gen.len, gen.len, disc.len, disc.len]) {
            v.clear();
            v.resize(len, 0.0);
        }
        let [ggx, ggy, _, _] = &mut self.grads;
        // Cycle terms, back through the second generator pass to fy / fx.
        self.drec.clear();
        self.drec.resize(xg.len(), 0.0);
        l.cycle = loss::l1_cycle(&tc.out, xg, cfg.lambda_cyc, n, &mut self.drec);
        let mut dfy = gen.backward(pgx, tc, &self.drec, ggx, true, &mut self.gs).expect("input grad");
        self.drec.fill(0.0);
        l.cycle += loss::l1_cycle(&td.out, yg, cfg.lambda_cyc, n, &mut self.drec);
        let mut dfx = gen.backward(pgy, td, &self.drec, ggy, true, &mut self.gs).expect("input grad");
        // Adversarial terms, back through D (input gradients only).
        let decisions = (n * 10) as f32;
        l.gan = loss::bce_logits(&te.logits, 0.9, decisions, &mut self.dl);
        let d = disc.backward(pdy, te, &self.dl, None, true, &mut self.ds).expect("input grad");
        dfy.iter_mut().zip(&d).for_each(|(a, b)| *a += b);
        l.gan += loss::bce_logits(&tf.logits, 0.9, decisions, &mut self.dl);
        let d = disc.backward(pdx, tf, &self.dl, None, true, &mut self.ds).expect("input grad");
        dfx.iter_mut().zip(&d).for_each(|(a, b)| *a += b);
        // Paired terms on the batch's first rows.
        let np = s.b.pairs.len();
        for i in r.start..r.end.min(np) {
            let weight = cfg.lambda_pair / np as f32;
            let k = (i - r.start) * GRID_LEN..(i - r.start + 1) * GRID_LEN;
            let (e, best) = loss::paired_min(&s.b.pairs[i], &ta.out[k.clone()], weight, &mut dfy[k.clone()]);
            l.pair_y += e;
            if cfg.lambda_height > 0.0 {
                let w = cfg.lambda_height / np as f32;
                l.height += loss::height_l1(s.b.pairs[i][best], &ta.out[k.clone()], w, &mut dfy[k.clone()]);
            }
            l.pair_x += loss::paired_sq(&xg[k.clone()], &tb.out[k.clone()], weight, &mut dfx[k]);
        }
        gen.backward(pgy, ta, &dfy, ggy, false, &mut self.gs);
        gen.backward(pgx, tb, &dfx, ggx, false, &mut self.gs);
        self.losses = l;
    }

    /// The discriminators' passes over rows `r`: reals now, fakes from the
    /// generators' passes (the discriminators have not changed since).
    fn discriminators(&mut self, s: &Shared, r: std::ops::Range<usize>) {
        let (disc, n) = (s.disc, s.n);
        let [_, _, pdx, pdy] = s.params;
        let g = r.start * GRID_LEN..r.end * GRID_LEN;
        let a = r.start * 10..r.end * 10;
        let [te, tf, tg, th] = &mut self.disc;
        disc.forward(pdy, &s.b.y_grid[g.clone()], &s.b.y_att[a.clone()], tg);
        disc.forward(pdx, &s.b.x_grid[g], &s.b.x_att[a], th);
        let [_, _, gdx, gdy] = &mut self.grads;
        let decisions = (n * 10) as f32;
        let mut l = 0.0;
        for (tape, target) in [(&*tg, 0.9), (&*te, 0.0)] {
            l += loss::bce_logits(&tape.logits, target, decisions, &mut self.dl);
            disc.backward(pdy, tape, &self.dl, Some(gdy), false, &mut self.ds);
        }
        for (tape, target) in [(&*th, 0.9), (&*tf, 0.0)] {
            l += loss::bce_logits(&tape.logits, target, decisions, &mut self.dl);
            disc.backward(pdx, tape, &self.dl, Some(gdx), false, &mut self.ds);
        }
        self.losses.disc = l;
    }
}

/// Sum the micro-batches' gradients of network `k` in chunk order.
fn reduce(chunks: &[Chunk], k: usize, out: &mut Vec<f32>) {
    out.clear();
    out.extend_from_slice(&chunks[0].grads[k]);
    for c in &chunks[1..] {
        out.par_chunks_mut(1 << 14).zip(c.grads[k].par_chunks(1 << 14)).for_each(|(o, g)| {
            o.iter_mut().zip(g).for_each(|(a, b)| *a += b);
        });
    }
}

/// The four networks, their optimisers and the step.
#[derive(Debug)]
pub struct CycleGan {
    /// Settings.
    pub cfg: GanConfig,
    gen: Generator,
    disc: Discriminator,
    /// Flat parameters of G_X, G_Y, D_X, D_Y.
    pub params: [Vec<f32>; 4],
    /// Their optimisers.
    pub opts: [Adam; 4],
    chunks: Vec<Chunk>,
    grads: Vec<f32>,
}

/// Index of each network in [`CycleGan::params`].
pub const GX: usize = 0;
/// See [`GX`].
pub const GY: usize = 1;
/// See [`GX`].
pub const DX: usize = 2;
/// See [`GX`].
pub const DY: usize = 3;
/// Names, for checkpoints.
pub const NAMES: [&str; 4] = ["g_x", "g_y", "d_x", "d_y"];

impl CycleGan {
    /// Fresh networks, initialised as PyTorch does, from `seed`.
    pub fn new(cfg: GanConfig, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let gen = Generator::new(cfg.width, cfg.arch);
        let disc = Discriminator::new();
        let params = [
            gen.load(&GeneratorWeights::init_arch(&mut rng, cfg.width, cfg.arch)),
            gen.load(&GeneratorWeights::init_arch(&mut rng, cfg.width, cfg.arch)),
            disc.load(&DiscriminatorWeights::init(&mut rng)),
            disc.load(&DiscriminatorWeights::init(&mut rng)),
        ];
        let opts = params.each_ref().map(|p| Adam::new(cfg.adam, p.len()));
        CycleGan { cfg, gen, disc, params, opts, chunks: Vec::new(), grads: Vec::new() }
    }

    /// Parameter counts of the four networks.
    pub fn sizes(&self) -> [usize; 4] {
        self.params.each_ref().map(Vec::len)
    }

    /// G_X (`y = false`) or G_Y (`y = true`) in PyTorch's layout.
    pub fn generator_weights(&self, y: bool) -> GeneratorWeights {
        self.gen.save(&self.params[if y { GY } else { GX }])
    }

    /// Run G_Y (`y = true`) or G_X over records; row 20 passes through.
    pub fn generate(&self, y: bool, records: &[Dem]) -> Vec<Dem> {
        let p = &self.params[if y { GY } else { GX }];
        let mut tape = GenTape::default();
        let mut out = Vec::with_capacity(records.len());
        for chunk in records.chunks(256) {
            let grid: Vec<f32> = chunk.iter().flat_map(|d| d[..GRID_LEN].iter().copied()).collect();
            let att: Vec<f32> = chunk.iter().flat_map(|d| d[GRID_LEN..].iter().copied()).collect();
            self.gen.forward(p, &grid, &att, &mut tape);
            for (d, o) in chunk.iter().zip(tape.out.chunks_exact(GRID_LEN)) {
                let mut r = *d;
                r[..GRID_LEN].copy_from_slice(o);
                out.push(r);
            }
        }
        out
    }

    /// Set the learning rate of all four optimisers (a schedule's value).
    pub fn set_lr(&mut self, lr: f32) {
        self.opts.iter_mut().for_each(|o| o.cfg.lr = lr);
    }

    /// One generators' update and one discriminators' update.
    pub fn step(&mut self, b: &Batch) -> Losses {
        let n = b.x_grid.len() / GRID_LEN;
        assert!(n > 0, "empty batch");
        assert_eq!(b.y_grid.len(), n * GRID_LEN, "batch sizes");
        let chunks = n.div_ceil(MICRO);
        let rows = |c: usize| c * MICRO..((c + 1) * MICRO).min(n);
        self.chunks.resize_with(chunks, Chunk::default);
        let work = &mut self.chunks[..chunks];
        let s = Shared { gen: &self.gen, disc: &self.disc, cfg: self.cfg, params: &self.params, b, n };
        work.par_iter_mut().enumerate().for_each(|(c, w)| w.generators(&s, rows(c)));
        for k in [GX, GY] {
            reduce(work, k, &mut self.grads);
            self.opts[k].step(&mut self.params[k], &self.grads);
        }
        let s = Shared { gen: &self.gen, disc: &self.disc, cfg: self.cfg, params: &self.params, b, n };
        work.par_iter_mut().enumerate().for_each(|(c, w)| w.discriminators(&s, rows(c)));
        for k in [DX, DY] {
            reduce(work, k, &mut self.grads);
            self.opts[k].step(&mut self.params[k], &self.grads);
        }
        work.iter().fold(Losses::default(), |a, c| Losses {
            gan: a.gan + c.losses.gan,
            cycle: a.cycle + c.losses.cycle,
            pair_y: a.pair_y + c.losses.pair_y,
            pair_x: a.pair_x + c.losses.pair_x,
            height: a.height + c.losses.height,
            disc: a.disc + c.losses.disc,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rate_is_constant_then_falls_linearly_to_zero() {
        let c = GanConfig { decay_from: 0.5, ..GanConfig::default() };
        let lr = c.adam.lr;
        assert_eq!(c.lr_at(0, 100), lr);
        assert_eq!(c.lr_at(49, 100), lr);
        assert_eq!(c.lr_at(50, 100), lr);
        assert!((c.lr_at(75, 100) - lr / 2.0).abs() < 1e-9);
        assert!(c.lr_at(99, 100) > 0.0 && c.lr_at(99, 100) < lr / 49.0);
        assert_eq!(c.lr_at(100, 100), 0.0);
        let thesis = GanConfig::thesis();
        assert!((0..100).all(|s| thesis.lr_at(s, 100) == thesis.adam.lr));
        // Runs saved before the schedule existed read as constant-rate runs.
        let mut old = serde_json::to_value(thesis).unwrap();
        old.as_object_mut().unwrap().retain(|k, _| !["arch", "lambda_height", "decay_from"].contains(&k.as_str()));
        let back: GanConfig = serde_json::from_value(old).unwrap();
        assert_eq!(back, thesis);
    }
}
