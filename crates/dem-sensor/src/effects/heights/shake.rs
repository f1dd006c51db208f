//! `shake`: vibration, the body's pitch and roll noise, larger on edges.

use super::{ops, step_under_tracks, tilt_plane, MAX_TILT};
use crate::draws::Draws;
use crate::effects::{params, EffectKind, EffectSpec, Family, Limit, Range, Stage};
use crate::evidence::{mm, tilted_unpaired, Context};
use crate::graph::ops::Cells;
use dem_core::distribution::Stats;
use dem_core::format::Dem;
use dem_graph::Builder;

params! {
    /// Vibration: the body's pitch and roll noise, larger on edges.
    #[serde(expecting = "struct variant Effect::Shake")]
    Shake {
        // On even ground up to 1 degree; per metre of step under the tracks up
        // to 0.3 rad (a 0.2 m stair edge: 3.4 degrees more).
        /// Sd (rad) on even ground.
        sigma: fit Range::lin(0.0, 0.02), limit Limit::new(0.0, 0.2).natural_lo();
        /// Extra sd per metre of step under the tracks (rad per m).
        edge: fit Range::lin(0.0, 0.3), limit Limit::new(0.0, 1.0).natural_lo();
    }
}

impl EffectKind for Shake {
    const SPEC: EffectSpec = EffectSpec {
        name: "shake",
        family: Family::Heights,
        emulator: &["vibration"],
        formula:
            "per record s = `sigma` + `edge` J, J the largest height step (m, capped at SHAKE_MAX_STEP) between valid x-neighbours of \
            the rows under the tracks (TRACK_ROWS, |x| <= 0.35 m) of the DEM as it comes in; a = s z1, b = s z2 (one Box-Muller \
            pair), h += a x + b y: the body rocks about C, more on edges. Unlike `tilt` it pivots at C (rows behind C move the other \
            way) and its spread follows the terrain under the tracks",
        params: Self::PARAMS,
        whole_record: true,
        run_draws: 0,
        stage: Stage::Registration,
        // One Box-Muller pair.
        draws: 2,
    };

    fn check(&self) -> Result<(), String> {
        let Self { sigma, edge } = *self;
        check_shake(sigma, edge)
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, _time: Option<f64>) {
        let Self { sigma, edge } = *self;
        shake(d, rng, sigma, edge)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, _time: Option<&str>) -> Cells {
        let Self { sigma, edge } = *self;
        operators(b, c, u, sigma, edge)
    }

    fn evidence(&self, c: &Context) -> String {
        let Self { sigma, edge } = *self;
        sentence(c, sigma, edge)
    }

    fn examples() -> Vec<Self> {
        vec![Shake { sigma: 0.003, edge: 0.1 }]
    }
}

fn check_shake(sigma: f64, edge: f64) -> Result<(), String> {
    if !(0.0..=MAX_TILT).contains(&sigma) || edge < 0.0 {
        return Err(format!("sigma = {sigma} must be in [0, {MAX_TILT}] rad and edge = {edge} >= 0"));
    }
    Ok(())
}

/// `shake` (formula in its spec).
fn shake(d: &mut Dem, rng: &mut Draws, sigma: f64, edge: f64) {
    let [z1, z2]: [f64; 2] = rng.normals();
    let s = sigma + edge * step_under_tracks(d);
    tilt_plane(d, s * z1, s * z2, |x| x);
}

/// `shake`.
fn operators(b: &mut Builder, c: &Cells, u: &str, sigma: f64, edge: f64) -> Cells {
    let (z1, z2) = ops::normal_pairs(b, u, 1);
    let s = ops::sd_with_the_step(b, c, sigma, edge);
    let a = b.bin("Mul", &s, &z1);
    let bb = b.bin("Mul", &s, &z2);
    ops::tilt_plane(b, c, &a, &bb, |x| x)
}

/// The evidence for `shake`.
fn sentence(c: &Context, sigma: f64, edge: f64) -> String {
    let real = c.real;
    let before = c.before;
    let spread = c.spread();
    if !real.paired {
        return c.fitted(tilted_unpaired(
            real,
            before,
            &format!(
                "the body rocks about its centre, with sd {:.2} degrees plus {:.2} degrees per 10 cm of step under the tracks",
                sigma.to_degrees(),
                (0.1 * edge).to_degrees()
            ),
        ));
    }
    let body = {
        // Both ends of the grid against the rows over C: a body rocking
        // about C moves both ends, the middle not at all.
        let sd = |s: &Stats, rows: std::ops::Range<usize>| s.mean_over("spread-sd", rows);
        let (rb, bb, rm, bm, rf, bf) =
            (sd(real, 0..3), sd(before, 0..3), sd(real, 5..7), sd(before, 5..7), sd(real, 16..20), sd(before, 16..20));
        let verdict = if (rb - bb).min(rf - bf) > rm - bm {
            format!(
                "real spreads more at both ends than over C: the body rocks about its centre, with sd {:.2} degrees plus {:.2} degrees per 10 cm of step under the tracks",
                sigma.to_degrees(),
                (0.1 * edge).to_degrees()
            )
        } else {
            "real's extra spread is not larger at both ends than over C: the shake is the closest effect, not a clear one".to_string()
        };
        format!(
            "height spread ({spread}) behind the robot (rows 0-2) real {} vs model {}, over C (rows 5-6) real {} vs model {}, far ahead (rows 16-19) real {} vs model {}: {verdict}",
            mm(rb),
            mm(bb),
            mm(rm),
            mm(bm),
            mm(rf),
            mm(bf),
        )
    };
    c.fitted(body)
}
