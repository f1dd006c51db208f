//! One measurement: a sensor model applied to the sim records, summarised
//! by the statistics the gap compares. Everything else in the crate
//! measures through here.

use dem_core::distribution::{self, Stats};
use dem_core::format::Dem;
use dem_sensor::SensorModel;

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
