//! Find where sim and real disagree, name the missing effect, add it to a
//! sensor model and show the gap shrink.
//!
//! [`load`](mod@load) reads the inputs into the compared sets. The loop
//! ([`run`], in [`search`], one function a step):
//! 1. **measure** model(sim) against real with [`dem_core::distribution`]
//!    ([`comparison`]): missing-cell rates, shadows, residual or height
//!    means and spreads, edge profiles, height steps, per row, and, with
//!    the runs in the labels, how consecutive frames move (the frame
//!    terms); one gap
//!    number ([`gap`]) that compares distributions and is 0 when they
//!    match. With pairs, heights are residuals against the paired sim
//!    record; without, the records' own distributions are compared.
//! 2. **name**: fit every effect not yet in the model ([`fit`]) on a
//!    subsample and rank them by how much of the gap each removes
//!    (`rank_candidates`); the evidence ([`evidence`]) says why in numbers.
//! 3. **add** the best one when it removes more than `min_gain` of the gap,
//!    with the models' random draws and again with other draws (a gain
//!    that is a draw's luck does not repeat); unpaired, it
//!    must also hold on each of two half-size comparisons, sim half k
//!    against real half k ([`sim_halves`], [`real_halves`]), and, below
//!    the sampling floor, re-fitted on either half, remove `min_gain` of
//!    the other half's gap (held out), so fitting which records happen to
//!    be in the set does not pass (`confirm_best`). A close rival the data
//!    does not tell from it is named with it ([`ties`]). Re-measure on all data, repeat; at the end
//!    each effect is re-fitted with the others in place (`polish`); with
//!    `--joint-refit`, when the loop stopped because no candidate held up
//!    alone, the best of them
//!    are tried once more with the others re-fitted beside them
//!    (`joint`). The
//!    report also gives the unpaired sampling floor, two halves of real
//!    scaled to the set sizes ([`sampling_floor`], in [`sampling`]), as
//!    what to expect of a perfect model.
//! 4. **show**: [`outcome`] puts together what the run found; [`report`]
//!    writes `report.json`, `sensor.json`, `report.md` and its pictures;
//!    [`unexplained`] says what the final model leaves above the sampling
//!    floor and where (statistic, band of rows, side, terrain), flags weak
//!    steps, and, for a gap below the floor, how many records (runs) would
//!    show it.

pub mod comparison;
pub mod evidence;
pub mod fit;
mod held_out;
mod joint;
pub mod load;
pub mod measurement;
pub mod mix;
pub mod outcome;
pub mod report;
pub mod sampling;
pub mod search;
mod state;
pub mod ties;
pub mod unexplained;

// The public items stay at the crate root, where the binary, the tests and
// the other tools name them.
pub use dem_core::distribution::{gap, gap_terms, Stats};
pub use dem_sensor::evidence::share_removed;
pub use load::{load, terrain_mix, GapConfig, Sets};
pub use measurement::{measure, measure_at};
pub use outcome::Tie;
pub use outcome::{Outcome, Refit, Step, TerrainRow};
pub use sampling::{
    below_floor, draw_floor, halves, halves_of_runs, real_halves, sampling_floor, sim_halves, two_draws, MIN_RUNS_FOR_HALVES,
};
pub use search::NEGLIGIBLE_GAP;
pub use ties::{named_ahead, tie_sentence, MAX_RIVALS, RIVAL_SHARE, SAME_PART};

// The subset floors of `unexplained` take the second draws as the run does.
pub(crate) use sampling::other_draws;

/// Run the measure-name-add loop on loaded sets; `log` gets progress lines,
/// `tick` is called after each candidate fit (for a progress bar).
pub fn run(cfg: &GapConfig, sets: &Sets, log: &dyn Fn(String), tick: &dyn Fn()) -> Outcome {
    match (&sets.frames_left_out, &sets.sim_steps, &sets.real_steps) {
        (Some(why), _, _) => log(format!("frame terms left out: {why}")),
        (None, Some(s), Some(r)) => {
            log(format!("frame terms over the runs' consecutive frames: {} sim-side steps, {} real-side", s.len(), r.len()))
        }
        _ => {}
    }
    let c = comparison::Comparison::new(cfg, sets);
    let (start, state) = search::measure_start(&c, log);
    let mut found = search::name_effects(&c, state, log, tick);
    ties::settle_ties(&mut found.steps, log);
    let mut refits = std::mem::take(&mut found.refits);
    refits.extend(search::polish(&c, &mut found.model, &mut found.gap, &mut found.stats, log));
    joint::extend(&c, &mut found, &mut refits, log, tick);
    outcome::finish(c, start, found, refits, log)
}
