//! `step-jitter`: vibration seen at steps.

use super::jitter_steps;
use crate::draws::Draws;
use crate::effects::heights::step_under_tracks;
use crate::effects::{heights, params, EffectKind, EffectSpec, Family, Limit, Range, Stage};
use crate::evidence::{part_way_steps, pct, side_share, with_step_coherence, Context};
use crate::graph::ops::{is_valid, neighbour, set_heights, Cells, Side};
use dem_core::distribution::{Stats, STEP_SIDES};
use dem_core::format::{Dem, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Vibration seen at steps: a map cell beside a step holds the points
    /// of the few frames whose heights agree (fusion replaces where they do
    /// not), so one frame's horizontal misregistration stays there, a
    /// different one in each cell; on even ground many frames average out.
    /// Each cell reads at a random distance off along x: h += clamp(s z,
    /// +-0.1 m) times the local slope along x, s = sigma + edge J.
    #[serde(expecting = "struct variant Effect::StepJitter")]
    StepJitter {
        // A frame misregistered by up to 3 cm sd on even ground, 0.3 m per
        // metre of step under the tracks (a 0.2 m stair edge: 6 cm more). A
        // cell read more than 0.1 m off is clamped there: 0.1 is no edge.
        /// Sd (m) of the misregistration on even ground.
        sigma: fit Range::lin(0.0, 0.03), limit Limit::new(0.0, 0.1).natural_lo();
        /// Extra sd per metre of step under the tracks (m per m).
        edge: fit Range::lin(0.0, 0.3), limit Limit::new(0.0, 1.0).natural_lo();
    }
}

impl EffectKind for StepJitter {
    const SPEC: EffectSpec = EffectSpec {
        name: "step-jitter",
        family: Family::Steps,
        emulator: &["vibration"],
        formula: "per record s = `sigma` + `edge` J (J as in `shake`); each valid cell reads dx = clamp(s z, +-0.1 m) off along x, z a \
            standard normal per cell (as `noise` draws them): h += dx (h(r + 1) - h(r - 1)) / 0.2, a neighbour missing or outside \
            the grid read as the cell's own height (jitter_steps): each map cell beside a step keeps the points of the few frames \
            whose heights agree, so one frame's horizontal misregistration (the body's vibration) stays in it, a different one in \
            each cell; even ground averages it out and reads nothing",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::Registration,
        // One normal per cell, as `noise` draws them.
        draws: GRID_ROWS * COLS,
    };

    fn check(&self) -> Result<(), String> {
        let Self { sigma, edge } = *self;
        check_step_jitter(sigma, edge)
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, _time: Option<f64>) {
        let Self { sigma, edge } = *self;
        jitter(d, rng, sigma, edge)
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
        vec![StepJitter { sigma: 0.02, edge: 0.2 }]
    }
}

fn check_step_jitter(sigma: f64, edge: f64) -> Result<(), String> {
    if sigma < 0.0 || edge < 0.0 {
        return Err(format!("sigma = {sigma} and edge = {edge} must be >= 0"));
    }
    Ok(())
}

/// `step-jitter` (formula in its spec): the record's sd from the step
/// under the tracks, then [`jitter_steps`].
fn jitter(d: &mut Dem, rng: &mut Draws, sigma: f64, edge: f64) {
    let normals: [f64; GRID_ROWS * COLS] = rng.normals();
    jitter_steps(d, &normals, sigma + edge * step_under_tracks(d));
}

/// `step-jitter`: dx = clamp((sigma + edge J) z, +-0.1 m) per cell, h +=
/// dx (h ahead - h behind) / 0.2, a missing or outside neighbour read as
/// the cell's own height.
fn operators(b: &mut Builder, c: &Cells, u: &str, sigma: f64, edge: f64) -> Cells {
    let cell = dem_core::format::CELL as f32;
    let z = heights::ops::cell_normals(b, u);
    let s = heights::ops::sd_with_the_step(b, c, sigma, edge);
    let dx = b.bin("Mul", &s, &z);
    let (lo, hi) = (b.scalar(-cell), b.scalar(cell));
    let dx = b.bin("Max", &dx, &lo);
    let dx = b.bin("Min", &dx, &hi);
    let (va, ha) = neighbour(b, c, Side::Ahead);
    let (vb, hb) = neighbour(b, c, Side::Behind);
    let ahead = b.select(&va, &ha, &c.h);
    let behind = b.select(&vb, &hb, &c.h);
    let rise = b.bin("Sub", &ahead, &behind);
    let slope = b.mul_const(&rise, 1.0 / (2.0 * cell));
    let dh = b.bin("Mul", &dx, &slope);
    let moved = b.bin("Add", &c.h, &dh);
    let valid = is_valid(b, &c.v);
    set_heights(b, c, &valid, &moved)
}

/// The evidence for `step-jitter`.
fn sentence(c: &Context, sigma: f64, edge: f64) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let fitted = format!(
            "each cell beside a step reads a random distance off along x (a frame's misregistration kept where fusion does not average), sd {:.0} mm plus {:.0} mm per 10 cm of step under the tracks",
            1000.0 * sigma,
            100.0 * edge
        );
        if real.paired {
            // Both ways across the step: cells moved > 2 cm toward the
            // other surface (component 2) and away from it (3).
            let share = |st: &Stats, k: usize| side_share(st, &STEP_SIDES, k);
            let (rt, bt, ra, ba) = (share(real, 2), share(before, 2), share(real, 3), share(before, 3));
            let verdict = if rt > bt && ra > ba {
                format!("cells beside steps move both toward and away from the other surface: {fitted}")
            } else {
                "real moves no more step cells both ways than the model: the jitter is the closest effect, not a clear one".to_string()
            };
            let body = format!(
                "cells beside steps moved more than 2 cm toward the other surface real {} vs model {}, away from it real {} vs model {}: {verdict}",
                pct(rt),
                pct(bt),
                pct(ra),
                pct(ba),
            );
            with_step_coherence(body, real, before, false)
        } else {
            part_way_steps(real, before, format!("steps read part of the way across: {fitted}"), "the jitter is")
        }
    };
    c.fitted(body)
}
