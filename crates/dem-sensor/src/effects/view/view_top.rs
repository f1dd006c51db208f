//! `view-top`: the upper edge of the vertical field of view.

use crate::draws::Draws;
use crate::effects::heights::ops::record_pitch as record_pitch_op;
use crate::effects::{params, record_pitch, EffectKind, EffectSpec, Family, Limit, Range, Stage};
use crate::evidence::{mm, pct, Context};
use crate::graph::ops::{drop_cells, is_valid, per_row, Cells};
use dem_core::distribution::Stats;
use dem_core::format::{row_center_x, Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// The upper edge of the vertical field of view: terrain above the top
    /// ray is never seen (far treads of stairs going up, tall obstacles).
    /// The camera is fixed to the body, so the ray turns with the record's
    /// pitch about C: nose up it clears the stairs ahead, nose down it
    /// meets the steps below.
    #[serde(expecting = "struct variant Effect::ViewTop")]
    ViewTop {
        // A camera 0.2-1.2 m above C whose top ray falls 0-60 degrees. High
        // enough or flat enough, the ray clears everything: natural ends.
        /// Height (m) of the top ray above C at x = 0, the body level.
        h: fit Range::lin(0.1, 1.5), limit Limit::new(0.0, 3.0).natural_hi();
        /// Its fall per metre along x (the tangent of its depression angle).
        t: fit Range::lin(0.0, 1.7), limit Limit::new(-1.0, 3.0).natural_lo();
    }
}

impl EffectKind for ViewTop {
    const SPEC: EffectSpec = EffectSpec {
        name: "view-top",
        family: Family::View,
        emulator: &["fov"],
        formula: "cells with (t cos p - sin p) x + (t sin p + cos p) z > h missing: above the line z = h - t x (the upper edge of the \
            camera's vertical field of view with the body level) turned about C by the record's pitch p (row 20 column 0, clamped to \
            +-MAX_CLIMB_PITCH, 0 if not finite)",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::FieldOfView,
        draws: 0,
    };

    fn check(&self) -> Result<(), String> {
        Ok(())
    }

    fn apply(&self, d: &mut Dem, _rng: &mut Draws, _time: Option<f64>) {
        let Self { h, t } = *self;
        cut_above_top_ray(d, h, t, record_pitch(d))
    }

    fn graph(&self, b: &mut Builder, c: &Cells, _u: &str, _time: Option<&str>) -> Cells {
        let Self { h, t } = *self;
        operators(b, c, h, t)
    }

    fn evidence(&self, c: &Context) -> String {
        let Self { h, t } = *self;
        sentence(c, h, t)
    }

    fn examples() -> Vec<Self> {
        vec![ViewTop { h: 0.3, t: 0.3 }]
    }
}

/// `view-top` (formula in its spec) at pitch `p`: the level body's
/// half-plane where t x + z exceeds h, turned by p about C (its normal
/// (t, 1) turned with it, the offset h kept).
///
/// Decided in float32, operation for operation as the graph decides it, so
/// a cell on the line is cut alike in every runtime (up to its cosine and
/// sine of the pitch).
fn cut_above_top_ray(d: &mut Dem, h: f64, t: f64, p: f64) {
    let (p, t) = (p as f32, t as f32);
    let (cos, sin) = (p.cos(), p.sin());
    let (along, up) = (cos * t - sin, sin * t + cos);
    for r in 0..GRID_ROWS {
        let x = row_center_x(r) as f32;
        for c in 0..COLS {
            if d.is_valid(r, c) && along * x + up * d.height(r, c) > h as f32 {
                d.set_missing(r, c);
            }
        }
    }
}

/// `view-top`, the pitch per record `(N, 1, 1)`.
fn operators(b: &mut Builder, c: &Cells, h: f64, t: f64) -> Cells {
    let p = record_pitch_op(b);
    let (cos, sin) = (b.un("Cos", &p), b.un("Sin", &p));
    let t_cos = b.mul_const(&cos, t as f32);
    let along = b.bin("Sub", &t_cos, &sin);
    let t_sin = b.mul_const(&sin, t as f32);
    let up = b.bin("Add", &t_sin, &cos);
    let x = per_row(b, row_center_x);
    let ax = b.bin("Mul", &along, &x);
    let uz = b.bin("Mul", &up, &c.h);
    let side = b.bin("Add", &ax, &uz);
    let above = b.gt_const(&side, h as f32);
    let valid = is_valid(b, &c.v);
    let miss = b.all(&[&valid, &above]);
    drop_cells(b, c, &miss)
}

/// The evidence for `view-top`.
fn sentence(c: &Context, h: f64, t: f64) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let far = |s: &Stats| s.mean_over("missing", 15..20);
        format!(
            "cells far ahead (rows 15-19) missing: real {} vs model {}: terrain above a line {} above C falling {} per metre, turning with the body's pitch, is out of view",
            pct(far(real)),
            pct(far(before)),
            mm(h),
            mm(t),
        )
    };
    c.fitted(body)
}
