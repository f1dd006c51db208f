//! The distribution gap: statistics of a set of DEMs and the gap number
//! between two such sets, one definition shared by dem-gap (what it fits)
//! and dem-eval (its `gap` column).
//!
//! Every statistic describes a *distribution* over records (rates,
//! means, spreads, quantiles), never one random draw against another, so a
//! model that adds the right noise to sim scores 0 against real, where the
//! paired equation 7.1 error would grow.
//!
//! Terms (per grid row r = 0..19 unless said otherwise):
//!
//! | term | what | scale |
//! |---|---|---|
//! | `missing` | fraction of cells missing | 0.02 |
//! | `row-missing` | fraction of records with the whole row missing | 0.02 |
//! | `shadow` | fraction of cells missing behind a drop: the nearest valid cell toward the sensor side (x = 0.1 m) is >= [`SHADOW_DROP`] taller than the nearest valid cell beyond | 0.01 |
//! | `jump-missing` | fraction of cells missing, in a row not wholly missing, between valid cells of their column that differ by >= [`JUMP`] either way (holes at height jumps, shadows) | 0.01 |
//! | `missing-pair` | fraction of across-robot neighbour pairs both missing, in rows not wholly missing (blobs against scattered cells) | 0.01 |
//! | `height` | paired: mean residual D = h - h_sim on cells valid in both; unpaired: mean height | 0.005 m |
//! | `spread-sd`, `spread-q50`, `spread-q90` (`spread-q99` paired) | paired: sd (root mean square without the largest [`SD_TRIM`] of the samples) and quantiles of abs(D - mean D of the row); unpaired: of `abs(h[r,c] - h[r,c+1])` / sqrt 2 (the across-robot roughness) | 0.002 m |
//! | `level-pairs` | fraction of across-robot neighbours with equal heights (within 0.1 mm) | 0.02 |
//! | `edge-2cm`, `edge-steep`, `edge-10cm` | fraction of steps `abs(h[r+1,c] - h[r,c])` (row pairs 0..18) above 0.02, 0.05, 0.1 m: sharp edges against ramps | 0.01 |
//! | `steps` | fraction of all neighbour pairs whose difference falls in each bin of [`STEP_BINS`] (0.1-1-3-10-30-100 mm; 5 numbers) | 0.01 |
//! | `riser-foot`, `riser-top`, `drop-lip`, `drop-floor` (paired only) | over the whole grid, on the cells beside a step of more than [`JUMP`] along x in the sim record (the foot, row r + 1 higher, and top, row r - 1 lower, of a riser; the lip, row r + 1 lower, and floor, row r - 1 higher, of a drop), with T = D sign(h_sim[n] - h_sim) the residual toward the other surface: mean T / 4, mean abs(T) / 4 (so 0.005 m is one scale), and the fractions of cells with T > 2 cm and T < -2 cm | 0.02 |
//! | `frame-flip`, `frame-dh`, `frame-rcorr` (with the runs' steps, [`frame_terms`]) | per row of the later frame, over consecutive frames of a run matched on the ground ([`crate::temporal`]): share of cells changing validity; mean abs(h(t+1) - h(t)); paired: lag-1 correlation of D, unpaired: of the change h(t+1) - h(t) with the next change | 0.005, 0.002 m, 0.1 |
//!
//! The gap between sets A (model(sim)) and B (real) is the sum over terms
//! of the mean over their components of ln(1 + z^2), z = (a - b) / scale;
//! a component is left out when either side has fewer than [`MIN_SUPPORT`]
//! samples, unless one side has support and the other (per record) less
//! than a quarter of it: then the component counts as a difference of
//! [`UNSUPPORTED_Z`] scales, so a model cannot shrink the gap by hiding
//! the cells the statistics are taken on. Each term is 0 when the distributions match; the scale is the
//! difference that matters physically (2 % of cells, 5 mm of height, 2 mm
//! of spread). ln(1 + z^2) is z^2 for small differences and grows slowly
//! for large ones, so no single statistic (say the 99th percentile of the
//! residual at step edges) outweighs all others: an effect is rewarded for
//! how many statistics it brings close, not for chasing one tail.
//!
//! Beside the terms, paired statistics carry `step_coherence`, which is
//! not part of the gap: the correlation (pooled over records) of the
//! residuals D of across-robot neighbours (columns c and c + 1 of a row)
//! that both lie beside a step of more than [`JUMP`] along x in the sim
//! record, cov / (sd sd' + [`COHERENCE_FLOOR`]^2): Pearson's for moves of
//! centimetres, near 0 for moves of a millimetre. A pose error (drift, a
//! tilted mount) moves a step's cells together (near 1), a misregistration
//! per cell each on its own (near 0), and the terms, which compare cells
//! one by one, cannot tell the two apart; the evidence sentences of the
//! effects that differ in it say it. It stays out of the gap because many
//! map stages move a step's cells together too (in `dem-synth`'s emulator
//! on the default mount the field of view 0.74, occlusion 0.85, smoothing
//! 0.68, drift 0.83, vibration 0.33; docs/results.md has the commands), so
//! one number weighed like a whole term would favour a row-wide pose
//! effect for any of them.

use std::borrow::Cow;
use std::ops::Range;

use rayon::prelude::*;

use crate::format::{row_center_x, Dem, DemCells, COLS, GRID_ROWS};
use crate::temporal::{chains, FrameSums, Step};

/// Height drop (m) behind which a missing cell counts as in a shadow.
pub const SHADOW_DROP: f64 = 0.08;
/// Fewest samples a component needs on both sides to count.
pub const MIN_SUPPORT: usize = 30;
/// x (m) that separates "toward the sensor" from "beyond" for shadows.
const SHADOW_REF_X: f64 = 0.1;
/// Height jump (m) around a missing cell that makes it a `jump-missing`
/// cell; dem-sensor's `mixed-cells`, `drop-blend` and `riser-blend` act on the same jump,
/// so the statistic sees those effects' steps and no others.
pub const JUMP: f64 = 0.05;
/// Share of the largest spread samples left out of `spread-sd`.
pub const SD_TRIM: f64 = 0.005;
/// The difference, in scales, a component counts for when one side has the
/// samples and the other has (next to) none.
pub const UNSUPPORTED_Z: f64 = 10.0;

/// The step-side terms (paired), indexed as `step_sides` returns them.
pub const STEP_SIDES: [&str; 4] = ["riser-foot", "riser-top", "drop-lip", "drop-floor"];

/// Residual (m) toward or away from the other surface beyond which a cell
/// beside a step counts as moved (the step-side rates).
const SIDE_MOVE: f32 = 0.02;

/// Residual sd (m) below which `step_coherence` shrinks toward 0: the
/// `height` term's scale, a move no step statistic resolves.
pub const COHERENCE_FLOOR: f64 = 0.005;

/// Edges (m) of the bins of non-zero neighbour differences (`steps`).
pub const STEP_BINS: [f64; 6] = [1e-4, 0.001, 0.003, 0.01, 0.03, 0.1];

/// The along-robot differences (m) the `edge-*` terms count above.
const EDGE_ABOVE: [(&str, f64); 3] = [("edge-2cm", 0.02), ("edge-steep", 0.05), ("edge-10cm", 0.1)];

/// The bin of [`STEP_BINS`] that a neighbour difference falls in.
fn step_bin(x: f32) -> Option<usize> {
    STEP_BINS.windows(2).position(|w| (w[0]..w[1]).contains(&(x as f64)))
}

/// One statistic: a value per component (row, row pair, or quantile) with
/// the number of samples behind it.
#[derive(Debug, Clone, PartialEq)]
pub struct Term {
    /// Name (`missing`, `shadow`, ...: see the module table).
    pub name: &'static str,
    /// Value per component.
    pub values: Vec<f64>,
    /// Samples behind each value.
    pub support: Vec<usize>,
    /// The difference that counts as 1.
    pub scale: f64,
}

/// The statistics of one set of records.
#[derive(Debug, Clone, PartialEq)]
pub struct Stats {
    /// Records summarised.
    pub records: usize,
    /// True when heights are residuals against paired sim records.
    pub paired: bool,
    /// The terms.
    pub terms: Vec<Term>,
    /// Paired: how together the cells beside a step move (module docs);
    /// not a term of the gap.
    pub step_coherence: Option<f64>,
}

#[derive(Default, Clone)]
struct Acc {
    n: usize,
    miss: [usize; GRID_ROWS],
    full_row: [usize; GRID_ROWS],
    shadow: [usize; GRID_ROWS],
    jump: [usize; GRID_ROWS],
    pair_miss: [usize; GRID_ROWS],
    partial: [usize; GRID_ROWS],
    level: [(usize, usize); GRID_ROWS],
    /// Paired: residuals D; unpaired: heights (for the mean).
    loc: Vec<Vec<f32>>,
    /// Paired: abs(D); unpaired: abs(across-robot differences) / sqrt 2.
    spread: Vec<Vec<f32>>,
    /// Per row pair: along-robot neighbour pairs, and how many differ by
    /// more than each of [`EDGE_ABOVE`].
    edge: [(usize, [usize; 3]); GRID_ROWS - 1],
    /// Non-zero neighbour differences per bin of [`STEP_BINS`].
    steps: [usize; STEP_BINS.len() - 1],
    /// Paired: residuals toward the other surface, per [`STEP_SIDES`].
    side: [Vec<f32>; 4],
    /// Paired: residuals of across-robot neighbours beside a step.
    coherence: Correlation,
}

/// Running sums for a Pearson correlation of pairs (x, y), in f64.
#[derive(Debug, Default, Clone, Copy, PartialEq)]
struct Correlation {
    n: usize,
    x: f64,
    y: f64,
    xy: f64,
    xx: f64,
    yy: f64,
}

impl Correlation {
    fn add(&mut self, x: f64, y: f64) {
        self.n += 1;
        self.x += x;
        self.y += y;
        self.xy += x * y;
        self.xx += x * x;
        self.yy += y * y;
    }

    fn merge(&mut self, o: &Correlation) {
        self.n += o.n;
        self.x += o.x;
        self.y += o.y;
        self.xy += o.xy;
        self.xx += o.xx;
        self.yy += o.yy;
    }

    /// The correlation shrunk by the size of the moves: cov / (sd_x sd_y +
    /// [`COHERENCE_FLOOR`]^2). Moves well above the floor give Pearson's
    /// correlation; moves of a millimetre (noise, or none at all, real
    /// equal to sim) give near 0 whatever their pattern, so a correlation of
    /// nothing cannot open a gap.
    fn value(&self) -> f64 {
        if self.n == 0 {
            return 0.0;
        }
        let n = self.n as f64;
        let (mx, my) = (self.x / n, self.y / n);
        let cov = self.xy / n - mx * my;
        let (vx, vy) = ((self.xx / n - mx * mx).max(0.0), (self.yy / n - my * my).max(0.0));
        (cov / ((vx * vy).sqrt() + COHERENCE_FLOOR * COHERENCE_FLOOR)).clamp(-1.0, 1.0)
    }
}

impl Acc {
    fn new() -> Self {
        Self::with_capacity(0)
    }

    /// Room for the samples of `records` records: the vectors then grow
    /// once, not cell by cell.
    fn with_capacity(records: usize) -> Self {
        // vec![v; n] would clone `v`, and a clone drops the capacity.
        let rows = |n: usize| (0..n).map(|_| Vec::with_capacity(records * COLS)).collect();
        Acc { loc: rows(GRID_ROWS), spread: rows(GRID_ROWS), ..Default::default() }
    }

    fn add(&mut self, d: &Dem, sim: Option<&Dem>) {
        self.n += 1;
        for r in 0..GRID_ROWS {
            let missing = (0..COLS).filter(|&c| !d.is_valid(r, c)).count();
            self.miss[r] += missing;
            self.full_row[r] += usize::from(missing == COLS);
            if missing < COLS {
                self.partial[r] += 1;
                self.pair_miss[r] += (0..COLS - 1).filter(|&c| !d.is_valid(r, c) && !d.is_valid(r, c + 1)).count();
            }
            // Paired: the residual of the cell to the left, when it lies
            // beside a step and is valid in both (the step-coherence pairs).
            let mut left_at_step: Option<f32> = None;
            for c in 0..COLS {
                if !d.is_valid(r, c) {
                    self.shadow[r] += usize::from(in_shadow(d, r, c));
                    self.jump[r] += usize::from(missing < COLS && at_jump(d, r, c));
                    left_at_step = None;
                    continue;
                }
                let h = d.height(r, c);
                match sim {
                    Some(s) if s.is_valid(r, c) => {
                        let res = h - s.height(r, c);
                        self.loc[r].push(res);
                        self.spread[r].push(res.abs());
                        let mut at_step = false;
                        for (side, toward) in step_sides(s, r, c) {
                            self.side[side].push(res * toward);
                            at_step = true;
                        }
                        if let (true, Some(left)) = (at_step, left_at_step) {
                            self.coherence.add(left as f64, res as f64);
                        }
                        left_at_step = at_step.then_some(res);
                    }
                    Some(_) => left_at_step = None,
                    None => self.loc[r].push(h),
                }
                if c + 1 < COLS && d.is_valid(r, c + 1) {
                    let dy = (h - d.height(r, c + 1)).abs();
                    self.level[r].1 += 1;
                    self.level[r].0 += usize::from(dy < 1e-4);
                    if sim.is_none() {
                        self.spread[r].push(dy * std::f32::consts::FRAC_1_SQRT_2);
                    }
                    if dy >= 1e-4 {
                        self.step(dy);
                    }
                }
                if r + 1 < GRID_ROWS && d.is_valid(r + 1, c) {
                    let dx = (d.height(r + 1, c) - h).abs();
                    let (pairs, above) = &mut self.edge[r];
                    *pairs += 1;
                    for (count, (_, min)) in above.iter_mut().zip(EDGE_ABOVE) {
                        *count += usize::from(dx as f64 > min);
                    }
                    if dx >= 1e-4 {
                        self.step(dx);
                    }
                }
            }
        }
    }

    fn step(&mut self, x: f32) {
        if let Some(b) = step_bin(x) {
            self.steps[b] += 1;
        }
    }

    /// The accumulators of consecutive chunks as one, the samples in the
    /// chunks' order, each copied once.
    fn concat(parts: Vec<Acc>) -> Acc {
        let len = |f: fn(&Acc) -> &[Vec<f32>], i: usize| parts.iter().map(|p| f(p)[i].len()).sum::<usize>();
        let mut all = Acc::new();
        for (r, (loc, spread)) in all.loc.iter_mut().zip(all.spread.iter_mut()).enumerate() {
            loc.reserve_exact(len(|p| &p.loc, r));
            spread.reserve_exact(len(|p| &p.spread, r));
        }
        for (k, side) in all.side.iter_mut().enumerate() {
            side.reserve_exact(len(|p| &p.side, k));
        }
        for o in parts {
            all.n += o.n;
            for r in 0..GRID_ROWS {
                all.miss[r] += o.miss[r];
                all.full_row[r] += o.full_row[r];
                all.shadow[r] += o.shadow[r];
                all.jump[r] += o.jump[r];
                all.pair_miss[r] += o.pair_miss[r];
                all.partial[r] += o.partial[r];
                all.level[r].0 += o.level[r].0;
                all.level[r].1 += o.level[r].1;
            }
            for (a, b) in all.edge.iter_mut().zip(o.edge) {
                a.0 += b.0;
                a.1.iter_mut().zip(b.1).for_each(|(x, y)| *x += y);
            }
            all.steps.iter_mut().zip(o.steps).for_each(|(x, y)| *x += y);
            for (a, b) in all.loc.iter_mut().zip(&o.loc) {
                a.extend_from_slice(b);
            }
            for (a, b) in all.spread.iter_mut().zip(&o.spread) {
                a.extend_from_slice(b);
            }
            for (a, b) in all.side.iter_mut().zip(&o.side) {
                a.extend_from_slice(b);
            }
            all.coherence.merge(&o.coherence);
        }
        all
    }
}

/// True when missing cell `(r, c)` lies behind a drop of at least
/// [`SHADOW_DROP`] as seen from the sensor side (x = 0.1 m): the nearest
/// valid cell toward it is that much taller than the nearest valid beyond.
pub fn in_shadow(d: &Dem, r: usize, c: usize) -> bool {
    let ahead = row_center_x(r) > SHADOW_REF_X;
    let near = if ahead { (0..r).rev().find(|&k| d.is_valid(k, c)) } else { (r + 1..GRID_ROWS).find(|&k| d.is_valid(k, c)) };
    let far = if ahead { (r + 1..GRID_ROWS).find(|&k| d.is_valid(k, c)) } else { (0..r).rev().find(|&k| d.is_valid(k, c)) };
    match (near, far) {
        (Some(n), Some(f)) => (d.height(n, c) - d.height(f, c)) as f64 >= SHADOW_DROP,
        _ => false,
    }
}

/// True when missing cell `(r, c)` lies between valid cells of its column
/// whose heights differ by at least [`JUMP`].
pub fn at_jump(d: &Dem, r: usize, c: usize) -> bool {
    let before = (0..r).rev().find(|&k| d.is_valid(k, c));
    let after = (r + 1..GRID_ROWS).find(|&k| d.is_valid(k, c));
    match (before, after) {
        (Some(a), Some(b)) => ((d.height(a, c) - d.height(b, c)) as f64).abs() >= JUMP,
        _ => false,
    }
}

/// The step sides (index into [`STEP_SIDES`]) cell `(r, c)` of sim record
/// `s` lies on, each with the sign (+-1) that points toward the other
/// surface: a cell between two steps lies on both. The riser and drop
/// cells are told apart because sensor effects move them differently (the
/// stereo window over a riser's corners, the shadow and mixed range past a
/// drop's lip); one pooled spread per row lets an effect fit one kind's
/// cells with the other kind's residuals.
fn step_sides(s: &Dem, r: usize, c: usize) -> impl Iterator<Item = (usize, f32)> {
    let h = s.height(r, c);
    let other = |k: Option<usize>| k.filter(|&k| k < GRID_ROWS && s.is_valid(k, c)).map(|k| s.height(k, c) - h);
    let (ahead, behind) = (other(Some(r + 1)), other(r.checked_sub(1)));
    let jump = JUMP as f32;
    [
        ahead.filter(|&dz| dz > jump).map(|_| (0, 1.0)),
        behind.filter(|&dz| dz < -jump).map(|_| (1, -1.0)),
        ahead.filter(|&dz| dz < -jump).map(|_| (2, -1.0)),
        behind.filter(|&dz| dz > jump).map(|_| (3, 1.0)),
    ]
    .into_iter()
    .flatten()
}

/// Quantiles `qs` (ascending, 0..1, nearest rank) of `v`, reordering it;
/// None when empty. Each selection searches only the part of `v` above
/// the one before, so four quantiles cost about two selections.
pub fn quantiles<const N: usize>(v: &mut [f32], qs: [f64; N]) -> [Option<f64>; N] {
    let mut out = [None; N];
    if v.is_empty() {
        return out;
    }
    let n = v.len();
    let mut from = 0;
    for (o, q) in out.iter_mut().zip(qs) {
        let k = ((n - 1) as f64 * q).round() as usize;
        assert!(k + 1 >= from, "quantiles: qs must be ascending");
        // Otherwise k == from - 1: the element the last selection placed.
        if k >= from {
            v[from..].select_nth_unstable_by(k - from, |a, b| a.total_cmp(b));
            from = k + 1;
        }
        *o = Some(v[k] as f64);
    }
    out
}

/// Mean and (population) sd of `v`, in f64; (0, 0) when empty.
pub fn mean_sd(v: &[f32]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let m = v.iter().map(|&x| x as f64).sum::<f64>() / n;
    let var = v.iter().map(|&x| (x as f64 - m).powi(2)).sum::<f64>() / n;
    (m, var.sqrt())
}

/// Records per parallel chunk of [`stats`] and [`stats_made`].
const CHUNK: usize = 256;

/// Summarise `out`; with `sim` (same length, record i paired with record
/// i), heights are taken as residuals against the sim records.
pub fn stats(out: &[Dem], sim: Option<&[Dem]>) -> Stats {
    summarise(accumulate(out.len(), sim, |range| Cow::Borrowed(&out[range])), sim.is_some())
}

/// [`stats`] of `n` records that `make(range)` makes a chunk at a time
/// (records `range`, in order). The same statistics, bit for bit, as
/// making all `n` first; a caller that makes records only to summarise
/// them (a model applied at each of a fit's points) then never holds more
/// than a chunk per thread, and each chunk is summarised while it is still
/// in cache.
pub fn stats_made(n: usize, sim: Option<&[Dem]>, make: impl Fn(Range<usize>) -> Vec<Dem> + Sync) -> Stats {
    summarise(accumulate(n, sim, |range| Cow::Owned(make(range))), sim.is_some())
}

/// The samples of `n` records, [`CHUNK`] at a time in parallel; the
/// chunks are merged in order, so the samples keep the records' order.
fn accumulate<'a>(n: usize, sim: Option<&[Dem]>, chunk: impl Fn(Range<usize>) -> Cow<'a, [Dem]> + Sync) -> Acc {
    if let Some(s) = sim {
        assert_eq!(s.len(), n, "paired sets have one sim record per record");
    }
    let parts = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|k| {
            let range = k * CHUNK..((k + 1) * CHUNK).min(n);
            let records = chunk(range.clone());
            let mut a = Acc::with_capacity(records.len());
            for (d, i) in records.iter().zip(range) {
                a.add(d, sim.map(|s| &s[i]));
            }
            a
        })
        .collect::<Vec<_>>();
    Acc::concat(parts)
}

fn summarise(mut a: Acc, paired: bool) -> Stats {
    let n = a.n;
    let rate = |v: &[usize; GRID_ROWS], per: usize| v.iter().map(|&x| x as f64 / (n * per).max(1) as f64).collect();
    let mut terms = vec![
        Term { name: "missing", values: rate(&a.miss, COLS), support: vec![n * COLS; GRID_ROWS], scale: 0.02 },
        Term { name: "row-missing", values: rate(&a.full_row, 1), support: vec![n; GRID_ROWS], scale: 0.02 },
        Term { name: "shadow", values: rate(&a.shadow, COLS), support: vec![n * COLS; GRID_ROWS], scale: 0.01 },
        Term { name: "jump-missing", values: rate(&a.jump, COLS), support: vec![n * COLS; GRID_ROWS], scale: 0.01 },
        Term {
            name: "missing-pair",
            values: (0..GRID_ROWS).map(|r| a.pair_miss[r] as f64 / (a.partial[r] * (COLS - 1)).max(1) as f64).collect(),
            support: a.partial.iter().map(|&p| p * (COLS - 1)).collect(),
            scale: 0.01,
        },
    ];
    let sup = |v: &[Vec<f32>]| v.iter().map(Vec::len).collect::<Vec<_>>();
    terms.push(Term { name: "height", values: a.loc.iter().map(|v| mean_sd(v).0).collect(), support: sup(&a.loc), scale: 0.005 });
    if paired {
        // Spread about the row's mean residual, so an offset (bias) does
        // not pass for spread.
        for (s, l) in a.spread.iter_mut().zip(&a.loc) {
            let m = mean_sd(l).0 as f32;
            s.iter_mut().zip(l).for_each(|(x, &d)| *x = (d - m).abs());
        }
    }
    // Per row: q50, q90, q99 and the trim's cut, each 0 for an empty row.
    let spread_q: Vec<[f64; 4]> = a
        .spread
        .iter()
        .map(|s| {
            let mut v = s.clone();
            let q = quantiles(&mut v, [0.5, 0.9, 0.99, 1.0 - SD_TRIM]);
            q.map(|x| x.unwrap_or(0.0))
        })
        .collect();
    // Root mean square of the spread samples without their top
    // [`SD_TRIM`]: a handful of cells (a changed height at one step edge)
    // must not carry the term; the tail has its own quantile terms.
    let spread_sd = a
        .spread
        .iter()
        .zip(&spread_q)
        .map(|(s, q)| {
            let cut = q[3];
            let kept: Vec<f64> = s.iter().map(|&x| x as f64).filter(|&x| x <= cut).collect();
            (kept.iter().map(|x| x * x).sum::<f64>() / kept.len().max(1) as f64).sqrt()
        })
        .collect();
    let spread_support = sup(&a.spread);
    terms.push(Term { name: "spread-sd", values: spread_sd, support: spread_support.clone(), scale: 0.002 });
    for (name, k) in [("spread-q50", 0), ("spread-q90", 1)] {
        let values = spread_q.iter().map(|q| q[k]).collect();
        terms.push(Term { name, values, support: spread_support.clone(), scale: 0.002 });
    }
    if paired {
        let values = spread_q.iter().map(|q| q[2]).collect();
        terms.push(Term { name: "spread-q99", values, support: spread_support, scale: 0.004 });
    }
    terms.push(Term {
        name: "level-pairs",
        values: a.level.iter().map(|&(z, t)| z as f64 / t.max(1) as f64).collect(),
        support: a.level.iter().map(|&(_, t)| t).collect(),
        scale: 0.02,
    });
    let edge_support: Vec<usize> = a.edge.iter().map(|e| e.0).collect();
    for (k, (name, _)) in EDGE_ABOVE.into_iter().enumerate() {
        terms.push(Term {
            name,
            values: a.edge.iter().map(|(pairs, above)| above[k] as f64 / (*pairs).max(1) as f64).collect(),
            support: edge_support.clone(),
            scale: 0.01,
        });
    }
    // Non-zero neighbour differences by size: rates over all pairs.
    let pairs: usize = a.level.iter().map(|l| l.1).sum::<usize>() + edge_support.iter().sum::<usize>();
    terms.push(Term {
        name: "steps",
        values: a.steps.iter().map(|&k| k as f64 / pairs.max(1) as f64).collect(),
        support: vec![pairs; STEP_BINS.len() - 1],
        scale: 0.01,
    });
    if paired {
        // Means and rates, not quantiles: at a step a cell either keeps its
        // surface or reads (part of the way to) the other one, and a
        // quantile on the border of the two modes jumps by the whole step
        // from one random draw of a model to the next.
        for (name, v) in STEP_SIDES.iter().zip(&a.side) {
            let n = v.len().max(1) as f64;
            let rate = |f: &dyn Fn(f32) -> bool| v.iter().filter(|&&x| f(x)).count() as f64 / n;
            let values = vec![
                v.iter().map(|&x| x as f64).sum::<f64>() / n / 4.0,
                v.iter().map(|&x| x.abs() as f64).sum::<f64>() / n / 4.0,
                rate(&|x| x > SIDE_MOVE),
                rate(&|x| x < -SIDE_MOVE),
            ];
            terms.push(Term { name, values, support: vec![v.len(); 4], scale: 0.02 });
        }
    }
    let step_coherence = (paired && a.coherence.n >= MIN_SUPPORT).then(|| a.coherence.value());
    Stats { records: n, paired, terms, step_coherence }
}

impl Stats {
    /// The term called `name`.
    pub fn term(&self, name: &str) -> Option<&Term> {
        self.terms.iter().find(|t| t.name == name)
    }

    /// Mean of term `name` over components `range` that have support,
    /// weighted by support.
    pub fn mean_over(&self, name: &str, range: std::ops::Range<usize>) -> f64 {
        let Some(t) = self.term(name) else { return 0.0 };
        let (mut s, mut w) = (0.0, 0.0);
        for i in range.filter(|&i| i < t.values.len()) {
            s += t.values[i] * t.support[i] as f64;
            w += t.support[i] as f64;
        }
        if w > 0.0 {
            s / w
        } else {
            0.0
        }
    }

    /// These statistics with the frame terms of the same records
    /// ([`frame_terms`]) after them.
    pub fn with_frames(mut self, frames: Vec<Term>) -> Stats {
        self.terms.extend(frames);
        self
    }

    /// These statistics moved by the difference between two summaries of
    /// one model's output, `to - from`, component by component where both
    /// have [`MIN_SUPPORT`] samples (elsewhere unchanged; supports are
    /// kept). dem-gap fits unpaired on a subsample of sim against all of
    /// real: with `from` = model(all sim) and `to` = model(subsample), real
    /// moved so stands to the subsample as real stands to all of sim, and
    /// the fit sees the data's gap, not which records the subsample drew
    /// (a control variate: exact at the model itself, to first order for a
    /// candidate added to it).
    pub fn shifted(&self, from: &Stats, to: &Stats) -> Stats {
        let mut out = self.clone();
        for t in &mut out.terms {
            let (Some(f), Some(g)) = (from.term(t.name), to.term(t.name)) else { continue };
            for (i, v) in t.values.iter_mut().enumerate() {
                let (Some(&sf), Some(&sg)) = (f.support.get(i), g.support.get(i)) else { continue };
                if sf >= MIN_SUPPORT && sg >= MIN_SUPPORT {
                    *v += g.values[i] - f.values[i];
                }
            }
        }
        out
    }
}

/// Scales of the frame terms ([`frame_terms`]): half a point of cells
/// changing validity, 2 mm of change, 0.1 of correlation (a quarter of
/// measured maps' flip and change, the tolerance a sensor model must meet
/// in time). The persistence of missing cells is no term: with the
/// missing rate m per row and the flip rate f it is about 1 - f / (2 m),
/// so the two terms carry it, and taken on the missing cells alone it
/// would count a row where one side misses none twice.
pub const FRAME_SCALES: [(&str, f64); 3] = [("frame-flip", 0.005), ("frame-dh", 0.002), ("frame-rcorr", 0.1)];

/// The frame terms of `x` over the runs' `steps` (positions in `x`), per
/// row of the later frame: with `reference` (paired: record i's sim), the
/// lag-1 correlation is of the error against it; without, of the change
/// with the next change ([`FrameSums::add_change`]). Terms of one set's
/// statistics are added to them ([`Stats::with_frames`]), so a model that
/// flickers where measured maps hold still has a gap to close.
pub fn frame_terms(x: &[Dem], reference: Option<&[Dem]>, steps: &[Step]) -> Vec<Term> {
    let chained = if reference.is_none() { chains(steps) } else { Vec::new() };
    let sums: Vec<FrameSums> = (0..GRID_ROWS)
        .into_par_iter()
        .map(|r| {
            let mut sums = FrameSums::default();
            for s in steps {
                sums.add((&x[s.from], &x[s.to]), reference.map(|q| (&q[s.from], &q[s.to])), s.shift, r..r + 1);
            }
            sums.add_changes(x, &chained, r..r + 1);
            sums
        })
        .collect();
    let stats: Vec<_> = sums.iter().map(FrameSums::stats).collect();
    let supports: [Vec<usize>; 3] = [
        sums.iter().map(|s| s.cells).collect(),
        sums.iter().map(|s| s.both).collect(),
        sums.iter().zip(&stats).map(|(s, st)| if st.rcorr.is_some() { s.n } else { 0 }).collect(),
    ];
    let values: [Vec<f64>; 3] = [
        stats.iter().map(|s| s.flip.unwrap_or(0.0)).collect(),
        stats.iter().map(|s| s.dh.unwrap_or(0.0)).collect(),
        stats.iter().map(|s| s.rcorr.unwrap_or(0.0)).collect(),
    ];
    FRAME_SCALES
        .iter()
        .zip(values.into_iter().zip(supports))
        .map(|(&(name, scale), (values, support))| Term { name, values, support, scale })
        .collect()
}

/// Per-term contributions to the gap between `a` (model) and `b` (real):
/// mean over supported components of ln(1 + ((a - b) / scale)^2).
pub fn gap_terms(a: &Stats, b: &Stats) -> Vec<(&'static str, f64)> {
    a.terms
        .iter()
        .filter_map(|ta| {
            let tb = b.term(ta.name)?;
            let (mut s, mut n) = (0.0, 0usize);
            let (ra, rb) = (a.records.max(1) as f64, b.records.max(1) as f64);
            for i in 0..ta.values.len().min(tb.values.len()) {
                let (sa, sb) = (ta.support[i], tb.support[i]);
                if sa >= MIN_SUPPORT && sb >= MIN_SUPPORT {
                    s += ((ta.values[i] - tb.values[i]) / ta.scale).powi(2).ln_1p();
                    n += 1;
                } else if sa.max(sb) >= MIN_SUPPORT {
                    // One side has the samples, the other (per record) few.
                    let (pa, pb) = (sa as f64 / ra, sb as f64 / rb);
                    if pa.min(pb) < 0.25 * pa.max(pb) {
                        s += UNSUPPORTED_Z.powi(2).ln_1p();
                        n += 1;
                    }
                }
            }
            Some((ta.name, if n > 0 { s / n as f64 } else { 0.0 }))
        })
        .collect()
}

/// Why a model that hides far more cells than real misses must not be
/// accepted, or None: over all cells, model(sim) may miss at most
/// 1.5 x real's rate + 3 %, and in no row more than real's rate + 30 %.
pub fn hides_too_much(model: &Stats, real: &Stats) -> Option<String> {
    let (m, r) = (model.mean_over("missing", 0..GRID_ROWS), real.mean_over("missing", 0..GRID_ROWS));
    if m > 1.5 * r + 0.03 {
        return Some(format!("it hides {:.1}% of cells where real misses {:.1}%", 100.0 * m, 100.0 * r));
    }
    let (tm, tr) = (model.term("missing")?, real.term("missing")?);
    let worst = (0..GRID_ROWS.min(tm.values.len()).min(tr.values.len()))
        .max_by(|&i, &j| (tm.values[i] - tr.values[i]).total_cmp(&(tm.values[j] - tr.values[j])))?;
    let excess = tm.values[worst] - tr.values[worst];
    (excess > 0.3).then(|| {
        format!(
            "it hides {:.1}% of row {worst} (x = {:.2} m) where real misses {:.1}%",
            100.0 * tm.values[worst],
            row_center_x(worst),
            100.0 * tr.values[worst]
        )
    })
}

/// The gap number: the sum of [`gap_terms`].
pub fn gap(a: &Stats, b: &Stats) -> f64 {
    gap_terms(a, b).iter().map(|(_, v)| v).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::empty_dem;

    /// Several quantiles at once equal the nearest-rank quantile of the
    /// sorted samples, one at a time, on lengths from 0 to 40 with ties,
    /// for coinciding and neighbouring ranks too.
    #[test]
    fn quantiles_at_once_equal_one_at_a_time() {
        let qs = [0.0, 0.5, 0.5, 0.51, 0.9, 0.99, 0.995, 1.0];
        for n in 0..40usize {
            let v: Vec<f32> = (0..n).map(|i| ((i * 7919) % 13) as f32 * 0.25).collect();
            let mut sorted = v.clone();
            sorted.sort_by(|a, b| a.total_cmp(b));
            let got = quantiles(&mut v.clone(), qs);
            for (g, &q) in got.iter().zip(&qs) {
                let want = (n > 0).then(|| sorted[((n - 1) as f64 * q).round() as usize] as f64);
                assert_eq!(*g, want, "n {n} q {q}");
            }
        }
    }

    /// Moved by the difference a subsample makes, real stands to the
    /// subsample as it stands to the whole set, component by component.
    #[test]
    fn shifted_stats_keep_the_difference_to_the_whole_set() {
        let mut sets: Vec<Vec<Dem>> = vec![Vec::new(), Vec::new()];
        for k in 0..400 {
            let mut d = empty_dem();
            for r in 0..GRID_ROWS {
                for c in 0..COLS {
                    if (k + r + c) % 7 != 0 {
                        d.set_valid(r, c, 0.001 * ((k * 13 + r * 5 + c) % 17) as f32);
                    }
                }
            }
            sets[k % 2].push(d);
            if k % 3 == 0 {
                let mut e = d;
                e.set_missing(k % GRID_ROWS, 0);
                sets[k % 2].push(e);
            }
        }
        let (all, real) = (stats(&sets.concat(), None), stats(&sets[1], None));
        let sub = stats(&sets[0][..150], None);
        let moved = real.shifted(&all, &sub);
        for ((tm, ts), (tr, ta)) in moved.terms.iter().zip(&sub.terms).zip(real.terms.iter().zip(&all.terms)) {
            for i in 0..tm.values.len() {
                if ts.support[i] >= MIN_SUPPORT && ta.support[i] >= MIN_SUPPORT {
                    let (d_sub, d_all) = (tm.values[i] - ts.values[i], tr.values[i] - ta.values[i]);
                    assert!((d_sub - d_all).abs() < 1e-12, "{} {i}: {d_sub} vs {d_all}", tm.name);
                } else {
                    assert_eq!(tm.values[i], tr.values[i]);
                }
                assert_eq!(tm.support[i], tr.support[i]);
            }
        }
        // At the subsample itself, the moved gap is the whole set's gap.
        assert!((gap(&sub, &moved) - gap(&all, &real)).abs() < 1e-9, "{} vs {}", gap(&sub, &moved), gap(&all, &real));
        assert_ne!(gap(&sub, &real), gap(&all, &real));
    }

    #[test]
    fn identical_sets_have_no_gap_and_missing_rows_show() {
        let mut d = empty_dem();
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                d.set_valid(r, c, -0.07 + 0.001 * (r * c) as f32);
            }
        }
        let a = vec![d; 100];
        assert_eq!(gap(&stats(&a, None), &stats(&a, None)), 0.0);
        let mut b = a.clone();
        for x in &mut b {
            (0..COLS).for_each(|c| x.set_missing(3, c));
        }
        let (sa, sb) = (stats(&a, None), stats(&b, None));
        assert_eq!(sb.term("row-missing").unwrap().values[3], 1.0);
        assert!(gap(&sa, &sb) > 1.0);
        let sp = stats(&b, Some(&a));
        assert!(sp.paired && sp.term("height").unwrap().values[0].abs() < 1e-9);
    }

    #[test]
    fn a_missing_cell_behind_a_drop_is_a_shadow() {
        let mut d = empty_dem();
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                d.set_valid(r, c, if r == 10 { 0.1 } else { -0.07 });
            }
        }
        d.set_missing(11, 0);
        d.set_missing(5, 0);
        assert!(in_shadow(&d, 11, 0));
        assert!(!in_shadow(&d, 5, 0));
    }

    /// A riser at rows 9/10 and a drop at 14/15 (sim); real moves every
    /// foot cell 3 cm up (toward the top, past the 2 cm of a moved cell)
    /// and every lip cell 1 cm up (away from the floor): the foot reads a
    /// mean of +0.03 (/ 4), all moved toward; the lip -0.01, none moved;
    /// the other two sides read 0, and a riser's move does not show as a
    /// drop's.
    #[test]
    fn the_step_sides_are_told_apart() {
        let mut sim = empty_dem();
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                sim.set_valid(r, c, if (10..15).contains(&r) { 0.1 } else { -0.07 });
            }
        }
        let mut real = sim;
        for c in 0..COLS {
            real.set_valid(9, c, -0.04);
            real.set_valid(14, c, 0.11);
        }
        let s = stats(&vec![real; 10], Some(&vec![sim; 10]));
        let q = |name| s.term(name).unwrap().values.iter().map(|v| (v * 1e4).round() / 1e4).collect::<Vec<_>>();
        assert_eq!(q("riser-foot"), [0.0075, 0.0075, 1.0, 0.0]);
        assert_eq!(q("drop-lip"), [-0.0025, 0.0025, 0.0, 0.0]);
        assert_eq!(q("riser-top"), [0.0; 4]);
        assert_eq!(q("drop-floor"), [0.0; 4]);
        assert_eq!(s.term("riser-foot").unwrap().support, [50; 4]);
        assert!(stats(&vec![real; 10], None).term("riser-foot").is_none(), "unpaired has no residuals");
    }

    /// A riser at rows 9/10 in every sim record. Real moves the step's
    /// cells either as one (the same offset across the row, sd 6 cm, a
    /// pose error) or each on its own (+-6 cm by a hash of record and
    /// column): `step_coherence` reads about 1 and about 0. Moved as one
    /// by millimetres, or not at all, it reads near 0. Even ground moved
    /// on its own does not count, and it is no term of the gap.
    #[test]
    fn step_coherence_tells_rows_that_move_together_from_cells_that_do_not() {
        let mut sim = empty_dem();
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                sim.set_valid(r, c, if r >= 10 { 0.17 } else { 0.0 });
            }
        }
        let moved = |offset: &dyn Fn(usize, usize) -> f32| {
            (0..200)
                .map(|k| {
                    let mut d = sim;
                    for r in 0..GRID_ROWS {
                        for c in 0..COLS {
                            d.set_valid(
                                r,
                                c,
                                sim.height(r, c) + offset(k, c) + if (9..=10).contains(&r) { 0.0 } else { 0.01 * (c % 2) as f32 },
                            );
                        }
                    }
                    d
                })
                .collect::<Vec<_>>()
        };
        let sims = vec![sim; 200];
        let together = moved(&|k, _| 0.03 * ((k % 7) as f32 - 3.0));
        let coin = |k: usize, c: usize| {
            // splitmix64 of the cell's index: independent signs.
            let mut z = ((k * COLS + c) as u64).wrapping_add(0x9E37_79B9_7F4A_7C15);
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            if (z ^ (z >> 31)) & 1 == 0 {
                1.0
            } else {
                -1.0
            }
        };
        let apart = moved(&|k, c| 0.06 * coin(k, c));
        let by_millimetres = moved(&|k, _| 0.0005 * ((k % 7) as f32 - 3.0));
        let coherence = |set: &[Dem]| {
            let s = stats(set, Some(&sims));
            (s.step_coherence.unwrap(), s)
        };
        let (c_together, s_together) = coherence(&together);
        let (c_apart, s_apart) = coherence(&apart);
        assert!(c_together > 0.99, "{c_together}");
        assert!(c_apart.abs() < 0.1, "{c_apart}");
        let c_millimetres = coherence(&by_millimetres).0;
        assert!(c_millimetres < 0.1, "{c_millimetres}");
        assert_eq!(coherence(&sims).0, 0.0, "real equal to sim");
        assert!(gap_terms(&s_together, &s_apart).iter().all(|(name, _)| !name.contains("coherence")));
        assert!(stats(&together, None).step_coherence.is_none(), "unpaired has no residuals");
    }

    /// The frame terms per row are the frame statistics of that row alone
    /// ([`crate::temporal::frame_stats`]), with each statistic's samples as
    /// support; unpaired, the correlation is the change's.
    #[test]
    fn frame_terms_are_the_frame_statistics_row_by_row() {
        use crate::temporal::{change_rcorr, frame_stats, Step};
        let frames: Vec<Dem> = (0..60)
            .map(|t| {
                let mut d = empty_dem();
                for r in 0..GRID_ROWS {
                    for c in 0..COLS {
                        if (t * 3 + r * 7 + c) % 11 != 0 {
                            d.set_valid(r, c, 0.01 * (((t * 13 + r * 5 + c * 3) % 17) as f32));
                        }
                    }
                }
                d
            })
            .collect();
        let reference: Vec<Dem> = frames
            .iter()
            .map(|d| {
                let mut q = *d;
                for r in 0..GRID_ROWS {
                    for c in 0..COLS {
                        q.set_valid(r, c, 0.0);
                    }
                }
                q
            })
            .collect();
        let steps: Vec<Step> = (0..59).filter(|t| t % 10 != 9).map(|t| Step { from: t, to: t + 1, shift: (t % 3) as i64 }).collect();
        for paired in [true, false] {
            let reference = paired.then_some(&reference[..]);
            let terms = frame_terms(&frames, reference, &steps);
            let names: Vec<&str> = terms.iter().map(|t| t.name).collect();
            assert_eq!(names, FRAME_SCALES.map(|t| t.0));
            for r in 0..GRID_ROWS {
                let s = frame_stats(&frames, reference, &steps, r..r + 1);
                let rcorr = if paired { s.rcorr } else { change_rcorr(&frames, &steps, r..r + 1) };
                assert_eq!(terms[0].values[r], s.flip.unwrap_or(0.0), "row {r}");
                assert_eq!(terms[1].values[r], s.dh.unwrap_or(0.0), "row {r}");
                assert_eq!(terms[2].values[r], rcorr.unwrap_or(0.0), "row {r}");
                assert_eq!(terms[0].support[r], s.cells, "row {r}");
                assert_eq!(terms[2].support[r] > 0, rcorr.is_some(), "row {r}");
            }
        }
    }
}
