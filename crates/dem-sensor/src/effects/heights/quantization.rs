//! `quantization`: heights rounded to multiples of q.

use super::{MIN_QUANTUM, ROUND_UP_FROM};
use crate::draws::Draws;
use crate::effects::{params, EffectKind, EffectSpec, Family, Limit, Range, Stage};
use crate::evidence::{mm, pct, small_steps, Context};
use crate::graph::ops::{is_valid, set_heights, Cells};
use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Heights rounded to multiples of q.
    #[serde(expecting = "struct variant Effect::Quantization")]
    Quantization {
        /// Step (m).
        q: fit Range::log(0.002, 0.05), limit Limit::new(MIN_QUANTUM, 0.2);
    }
}

impl EffectKind for Quantization {
    const SPEC: EffectSpec = EffectSpec {
        name: "quantization",
        family: Family::Heights,
        emulator: &[],
        formula: "h = q floor(h / q + ROUND_UP_FROM) (half steps round up, the same in every runtime)",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::Quantization,
        draws: 0,
    };

    fn check(&self) -> Result<(), String> {
        let Self { q } = *self;
        check_quantization(q)
    }

    fn apply(&self, d: &mut Dem, _rng: &mut Draws, _time: Option<f64>) {
        let Self { q } = *self;
        quantize(d, q)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, _u: &str, _time: Option<&str>) -> Cells {
        let Self { q } = *self;
        operators(b, c, q)
    }

    fn evidence(&self, c: &Context) -> String {
        let Self { q } = *self;
        sentence(c, q)
    }

    fn examples() -> Vec<Self> {
        vec![Quantization { q: 0.02 }]
    }
}

fn check_quantization(q: f64) -> Result<(), String> {
    if q < MIN_QUANTUM {
        return Err(format!("q = {q:e} must be >= {MIN_QUANTUM:e} m"));
    }
    Ok(())
}

/// `quantization` (formula in its spec).
fn quantize(d: &mut Dem, q: f64) {
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            if d.is_valid(r, c) {
                // In float32, the graph's arithmetic: the same rounding everywhere.
                let (h, q) = (d.height(r, c), q as f32);
                d.set_valid(r, c, q * (h / q + ROUND_UP_FROM as f32).floor());
            }
        }
    }
}

/// `quantization`, in float32 as the native code rounds.
fn operators(b: &mut Builder, c: &Cells, q: f64) -> Cells {
    let q = b.scalar(q as f32);
    let x = b.bin("Div", &c.h, &q);
    let x = b.add_const(&x, crate::effects::ROUND_UP_FROM as f32);
    let x = b.un("Floor", &x);
    let x = b.bin("Mul", &q, &x);
    let valid = is_valid(b, &c.v);
    set_heights(b, c, &valid, &x)
}

/// The evidence for `quantization`.
fn sentence(c: &Context, q: f64) -> String {
    let real = c.real;
    let before = c.before;
    let body = format!(
        "neighbour differences of 0.1-10 mm: real {} vs model {}; equal neighbours real {} vs model {}: heights come in steps of {}",
        pct(small_steps(real)),
        pct(small_steps(before)),
        pct(real.mean_over("level-pairs", 0..20)),
        pct(before.mean_over("level-pairs", 0..20)),
        mm(q),
    );
    c.fitted(body)
}
