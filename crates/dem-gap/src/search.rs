//! The measure-name-add loop ([`crate::run`]), one function per step of it:
//! measure the start model; per step, fit and rank every effect not yet
//! in the model on the fitting subsample (`rank_candidates`), confirm the
//! best on all records, with other draws and on the halves
//! (`confirm_best`), check its close rivals ([`crate::ties`]) and add it;
//! then re-fit each effect with the others in place (`polish`). [`crate::run`]
//! chains them, with `joint` after them under `--joint-refit`,
//! and puts the [`crate::Outcome`] together ([`crate::outcome`]). What stays fixed over a
//! run (real's statistics, halves, fitting subsample) is measured once,
//! in [`crate::comparison`]; here is only what changes from step to step.

use dem_core::distribution::{self, gap, Stats};
use dem_sensor::effects::{EffectSpec, SPECS};
use dem_sensor::evidence::share_removed;
use dem_sensor::{Effect, SensorModel};

use crate::comparison::Comparison;
use crate::outcome::{Found, Refit, Start, Step, Tie};
use crate::sampling::{below_floor, other_draws};
use crate::state::{Added, Candidate, State, StepLog};
use crate::ties;
use crate::{evidence, fit};

/// A gap below this is left as it is: each statistic enters as
/// ln(1 + z^2) averaged over rows, so a sum this small means no statistic
/// differs from real by a fifth of its physical scale (0.4 % of cells,
/// 1 mm of height). An effect fitted to such a gap fits what is left of
/// the others' fits, not a physical effect.
pub const NEGLIGIBLE_GAP: f64 = 0.05;

/// What confirming a step's best candidates gave.
pub(crate) struct Confirmation {
    pub added: Option<Added>,
    /// Candidates whose model hides far more cells than real misses, or
    /// moves level records as a whole more than real's move, with the reason.
    pub refused: Vec<(Effect, String)>,
}

/// The start model as measured, said in the log's first line, and the
/// loop's state with it.
pub(crate) fn measure_start(c: &Comparison, log: &dyn Fn(String)) -> (Start, State) {
    let model = c.cfg.start.clone();
    let (start_out, stats) = c.measure(&model, c.cfg.seed);
    let halves = c.half_stats(&start_out);
    drop(start_out);
    let gap_initial = gap(&stats, &c.real);
    let floor_initial = c.floor_of(&model);
    log(format!(
        "{} mode, {} vs {} records; start model: {}; gap {gap_initial:.3} (sampling floor {floor_initial:.3}){}",
        if c.paired { "paired" } else { "unpaired" },
        c.sets.sim.len(),
        c.sets.real.len(),
        model.summary(),
        if gap_initial < floor_initial { format!("; {}", below_floor(gap_initial, floor_initial)) } else { String::new() }
    ));
    if let Some(why) = c.whole_record_left_out() {
        log(format!(
            "{why}: the effects that move whole records ({}) are left out (--whole-record-effects fits them)",
            whole_record_names()
        ));
    }
    let start = Start { gap: gap_initial, floor: floor_initial, stats: stats.clone() };
    (start, State { model, gap: gap_initial, stats, halves })
}

/// Add effects to the model in `state`, one a step, while one holds up
/// and the gap left is not negligible.
pub(crate) fn name_effects(c: &Comparison, mut state: State, log: &dyn Fn(String), tick: &dyn Fn()) -> Found {
    let mut steps = Vec::new();
    let mut stop = format!("stopped after --max-steps {}", c.cfg.max_steps);
    let mut short = Vec::new();
    let mut refits = Vec::new();
    for number in 1..=c.cfg.max_steps {
        // A candidate refused for moving level records is fitted again
        // in the next step: on top of the effect added meanwhile it fits
        // what that effect left (a tilt fitted before `noise` takes the
        // across-robot spread for a roll).
        let candidates = not_in(c, &state.model);
        if candidates.is_empty() {
            stop = "every effect of the vocabulary is in the model".into();
            break;
        }
        if state.gap < NEGLIGIBLE_GAP {
            stop = format!(
                "the gap left, {:.4}, is below {NEGLIGIBLE_GAP}: no statistic differs by a fifth of its scale, so no effect is added for it",
                state.gap
            );
            break;
        }
        let step_log = StepLog { number, log };
        // Below the sampling floor, what is left may be the misfit of the
        // effects named so far (each fitted before the next was there),
        // and a later effect would be named for it: on occlusion and noise
        // made by the vocabulary's own formulas, `noise` fitted before
        // `occlusion` left a spread that `tilt` then took. So the named
        // effects are re-fitted with each other in place first.
        if state.model.effects.len() > 1 && c.below_floor(&state.model, state.gap) {
            let done = refits.len();
            refits.extend(polish(c, &mut state.model, &mut state.gap, &mut state.stats, &|line| step_log.line(line)));
            if refits.len() > done {
                state.halves = c.half_stats(&c.measure(&state.model, c.cfg.seed).0);
            }
        }
        let ranking = rank_candidates(c, &state, &candidates, &step_log, tick);
        let trials = ranking.iter().map(|r| (r.fit.effect, state.model.with(r.fit.effect), r.share));
        let Confirmation { added, refused } = confirm_best(c, &state, trials, &step_log);
        let Some(added) = added else {
            stop = nothing_holds(c.cfg.min_gain, c.paired, &ranking, state.gap, &refused);
            log(stop.clone());
            short = ranking.into_iter().filter(|r| !refused.iter().any(|(e, _)| e.name() == r.fit.effect.name())).collect();
            break;
        };
        let tied_with = ties::check_rivals(c, &state, &added, &ranking, &step_log);
        steps.push(record_step(c, &state, &added, &ranking, refused, tied_with, &step_log));
        state = added.state;
    }
    Found { steps, stop, model: state.model, gap: state.gap, stats: state.stats, short, refits }
}

/// The names of the effects that move whole records, comma-separated.
pub(crate) fn whole_record_names() -> String {
    SPECS.iter().filter(|s| s.whole_record).map(|s| s.name).collect::<Vec<_>>().join(", ")
}

/// The effects of the vocabulary not yet in `model` that this comparison
/// may fit ([`Comparison::fits`]), in the vocabulary's order.
pub(crate) fn not_in(c: &Comparison, model: &SensorModel) -> Vec<&'static EffectSpec> {
    SPECS.iter().copied().filter(|s| c.fits(s) && !model.effects.iter().any(|e| e.name() == s.name)).collect()
}

/// Fit each of `candidates` on top of the model on the fitting subsample;
/// the fitted ones ranked by the gap they leave there, best first.
pub(crate) fn rank_candidates(c: &Comparison, state: &State, candidates: &[&EffectSpec], log: &StepLog, tick: &dyn Fn()) -> Vec<Candidate> {
    let real = c.fitting_real(&state.model, &state.stats);
    let target = c.target(&real);
    let base_fit = target.gap(&state.model);
    let mut ranking = Vec::new();
    for spec in candidates {
        if let Some(f) = fit::fit(spec, &state.model, &target) {
            let share = share_removed(base_fit, f.gap);
            let edge = if f.at_edge.is_empty() { String::new() } else { format!(" [AT THE EDGE of its box: {}]", f.at_edge.join(", ")) };
            log.line(format!("candidate {} removes {:.1}% of the gap on the fitting subsample{edge}", f.effect, 100.0 * share));
            ranking.push(Candidate { fit: f, share });
        } else {
            log.line(format!("candidate {}: no fit that does not hide far more cells than real misses", spec.name));
        }
        tick();
    }
    ranking.sort_by(|a, b| a.fit.gap.total_cmp(&b.fit.gap));
    ranking
}

/// The first of `trials` (a candidate, the model with it and the share of
/// the gap it removed on the fitting subsample, best first) that holds up
/// on all data. The best two always get their chance; after them, every
/// candidate whose share on the fitting subsample exceeds `min_gain`
/// does too, so a third effect the data shows is not lost behind two
/// that fit the sampling (a candidate refused for moving level records
/// as a whole does not count among the two). A gain must exceed `min_gain` of the gap with the model's
/// draws and again with other draws, where the halves decide, hold on
/// both halves, and below the sampling floor, re-fitted on either half,
/// on the other ([`crate::held_out`]).
pub(crate) fn confirm_best(
    c: &Comparison,
    state: &State,
    trials: impl Iterator<Item = (Effect, SensorModel, f64)>,
    log: &StepLog,
) -> Confirmation {
    let seed = c.cfg.seed;
    let mut refused = Vec::new();
    let threshold = c.cfg.min_gain * state.gap;
    // The model's own gap with other draws, measured once for all
    // candidates that may need it.
    let mut model_redrawn: Option<f64> = None;
    // Paired, the halves decide only below the model's sampling floor
    // (measured once, when a candidate gets that far): there what
    // separates the sets may be the draws, and a gain that is an effect
    // holds on both halves of the records. Below the floor the gain must
    // also hold out.
    let mut below_floor_now: Option<bool> = None;
    // The model's statistics on each half for the held-out check, measured
    // once for all candidates.
    let mut held_out_base: Option<Vec<Stats>> = None;
    let mut tried = 0;
    for (e, trial, share) in trials {
        if tried >= 2 && share <= c.cfg.min_gain {
            continue;
        }
        let (out, s) = c.measure(&trial, seed);
        // A record-wide move shows, paired, in the planes of the pairs'
        // residuals; unpaired, on level records, where no terrain stands
        // in for it.
        let planes = |c: &Comparison| {
            let of = if c.paired { crate::mix::LevelPlanes::of_residuals } else { crate::mix::LevelPlanes::of };
            of(&c.sets.sim, &out, &c.sets.real)
        };
        if let Some(why) = e.spec().whole_record.then(|| planes(c)).flatten().and_then(|l| l.too_wide()) {
            log.line(format!("{e} refused: {why}"));
            refused.push((e, why));
            continue;
        }
        tried += 1;
        if let Some(why) = distribution::hides_too_much(&s, &c.real) {
            log.line(format!("{e} refused: {why}"));
            refused.push((e, why));
            continue;
        }
        let g = gap(&s, &c.real);
        let gain = state.gap - g;
        // The gain once more with the models' other random draws: a
        // gain that is the draw's luck does not repeat. (Half the draw
        // floor was the bar before; the floor is mostly the per-row
        // residual tails, which jump between draws however right the
        // model, and it kept out effects whose gain repeats.)
        let redrawn = if gain > threshold {
            let other = other_draws(seed);
            let before = *model_redrawn.get_or_insert_with(|| c.gap_with(&state.model, other));
            let again = before - c.gap_with(&trial, other);
            if again <= threshold {
                log.line(format!(
                    "{e} not added: it removes {gain:.3} of the gap, but {again:.3} with other random draws (the draws' luck, not an effect)"
                ));
            }
            again > threshold
        } else {
            false
        };
        if !redrawn {
            continue;
        }
        let halves = c.half_stats(&out);
        let on_halves: Vec<f64> =
            c.half_gaps(&state.halves).iter().zip(c.half_gaps(&halves)).map(|(before, after)| before - after).collect();
        let below_floor = *below_floor_now.get_or_insert_with(|| c.below_floor(&state.model, state.gap));
        let halves_decide = !c.paired || below_floor;
        if halves_decide && !on_halves.iter().all(|&x| x > 0.0) {
            log.line(format!(
                "{e} not added: it removes {gain:.3} of the gap, but {} on the two halves (sim half against real half): not on both (sampling, not an effect)",
                both(&on_halves)
            ));
            continue;
        }
        if below_floor {
            let base = held_out_base.get_or_insert_with(|| c.held_out().base(&state.model));
            let held = c.held_out().shares(e.spec(), &state.model, base);
            let percent = held.iter().map(|x| format!("{:.1}%", 100.0 * x)).collect::<Vec<_>>().join(" and ");
            if held.iter().any(|&x| x <= c.cfg.min_gain) {
                log.line(format!(
                    "{e} not added: re-fitted on either half, it removes {percent} of the other half's gap (held out; needed: more than {:.0}%): it fits the records' sampling, not an effect",
                    100.0 * c.cfg.min_gain
                ));
                continue;
            }
            if !held.is_empty() {
                log.line(format!("{e} holds out: re-fitted on either half, it removes {percent} of the other half's gap"));
            }
        }
        let added = Added { effect: e, state: State { model: trial, gap: g, stats: s, halves } };
        return Confirmation { added: Some(added), refused };
    }
    Confirmation { added: None, refused }
}

/// Two gains, as the log gives them.
fn both(gains: &[f64]) -> String {
    gains.iter().map(|x| format!("{x:.3}")).collect::<Vec<_>>().join(" and ")
}

/// Why the loop stops when no candidate of a step holds up.
fn nothing_holds(min_gain: f64, paired: bool, ranking: &[Candidate], gap_before: f64, refused: &[(Effect, String)]) -> String {
    let Some(best) = ranking.first() else { return "no candidate could be fitted".into() };
    let refusals = if refused.is_empty() {
        String::new()
    } else {
        let names: Vec<&str> = refused.iter().map(|(e, _)| e.name()).collect();
        format!("; refused, as their models hide far more cells than real misses: {}", names.join(", "))
    };
    format!(
        "nothing explains the rest: the best candidate, {}, removes {:.1}% of the gap {gap_before:.3} on the fitting subsample (needed on all data: more than {:.3}, {:.0}% of the gap, with the model's random draws and with others{}){refusals}",
        best.fit.effect,
        100.0 * best.share,
        min_gain * gap_before,
        100.0 * min_gain,
        if paired { "" } else { ", and a gain on each half of real" }
    )
}

/// The step that adds `added` to `before`, with its evidence; a fit at
/// the edge of its box is warned of in both.
pub(crate) fn record_step(
    c: &Comparison,
    before: &State,
    added: &Added,
    ranking: &[Candidate],
    refused: Vec<(Effect, String)>,
    tied_with: Vec<Tie>,
    log: &StepLog,
) -> Step {
    let effect = added.effect;
    let (gap_before, gap_after) = (before.gap, added.state.gap);
    let (at_edge, widened) =
        ranking.iter().find(|r| r.fit.effect == effect).map(|r| (r.fit.at_edge.clone(), r.fit.widened.clone())).unwrap_or_default();
    let mut ev = evidence::evidence(&effect, &before.stats, &added.state.stats, &c.real, gap_before, gap_after);
    if !at_edge.is_empty() {
        let w = if widened.is_empty() { String::new() } else { format!(" (widened: {})", widened.join(", ")) };
        ev.push_str(&format!(
            "; WARNING: {} at the edge of its search box{w}: {} is only the closest effect of the vocabulary, not the right one",
            at_edge.join(", "),
            effect.name()
        ));
        log.line(format!("WARNING: {effect} is at the edge of its box in {}", at_edge.join(", ")));
    }
    log.line(format!("added {effect}: gap {gap_before:.3} -> {gap_after:.3}; {ev}"));
    Step {
        effect,
        gap_before,
        gap_after,
        evidence: ev,
        ranking: ranking.iter().map(|r| (r.fit.effect, r.share)).collect(),
        at_edge,
        widened,
        refused,
        tied_with,
    }
}

/// Polish: the greedy order can leave an early effect covering for one
/// named later (an occlusion fitted before startup hides rows startup
/// explains better). Re-fit each effect of `model` once with all others
/// in place; keep the new parameters when they lower the gap on all data
/// (`gap`, `stats`: the model's, updated with it).
pub(crate) fn polish(c: &Comparison, model: &mut SensorModel, gap_now: &mut f64, stats: &mut Stats, log: &dyn Fn(String)) -> Vec<Refit> {
    let mut refits = Vec::new();
    if model.effects.len() < 2 {
        return refits;
    }
    let real = c.fitting_real(model, stats);
    let target = c.target(&real);
    for i in 0..model.effects.len() {
        let old = model.effects[i];
        let mut base = model.clone();
        base.effects.remove(i);
        let Some(f) = fit::fit(old.spec(), &base, &target) else { continue };
        if f.effect == old {
            continue;
        }
        let trial = base.with(f.effect);
        let (_, s) = c.measure(&trial, c.cfg.seed);
        let g = gap(&s, &c.real);
        if distribution::hides_too_much(&s, &c.real).is_none() && g < *gap_now {
            let edge = if f.at_edge.is_empty() {
                String::new()
            } else {
                format!(" (WARNING: at the edge of its box in {})", f.at_edge.join(", "))
            };
            log(format!("re-fitted {old} with the others in place: {}{edge}; gap {:.3} -> {g:.3}", f.effect, *gap_now));
            refits.push(Refit { before: old, after: f.effect, gap_before: *gap_now, gap_after: g, at_edge: f.at_edge });
            *model = trial;
            *gap_now = g;
            *stats = s;
        }
    }
    refits
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_sensor::effects::Occlusion;

    /// The stop names the gain a candidate needed, also when every one
    /// tried was refused, and says which were refused.
    #[test]
    fn the_stop_names_the_gain_needed_and_the_refused() {
        let occlusion = Effect::Occlusion(Occlusion { h: 0.3, x0: 0.0 });
        let ranking = [Candidate { fit: fit::Fitted { effect: occlusion, gap: 1.5, at_edge: vec![], widened: vec![] }, share: 0.25 }];
        let refused = [(occlusion, "it hides too much".to_string())];
        let stop = nothing_holds(0.05, true, &ranking, 2.0, &refused);
        assert!(stop.contains("removes 25.0% of the gap 2.000"), "{stop}");
        assert!(stop.contains("more than 0.100, 5% of the gap"), "{stop}");
        assert!(stop.ends_with("refused, as their models hide far more cells than real misses: occlusion"), "{stop}");
        let stop = nothing_holds(0.05, false, &ranking, 2.0, &[]);
        assert!(stop.ends_with("and a gain on each half of real)"), "{stop}");
        assert_eq!(nothing_holds(0.05, true, &[], 2.0, &[]), "no candidate could be fitted");
    }
}
