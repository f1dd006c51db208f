//! `row-dropout`: whole grid rows missing at random.

use super::RATE;
use crate::draws::Draws;
use crate::effects::{params, probability, EffectKind, EffectSpec, Family, Stage};
use crate::evidence::{pct, per_rec, Context};
use crate::graph::ops::{below, drop_cells, Cells};
use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Whole grid rows missing at random.
    #[serde(expecting = "struct variant Effect::RowDropout")]
    RowDropout {
        /// Probability per row.
        p: fit RATE.0, limit RATE.1;
    }
}

impl EffectKind for RowDropout {
    const SPEC: EffectSpec = EffectSpec {
        name: "row-dropout",
        family: Family::Holes,
        emulator: &[],
        formula: "each grid row wholly missing with probability p",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::RowDropout,
        // One per row.
        draws: GRID_ROWS,
    };

    fn check(&self) -> Result<(), String> {
        let Self { p } = *self;
        probability(p)
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, _time: Option<f64>) {
        let Self { p } = *self;
        drop_rows(d, rng, p)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, _time: Option<&str>) -> Cells {
        let Self { p } = *self;
        operators(b, c, u, p)
    }

    fn evidence(&self, c: &Context) -> String {
        sentence(c)
    }

    fn examples() -> Vec<Self> {
        vec![RowDropout { p: 0.2 }]
    }
}

/// `row-dropout` (formula in its spec).
fn drop_rows(d: &mut Dem, rng: &mut Draws, p: f64) {
    for r in 0..GRID_ROWS {
        let u: f64 = rng.gen();
        if u < p {
            (0..COLS).for_each(|c| d.set_missing(r, c));
        }
    }
}

/// `row-dropout`.
fn operators(b: &mut Builder, c: &Cells, u: &str, p: f64) -> Cells {
    let u = b.reshape(u, &[-1, GRID_ROWS as i64, 1]);
    let miss = below(b, &u, p);
    drop_cells(b, c, &miss)
}

/// The evidence for `row-dropout`.
fn sentence(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let extra = per_rec(real, "missing") - per_rec(before, "missing");
        let rows = 5.0 * (per_rec(real, "row-missing") - per_rec(before, "row-missing"));
        format!(
            "whole rows missing: real {} of rows vs model {}; {} of the extra missing cells come as whole rows, spread over all ranges",
            pct(real.mean_over("row-missing", 0..20)),
            pct(before.mean_over("row-missing", 0..20)),
            pct((rows / extra.max(1e-9)).clamp(0.0, 1.0)),
        )
    };
    c.fitted(body)
}
