//! `tilt`: the camera's pitch and roll off their calibration.

use super::{ops, tilt_plane, MAX_TILT, MAX_TILT_RANGE};
use crate::draws::Draws;
use crate::effects::{params, EffectKind, EffectSpec, Family, Limit, Range, Stage};
use crate::evidence::{mm, tilted_unpaired, Context};
use crate::graph::ops::Cells;
use dem_core::distribution::Stats;
use dem_core::format::{row_center_x, Dem, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// The camera's pitch and roll off their calibration (extrinsic error):
    /// heights tilted by distance times angle, one angle per run.
    #[serde(expecting = "struct variant Effect::Tilt")]
    Tilt {
        // Sds of the camera's pitch and roll errors up to 3 degrees (0.05
        // rad); x0 from behind the grid (every row tilts) to 1 m ahead; the
        // lever at x0 from none to the camera's farthest depth
        // (MAX_TILT_RANGE): no cell is seen from farther, so no lever is
        // longer. No error (sd 0) is a natural end; x0 behind the grid
        // (every row tilts) or past it (no row pitches) too, and no lever at
        // x0.
        /// Sd (rad) of the pitch error.
        pitch: fit Range::lin(0.0, 0.05), limit Limit::new(0.0, 0.2).natural_lo();
        /// Sd (rad) of the roll error.
        roll: fit Range::lin(0.0, 0.05), limit Limit::new(0.0, 0.2).natural_lo();
        /// Cells behind this x (m) keep the error of x0.
        x0: fit Range::lin(-0.6, 1.0), limit Limit::new(-0.6, 1.45).natural_lo().natural_hi();
        /// Mean horizontal range (m) from which the map's cells at x0 were seen: the lever of the angle there.
        range: fit Range::lin(0.0, MAX_TILT_RANGE), limit Limit::new(0.0, MAX_TILT_RANGE).natural_lo();
    }
}

impl EffectKind for Tilt {
    const SPEC: EffectSpec = EffectSpec {
        name: "tilt",
        family: Family::Heights,
        emulator: &["extrinsic"],
        formula:
            "per run a = `pitch` z1, b = `roll` z2 (z1, z2 standard normals, one Box-Muller pair of the run's draws; radians, used as slopes), h += a \
            (`range` + max(x, x0) - x0) + b y: the camera's pitch and roll off their calibration (the extrinsic error). A point seen \
            at horizontal range d moves by a d in height, and the map fuses each cell over the ranges it was seen from: a cell past \
            x0 was seen from `range` + (x - x0) on average, the cells behind x0 keep the error of their last views, so the whole DEM \
            rises or falls with the angle and tilts about a pivot `range` behind x0",
        params: Self::PARAMS,
        whole_record: true,
        // The mount's angle is the run's: a real mount keeps its
        // miscalibration for the robot's life, the emulator for a run.
        run_draws: 2,
        stage: Stage::Registration,
        // One Box-Muller pair.
        draws: 2,
    };

    fn check(&self) -> Result<(), String> {
        let Self { pitch, roll, range, .. } = *self;
        check_tilt(pitch, roll, range)
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, _time: Option<f64>) {
        let Self { pitch, roll, x0, range } = *self;
        tilt(d, rng, pitch, roll, x0, range)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, _time: Option<&str>) -> Cells {
        let Self { pitch, roll, x0, range } = *self;
        operators(b, c, u, pitch, roll, x0, range)
    }

    fn evidence(&self, c: &Context) -> String {
        let Self { pitch, roll, x0, range } = *self;
        sentence(c, pitch, roll, x0, range)
    }

    fn examples() -> Vec<Self> {
        vec![Tilt { pitch: 0.02, roll: 0.015, x0: 0.45, range: 1.5 }]
    }
}

fn check_tilt(pitch: f64, roll: f64, range: f64) -> Result<(), String> {
    if !(0.0..=MAX_TILT).contains(&pitch) || !(0.0..=MAX_TILT).contains(&roll) {
        return Err(format!("pitch = {pitch} and roll = {roll} must be in [0, {MAX_TILT}] rad"));
    }
    if !(0.0..=MAX_TILT_RANGE).contains(&range) {
        return Err(format!("range = {range} must be in [0, {MAX_TILT_RANGE}] m"));
    }
    Ok(())
}

/// `tilt` (formula in its spec).
fn tilt(d: &mut Dem, rng: &mut Draws, pitch: f64, roll: f64, x0: f64, range: f64) {
    let [z1, z2]: [f64; 2] = rng.normals();
    tilt_plane(d, pitch * z1, roll * z2, |x| range + x.max(x0) - x0);
}

/// `tilt`.
fn operators(b: &mut Builder, c: &Cells, u: &str, pitch: f64, roll: f64, x0: f64, range: f64) -> Cells {
    let (z1, z2) = ops::normal_pairs(b, u, 1);
    let a = b.mul_const(&z1, pitch as f32);
    let bb = b.mul_const(&z2, roll as f32);
    ops::tilt_plane(b, c, &a, &bb, |x| range + x.max(x0) - x0)
}

/// The evidence for `tilt`.
fn sentence(c: &Context, pitch: f64, roll: f64, x0: f64, range: f64) -> String {
    let real = c.real;
    let before = c.before;
    let spread = c.spread();
    if !real.paired {
        return c.fitted(tilted_unpaired(
            real,
            before,
            &format!(
                "a camera angle that differs from record to record (sd pitch {:.2}, roll {:.2} degrees)",
                pitch.to_degrees(),
                roll.to_degrees()
            ),
        ));
    }
    let body = {
        // Rows just ahead of x0 against the far rows: a tilt's spread
        // grows with the range, range at x0 and more past it.
        let first = (0..GRID_ROWS).find(|&r| row_center_x(r) > x0).unwrap_or(GRID_ROWS).min(12);
        let near = first..first + 3;
        let sd = |s: &Stats, rows: std::ops::Range<usize>| s.mean_over("spread-sd", rows);
        let (rn, bn, rf, bf) = (sd(real, near.clone()), sd(before, near.clone()), sd(real, 15..20), sd(before, 15..20));
        let verdict = if rf > bf && rf - bf > rn - bn {
            format!(
                "real spreads more the farther ahead of x0: heights tilted by a camera angle that differs from record to record (sd pitch {:.2}, roll {:.2} degrees), seen from {range:.1} m at x0 and farther beyond",
                pitch.to_degrees(),
                roll.to_degrees()
            )
        } else {
            "real's extra spread does not grow with range: the tilt is the closest effect, not a clear one".to_string()
        };
        format!(
            "height spread ({spread}) just ahead of x = {x0:.2} m (rows {}-{}) real {} vs model {}, far ahead (rows 15-19) real {} vs model {}: {verdict}",
            near.start,
            near.end - 1,
            mm(rn),
            mm(bn),
            mm(rf),
            mm(bf),
        )
    };
    c.fitted(body)
}
