//! `pit-fill`: narrow pits read as their rims.

use super::{check_jump, JUMP};
use crate::draws::Draws;
use crate::effects::{cell_heights, exceeds, hit, params, EffectKind, EffectSpec, Family, Limit, Range, Stage};
use crate::evidence::{pct, Context};
use crate::graph::ops::{below, is_valid, neighbour, set_heights, Cells, Side, FAR};
use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Narrow pits read as their rims: a gap narrower than a map cell (between
    /// pallet boards, say) is never seen to its bottom, and a map cell over it
    /// keeps the tops around it.
    #[serde(expecting = "struct variant Effect::PitFill")]
    PitFill {
        /// Depth (m) below both neighbours above which a cell is a pit.
        g: fit JUMP.0, limit JUMP.1;
        // Every pit filled (p = 1) is a natural end: no gap is ever seen.
        /// Probability that a pit is filled.
        p: fit Range::lin(0.0, 1.0), limit Limit::new(0.0, 1.0).natural_lo().natural_hi();
    }
}

impl EffectKind for PitFill {
    const SPEC: EffectSpec = EffectSpec {
        name: "pit-fill",
        family: Family::Holes,
        emulator: &["occlusion"],
        formula:
            "a valid cell lower by more than g than both valid neighbours of a line through it (rows r +- 1, or columns c +- 1) reads \
            the lower of the two with probability p",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::PitFill,
        // One per cell.
        draws: GRID_ROWS * COLS,
    };

    fn check(&self) -> Result<(), String> {
        let Self { g, p } = *self;
        check_jump(g, p)
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, _time: Option<f64>) {
        let Self { g, p } = *self;
        fill_pits(d, rng, g, p)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, _time: Option<&str>) -> Cells {
        let Self { g, p } = *self;
        operators(b, c, u, g, p)
    }

    fn evidence(&self, c: &Context) -> String {
        sentence(c)
    }

    fn examples() -> Vec<Self> {
        vec![PitFill { g: 0.02, p: 0.8 }]
    }
}

/// `pit-fill` (formula in its spec): pits are found on the DEM as it comes
/// in; a pit along both lines reads the higher of the two rims.
fn fill_pits(d: &mut Dem, rng: &mut Draws, g: f64, p: f64) {
    let z = cell_heights(d);
    let at = |r: usize, c: usize| if r < GRID_ROWS && c < COLS { z[r][c] } else { None };
    for (r, row) in z.iter().enumerate() {
        for (c, &zc) in row.iter().enumerate() {
            let u: f64 = rng.gen();
            let Some(zc) = zc else { continue };
            let rims = [(at(r.wrapping_sub(1), c), at(r + 1, c)), (at(r, c.wrapping_sub(1)), at(r, c + 1))];
            let fill = rims.into_iter().filter_map(|(a, b)| Some(a?.min(b?))).filter(|&rim| exceeds(rim, zc, g)).reduce(f64::max);
            if let (Some(rim), true) = (fill, hit(u, p)) {
                d.set_valid(r, c, rim as f32);
            }
        }
    }
}

/// `pit-fill`: a cell deeper than g below both neighbours of a line reads
/// the lower of them (the larger of the two lines' rims), with probability p.
fn operators(b: &mut Builder, c: &Cells, u: &str, g: f64, p: f64) -> Cells {
    let u = b.reshape(u, &[-1, GRID_ROWS as i64, COLS as i64]);
    let none = b.scalar(-FAR);
    let mut rims = Vec::new();
    for (s1, s2) in [(Side::Behind, Side::Ahead), (Side::Left, Side::Right)] {
        let (v1, z1) = neighbour(b, c, s1);
        let (v2, z2) = neighbour(b, c, s2);
        let rim = b.bin("Min", &z1, &z2);
        let depth = b.bin("Sub", &rim, &c.h);
        let deep = b.gt_const(&depth, g as f32);
        let ok = b.all(&[&v1, &v2, &deep]);
        rims.push(b.select(&ok, &rim, &none));
    }
    let fill = b.bin("Max", &rims[0], &rims[1]);
    let has = b.gt_const(&fill, -FAR / 2.0);
    let valid = is_valid(b, &c.v);
    let hit = below(b, &u, p);
    let cond = b.all(&[&valid, &has, &hit]);
    set_heights(b, c, &cond, &fill)
}

/// The evidence for `pit-fill`.
fn sentence(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let (r2, b2) = (real.mean_over("edge-2cm", 0..19), before.mean_over("edge-2cm", 0..19));
        format!(
            "steps between neighbouring rows above 0.02 m: real {} vs model {}: {}",
            pct(r2),
            pct(b2),
            if r2 < b2 {
                "narrow pits read as their rims"
            } else {
                "real has as many steps: the filled pits are the closest effect, not a clear one"
            }
        )
    };
    c.fitted(body)
}
