//! `bias`: calibration offset and tilt.

use crate::draws::Draws;
use crate::effects::{params, EffectKind, EffectSpec, Family, Limit, Range, Stage};
use crate::evidence::{mm, Context};
use crate::graph::ops::{is_valid, per_row, set_heights, Cells};
use dem_core::format::{row_center_x, Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Calibration offset and tilt: h += b + t x.
    #[serde(expecting = "struct variant Effect::Bias")]
    Bias {
        /// Offset (m).
        b: fit Range::lin(-0.1, 0.1), limit Limit::new(-0.5, 0.5);
        /// Tilt (m per m along x).
        t: fit Range::lin(-0.1, 0.1), limit Limit::new(-0.5, 0.5);
    }
}

impl EffectKind for Bias {
    const SPEC: EffectSpec = EffectSpec {
        name: "bias",
        family: Family::Heights,
        emulator: &[],
        formula: "h += b + t x",
        params: Self::PARAMS,
        whole_record: true,
        run_draws: 0,
        stage: Stage::Registration,
        draws: 0,
    };

    fn check(&self) -> Result<(), String> {
        Ok(())
    }

    fn apply(&self, d: &mut Dem, _rng: &mut Draws, _time: Option<f64>) {
        let Self { b, t } = *self;
        offset(d, b, t)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, _u: &str, _time: Option<&str>) -> Cells {
        let Self { b: off, t } = *self;
        operators(b, c, off, t)
    }

    fn evidence(&self, c: &Context) -> String {
        sentence(c)
    }

    fn examples() -> Vec<Self> {
        vec![Bias { b: 0.02, t: -0.03 }]
    }
}

/// `bias` (formula in its spec).
fn offset(d: &mut Dem, b: f64, t: f64) {
    for r in 0..GRID_ROWS {
        let off = b + t * row_center_x(r);
        for c in 0..COLS {
            if d.is_valid(r, c) {
                d.set_valid(r, c, (d.height(r, c) as f64 + off) as f32);
            }
        }
    }
}

/// `bias`.
fn operators(b: &mut Builder, c: &Cells, off: f64, t: f64) -> Cells {
    let shift = per_row(b, |r| off + t * row_center_x(r));
    let moved = b.bin("Add", &c.h, &shift);
    let valid = is_valid(b, &c.v);
    set_heights(b, c, &valid, &moved)
}

/// The evidence for `bias`.
fn sentence(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let (rb, mb) = (real.mean_over("height", 0..6), before.mean_over("height", 0..6));
        let (ra, ma) = (real.mean_over("height", 15..20), before.mean_over("height", 15..20));
        // Unpaired, mean heights follow the terrain: real higher than
        // the model on one side of the robot and lower on the other is
        // more like two sets of different terrain than a sensor offset.
        let mixed = !real.paired && (rb - mb).abs() > 0.005 && (ra - ma).abs() > 0.005 && (rb - mb).signum() != (ra - ma).signum();
        format!(
            "mean {} behind (rows 0-5) real {} vs model {}, far ahead (rows 15-19) real {} vs model {}: {}",
            if real.paired { "residual" } else { "height" },
            mm(rb),
            mm(mb),
            mm(ra),
            mm(ma),
            if mixed {
                "real is higher on one side and lower on the other, more like two sets of different terrain than one offset: \
                     read it as the closest effect, and compare the same terrain mix (both label files, which draw sim to real's mix, or --pairs)"
            } else {
                "an offset and a tilt"
            }
        )
    };
    c.fitted(body)
}
