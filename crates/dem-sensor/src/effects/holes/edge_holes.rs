//! `edge-holes`: holes at the foot of height jumps.

use super::{check_jump, jump_holes, ops, JUMP, LOST};
use crate::draws::Draws;
use crate::effects::{params, EffectKind, EffectSpec, Family, Stage};
use crate::evidence::{pct, Context};
use crate::graph::ops::Cells;
use dem_core::format::{Dem, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Holes at the foot of height jumps (stereo consistency check, mixed
    /// heights in one map cell).
    #[serde(expecting = "struct variant Effect::EdgeHoles")]
    EdgeHoles {
        /// Jump (m) above which the lower cell may be lost.
        g: fit JUMP.0, limit JUMP.1;
        /// Probability that such a cell is lost.
        p: fit LOST.0, limit LOST.1;
    }
}

impl EffectKind for EdgeHoles {
    const SPEC: EffectSpec = EffectSpec {
        name: "edge-holes",
        family: Family::Holes,
        emulator: &["smoothing", "holes"],
        formula: "a valid cell whose valid 4-neighbour is higher by more than g is missing with probability p (the foot of a height jump)",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::JumpHoles,
        // One per cell.
        draws: GRID_ROWS * COLS,
    };

    fn check(&self) -> Result<(), String> {
        let Self { g, p } = *self;
        check_jump(g, p)
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, _time: Option<f64>) {
        let Self { g, p } = *self;
        jump_holes(d, rng, g, p, 1.0)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, _time: Option<&str>) -> Cells {
        let Self { g, p } = *self;
        ops::jump_holes(b, c, u, g, p, 1.0)
    }

    fn evidence(&self, c: &Context) -> String {
        sentence(c)
    }

    fn examples() -> Vec<Self> {
        vec![EdgeHoles { g: 0.05, p: 0.6 }]
    }
}

/// The evidence for `edge-holes`.
fn sentence(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let (r, b) = (real.mean_over("jump-missing", 0..20), before.mean_over("jump-missing", 0..20));
        format!(
            "missing cells between valid cells of their column that differ by 5 cm or more: real {} vs model {}: {}",
            pct(r),
            pct(b),
            if r > b { "holes at height jumps" } else { "no more of them in real: the holes are the closest effect, not a clear one" }
        )
    };
    c.fitted(body)
}
