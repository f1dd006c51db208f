//! What a run found ([`Outcome`]) and how it is put together once the
//! loop is done: the final model measured with draws no fit saw, its
//! sampling floor, what it leaves unexplained and where, per terrain and
//! against the start. [`crate::report`] writes it out.

use dem_core::distribution::{gap, Stats};
use dem_core::format::{Dem, Terrain, GRID_ROWS};
use dem_core::metric;
use dem_core::temporal::{change_rcorr, frame_stats, FrameStats};
use dem_sensor::{Effect, SensorModel};

use crate::comparison::Comparison;
use crate::load::{pick, Sets};
use crate::measurement::{measure_at, summarise};
use crate::sampling::{real_halves, two_draws, unseen_draws};
use crate::{mix, unexplained};

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
    /// real misses, or moves level records as a whole more than real's
    /// move, with the reason.
    pub refused: Vec<(Effect, String)>,
    /// Close rivals the data does not tell from the effect ([`Tie`]).
    pub tied_with: Vec<Tie>,
}

/// A candidate that came close to the named effect (on the fitting
/// subsample and on all records, [`crate::ties::RIVAL_SHARE`]), that the data does
/// not order behind it (the named effect
/// does not remove more of the gap than the rival on all records and on
/// each of two halves of them, [`crate::ties::named_ahead`]) and that explains the same
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
    /// as fitted alone): less than [`crate::ties::SAME_PART`] of `gain`.
    pub gain_on_top: f64,
    /// Gap it removes on each half of the records.
    pub gains_halves: Vec<f64>,
    /// Gap the named effect removes on each half.
    pub named_gains_halves: Vec<f64>,
}
/// The start model as measured, for the report's before and after.
pub(crate) struct Start {
    pub gap: f64,
    /// Its sampling floor ([`Comparison::floor_of`]).
    pub floor: f64,
    pub stats: Stats,
}
/// What the naming loop leaves: the steps, why it stopped, and the model
/// with its gap and statistics on all records (re-fits change these).
pub(crate) struct Found {
    pub steps: Vec<Step>,
    pub stop: String,
    pub model: SensorModel,
    pub gap: f64,
    pub stats: Stats,
    /// When no candidate held up: the candidates of that step (best
    /// first, the refused left out), for [`crate::joint`].
    pub(crate) short: Vec<crate::state::Candidate>,
    /// Effects re-fitted before a step below the sampling floor.
    pub refits: Vec<Refit>,
}
/// An effect re-fitted with all others in place: before a step below the
/// sampling floor, or after the naming loop.
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
    /// With the runs' steps: how consecutive frames move (over all rows;
    /// the correlation unpaired of the change with the next change): sim,
    /// model(sim), real.
    pub frames: Option<[FrameStats; 3]>,
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
    /// fit and no check saw (`unseen_draws`).
    pub gap_final_unseen: f64,
    /// The final model.
    pub model: SensorModel,
    /// Expected gap from sampling alone, of the final model.
    pub floor: f64,
    /// The same of the start model: a gap below it may be sampling
    /// ([`below_floor`](crate::below_floor)).
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

/// The outcome of a run that started at `start` and ended at `found`,
/// with the effects `refits` re-fitted.
pub(crate) fn finish(c: Comparison, start: Start, found: Found, refits: Vec<Refit>, log: &dyn Fn(String)) -> Outcome {
    let (cfg, sets) = (c.cfg, c.sets);
    let Found { steps, stop, mut model, gap: gap_final, stats: final_stats, .. } = found;
    // The parameters were searched with the seed's draws and each step
    // checked with `other_draws`: where the effects are random (holes,
    // blobs), the gap on those draws includes the luck the search found.
    let gap_final_unseen = c.gap_with(&model, unseen_draws(cfg.seed));
    let sim_stats = c.measure(&SensorModel::default(), cfg.seed).1;
    let eq71 = mean_eq71(&c, &model);
    let terrains = per_terrain(sets, &cfg.start, &model, cfg.seed);
    let left = leftover(&c, &model, gap_final, &start, &steps, log);
    let more_data = unexplained::more_data(sets, &cfg.start, start.gap, start.floor, cfg.seed);
    let record_kinds = mix::record_kinds(&sets.sim, &sets.real);
    if record_kinds.differs() {
        log(format!("warning: {}", record_kinds.sentence()));
    }
    if let Some(m) = &more_data {
        log(m.sentence(sets.real.len(), sets.sim.len()));
    }
    model.warnings = warnings(&c, &model, &steps, &refits, &record_kinds);
    Outcome {
        steps,
        gap_initial: start.gap,
        gap_final,
        gap_final_unseen,
        model,
        floor: left.floor,
        floor_initial: start.floor,
        stop,
        paired: c.paired,
        sizes: (sets.sim.len(), sets.real.len()),
        stats: [sim_stats, start.stats, final_stats, c.real],
        eq71,
        terrains,
        refits,
        terrain_mix: sets.terrain_mix,
        over_pairs: sets.over_pairs,
        unexplained: left.unexplained,
        more_data,
        missing_bands: left.missing_bands,
        record_kinds,
    }
}

/// Why the final `model` may not be the sensor's, one sentence each, for
/// its file's metadata: sets of different terrain, an effect that moves
/// whole records fitted where the mixes are not known to match, effects
/// whose fit (as named or re-fitted) ended at the edge of its box.
fn warnings(c: &Comparison, model: &SensorModel, steps: &[Step], refits: &[Refit], kinds: &mix::RecordKinds) -> Vec<String> {
    let mut w = Vec::new();
    if kinds.differs() {
        w.push(kinds.sentence());
    }
    if let Some(why) = c.sets.unmatched_mix.filter(|_| !c.paired) {
        let whole: Vec<&str> = model.effects.iter().filter(|e| e.spec().whole_record).map(|e| e.name()).collect();
        if !whole.is_empty() {
            w.push(format!(
                "{} move whole records and were fitted on sets whose terrain mixes are not known to match ({why})",
                whole.join(", ")
            ));
        }
    }
    // The model holds each effect as last re-fitted: a re-fit's edge, else
    // the step's.
    let edges: Vec<String> = model
        .effects
        .iter()
        .filter_map(|e| {
            let refit = refits.iter().rev().find(|r| r.after.name() == e.name()).map(|r| &r.at_edge);
            let at = refit.or_else(|| steps.iter().find(|s| s.effect.name() == e.name()).map(|s| &s.at_edge))?;
            (!at.is_empty()).then(|| format!("{} ({})", e.name(), at.join(", ")))
        })
        .collect();
    if !edges.is_empty() {
        w.push(format!(
            "fitted at the edge of the search box, widened to the physical limits: {}; such an effect is the closest of the vocabulary, not a measurement",
            edges.join(", ")
        ));
    }
    w
}

/// Mean paired equation 7.1 error of sim, the start model(sim) and
/// `model`(sim) against real; None unpaired.
fn mean_eq71(c: &Comparison, model: &SensorModel) -> Option<[f64; 3]> {
    c.paired.then(|| {
        let mean = |m: &SensorModel| {
            let (out, _) = c.measure(m, c.cfg.seed);
            out.iter().zip(&c.sets.real).map(|(p, y)| metric::dem_error(y, p)).sum::<f64>() / out.len() as f64
        };
        [mean(&SensorModel::default()), mean(&c.cfg.start), mean(model)]
    })
}

/// What the final model leaves, with the sampling floor it is read against.
struct Leftover {
    floor: f64,
    unexplained: unexplained::Unexplained,
    missing_bands: Vec<unexplained::BandRow>,
}

/// The final `model`'s floor and what it leaves unexplained, where; the
/// summary goes to the log.
fn leftover(c: &Comparison, model: &SensorModel, gap_final: f64, start: &Start, steps: &[Step], log: &dyn Fn(String)) -> Leftover {
    let (sets, paired) = (c.sets, c.paired);
    // The final model's two draws, once: the draw floor (as `draw_floor`
    // takes it) and what the model leaves unexplained, where.
    let [(out_a, stats_a), (out_b, stats_b)] = two_draws(model, &sets.sim, c.moments, c.steps, paired, c.cfg.seed);
    let floor = if *model == c.cfg.start { start.floor } else { c.split_floor.max(gap(&stats_a, &stats_b)) };
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
        gap_initial: start.gap,
        steps: steps.iter().map(|s| (s.effect.name().to_string(), s.gap_before, s.gap_after)).collect(),
        frames: sets.sim_steps.as_deref().zip(sets.real_steps.as_deref()),
    });
    drop(out_b);
    log(unexplained.summary());
    let missing_bands = unexplained::missing_bands(
        &sets.sim,
        &out_a,
        &sets.real,
        both_terrains,
        dem_sensor::any_time(sets.sim_moments.as_deref()),
        gap_final < floor,
    );
    Leftover { floor, unexplained, missing_bands }
}

/// The start and the final model against real on each terrain with at
/// least 10 records on both sides (both sides labelled).
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
        let moments = sets.sim_moments.as_ref().map(|t| pick(t, &si));
        let (sim_steps, real_steps) = (sets.sim_steps_in(&si), sets.real_steps_in(&ri));
        let (sim_steps, real_steps) = (sim_steps.as_deref(), real_steps.as_deref());
        let rs = summarise(&real, sets.paired.then_some(&sim[..]), real_steps);
        let (_, s0) = measure_at(start, &sim, moments.as_deref(), sim_steps, sets.paired, seed);
        let (out, s1) = measure_at(model, &sim, moments.as_deref(), sim_steps, sets.paired, seed);
        let (_, sr) = measure_at(&SensorModel::default(), &sim, None, sim_steps, sets.paired, seed);
        let three = |name: &str, n: usize| [&sr, &s1, &rs].map(|s| s.mean_over(name, 0..n));
        let frames = sim_steps.zip(real_steps).map(|(ss, rs_steps)| {
            let reference = sets.paired.then_some(&sim[..]);
            let of = |x: &[Dem], steps: &[dem_core::temporal::Step]| {
                let mut f = frame_stats(x, reference, steps, 0..GRID_ROWS);
                if reference.is_none() {
                    f.rcorr = change_rcorr(x, steps, 0..GRID_ROWS);
                }
                f
            };
            [of(&sim, ss), of(&out, ss), of(&real, rs_steps)]
        });
        rows.push(TerrainRow {
            terrain: t,
            records: ri.len(),
            missing: three("missing", 20),
            height: three("height", 20),
            spread: three("spread-sd", 20),
            edges: three("edge-2cm", 19),
            gap: [gap(&s0, &rs), gap(&s1, &rs)],
            frames,
        });
    }
    rows
}
