//! `dropout`: single valid cells missing at random.

use super::RATE;
use crate::draws::Draws;
use crate::effects::{params, probability, EffectKind, EffectSpec, Family, Stage};
use crate::evidence::{pct, per_rec, Context};
use crate::graph::ops::{below, drop_cells, Cells};
use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Single valid cells missing at random.
    #[serde(expecting = "struct variant Effect::Dropout")]
    Dropout {
        /// Probability per valid cell.
        p: fit RATE.0, limit RATE.1;
    }
}

impl EffectKind for Dropout {
    const SPEC: EffectSpec = EffectSpec {
        name: "dropout",
        family: Family::Holes,
        emulator: &["dropout", "holes"],
        formula: "each valid cell missing with probability p",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::Dropout,
        // One per cell.
        draws: GRID_ROWS * COLS,
    };

    fn check(&self) -> Result<(), String> {
        let Self { p } = *self;
        probability(p)
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, _time: Option<f64>) {
        let Self { p } = *self;
        lose_cells(d, rng, p)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, _time: Option<&str>) -> Cells {
        let Self { p } = *self;
        operators(b, c, u, p)
    }

    fn evidence(&self, c: &Context) -> String {
        sentence(c)
    }

    fn examples() -> Vec<Self> {
        vec![Dropout { p: 0.3 }]
    }
}

/// `dropout` (formula in its spec).
fn lose_cells(d: &mut Dem, rng: &mut Draws, p: f64) {
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let u: f64 = rng.gen();
            if u < p && d.is_valid(r, c) {
                d.set_missing(r, c);
            }
        }
    }
}

/// `dropout`.
fn operators(b: &mut Builder, c: &Cells, u: &str, p: f64) -> Cells {
    let u = b.reshape(u, &[-1, GRID_ROWS as i64, COLS as i64]);
    let miss = below(b, &u, p);
    drop_cells(b, c, &miss)
}

/// The evidence for `dropout`.
fn sentence(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let removed = c.removed();
    let effect = c.effect;
    let (gap_before, gap_after) = (c.gap_before, c.gap_after);
    let body = {
        let extra = per_rec(real, "missing") - per_rec(before, "missing");
        let rows = 5.0 * (per_rec(real, "row-missing") - per_rec(before, "row-missing"));
        let shadow = per_rec(real, "shadow") - per_rec(before, "shadow");
        if extra <= 0.0 {
            return format!(
                "missing cells real {} vs model {}: no extra missing cells, the fitted {effect} trades where cells are missing; it removes {} of the gap ({gap_before:.3} -> {gap_after:.3})",
                pct(real.mean_over("missing", 0..20)),
                pct(before.mean_over("missing", 0..20)),
                pct(removed)
            );
        }
        format!(
            "missing cells real {} vs model {}; of the {:.1} extra missing cells per record only {} are whole rows and {} lie in shadows: scattered single cells",
            pct(real.mean_over("missing", 0..20)),
            pct(before.mean_over("missing", 0..20)),
            extra,
            pct((rows / extra.max(1e-9)).clamp(0.0, 1.0)),
            pct((shadow / extra.max(1e-9)).clamp(0.0, 1.0)),
        )
    };
    c.fitted(body)
}
