//! `map-memory`: a fused map keeps each cell's estimate and hole from one
//! frame to the next, moved with the robot, and blends a new frame in.

use crate::draws::Draws;
use crate::effects::{params, EffectKind, EffectSpec, Family, Limit, Range, Stage};
use crate::evidence::{mm, pct, Context};
use crate::graph::ops::Cells;
use dem_core::format::{Dem, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// A fused map across frames: each cell keeps the map's estimate, moved
    /// with the robot, and a new frame is blended in (crate::fusion).
    #[serde(expecting = "struct variant Effect::MapMemory")]
    MapMemory {
        /// Time constant (s) of the map's estimate: a frame dt after the last weighs 1 - e^(-dt/tau) (0: the frame alone).
        tau: fit Range::log(0.02, 5.0), limit Limit::new(0.0, 10.0).natural_lo();
        /// Mean time (s) the map keeps a cell no frame shows: kept with probability e^(-dt/keep) (0: the frame's holes).
        keep: fit Range::log(0.02, 10.0), limit Limit::new(0.0, 10.0).natural_lo().natural_hi();
    }
}

impl EffectKind for MapMemory {
    const SPEC: EffectSpec = EffectSpec {
        name: "map-memory",
        family: Family::View,
        emulator: &["memory"],
        formula: "with the last frame's map moved by the motion (labels' poses) and the climb taken out, dt after it: \
            h = m + (1 - e^(-dt/tau)) (f - m) where both hold the cell, the frame's where the map misses it, \
            the map's with probability e^(-dt/keep) where the frame misses it; a run's first frame is the frame",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::Memory,
        // One per cell: whether a cell the frame misses keeps the map's.
        draws: GRID_ROWS * COLS,
    };

    fn check(&self) -> Result<(), String> {
        Ok(())
    }

    /// A frame alone is a run's first: the map is the frame. The step from
    /// one frame to the next is [`crate::fusion::step`].
    fn apply(&self, _d: &mut Dem, _rng: &mut Draws, _time: Option<f64>) {}

    /// The frame's cells; the step is [`crate::fusion::operators`], which
    /// reads the graph's state inputs.
    fn graph(&self, _b: &mut Builder, c: &Cells, _u: &str, _time: Option<&str>) -> Cells {
        c.clone()
    }

    fn evidence(&self, c: &Context) -> String {
        sentence(c)
    }

    fn examples() -> Vec<Self> {
        vec![MapMemory { tau: 0.5, keep: 2.0 }]
    }
}

/// The evidence for `map-memory`: what consecutive frames showed.
fn sentence(c: &Context) -> String {
    let (real, before) = (c.real, c.before);
    let body = match real.term("frame-dh") {
        None => "the data gives no runs in time (labels with sequence, time, x, y and yaw), so nothing shows a map's memory".to_string(),
        Some(_) => format!(
            "over the same ground in consecutive frames heights change by real {} vs {} without it, cells change validity in real {} \
             vs {}, the lag-1 correlation is real {:.2} vs {:.2}: a map that keeps what it saw",
            mm(real.mean_over("frame-dh", 0..20)),
            mm(before.mean_over("frame-dh", 0..20)),
            pct(real.mean_over("frame-flip", 0..20)),
            pct(before.mean_over("frame-flip", 0..20)),
            real.mean_over("frame-rcorr", 0..20),
            before.mean_over("frame-rcorr", 0..20),
        ),
    };
    c.fitted(body)
}
