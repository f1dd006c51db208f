//! `drift`: pose drift, older rows displaced by a random walk.

use super::{drift_walk, ops, shift_rows};
use crate::draws::Draws;
use crate::effects::{params, EffectKind, EffectSpec, Family, Limit, Range, Stage};
use crate::evidence::{mm, pct, with_step_coherence, Context};
use crate::graph::ops::Cells;
use dem_core::distribution::Stats;
use dem_core::format::{row_center_x, Dem, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Pose drift: rows behind x0 (older frames) displaced along x and in
    /// height by a random walk per 10 cm travelled.
    #[serde(expecting = "struct variant Effect::Drift")]
    Drift {
        // Walks up to 0.1 m per sqrt(m) along x, 0.05 in height; x0 as tilt's.
        /// Sd of the x walk (m per sqrt(m) travelled).
        rate: fit Range::lin(0.0, 0.1), limit Limit::new(0.0, 1.0).natural_lo();
        /// Sd of the height walk (m per sqrt(m) travelled).
        zrate: fit Range::lin(0.0, 0.05), limit Limit::new(0.0, 0.5).natural_lo();
        /// Rows whose centre lies behind this x (m) are displaced.
        x0: fit Range::lin(-0.6, 1.0), limit Limit::new(-0.6, 1.45).natural_lo().natural_hi();
    }
}

impl EffectKind for Drift {
    const SPEC: EffectSpec = EffectSpec {
        name: "drift",
        family: Family::Heights,
        emulator: &["drift"],
        formula: "rows whose centre x < `x0` are displaced by a random walk going back from x0: per row r, from the row just behind x0 \
            backward, dx(r) = `rate` sqrt(0.1) sum of xi_j and dz(r) = `zrate` sqrt(0.1) sum of zeta_j over the rows j from r to the \
            last row behind x0 (xi_j, zeta_j the normals of Box-Muller pair j); h'(x) = h(x - dx) + dz by shift_rows; rows from x0 \
            on are left alone: the map registers older frames at a believed pose that walks at random per metre travelled; with the record's \
            run, time and pose known, xi_j and zeta_j are the steps of the run's walk over the path under row j (crate::memory::path_steps)",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::Pose,
        // A Box-Muller pair per row: its x and its height step.
        draws: 2 * GRID_ROWS,
    };

    fn check(&self) -> Result<(), String> {
        let Self { rate, zrate, .. } = *self;
        check_drift(rate, zrate)
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, _time: Option<f64>) {
        let Self { rate, zrate, x0 } = *self;
        drift(d, rng, rate, zrate, x0)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, _time: Option<&str>) -> Cells {
        let Self { rate, zrate, x0 } = *self;
        operators(b, c, u, rate, zrate, x0)
    }

    fn evidence(&self, c: &Context) -> String {
        let Self { rate, zrate, x0 } = *self;
        sentence(c, rate, zrate, x0)
    }

    fn examples() -> Vec<Self> {
        vec![Drift { rate: 0.08, zrate: 0.03, x0: 0.4 }, Drift { rate: 1.0, zrate: 0.0, x0: 1.45 }]
    }
}

fn check_drift(rate: f64, zrate: f64) -> Result<(), String> {
    if rate < 0.0 || zrate < 0.0 {
        return Err(format!("rate = {rate} and zrate = {zrate} must be >= 0"));
    }
    Ok(())
}

/// `drift` (formula in its spec).
fn drift(d: &mut Dem, rng: &mut Draws, rate: f64, zrate: f64, x0: f64) {
    let z: [f64; 2 * GRID_ROWS] = rng.normals();
    let (dx, dz) = drift_walk(&z, rate, zrate, x0);
    shift_rows(d, &dx, &dz);
}

/// `drift`: the walks as the normals times a constant triangular matrix
/// (a cumulative sum going back from x0, as MatMul: CumSum is not in every
/// runtime), then [`shift_rows`].
fn operators(b: &mut Builder, c: &Cells, u: &str, rate: f64, zrate: f64, x0: f64) -> Cells {
    let rows = GRID_ROWS as i64;
    let (xi, zeta) = ops::normal_pairs(b, u, GRID_ROWS);
    // sum[r] = sum of z[j] over r <= j, j behind x0: T[j][r] = 1 there.
    let behind = |r: usize| row_center_x(r) < x0;
    let t: Vec<f32> = (0..GRID_ROWS * GRID_ROWS)
        .map(|i| {
            let (j, r) = (i / GRID_ROWS, i % GRID_ROWS);
            f32::from(u8::from(r <= j && behind(j)))
        })
        .collect();
    let t = b.constant(&[GRID_ROWS, GRID_ROWS], &t);
    let step = dem_core::format::CELL.sqrt();
    let walk = |b: &mut Builder, z: &str, sd: f64| {
        let z = b.reshape(z, &[-1, rows]);
        let z = b.mul_const(&z, (sd * step) as f32);
        let w = b.op("MatMul", &[&z, &t], vec![]);
        b.reshape(&w, &[-1, rows, 1])
    };
    let dx = walk(b, &xi, rate);
    let dz = walk(b, &zeta, zrate);
    let q = b.mul_const(&dx, (1.0 / dem_core::format::CELL) as f32);
    ops::shift_rows(b, c, &q, &dz)
}

/// The evidence for `drift`.
fn sentence(c: &Context, rate: f64, zrate: f64, x0: f64) -> String {
    let real = c.real;
    let before = c.before;
    let spread = c.spread();
    if !real.paired {
        return c.fitted(
{
            // Along-x steps between the rows behind x0 (each row its own
            // height offset) against those ahead of it.
            let behind = (0..GRID_ROWS).filter(|&r| row_center_x(r) < x0).count().clamp(2, 18);
            let e = |s: &Stats, rows: std::ops::Range<usize>| s.mean_over("edge-2cm", rows);
            let (rb, bb, ra, ba) = (e(real, 0..behind - 1), e(before, 0..behind - 1), e(real, behind..19), e(before, behind..19));
            let verdict = if rb - bb > ra - ba && rb > bb {
                format!(
                    "the rows behind x0 step against each other: rows seen earlier are displaced by a pose that walks {:.0} mm along x and {:.0} mm in height per sqrt(m) travelled",
                    1000.0 * rate,
                    1000.0 * zrate
                )
            } else {
                "no more steps behind x0 than ahead of it in real: the drift is the closest effect, not a clear one".to_string()
            };
            format!(
                "steps above 2 cm between neighbouring rows behind x = {x0:.2} m real {} vs model {}, ahead of it real {} vs model {}: {verdict}",
                pct(rb),
                pct(bb),
                pct(ra),
                pct(ba),
            )
}
        );
    }
    let body = {
        // The oldest rows against those just behind x0 and those ahead:
        // a walk back from x0 spreads most in the oldest rows.
        let behind = (0..GRID_ROWS).filter(|&r| row_center_x(r) < x0).count().clamp(4, 17);
        let sd = |s: &Stats, rows: std::ops::Range<usize>| s.mean_over("spread-sd", rows);
        let (old, just, ahead) = (0..2, behind - 2..behind, behind..behind + 3);
        let ex = |rows: std::ops::Range<usize>| sd(real, rows.clone()) - sd(before, rows);
        let verdict = if ex(old.clone()) > ex(just.clone()) && ex(old.clone()) > ex(ahead.clone()) {
            format!(
                "real's extra spread grows going back from x0: rows seen earlier are displaced by a pose that walks {:.0} mm along x and {:.0} mm in height per sqrt(m) travelled",
                1000.0 * rate,
                1000.0 * zrate
            )
        } else {
            "real's extra spread does not grow going back: the drift is the closest effect, not a clear one".to_string()
        };
        format!(
            "height spread ({spread}) in the oldest rows (0-1) real {} vs model {}, just behind x = {x0:.2} m (rows {}-{}) real {} vs model {}, ahead of it (rows {}-{}) real {} vs model {}: {verdict}",
            mm(sd(real, old.clone())),
            mm(sd(before, old)),
            just.start,
            just.end - 1,
            mm(sd(real, just.clone())),
            mm(sd(before, just.clone())),
            ahead.start,
            ahead.end - 1,
            mm(sd(real, ahead.clone())),
            mm(sd(before, ahead.clone())),
        )
    };
    c.fitted(with_step_coherence(body, real, before, true))
}
