//! `smoothing`: fusion blurs edges.

use crate::draws::Draws;
use crate::effects::{cell_heights, params, EffectKind, EffectSpec, Family, Limit, Range, Stage};
use crate::evidence::{pct, Context};
use crate::graph::ops::{is_valid, set_heights, Cells};
use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Fusion blurs edges: 3x3 kernel with centre weight w.
    #[serde(expecting = "struct variant Effect::Smoothing")]
    Smoothing {
        /// Centre weight in (0, 1]; 1 is no smoothing.
        w: fit Range::lin(0.05, 1.0), limit Limit::new(0.01, 1.0).natural_hi();
    }
}

impl EffectKind for Smoothing {
    const SPEC: EffectSpec = EffectSpec {
        name: "smoothing",
        family: Family::Steps,
        emulator: &["smoothing"],
        formula: "h = (w h + (1-w)/8 sum of valid 3x3 neighbours) / (w + (1-w)/8 n_valid)",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::Smoothing,
        draws: 0,
    };

    fn check(&self) -> Result<(), String> {
        let Self { w } = *self;
        check_smoothing(w)
    }

    fn apply(&self, d: &mut Dem, _rng: &mut Draws, _time: Option<f64>) {
        let Self { w } = *self;
        smooth(d, w)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, _u: &str, _time: Option<&str>) -> Cells {
        let Self { w } = *self;
        operators(b, c, w)
    }

    fn evidence(&self, c: &Context) -> String {
        sentence(c)
    }

    fn examples() -> Vec<Self> {
        vec![Smoothing { w: 0.4 }]
    }
}

fn check_smoothing(w: f64) -> Result<(), String> {
    if !(w > 0.0 && w <= 1.0) {
        return Err(format!("w = {w} must be in (0, 1]"));
    }
    Ok(())
}

/// `smoothing` (formula in its spec), on the DEM as it comes in.
fn smooth(d: &mut Dem, w: f64) {
    let z = cell_heights(d);
    let wn = (1.0 - w) / 8.0;
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let Some(zc) = z[r][c] else { continue };
            let (mut sum, mut weight) = (w * zc, w);
            let (r0, c0) = (r.saturating_sub(1), c.saturating_sub(1));
            for (rr, row) in z.iter().enumerate().take(r + 2).skip(r0) {
                for (cc, zn) in row.iter().enumerate().take(c + 2).skip(c0) {
                    if let (true, Some(zn)) = ((rr, cc) != (r, c), zn) {
                        sum += wn * zn;
                        weight += wn;
                    }
                }
            }
            d.set_valid(r, c, (sum / weight) as f32);
        }
    }
}

/// `smoothing`: the valid-weighted 3x3 mean, as two convolutions.
fn operators(b: &mut Builder, c: &Cells, w: f64) -> Cells {
    let wn = (1.0 - w) / 8.0;
    let kernel: Vec<f32> = (0..9).map(|i| if i == 4 { 0.0 } else { 1.0 }).collect();
    let k = b.constant(&[1, 1, 3, 3], &kernel);
    let img = [-1, 1, GRID_ROWS as i64, COLS as i64];
    let attrs = || vec![dem_graph::attr_ints("kernel_shape", &[3, 3]), dem_graph::attr_ints("pads", &[1, 1, 1, 1])];
    let h4 = b.reshape(&c.h, &img);
    let v4 = b.reshape(&c.v, &img);
    let sum = b.op("Conv", &[&h4, &k], attrs());
    let count = b.op("Conv", &[&v4, &k], attrs());
    let grid = [-1, GRID_ROWS as i64, COLS as i64];
    let sum = b.reshape(&sum, &grid);
    let count = b.reshape(&count, &grid);
    let num = b.mul_const(&sum, wn as f32);
    let own = b.mul_const(&c.h, w as f32);
    let num = b.bin("Add", &own, &num);
    let den = b.mul_const(&count, wn as f32);
    let den = b.add_const(&den, w as f32);
    let mean = b.bin("Div", &num, &den);
    let valid = is_valid(b, &c.v);
    set_heights(b, c, &valid, &mean)
}

/// The evidence for `smoothing`.
fn sentence(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let (r10, b10) = (real.mean_over("edge-10cm", 0..19), before.mean_over("edge-10cm", 0..19));
        let verdict = if r10 < b10 {
            "sharp edges become ramps"
        } else {
            "real has as many sharp edges: the smoothing is named for the small steps and spreads, not for ramps"
        };
        format!(
            "steps between neighbouring rows above 0.1 m: real {} vs model {}; above 0.02 m: real {} vs model {}: {verdict}",
            pct(r10),
            pct(b10),
            pct(real.mean_over("edge-2cm", 0..19)),
            pct(before.mean_over("edge-2cm", 0..19)),
        )
    };
    c.fitted(body)
}
