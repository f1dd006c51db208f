//! Close rivals of a named effect. Two effects of the vocabulary can leave
//! the same trace, and the data then does not say which one it is: a
//! step that names one of them says so ([`Tie`]) rather than claim the
//! one. The checks run after a step's effect is confirmed, on all records
//! and on the comparison's two halves; a rival a later step names is no
//! tie, which is settled once the loop is done.

use dem_core::distribution::{self, gap};
use dem_sensor::Effect;

use crate::comparison::Comparison;
use crate::outcome::{Step, Tie};
use crate::state::{Added, Candidate, State, StepLog};

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

/// True when the named effect leaves a smaller gap than the rival on all
/// records and on every half: the data orders the two. Gaps after each,
/// all records first, then per half (no halves: all records decide).
pub fn named_ahead(named: f64, named_halves: &[f64], rival: f64, rival_halves: &[f64]) -> bool {
    named < rival && named_halves.iter().zip(rival_halves).all(|(n, r)| n < r)
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

/// The rivals the step that adds `named` to `before` cannot tell from it,
/// of the candidates ranked below it (`ranking`, best first): those above
/// it were tried and did not hold up. At most [`MAX_RIVALS`], each close
/// to the named effect on the fitting subsample ([`RIVAL_SHARE`]).
pub(crate) fn check_rivals(c: &Comparison, before: &State, named: &Added, ranking: &[Candidate], log: &StepLog) -> Vec<Tie> {
    let effect = named.effect;
    let named_share = ranking.iter().find(|r| r.fit.effect == effect).map_or(0.0, |r| r.share);
    let past_named = ranking.iter().skip_while(|r| r.fit.effect != effect).skip(1);
    past_named
        .filter(|r| r.share > 0.0 && r.share >= RIVAL_SHARE * named_share)
        .take(MAX_RIVALS)
        .filter_map(|r| check_rival(c, before, named, r, log))
        .collect()
}

/// `rival` in place of `named`, on all records and on the halves: the tie
/// when the data does not order the two and they explain the same part
/// of the gap.
fn check_rival(c: &Comparison, before: &State, named: &Added, rival: &Candidate, log: &StepLog) -> Option<Tie> {
    let (effect, share, rival) = (named.effect, rival.share, rival.fit.effect);
    let (gap_before, gap_after) = (before.gap, named.state.gap);
    let (out, s) = c.measure(&before.model.with(rival), c.cfg.seed);
    if distribution::hides_too_much(&s, &c.real).is_some() {
        return None;
    }
    let (before_h, named_h, rival_h) = (c.half_gaps(&before.halves), c.half_gaps(&named.state.halves), c.half_gaps(&c.half_stats(&out)));
    let g = gap(&s, &c.real);
    let gain = gap_before - g;
    if gain < RIVAL_SHARE * (gap_before - gap_after) {
        log.line(format!("{effect} removes {:.3} of the gap on all records, {rival} {gain:.3}: no rival", gap_before - gap_after));
        return None;
    }
    if named_ahead(gap_after, &named_h, g, &rival_h) {
        log.line(format!("{effect} is ahead of {rival} ({:.1}% on the subsample) on all records and on both halves", 100.0 * share));
        return None;
    }
    // Not ordered, but two parts of the gap of a like size are no
    // tie: the rival must explain the part the named effect does.
    let on_top = gap_after - c.gap_with(&named.state.model.with(rival), c.cfg.seed);
    if on_top >= SAME_PART * gain {
        log.line(format!(
            "{effect} and {rival} are not ordered by the data, but explain different parts of the gap ({rival} removes {gain:.3} alone, {on_top:.3} on top)"
        ));
        return None;
    }
    log.line(format!(
        "{effect} and {rival} are not ordered by the data, and {rival} on top removes {on_top:.3} against {gain:.3} alone: tied, unless a later step names it"
    ));
    let gains = |h: &[f64]| before_h.iter().zip(h).map(|(b, a)| b - a).collect::<Vec<f64>>();
    Some(Tie { effect: rival, gain, gain_on_top: on_top, gains_halves: gains(&rival_h), named_gains_halves: gains(&named_h) })
}

/// A rival a later step names (re-fitted with the named effect in place)
/// explains a part of its own: both are in the model, and the step is
/// no choice between them. The ties left are said in each step's evidence.
pub(crate) fn settle_ties(steps: &mut [Step], log: &dyn Fn(String)) {
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
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
