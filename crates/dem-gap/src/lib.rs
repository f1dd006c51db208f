//! Find where sim and real disagree, name the missing effect, add it to a
//! sensor model and show the gap shrink.
//!
//! The loop ([`run`]):
//! 1. **measure** model(sim) against real with [`dem_core::distribution`]: missing-cell
//!    rates, shadows, residual or height means and spreads, edge profiles,
//!    height steps, per row; one gap number ([`gap`]) that compares
//!    distributions and is 0 when they match. With pairs, heights are
//!    residuals against the paired sim record; without, the records'
//!    own distributions are compared.
//! 2. **name**: fit every effect not yet in the model ([`fit`]) on a
//!    subsample and rank them by how much of the gap each removes; the
//!    evidence ([`evidence`]) says why in numbers.
//! 3. **add** the best one when it removes more than `min_gain` of the gap,
//!    with the models' random draws and again with other draws (a gain
//!    that is a draw's luck does not repeat); unpaired, it
//!    must also hold on each of two half-size comparisons, sim half k
//!    against real half k ([`sim_halves`], [`real_halves`]), so fitting
//!    which records happen to be in the set does not pass. Re-measure on
//!    all data, repeat. The report
//!    also gives the unpaired sampling floor, two halves of real scaled to
//!    the set sizes ([`noise_floor`]), as what to expect of a perfect model.
//! 4. **show**: [`report`] writes `report.json`, `sensor.json`, `report.md`
//!    and its pictures; [`unexplained`] says what the final model leaves
//!    above the sampling floor and where (statistic, band of rows, side,
//!    terrain), flags weak steps, and, for a gap below the floor, how many
//!    records (runs) would show it.

pub mod evidence;
pub mod fit;
pub mod mix;
pub mod report;
pub mod unexplained;

use rand::seq::index::sample;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use dem_core::error::{DemError, Result};
use dem_core::format::{Dem, Terrain};
use dem_core::table::Split;
use dem_core::{distribution, metric, npy, table};
use dem_sensor::effects::NAMES;
use dem_sensor::{Effect, SensorModel};

pub use dem_core::distribution::{gap, gap_terms, Stats};

/// Everything one run needs.
#[derive(Debug, Clone)]
pub struct GapConfig {
    /// Sim NPY file.
    pub sim: String,
    /// Real NPY file.
    pub real: String,
    /// Pairs CSV (sim_index,real_index): compare per position.
    pub pairs: Option<String>,
    /// Labels CSV of the sim file.
    pub labels_sim: Option<String>,
    /// Labels CSV of the real file.
    pub labels_real: Option<String>,
    /// The model to start from.
    pub start: SensorModel,
    /// Output folder.
    pub out: String,
    /// Most effects added.
    pub max_steps: usize,
    /// Seed of the model's random effects and of the subsample.
    pub seed: u64,
    /// Records (pairs, or sim records) the candidates are fitted on.
    pub fit_records: usize,
    /// Smallest fraction of the gap an added effect must remove.
    pub min_gain: f64,
    /// Unpaired, with terrain labels on both sides: draw the sim records
    /// to the real set's terrain mix first (see [`terrain_mix`]).
    pub match_terrain: bool,
    /// Only the pairs of this split.
    pub split: Option<Split>,
    /// With pairs: compare the pairs' records as two sets (each record once
    /// per pair it is in), not per position: the gap over the pairs, as
    /// dem-eval's.
    pub over_pairs: bool,
}

/// One added effect.
#[derive(Debug, Clone)]
pub struct Step {
    /// The effect with its fitted parameters.
    pub effect: Effect,
    /// Gap before adding it (all data).
    pub gap_before: f64,
    /// Gap after (all data).
    pub gap_after: f64,
    /// Why, in words and numbers.
    pub evidence: String,
    /// Every candidate of this step with the fraction of the gap it removed
    /// on the fitting subsample, best first.
    pub ranking: Vec<(Effect, f64)>,
    /// Parameters fitted on an edge of their (widened) box: the effect is
    /// the closest of the vocabulary, not the right one.
    pub at_edge: Vec<&'static str>,
    /// Parameters whose box was widened because the first fit hit its edge.
    pub widened: Vec<&'static str>,
    /// Candidates refused because their model hides far more cells than
    /// real misses, with the reason.
    pub refused: Vec<(Effect, String)>,
    /// Close rivals the data does not tell from the effect ([`Tie`]).
    pub tied_with: Vec<Tie>,
}

/// A candidate that came close to the named effect (on the fitting
/// subsample and on all records, [`RIVAL_SHARE`]), that the data does
/// not order behind it (the named effect
/// does not remove more of the gap than the rival on all records and on
/// each of two halves of them, [`named_ahead`]) and that explains the same
/// part of the gap (on top of the named effect it removes little, and no
/// later step names it). Two effects of the
/// vocabulary can leave the same trace (the floor beyond a drop edge read
/// part of the way up: the edge's occlusion or the stereo window's blend);
/// the step then names one of the two, and says so.
#[derive(Debug, Clone)]
pub struct Tie {
    /// The rival with its fitted parameters.
    pub effect: Effect,
    /// Gap it removes on all records, in place of the named effect.
    pub gain: f64,
    /// Gap it removes added on top of the named effect (its parameters
    /// as fitted alone): less than [`SAME_PART`] of `gain`.
    pub gain_on_top: f64,
    /// Gap it removes on each half of the records.
    pub gains_halves: Vec<f64>,
    /// Gap the named effect removes on each half.
    pub named_gains_halves: Vec<f64>,
}

/// A rival is checked when it removes at least this share of what the
/// named effect removes on the fitting subsample, and is one only when it
/// does so on all records too: a rival that removes next to nothing is no
/// choice, however the halves fall.
pub const RIVAL_SHARE: f64 = 0.8;

/// A rival not ordered behind the named effect is tied with it when, added
/// on top of it, it removes less than this share of what it removes alone:
/// the two explain the same part of the gap. (Otherwise they explain two
/// parts of a like size, and the next step names the other.)
pub const SAME_PART: f64 = 0.5;

/// Rivals checked per step, closest first.
pub const MAX_RIVALS: usize = 2;

/// A gap below this is left as it is: each statistic enters as
/// ln(1 + z^2) averaged over rows, so a sum this small means no statistic
/// differs from real by a fifth of its physical scale (0.4 % of cells,
/// 1 mm of height). An effect fitted to such a gap fits what is left of
/// the others' fits, not a physical effect.
pub const NEGLIGIBLE_GAP: f64 = 0.05;

/// True when the named effect leaves a smaller gap than the rival on all
/// records and on every half: the data orders the two. Gaps after each,
/// all records first, then per half (no halves: all records decide).
pub fn named_ahead(named: f64, named_halves: &[f64], rival: f64, rival_halves: &[f64]) -> bool {
    named < rival && named_halves.iter().zip(rival_halves).all(|(n, r)| n < r)
}

/// An effect re-fitted after the naming loop with all others in place.
#[derive(Debug, Clone)]
pub struct Refit {
    /// As named.
    pub before: Effect,
    /// As re-fitted (in the final model).
    pub after: Effect,
    /// Gap before and after the re-fit (all data).
    pub gap_before: f64,
    /// Gap after.
    pub gap_after: f64,
    /// Parameters of the re-fit at the edge of their box.
    pub at_edge: Vec<&'static str>,
}

/// Per-terrain comparison (when labels are given).
#[derive(Debug, Clone)]
pub struct TerrainRow {
    /// The terrain.
    pub terrain: Terrain,
    /// Records of the compared set with this terrain (real side).
    pub records: usize,
    /// Missing-cell rate: sim, final model(sim), real.
    pub missing: [f64; 3],
    /// Mean residual (paired) or mean height (m): sim, model(sim), real.
    pub height: [f64; 3],
    /// Residual spread (paired) or across-robot roughness (m), the same three.
    pub spread: [f64; 3],
    /// Share of steps between rows above 0.02 m (edge profile), the same three.
    pub edges: [f64; 3],
    /// Gap of the start and of the final model on this terrain.
    pub gap: [f64; 2],
}

/// What a run found.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// Effects added, in order.
    pub steps: Vec<Step>,
    /// Gap of the start model.
    pub gap_initial: f64,
    /// Gap of the final model.
    pub gap_final: f64,
    /// Gap of the final model with random draws of its effects that no
    /// fit and no check saw ([`unseen_draws`]).
    pub gap_final_unseen: f64,
    /// The final model.
    pub model: SensorModel,
    /// Expected gap from sampling alone, of the final model.
    pub floor: f64,
    /// The same of the start model: a gap below it may be sampling
    /// ([`below_floor`]).
    pub floor_initial: f64,
    /// Why the loop stopped.
    pub stop: String,
    /// True when compared per position (pairs).
    pub paired: bool,
    /// Records compared: model side, real side.
    pub sizes: (usize, usize),
    /// Statistics: sim as is, start model(sim), final model(sim), real.
    pub stats: [Stats; 4],
    /// Mean paired equation 7.1 error of sim, start and final model(sim)
    /// against real (pairs only), reported beside the gap.
    pub eq71: Option<[f64; 3]>,
    /// Effects re-fitted after naming, with all others in place.
    pub refits: Vec<Refit>,
    /// Per terrain, when labels are given.
    pub terrains: Vec<TerrainRow>,
    /// Sim records compared after drawing them to the real set's terrain
    /// mix, and sim records read (unpaired, both sides labelled, when the
    /// draw changed anything).
    pub terrain_mix: Option<(usize, usize)>,
    /// Unpaired over the records of pairs (`--unpaired` with `--pairs`).
    pub over_pairs: bool,
    /// What the final model leaves above the sampling floor, and where.
    pub unexplained: unexplained::Unexplained,
    /// With the start gap below its sampling floor: the records (runs)
    /// that would lift it above.
    pub more_data: Option<unexplained::MoreData>,
    /// Missing-cell rates behind and ahead of the robot, for all records
    /// and per terrain (labels).
    pub missing_bands: Vec<unexplained::BandRow>,
    /// The kinds of terrain each set holds, read from the heights.
    pub record_kinds: mix::RecordKinds,
}

/// The compared sets: model side (sim) and real side, aligned when paired.
pub struct Sets {
    /// Sim records (one per pair when paired).
    pub sim: Vec<Dem>,
    /// Real records (one per pair when paired).
    pub real: Vec<Dem>,
    /// Compared per position.
    pub paired: bool,
    /// Terrain of each sim-side record, when known.
    pub sim_terrain: Option<Vec<Terrain>>,
    /// Terrain of each real-side record, when known.
    pub real_terrain: Option<Vec<Terrain>>,
    /// Time in its run of each sim-side record (labels; NaN where not
    /// given), when the sim labels carry times.
    pub sim_time: Option<Vec<f64>>,
    /// Run (labels' `sequence`) of each real record, when every real label
    /// has one: the sampling halves (unpaired) and the halves that order a
    /// named effect and its rival (both modes) deal whole runs.
    pub real_runs: Option<Vec<u64>>,
    /// Run of each sim record, likewise (unpaired only).
    pub sim_runs: Option<Vec<u64>>,
    /// Sim records compared after drawing them to the real set's terrain
    /// mix, and sim records read, when the draw changed anything.
    pub terrain_mix: Option<(usize, usize)>,
    /// Unpaired over the records of pairs: each record once per pair it is
    /// in, so both sides share the pairs' terrain mix.
    pub over_pairs: bool,
}

/// Terrains; times when any label has one; runs when every label has one.
type Labelled = Option<(Vec<Terrain>, Option<Vec<f64>>, Option<Vec<u64>>)>;

/// Terrains, times and runs of the labels at `path`.
fn terrains(path: &Option<String>, n: usize) -> Result<Labelled> {
    let Some(p) = path else { return Ok(None) };
    let l = table::read_labels(p)?;
    if l.len() != n {
        return Err(DemError::input(p, format!("{} labels for {n} records", l.len())));
    }
    let times = l.iter().any(|l| l.time.is_some()).then(|| table::times(&l));
    let runs = l.iter().map(|l| l.sequence).collect::<Option<Vec<u64>>>();
    Ok(Some((l.into_iter().map(|l| l.terrain).collect(), times, runs)))
}

/// Read the inputs of `cfg` into the compared sets.
pub fn load(cfg: &GapConfig) -> Result<Sets> {
    let sim = npy::read_all(&cfg.sim)?;
    let real = npy::read_all(&cfg.real)?;
    for (p, v) in [(&cfg.sim, &sim), (&cfg.real, &real)] {
        if v.is_empty() {
            return Err(DemError::input(p.as_str(), "no records"));
        }
    }
    let (ts, times, sim_runs) = match terrains(&cfg.labels_sim, sim.len())? {
        Some((t, time, runs)) => (Some(t), time, runs),
        None => (None, None, None),
    };
    let (tr, real_runs) = match terrains(&cfg.labels_real, real.len())? {
        Some((t, _, runs)) => (Some(t), runs),
        None => (None, None),
    };
    let over_pairs = cfg.over_pairs && cfg.pairs.is_some();
    let Some(pp) = &cfg.pairs else {
        let (mut sim, mut ts, mut times, mut sim_runs, mut mix) = (sim, ts, times, sim_runs, None);
        if let (true, Some(s), Some(r)) = (cfg.match_terrain, &ts, &tr) {
            let keep = terrain_mix(s, r, cfg.seed);
            if !keep.iter().copied().eq(0..sim.len()) {
                mix = Some((keep.len(), sim.len()));
                sim = pick(&sim, &keep);
                times = times.map(|t| pick(&t, &keep));
                sim_runs = sim_runs.map(|r| pick(&r, &keep));
                ts = Some(pick(s, &keep));
            }
        }
        return Ok(Sets {
            sim,
            real,
            paired: false,
            sim_terrain: ts,
            real_terrain: tr,
            sim_time: times,
            real_runs,
            sim_runs,
            terrain_mix: mix,
            over_pairs,
        });
    };
    let mut pairs = table::read_pairs(pp)?;
    if let Some(split) = cfg.split {
        pairs.retain(|p| p.split == Some(split));
    }
    if pairs.is_empty() {
        let of = cfg.split.map_or(String::new(), |s| format!(" of split {s}"));
        return Err(DemError::input(pp, format!("no pairs{of}")));
    }
    let mut s = Vec::with_capacity(pairs.len());
    let mut r = Vec::with_capacity(pairs.len());
    let (mut st, mut rt, mut tt, mut runs) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (line, p) in pairs.iter().enumerate() {
        let (si, ri) = (p.sim_index as usize, p.real_index as usize);
        if si >= sim.len() || ri >= real.len() {
            return Err(DemError::Table {
                path: pp.clone(),
                line: line as u64 + 2,
                reason: format!("pair ({si}, {ri}) past the data ({} sim, {} real records)", sim.len(), real.len()),
            });
        }
        s.push(sim[si]);
        r.push(real[ri]);
        if let Some(t) = &ts {
            st.push(t[si]);
        }
        if let Some(t) = &times {
            tt.push(t[si]);
        }
        if let Some(t) = &tr {
            rt.push(t[ri]);
        }
        if let Some(r) = &real_runs {
            runs.push(r[ri]);
        }
    }
    if over_pairs {
        return Ok(Sets {
            sim: s,
            real: r,
            paired: false,
            sim_terrain: ts.map(|_| st),
            real_terrain: tr.map(|_| rt),
            sim_time: times.map(|_| tt),
            real_runs: real_runs.map(|_| runs),
            // Over pairs the i-th sim record is the i-th real record's
            // pair: the halves split both sides alike by the real runs.
            sim_runs: None,
            terrain_mix: None,
            over_pairs,
        });
    }
    // Paired: both sides share the pair's terrain; prefer the real label.
    let t = if tr.is_some() {
        Some(rt)
    } else if ts.is_some() {
        Some(st)
    } else {
        None
    };
    Ok(Sets {
        sim: s,
        real: r,
        paired: true,
        sim_terrain: t.clone(),
        real_terrain: t,
        sim_time: times.map(|_| tt),
        real_runs: real_runs.map(|_| runs),
        sim_runs: None,
        terrain_mix: None,
        over_pairs: false,
    })
}

/// The sim records (indices, ascending, a record may repeat) to compare
/// unpaired when both sides carry terrain labels: as many records as sim
/// has, shared among the terrains as real's records are, each terrain's
/// share drawn from its sim records (seeded; without replacement while
/// they last, then with). Sim terrains that real lacks are left out. A
/// distribution comparison otherwise reads a difference of terrain mix as
/// a sensor effect: more stairs on the sim side looks like more holes and
/// a height bias, and the fit names those. Prepared sims deduplicated to
/// unique keys (one flat record) are the extreme case. Equal mixes keep
/// every record once.
pub fn terrain_mix(sim: &[Terrain], real: &[Terrain], seed: u64) -> Vec<usize> {
    let mut by_terrain: Vec<(Terrain, Vec<usize>, usize)> = Vec::new();
    for (i, &t) in sim.iter().enumerate() {
        match by_terrain.iter_mut().find(|(u, _, _)| *u == t) {
            Some(e) => e.1.push(i),
            None => by_terrain.push((t, vec![i], 0)),
        }
    }
    for &t in real {
        if let Some(e) = by_terrain.iter_mut().find(|(u, _, _)| *u == t) {
            e.2 += 1;
        }
    }
    let shared: usize = by_terrain.iter().map(|e| e.2).sum();
    if shared == 0 {
        return (0..sim.len()).collect();
    }
    let mut rng = ChaCha8Rng::seed_from_u64(dem_core::seeded::mix(seed ^ 0x7e22a1));
    let mut keep = Vec::with_capacity(sim.len());
    for (_, idx, n_real) in &by_terrain {
        let n = (sim.len() as f64 * *n_real as f64 / shared as f64).round() as usize;
        if n >= idx.len() {
            keep.extend_from_slice(idx);
            keep.extend((idx.len()..n).map(|_| idx[rng.gen_range(0..idx.len())]));
        } else {
            keep.extend(sample(&mut rng, idx.len(), n).into_iter().map(|j| idx[j]));
        }
    }
    keep.sort_unstable();
    keep
}

fn pick<T: Copy>(v: &[T], idx: &[usize]) -> Vec<T> {
    idx.iter().map(|&i| v[i]).collect()
}

/// Apply `model` to `sim` and summarise (residuals against `sim` when paired).
pub fn measure(model: &SensorModel, sim: &[Dem], paired: bool, seed: u64) -> (Vec<Dem>, Stats) {
    measure_at(model, sim, None, paired, seed)
}

/// [`measure`] with the records' times in their runs, when known.
pub fn measure_at(model: &SensorModel, sim: &[Dem], times: Option<&[f64]>, paired: bool, seed: u64) -> (Vec<Dem>, Stats) {
    let mut out = sim.to_vec();
    model.apply_all_at(&mut out, seed, 0, times);
    let s = distribution::stats(&out, paired.then_some(sim));
    (out, s)
}

/// Run the measure-name-add loop on loaded sets; `log` gets progress lines,
/// `tick` is called after each candidate fit (for a progress bar).
pub fn run(cfg: &GapConfig, sets: &Sets, log: &dyn Fn(String), tick: &dyn Fn()) -> Outcome {
    let paired = sets.paired;
    let real_stats = distribution::stats(&sets.real, paired.then_some(&sets.sim[..]));
    let split_floor = if paired { 0.0 } else { noise_floor(sets) };
    let times = sets.sim_time.as_deref();
    let floor_of = |m: &SensorModel| split_floor.max(draw_floor(m, &sets.sim, times, paired, cfg.seed));
    // Two halves of the comparison, sim half k against real half k.
    // Unpaired (and paired below the sampling floor), a gain must also hold
    // on both, replicates at half the size (whole sim when it is too small
    // to split); in both modes they tell a named effect from a close rival
    // ([`Tie`]). Paired, sim record i is real record i's pair, and the
    // halves are real's (whole runs when labelled).
    let halves: Vec<(Vec<usize>, Stats)> = if sets.real.len() < 100 {
        Vec::new()
    } else if paired {
        real_halves(sets)
            .into_iter()
            .filter(|h| !h.is_empty())
            .map(|h| {
                let st = distribution::stats(&pick(&sets.real, &h), Some(&pick(&sets.sim, &h)));
                (h, st)
            })
            .collect()
    } else {
        let mut sh = sim_halves(sets);
        if sh.iter().any(Vec::is_empty) {
            sh = [(0..sets.sim.len()).collect(), (0..sets.sim.len()).collect()];
        }
        sh.into_iter().zip(real_halves(sets)).map(|(s, r)| (s, distribution::stats(&pick(&sets.real, &r), None))).collect()
    };
    let half_stats = |out: &[Dem]| -> Vec<Stats> {
        halves
            .iter()
            .map(|(s, _)| {
                let sim_half = paired.then(|| pick(&sets.sim, s));
                distribution::stats(&pick(out, s), sim_half.as_deref())
            })
            .collect()
    };
    let half_gaps = |per_half: &[Stats]| -> Vec<f64> { halves.iter().zip(per_half).map(|((_, r), s)| gap(s, r)).collect() };
    let measure = |m: &SensorModel, sim: &[Dem], paired: bool, seed: u64| measure_at(m, sim, times, paired, seed);
    // The fitting subsample (all records when few).
    let mut rng = ChaCha8Rng::seed_from_u64(dem_core::seeded::mix(cfg.seed ^ 0x5eed));
    let n = sets.sim.len();
    let mut idx: Vec<usize> = if n > cfg.fit_records { sample(&mut rng, n, cfg.fit_records).into_vec() } else { (0..n).collect() };
    idx.sort_unstable();
    let fit_sim = pick(&sets.sim, &idx);
    let fit_times = times.map(|t| pick(t, &idx));
    let fit_real = if paired { distribution::stats(&pick(&sets.real, &idx), Some(&fit_sim)) } else { real_stats.clone() };
    // Unpaired on a subsample, real is moved by what the subsample's draw
    // of records does to model(sim) at the current model
    // (`Stats::shifted`), so a small gap is not drowned by the subsample's
    // own sampling: on the emulator's dark-patch stage over 100 runs the
    // right effect removed 11% of the gap on 1,000 records against all of
    // real, 80% on all records.
    let subsampled = !paired && idx.len() < n;
    let moved_real = |model: &SensorModel, all: &Stats| -> Option<Stats> {
        subsampled.then(|| {
            let t = fit::Target { sim: &fit_sim, times: fit_times.as_deref(), paired, real: &fit_real, seed: cfg.seed };
            fit_real.shifted(all, &t.model_stats(model))
        })
    };

    let mut model = cfg.start.clone();
    let (start_out, start_stats) = measure(&model, &sets.sim, paired, cfg.seed);
    let mut current_halves = half_stats(&start_out);
    drop(start_out);
    let gap_initial = gap(&start_stats, &real_stats);
    let floor_initial = floor_of(&model);
    log(format!(
        "{} mode, {} vs {} records; start model: {}; gap {gap_initial:.3} (sampling floor {floor_initial:.3}){}",
        if paired { "paired" } else { "unpaired" },
        sets.sim.len(),
        sets.real.len(),
        model.summary(),
        if gap_initial < floor_initial { format!("; {}", below_floor(gap_initial, floor_initial)) } else { String::new() }
    ));
    let mut current = (gap_initial, start_stats.clone());
    let mut steps = Vec::new();
    let mut stop = format!("stopped after --max-steps {}", cfg.max_steps);
    for step in 0..cfg.max_steps {
        let candidates: Vec<&str> = NAMES.iter().copied().filter(|n| !model.effects.iter().any(|e| e.name() == *n)).collect();
        if candidates.is_empty() {
            stop = "every effect of the vocabulary is in the model".into();
            break;
        }
        if current.0 < NEGLIGIBLE_GAP {
            stop = format!(
                "the gap left, {:.4}, is below {NEGLIGIBLE_GAP}: no statistic differs by a fifth of its scale, so no effect is added for it",
                current.0
            );
            break;
        }
        let moved = moved_real(&model, &current.1);
        let target =
            fit::Target { sim: &fit_sim, times: fit_times.as_deref(), paired, real: moved.as_ref().unwrap_or(&fit_real), seed: cfg.seed };
        let base_fit = target.gap(&model);
        let mut ranking: Vec<(Effect, f64, f64)> = Vec::new();
        let mut flags: Vec<(Effect, Vec<&'static str>, Vec<&'static str>)> = Vec::new();
        for name in &candidates {
            if let Some(f) = fit::fit(name, &model, &target) {
                let removed = share_removed(base_fit, f.gap);
                let edge =
                    if f.at_edge.is_empty() { String::new() } else { format!(" [AT THE EDGE of its box: {}]", f.at_edge.join(", ")) };
                log(format!(
                    "step {}: candidate {} removes {:.1}% of the gap on the fitting subsample{edge}",
                    step + 1,
                    f.effect,
                    100.0 * removed
                ));
                ranking.push((f.effect, removed, f.gap));
                flags.push((f.effect, f.at_edge, f.widened));
            } else {
                log(format!("step {}: candidate {name}: no fit that does not hide far more cells than real misses", step + 1));
            }
            tick();
        }
        ranking.sort_by(|a, b| a.2.total_cmp(&b.2));
        let (gap_before, before_stats) = current.clone();
        let mut threshold = 0.0;
        let mut added = None;
        let mut refused = Vec::new();
        // The model's own gap with other draws, measured once for both
        // candidates that may need it.
        let mut model_redrawn: Option<f64> = None;
        // Paired, the halves decide only below the model's sampling floor
        // (measured once, when a candidate gets that far): there what
        // separates the sets may be the draws, and a gain that is an effect
        // holds on both halves of the records.
        let mut below_floor_now: Option<bool> = None;
        // The best candidate on the subsample, confirmed on all data; the
        // runner-up gets a chance when the best does not hold up.
        for (e, _, _) in ranking.iter().take(2) {
            let trial = model.with(*e);
            let (out, s) = measure(&trial, &sets.sim, paired, cfg.seed);
            if let Some(why) = distribution::hides_too_much(&s, &real_stats) {
                log(format!("step {}: {e} refused: {why}", step + 1));
                refused.push((*e, why));
                continue;
            }
            let g = gap(&s, &real_stats);
            threshold = cfg.min_gain * gap_before;
            let gain = gap_before - g;
            // The gain once more with the models' other random draws: a
            // gain that is the draw's luck does not repeat. (Half the draw
            // floor was the bar before; the floor is mostly the per-row
            // residual tails, which jump between draws however right the
            // model, and it kept out effects whose gain repeats.)
            let redrawn = if gain > threshold {
                let other = other_draws(cfg.seed);
                let before = *model_redrawn.get_or_insert_with(|| gap(&measure(&model, &sets.sim, paired, other).1, &real_stats));
                let again = before - gap(&measure(&trial, &sets.sim, paired, other).1, &real_stats);
                if again <= threshold {
                    log(format!(
                        "step {}: {e} not added: it removes {gain:.3} of the gap, but {again:.3} with other random draws (the draws' luck, not an effect)",
                        step + 1
                    ));
                }
                again > threshold
            } else {
                false
            };
            if !redrawn {
                continue;
            }
            let after_halves = half_stats(&out);
            let on_halves: Vec<f64> =
                half_gaps(&current_halves).iter().zip(half_gaps(&after_halves)).map(|(before, after)| before - after).collect();
            let halves_decide = !paired || *below_floor_now.get_or_insert_with(|| gap_before < floor_of(&model));
            if !halves_decide || on_halves.iter().all(|&x| x > 0.0) {
                added = Some((*e, trial, g, s, after_halves));
                break;
            }
            let why = format!(
                "it removes {gain:.3} of the gap, but {} on the two halves (sim half against real half): not on both (sampling, not an effect)",
                on_halves.iter().map(|x| format!("{x:.3}")).collect::<Vec<_>>().join(" and ")
            );
            log(format!("step {}: {e} not added: {why}", step + 1));
        }
        let Some((effect, trial, gap_after, after_stats, after_halves)) = added else {
            stop = match ranking.first() {
                Some((e, r, _)) => format!(
                    "nothing explains the rest: the best candidate, {e}, removes {:.1}% of the gap {gap_before:.3} on the fitting subsample (needed on all data: more than {:.3}, {:.0}% of the gap, with the model's random draws and with others{})",
                    100.0 * r, threshold, 100.0 * cfg.min_gain,
                    if paired { "" } else { ", and a gain on each half of real" }
                ),
                None => "no candidate could be fitted".into(),
            };
            log(stop.clone());
            break;
        };
        let (at_edge, widened) = flags.iter().find(|f| f.0 == effect).map(|f| (f.1.clone(), f.2.clone())).unwrap_or_default();
        // Close rivals further down the ranking (those above it were tried
        // and did not hold up), on all records and on the halves.
        let named_share = ranking.iter().find(|r| r.0 == effect).map_or(0.0, |r| r.1);
        let past_named = ranking.iter().skip_while(|r| r.0 != effect).skip(1);
        let mut tied_with = Vec::new();
        for (rival, share, _) in past_named.filter(|r| r.1 > 0.0 && r.1 >= RIVAL_SHARE * named_share).take(MAX_RIVALS) {
            let (out, s) = measure(&model.with(*rival), &sets.sim, paired, cfg.seed);
            if distribution::hides_too_much(&s, &real_stats).is_some() {
                continue;
            }
            let (before_h, named_h, rival_h) = (half_gaps(&current_halves), half_gaps(&after_halves), half_gaps(&half_stats(&out)));
            let g = gap(&s, &real_stats);
            let gain = gap_before - g;
            if gain < RIVAL_SHARE * (gap_before - gap_after) {
                log(format!(
                    "step {}: {effect} removes {:.3} of the gap on all records, {rival} {gain:.3}: no rival",
                    step + 1,
                    gap_before - gap_after
                ));
                continue;
            }
            if named_ahead(gap_after, &named_h, g, &rival_h) {
                log(format!(
                    "step {}: {effect} is ahead of {rival} ({:.1}% on the subsample) on all records and on both halves",
                    step + 1,
                    100.0 * share
                ));
                continue;
            }
            // Not ordered, but two parts of the gap of a like size are no
            // tie: the rival must explain the part the named effect does.
            let on_top = gap_after - gap(&measure(&trial.with(*rival), &sets.sim, paired, cfg.seed).1, &real_stats);
            if on_top >= SAME_PART * gain {
                log(format!(
                    "step {}: {effect} and {rival} are not ordered by the data, but explain different parts of the gap ({rival} removes {gain:.3} alone, {on_top:.3} on top)",
                    step + 1
                ));
                continue;
            }
            log(format!(
                "step {}: {effect} and {rival} are not ordered by the data, and {rival} on top removes {on_top:.3} against {gain:.3} alone: tied, unless a later step names it",
                step + 1
            ));
            let gains = |h: &[f64]| before_h.iter().zip(h).map(|(b, a)| b - a).collect::<Vec<f64>>();
            tied_with.push(Tie {
                effect: *rival,
                gain,
                gain_on_top: on_top,
                gains_halves: gains(&rival_h),
                named_gains_halves: gains(&named_h),
            });
        }
        let mut ev = evidence::evidence(&effect, &before_stats, &after_stats, &real_stats, gap_before, gap_after);
        if !at_edge.is_empty() {
            let w = if widened.is_empty() { String::new() } else { format!(" (widened: {})", widened.join(", ")) };
            ev.push_str(&format!(
                "; WARNING: {} at the edge of its search box{w}: {} is only the closest effect of the vocabulary, not the right one",
                at_edge.join(", "),
                effect.name()
            ));
            log(format!("step {}: WARNING: {effect} is at the edge of its box in {}", step + 1, at_edge.join(", ")));
        }
        log(format!("step {}: added {effect}: gap {gap_before:.3} -> {gap_after:.3}; {ev}", step + 1));
        steps.push(Step {
            effect,
            gap_before,
            gap_after,
            evidence: ev,
            ranking: ranking.iter().map(|(e, r, _)| (*e, *r)).collect(),
            at_edge,
            widened,
            refused,
            tied_with,
        });
        model = trial;
        current = (gap_after, after_stats);
        current_halves = after_halves;
    }
    // A rival a later step names (re-fitted with the named effect in place)
    // explains a part of its own: both are in the model, and the step is
    // no choice between them.
    for k in 0..steps.len() {
        let later: Vec<&str> = steps[k + 1..].iter().map(|st| st.effect.name()).collect();
        let st = &mut steps[k];
        st.tied_with.retain(|t| !later.contains(&t.effect.name()));
        for t in &st.tied_with {
            let sentence = tie_sentence(&st.effect, st.gap_before - st.gap_after, t);
            log(format!("step {}: {sentence}", k + 1));
            st.evidence.push_str(&format!("; {sentence}"));
        }
    }
    // Polish: the greedy order can leave an early effect covering for one
    // named later (an occlusion fitted before startup hides rows startup
    // explains better). Re-fit each effect once with all others in place;
    // keep the new parameters when they lower the gap on all data.
    let mut refits = Vec::new();
    if model.effects.len() >= 2 {
        let moved = moved_real(&model, &current.1);
        let target =
            fit::Target { sim: &fit_sim, times: fit_times.as_deref(), paired, real: moved.as_ref().unwrap_or(&fit_real), seed: cfg.seed };
        for i in 0..model.effects.len() {
            let old = model.effects[i];
            let mut base = model.clone();
            base.effects.remove(i);
            let Some(f) = fit::fit(old.name(), &base, &target) else { continue };
            if f.effect == old {
                continue;
            }
            let trial = base.with(f.effect);
            let (_, s) = measure(&trial, &sets.sim, paired, cfg.seed);
            let g = gap(&s, &real_stats);
            if distribution::hides_too_much(&s, &real_stats).is_none() && g < current.0 {
                let edge = if f.at_edge.is_empty() {
                    String::new()
                } else {
                    format!(" (WARNING: at the edge of its box in {})", f.at_edge.join(", "))
                };
                log(format!("re-fitted {old} with the others in place: {}{edge}; gap {:.3} -> {g:.3}", f.effect, current.0));
                refits.push(Refit { before: old, after: f.effect, gap_before: current.0, gap_after: g, at_edge: f.at_edge });
                model = trial;
                current = (g, s);
            }
        }
    }
    let (gap_final, final_stats) = current;
    // The parameters were searched with the seed's draws and each step
    // checked with `other_draws`: where the effects are random (holes,
    // blobs), the gap on those draws includes the luck the search found.
    let gap_final_unseen = gap(&measure(&model, &sets.sim, paired, unseen_draws(cfg.seed)).1, &real_stats);
    let sim_stats = measure(&SensorModel::default(), &sets.sim, paired, cfg.seed).1;
    let eq71 = paired.then(|| {
        let mean = |m: &SensorModel| {
            let (out, _) = measure(m, &sets.sim, true, cfg.seed);
            out.iter().zip(&sets.real).map(|(p, y)| metric::dem_error(y, p)).sum::<f64>() / out.len() as f64
        };
        [mean(&SensorModel::default()), mean(&cfg.start), mean(&model)]
    });
    let terrains = per_terrain(sets, &cfg.start, &model, cfg.seed);
    // The final model's two draws, once: the draw floor (as `draw_floor`
    // takes it) and what the model leaves unexplained, where.
    let [(out_a, stats_a), (out_b, stats_b)] = two_draws(&model, &sets.sim, times, paired, cfg.seed);
    let floor = if model == cfg.start { floor_initial } else { split_floor.max(gap(&stats_a, &stats_b)) };
    drop((stats_a, stats_b));
    let real_h = (!paired && sets.real.len() >= 100).then(|| real_halves(sets));
    let both_terrains = match (&sets.sim_terrain, &sets.real_terrain) {
        (Some(s), Some(r)) => Some((&s[..], &r[..])),
        _ => None,
    };
    let unexplained = unexplained::analyse(&unexplained::Inputs {
        out_a: &out_a,
        out_b: &out_b,
        sim: &sets.sim,
        real: &sets.real,
        paired,
        terrains: both_terrains,
        halves: real_h.as_ref(),
        gap: gap_final,
        floor,
        gap_initial,
        steps: steps.iter().map(|s| (s.effect.name().to_string(), s.gap_before, s.gap_after)).collect(),
    });
    drop(out_b);
    log(unexplained.summary());
    let missing_bands = unexplained::missing_bands(&sets.sim, &out_a, &sets.real, both_terrains, sets.sim_time.is_some());
    drop(out_a);
    let more_data = unexplained::more_data(sets, &cfg.start, gap_initial, floor_initial, cfg.seed);
    let record_kinds = mix::record_kinds(&sets.sim, &sets.real);
    if record_kinds.differs() {
        log(format!("warning: {}", record_kinds.sentence()));
    }
    if let Some(m) = &more_data {
        log(m.sentence(sets.real.len(), sets.sim.len()));
    }
    Outcome {
        steps,
        gap_initial,
        gap_final,
        gap_final_unseen,
        model,
        floor,
        floor_initial,
        stop,
        paired,
        sizes: (sets.sim.len(), sets.real.len()),
        stats: [sim_stats, start_stats, final_stats, real_stats],
        eq71,
        terrains,
        refits,
        terrain_mix: sets.terrain_mix,
        over_pairs: sets.over_pairs,
        unexplained,
        more_data,
        missing_bands,
        record_kinds,
    }
}

/// Share of the gap `before` that `after` removes (0 when there was none).
pub fn share_removed(before: f64, after: f64) -> f64 {
    if before > 0.0 {
        1.0 - after / before
    } else {
        0.0
    }
}

/// The words for a tie: `named` removed `gain` of the gap on all records.
pub fn tie_sentence(named: &Effect, gain: f64, t: &Tie) -> String {
    let halves = |h: &[f64]| h.iter().map(|x| format!("{x:.3}")).collect::<Vec<_>>().join(" and ");
    let on_halves = if t.gains_halves.is_empty() {
        String::new()
    } else {
        format!(", on the two halves of the records {} against {}", halves(&t.named_gains_halves), halves(&t.gains_halves))
    };
    format!(
        "TIED with {}: the data does not order the two ({} removes {gain:.3} of the gap, {} {:.3}{on_halves}) and they explain the same part \
         of it ({} added on top {}): the step names one of two effects that leave the same trace here, not the one",
        t.effect,
        named.name(),
        t.effect.name(),
        t.gain,
        t.effect.name(),
        if t.gain_on_top > -5e-4 { format!("removes only {:.3} more", t.gain_on_top.max(0.0)) } else { format!("widens the gap by {:.3}", -t.gain_on_top) }
    )
}

/// What a gap below the sampling floor means, in one sentence (the log's
/// first line and report.md say it).
pub fn below_floor(gap: f64, floor: f64) -> String {
    format!(
        "the gap is below the sampling floor ({:.0}% of it): a perfect model's own random draws or, unpaired, two halves of real \
         differ as much, so what separates the sets may be sampling; an effect is named only where it also helps on other draws \
         and on both halves, and more records (runs) lower the floor",
        100.0 * gap / floor
    )
}

/// The gap a perfect model would still show from its own random draws:
/// model(sim) with the run's seed against model(sim) with another seed.
pub fn draw_floor(model: &SensorModel, sim: &[Dem], times: Option<&[f64]>, paired: bool, seed: u64) -> f64 {
    let [(_, a), (_, b)] = two_draws(model, sim, times, paired, seed);
    gap(&a, &b)
}

/// model(sim) and its statistics with the draws of `seed` and of
/// [`other_draws`]: the two outputs [`draw_floor`] compares.
pub fn two_draws(model: &SensorModel, sim: &[Dem], times: Option<&[f64]>, paired: bool, seed: u64) -> [(Vec<Dem>, Stats); 2] {
    [measure_at(model, sim, times, paired, seed), measure_at(model, sim, times, paired, other_draws(seed))]
}

/// The seed of a model's second set of random draws: the draw floor and
/// the check that an effect's gain repeats both use it.
fn other_draws(seed: u64) -> u64 {
    dem_core::seeded::mix(seed ^ 0xf100_f100)
}

/// Seed of draws that neither the fits nor the checks use: the final
/// model's gap on them is the one a user gets applying it with a new seed.
fn unseen_draws(seed: u64) -> u64 {
    dem_core::seeded::mix(seed ^ 0x0b5e_57ed)
}

/// Records per block of [`real_halves`]: neighbouring frames of a run
/// look alike, so they go to the same half.
const HALF_BLOCK: usize = 50;

/// Fewest real runs for halves of whole runs: with fewer, one run more or
/// less in a half is most of its difference, and blocks are dealt instead.
pub const MIN_RUNS_FOR_HALVES: usize = 8;

/// Two halves of the real records, for the sampling checks ([`halves`]).
pub fn real_halves(sets: &Sets) -> [Vec<usize>; 2] {
    halves(sets.real.len(), sets.real_runs.as_deref(), sets.real_terrain.as_deref())
}

/// Two halves of the sim records, dealt as [`real_halves`] deals real's,
/// so that sim half k against real half k is the comparison again at half
/// the size. Over pairs, sim record i is real record i's pair, and the
/// halves are real's.
pub fn sim_halves(sets: &Sets) -> [Vec<usize>; 2] {
    if sets.over_pairs {
        return real_halves(sets);
    }
    halves(sets.sim.len(), sets.sim_runs.as_deref(), sets.sim_terrain.as_deref())
}

/// Two halves of `n` records. The units
/// dealt are whole runs when the labels give each record's run
/// (`sequence`) and there are at least `MIN_RUNS_FOR_HALVES` (8) runs, else
/// blocks of consecutive records, so that neighbouring
/// frames of a run stay together: a run's first frames (the startup rows)
/// then go with the rest of it, not into one half. With terrain labels the
/// units are dealt per terrain (a run by the terrain of most of its
/// records), each to the half with fewer records of that terrain so far,
/// so both halves have the set's terrain mix: halves of 10 runs each differ
/// in stairs and pallets by chance, and an effect that only shows at steps
/// then "gains on one half and loses on the other" for that reason alone.
/// The deal is deterministic, so two sets with the same runs and terrains
/// in the same order (a sim and a real recording of the same poses) are
/// split alike.
pub fn halves(n: usize, runs: Option<&[u64]>, terrain: Option<&[Terrain]>) -> [Vec<usize>; 2] {
    halves_of_runs(n, runs, terrain, MIN_RUNS_FOR_HALVES)
}

/// [`halves`], dealing whole runs from `min_runs` runs on (the sampling
/// floor at half the size deals a half's runs as the whole set's were).
pub fn halves_of_runs(n: usize, runs: Option<&[u64]>, terrain: Option<&[Terrain]>, min_runs: usize) -> [Vec<usize>; 2] {
    let blocks = |idx: Vec<usize>| idx.chunks(HALF_BLOCK).map(<[usize]>::to_vec).collect::<Vec<_>>();
    // Runs in order of first appearance.
    let mut by_run: Vec<(u64, Vec<usize>)> = Vec::new();
    for (i, &r) in runs.iter().copied().flatten().enumerate() {
        match by_run.iter_mut().find(|(k, _)| *k == r) {
            Some((_, v)) => v.push(i),
            None => by_run.push((r, vec![i])),
        }
    }
    let units: Vec<Vec<usize>> = if by_run.len() >= min_runs.max(2) {
        by_run.into_iter().map(|(_, v)| v).collect()
    } else {
        // Blocks within each terrain's records, so a block has one terrain.
        match terrain {
            Some(t) => Terrain::ALL.iter().flat_map(|&k| blocks((0..n).filter(|&i| t[i] == k).collect())).collect(),
            None => blocks((0..n).collect()),
        }
    };
    let terrain_of = |u: &[usize]| -> usize {
        let Some(t) = terrain else { return 0 };
        let count = |k: Terrain| u.iter().filter(|&&i| t[i] == k).count();
        (0..Terrain::ALL.len()).max_by_key(|&j| (count(Terrain::ALL[j]), usize::MAX - j)).unwrap_or(0)
    };
    let mut halves = [Vec::new(), Vec::new()];
    let mut count = vec![[0usize; 2]; Terrain::ALL.len()];
    for u in units {
        let c = &mut count[terrain_of(&u)];
        let h = usize::from(c[1] < c[0]);
        c[h] += u.len();
        halves[h].extend(u);
    }
    halves.iter_mut().for_each(|h| h.sort_unstable());
    halves
}

/// The gap two halves of real show from sampling alone ([`real_halves`]),
/// scaled to the sizes compared: var of a difference of means goes as
/// 1/n_a + 1/n_b, so floor = split gap x (1/n_sim + 1/n_real) / (4/n_real).
pub fn noise_floor(sets: &Sets) -> f64 {
    let n = sets.real.len();
    if n < 100 {
        return 0.0;
    }
    let [a, b] = real_halves(sets);
    let side = |idx: &[usize]| {
        let r = pick(&sets.real, idx);
        if sets.paired {
            distribution::stats(&r, Some(&pick(&sets.sim, idx)))
        } else {
            distribution::stats(&r, None)
        }
    };
    let split = gap(&side(&a), &side(&b));
    split * (1.0 / sets.sim.len() as f64 + 1.0 / n as f64) / (4.0 / n as f64)
}

fn per_terrain(sets: &Sets, start: &SensorModel, model: &SensorModel, seed: u64) -> Vec<TerrainRow> {
    let (Some(ts), Some(tr)) = (&sets.sim_terrain, &sets.real_terrain) else { return vec![] };
    let mut rows = Vec::new();
    for t in Terrain::ALL {
        let si: Vec<usize> = (0..ts.len()).filter(|&i| ts[i] == t).collect();
        let ri: Vec<usize> = (0..tr.len()).filter(|&i| tr[i] == t).collect();
        if si.len() < 10 || ri.len() < 10 {
            continue;
        }
        let sim = pick(&sets.sim, &si);
        let real = pick(&sets.real, &ri);
        let times = sets.sim_time.as_ref().map(|t| pick(t, &si));
        let rs = distribution::stats(&real, sets.paired.then_some(&sim[..]));
        let (_, s0) = measure_at(start, &sim, times.as_deref(), sets.paired, seed);
        let (_, s1) = measure_at(model, &sim, times.as_deref(), sets.paired, seed);
        let (_, sr) = measure(&SensorModel::default(), &sim, sets.paired, seed);
        let three = |name: &str, n: usize| [&sr, &s1, &rs].map(|s| s.mean_over(name, 0..n));
        rows.push(TerrainRow {
            terrain: t,
            records: ri.len(),
            missing: three("missing", 20),
            height: three("height", 20),
            spread: three("spread-sd", 20),
            edges: three("edge-2cm", 19),
            gap: [gap(&s0, &rs), gap(&s1, &rs)],
        });
    }
    rows
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::format::{empty_dem, DemCells};

    /// The point: the gap compares distributions, so sim with the
    /// right noise (other draws) beats noise-free sim, while the paired
    /// equation 7.1 error prefers the noise-free one.
    #[test]
    fn the_right_noise_lowers_the_gap_but_raises_equation_7_1() {
        let sim: Vec<Dem> = (0..400)
            .map(|i| {
                let mut d = empty_dem();
                for r in 0..20 {
                    for c in 0..5 {
                        d.set_valid(r, c, if r > 8 + i % 7 { 0.1 } else { -0.07 });
                    }
                }
                d
            })
            .collect();
        let noise = SensorModel { effects: vec![Effect::Noise { sigma0: 0.004, k: 0.01 }] };
        let (real, _) = measure(&noise, &sim, true, 1);
        for paired in [true, false] {
            let rs = distribution::stats(&real, paired.then_some(&sim[..]));
            let (plain, s0) = measure(&SensorModel::default(), &sim, paired, 2);
            let (model, s1) = measure(&noise, &sim, paired, 2);
            assert!(gap(&s1, &rs) < 0.05 * gap(&s0, &rs), "paired {paired}: {} vs {}", gap(&s1, &rs), gap(&s0, &rs));
            let e = |p: &[Dem]| p.iter().zip(&real).map(|(p, y)| metric::dem_error(y, p)).sum::<f64>();
            assert!(e(&model) > e(&plain));
        }
    }

    /// The halves deal whole runs, per terrain, each half getting its share
    /// of every terrain; two sets with the same runs and terrains (a sim
    /// and a real recording of the same poses) are split alike, and a sim
    /// side without runs falls back to blocks.
    #[test]
    fn halves_deal_whole_runs_per_terrain_and_split_like_sets_alike() {
        use Terrain::{Flat, StairsUp};
        // 12 runs of 30 records: runs 0-3 stairs, the rest flat.
        let runs: Vec<u64> = (0..360).map(|i| i / 30).collect();
        let terrain: Vec<Terrain> = runs.iter().map(|&r| if r < 4 { StairsUp } else { Flat }).collect();
        let [a, b] = halves(360, Some(&runs), Some(&terrain));
        assert_eq!((a.len(), b.len()), (180, 180));
        for h in [&a, &b] {
            assert!(h.iter().all(|&i| h.contains(&(i - i % 30))), "whole runs");
            assert_eq!(h.iter().filter(|&&i| terrain[i] == StairsUp).count(), 60, "half the stairs");
        }
        assert_eq!(halves(360, Some(&runs), Some(&terrain)), [a, b]);
        // Too few runs: blocks of HALF_BLOCK consecutive records.
        let few: Vec<u64> = (0..360).map(|i| i / 120).collect();
        let [a, b] = halves(360, Some(&few), None);
        assert_eq!((a[..HALF_BLOCK].to_vec(), b[..HALF_BLOCK].to_vec()), ((0..50).collect(), (50..100).collect()));
    }

    /// The named effect is ahead of a rival only with a smaller gap on all
    /// records and on every half; equal gaps (two effects that give the
    /// same cells) are not ordered.
    #[test]
    fn a_rival_is_ordered_behind_only_on_all_records_and_every_half() {
        assert!(named_ahead(1.0, &[0.4, 0.6], 1.2, &[0.5, 0.7]));
        assert!(!named_ahead(1.0, &[0.4, 0.6], 1.2, &[0.5, 0.5]), "behind on one half");
        assert!(!named_ahead(1.0, &[0.4, 0.6], 0.9, &[0.5, 0.7]), "behind on all records");
        assert!(!named_ahead(0.0, &[0.0, 0.0], 0.0, &[0.0, 0.0]), "the same cells");
        assert!(named_ahead(1.0, &[], 1.1, &[]), "no halves: all records decide");
    }

    /// Equal mixes keep every record once; a sim set heavy in stairs is
    /// drawn to real's shares: a terrain real lacks is left out, one with
    /// too few sim records is taken whole and then repeated.
    #[test]
    fn sim_records_are_drawn_to_the_real_terrain_mix() {
        use Terrain::{Flat, Pallet, StairsUp};
        let real = [vec![Flat; 50], vec![StairsUp; 50]].concat();
        assert_eq!(terrain_mix(&real, &real, 1), (0..100).collect::<Vec<_>>());
        let sim = [vec![StairsUp; 120], vec![Flat; 10], vec![Pallet; 40], vec![StairsUp; 30]].concat();
        let keep = terrain_mix(&sim, &real, 1);
        assert_eq!(keep.len(), sim.len());
        assert!(keep.windows(2).all(|w| w[0] <= w[1]), "ascending");
        let distinct = |t: Terrain| {
            let mut k: Vec<usize> = keep.iter().copied().filter(|&i| sim[i] == t).collect();
            let n = k.len();
            k.dedup();
            (n, k.len())
        };
        assert_eq!(distinct(Flat), (100, 10));
        assert_eq!(distinct(StairsUp), (100, 100));
        assert_eq!(distinct(Pallet), (0, 0));
        assert_eq!(keep, terrain_mix(&sim, &real, 1), "by seed");
        assert_ne!(keep, terrain_mix(&sim, &real, 2));
        // No terrain in common: nothing to match, every record as it is.
        assert_eq!(terrain_mix(&[Pallet; 5], &real, 1), (0..5).collect::<Vec<_>>());
    }
}
