//! One measurement: a sensor model applied to the sim records, summarised
//! by the statistics the gap compares. Everything else in the crate
//! measures through here.

use dem_core::distribution::{self, Stats};
use dem_core::format::Dem;
use dem_core::temporal::Step;
use dem_sensor::Moment;
use dem_sensor::SensorModel;

/// Apply `model` to `sim` and summarise (residuals against `sim` when paired).
pub fn measure(model: &SensorModel, sim: &[Dem], paired: bool, seed: u64) -> (Vec<Dem>, Stats) {
    measure_at(model, sim, None, None, paired, seed)
}

/// [`measure`] with the records' times in their runs and the runs' steps,
/// when known (the frame terms then count).
pub fn measure_at(
    model: &SensorModel,
    sim: &[Dem],
    moments: Option<&[Moment]>,
    steps: Option<&[Step]>,
    paired: bool,
    seed: u64,
) -> (Vec<Dem>, Stats) {
    let mut out = sim.to_vec();
    model.apply_all_at(&mut out, seed, 0, moments);
    let s = summarise(&out, paired.then_some(sim), steps);
    (out, s)
}

/// The statistics of `records` (model(sim) or real), as residuals against
/// `paired_sim` when given, with the frame terms over the runs' `steps`
/// (positions in `records`) when given.
pub fn summarise(records: &[Dem], paired_sim: Option<&[Dem]>, steps: Option<&[Step]>) -> Stats {
    let s = distribution::stats(records, paired_sim);
    match steps {
        Some(steps) => s.with_frames(distribution::frame_terms(records, paired_sim, steps)),
        None => s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::distribution::{gap_terms, FRAME_SCALES};
    use dem_core::format::{empty_dem, DemCells, COLS, GRID_ROWS};
    use dem_sensor::effects::Noise;
    use dem_sensor::Effect;

    /// Runs of frames one cell apart over a rough ground: real keeps each
    /// ground cell's error from frame to frame (a map), the model draws the
    /// same noise afresh every frame. Frame by frame the two cannot be told
    /// apart; in time the frame terms carry the gap, paired and unpaired.
    #[test]
    fn a_sensor_that_flickers_where_the_map_holds_still_has_a_gap_in_time() {
        let ground = |g: usize| 0.03 * ((g * 7919 % 13) as f32 / 13.0);
        let noise = SensorModel::new(vec![Effect::Noise(Noise { sigma0: 0.0035, k: 0.0, tau: 0.0 })]);
        // Real's error of each ground strip, drawn once by the same noise:
        // strip g of run k is index k * 50 + g.
        let mut strips: Vec<Dem> = (0..20 * 50)
            .map(|i| {
                let mut d = empty_dem();
                for c in 0..COLS {
                    d.set_valid(0, c, ground(i));
                }
                d
            })
            .collect();
        noise.apply_all(&mut strips, 7, 0);
        let (mut sim, mut real, mut steps) = (Vec::new(), Vec::new(), Vec::new());
        for run in 0..20 {
            for t in 0..30 {
                let (mut s, mut r) = (empty_dem(), empty_dem());
                for row in 0..GRID_ROWS {
                    let g = run * 50 + t + row;
                    for c in 0..COLS {
                        s.set_valid(row, c, ground(g));
                        r.set_valid(row, c, strips[g].height(0, c));
                    }
                }
                if t > 0 {
                    steps.push(Step { from: sim.len() - 1, to: sim.len(), shift: 1 });
                }
                sim.push(s);
                real.push(r);
            }
        }
        let frame_names: Vec<&str> = FRAME_SCALES.iter().map(|t| t.0).collect();
        for paired in [true, false] {
            let by_frames = |with: Option<&[Step]>| {
                let (_, m) = measure_at(&noise, &sim, None, with, paired, 5);
                let r = summarise(&real, paired.then_some(&sim[..]), with);
                let terms = gap_terms(&m, &r);
                let part = |frames: bool| terms.iter().filter(|(n, _)| frame_names.contains(n) == frames).map(|t| t.1).sum::<f64>();
                (part(false), part(true))
            };
            let (statics, none) = by_frames(None);
            let (statics_too, in_time) = by_frames(Some(&steps));
            assert_eq!(none, 0.0, "no steps, no frame terms");
            assert_eq!(statics, statics_too, "the frame terms leave the others alone");
            assert!(in_time > 1.0 && in_time > 2.0 * statics, "paired {paired}: in time {in_time}, frame by frame {statics}");
        }
    }
}
