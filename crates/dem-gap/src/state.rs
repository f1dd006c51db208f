//! What the naming loop carries from one step to the next: where it stands
//! ([`State`]), the candidates it fitted, the effect a step adds, and the
//! step's log. The loop ([`crate::search`]) and the rival check
//! ([`crate::ties`]) both work on these.

use std::fmt::Display;

use dem_core::distribution::Stats;
use dem_sensor::{Effect, SensorModel};

use crate::fit;

/// Where the naming loop stands: the model so far, its gap and statistics
/// on all records, and its statistics on each half of the comparison.
pub(crate) struct State {
    pub model: SensorModel,
    pub gap: f64,
    pub stats: Stats,
    pub halves: Vec<Stats>,
}
/// A candidate fitted at one step, with the share of the gap it removes
/// on the fitting subsample.
pub(crate) struct Candidate {
    pub fit: fit::Fitted,
    pub share: f64,
}
/// The effect a step adds, and where the loop stands with it.
pub(crate) struct Added {
    pub effect: Effect,
    pub state: State,
}
/// The log of one step: each line headed by the step's number.
pub(crate) struct StepLog<'a> {
    pub number: usize,
    pub log: &'a dyn Fn(String),
}
impl StepLog<'_> {
    pub fn line(&self, line: impl Display) {
        (self.log)(format!("step {}: {line}", self.number))
    }
}
