//! `noise`: height noise growing with range.

use super::{ops, NOISE_ORIGIN, NOISE_RANGE_HEIGHT};
use crate::draws::Draws;
use crate::effects::{params, EffectKind, EffectSpec, Family, Limit, Range, Stage};
use crate::evidence::{mm, pct, Context};
use crate::graph::ops::{is_valid, per_cell, set_heights, Cells};
use dem_core::format::{col_center_y, row_center_x, Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Height noise growing with range: sigma = sigma0 + k d^2 (m).
    #[serde(expecting = "struct variant Effect::Noise")]
    Noise {
        /// Noise at the sensor (m).
        sigma0: fit Range::lin(0.0, 0.03), limit Limit::new(0.0, 0.1).natural_lo();
        /// Growth with squared range (1/m).
        k: fit Range::lin(0.0, 0.03), limit Limit::new(0.0, 0.1).natural_lo();
        /// The fused map's memory (s): over the same ground a cell's noise
        /// is a first-order process of this time constant; 0, new every frame.
        #[serde(default)]
        tau: fit Range::lin(0.0, 2.0), limit Limit::new(0.0, 10.0).natural_lo();
    }
}

impl EffectKind for Noise {
    const SPEC: EffectSpec = EffectSpec {
        name: "noise",
        family: Family::Heights,
        emulator: &["noise"],
        formula: "h += sigma z, z a standard normal (Box-Muller, crate::draws), sigma = sigma0 + k d^2, d = distance from the nominal \
            sensor mount NOISE_ORIGIN to the cell's centre at its height (clamped to +-NOISE_RANGE_HEIGHT); \
            with tau > 0 and the record's run, time and pose known, z follows the ground the cell sees: a first-order \
            process of time constant tau per 10 cm ground cell of the run (crate::memory), new every frame otherwise",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::Noise,
        // 50 Box-Muller pairs: one normal per cell.
        draws: GRID_ROWS * COLS,
    };

    fn check(&self) -> Result<(), String> {
        let Self { sigma0, k, tau } = *self;
        check_noise(sigma0, k)?;
        if tau < 0.0 {
            return Err("tau must be >= 0".into());
        }
        Ok(())
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, _time: Option<f64>) {
        let Self { sigma0, k, .. } = *self;
        add_noise(d, rng, sigma0, k)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, _time: Option<&str>) -> Cells {
        let Self { sigma0, k, .. } = *self;
        operators(b, c, u, sigma0, k)
    }

    fn evidence(&self, c: &Context) -> String {
        sentence(self.tau, c)
    }

    fn examples() -> Vec<Self> {
        vec![Noise { sigma0: 0.01, k: 0.02, tau: 0.0 }, Noise { sigma0: 0.01, k: 0.02, tau: 0.5 }]
    }
}

fn check_noise(sigma0: f64, k: f64) -> Result<(), String> {
    if sigma0 < 0.0 || k < 0.0 {
        return Err("sigma0 and k must be >= 0".into());
    }
    Ok(())
}

/// `noise` (formula in its spec).
fn add_noise(d: &mut Dem, rng: &mut Draws, sigma0: f64, k: f64) {
    let (sx, sz) = NOISE_ORIGIN;
    let normals: [f64; GRID_ROWS * COLS] = rng.normals();
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let z = normals[r * COLS + c];
            if d.is_valid(r, c) {
                let h = d.height(r, c) as f64;
                let (dx, dy, dz) = (row_center_x(r) - sx, col_center_y(c), h.clamp(-NOISE_RANGE_HEIGHT, NOISE_RANGE_HEIGHT) - sz);
                let sigma = sigma0 + k * (dx * dx + dy * dy + dz * dz);
                d.set_valid(r, c, (h + sigma * z) as f32);
            }
        }
    }
}

/// `noise`: h += sigma z, z one normal per cell ([`cell_normals`]).
fn operators(b: &mut Builder, c: &Cells, u: &str, sigma0: f64, k: f64) -> Cells {
    let z = ops::cell_normals(b, u);
    let (sx, sz) = NOISE_ORIGIN;
    // d^2 = (x - sx)^2 + y^2 + (clamp(h) - sz)^2: the first two are constants.
    let flat = per_cell(b, |r, col| (row_center_x(r) - sx).powi(2) + col_center_y(col).powi(2));
    let lo = b.scalar(-NOISE_RANGE_HEIGHT as f32);
    let hi = b.scalar(NOISE_RANGE_HEIGHT as f32);
    let hc = b.bin("Max", &c.h, &lo);
    let hc = b.bin("Min", &hc, &hi);
    let dz = b.add_const(&hc, -sz as f32);
    let dz2 = b.bin("Mul", &dz, &dz);
    let d2 = b.bin("Add", &flat, &dz2);
    let sigma = b.mul_const(&d2, k as f32);
    let sigma = b.add_const(&sigma, sigma0 as f32);
    let dh = b.bin("Mul", &sigma, &z);
    let moved = b.bin("Add", &c.h, &dh);
    let valid = is_valid(b, &c.v);
    set_heights(b, c, &valid, &moved)
}

/// The evidence for `noise`.
fn sentence(tau: f64, c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let spread = c.spread();
    let body = {
        let (rn, bn, rf, bf) = (
            real.mean_over("spread-sd", 6..10),
            before.mean_over("spread-sd", 6..10),
            real.mean_over("spread-sd", 15..20),
            before.mean_over("spread-sd", 15..20),
        );
        let verdict = if rn >= bn && rf >= bf {
            "real is the noisier"
        } else {
            "the model's spread is already as large or larger in part (terrain, not noise): the noise is named for the equal neighbours and the small height steps"
        };
        format!(
            "neighbouring cells of equal height real {} vs model {}; height spread ({spread}) near (rows 6-9) real {} vs model {}, far (rows 15-19) real {} vs model {}: {verdict}",
            pct(real.mean_over("level-pairs", 0..20)),
            pct(before.mean_over("level-pairs", 0..20)),
            mm(rn),
            mm(bn),
            mm(rf),
            mm(bf),
        )
    };
    let memory = match tau > 0.0 && real.term("frame-dh").is_some() {
        true => format!(
            "; over the same ground in consecutive frames heights change by real {} vs {} without it, and keep a lag-1 correlation \
             of real {:.2} vs {:.2} without it: the map holds a cell's noise for about {tau:.2} s",
            mm(real.mean_over("frame-dh", 0..20)),
            mm(before.mean_over("frame-dh", 0..20)),
            real.mean_over("frame-rcorr", 0..20),
            before.mean_over("frame-rcorr", 0..20),
        ),
        false => String::new(),
    };
    c.fitted(body + &memory)
}
