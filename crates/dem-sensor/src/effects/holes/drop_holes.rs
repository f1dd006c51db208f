//! `drop-holes`: holes at drop edges.

use super::ops;
use crate::draws::Draws;
use crate::effects::{cell_heights, exceeds, hit, params, probability, EffectKind, EffectSpec, Family, Limit, Range, Stage, MIXED_JUMP};
use crate::evidence::{pct, Context};
use crate::graph::ops::{below, cell_pairs, drop_cells, nb, Cells, Side};
use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Holes at drop edges: the map cells that hold a drop edge get points
    /// from the lip and from the floor below it as the view moves, the
    /// later ones outliers of the older, and each adds variance until the
    /// cell passes the map's threshold and becomes a hole.
    #[serde(expecting = "struct variant Effect::DropHoles")]
    DropHoles {
        // No drop edge lost, or every one: natural ends.
        /// Probability that the cell holding a drop's edge is lost.
        p: fit Range::lin(0.0, 1.0), limit Limit::new(0.0, 1.0).natural_lo().natural_hi();
    }
}

impl EffectKind for DropHoles {
    const SPEC: EffectSpec = EffectSpec {
        name: "drop-holes",
        family: Family::Holes,
        emulator: &["smoothing", "holes"],
        formula: "at a drop along x (valid cells of rows r and r + 1, row r + 1 lower by more than MIXED_JUMP), with probability p the \
            cell that holds the edge is missing: the lip (row r) or the floor (row r + 1), one of the two with equal chance (the \
            edge lies anywhere between their centres): the map cells over a drop edge get points from the lip and, as the view \
            moves, from the floor below it, outliers of the older ones; their variance grows past the map's threshold",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::JumpHoles,
        // Two per cell: whether the edge's cell is lost, and which of the two.
        draws: 2 * GRID_ROWS * COLS,
    };

    fn check(&self) -> Result<(), String> {
        let Self { p } = *self;
        probability(p)
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, _time: Option<f64>) {
        let Self { p } = *self;
        drop_holes(d, rng, p)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, _time: Option<&str>) -> Cells {
        let Self { p } = *self;
        operators(b, c, u, p)
    }

    fn evidence(&self, c: &Context) -> String {
        sentence(c)
    }

    fn examples() -> Vec<Self> {
        vec![DropHoles { p: 0.7 }]
    }
}

/// `drop-holes` (formula in its spec): drops are read on the DEM as it
/// comes in, so a lost lip makes no new drop. Two uniforms per row
/// boundary and column (the last row's pair unused): whether the edge's
/// cell is lost, and which of the two holds the edge.
fn drop_holes(d: &mut Dem, rng: &mut Draws, p: f64) {
    let z = cell_heights(d);
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let (u, v): (f64, f64) = (rng.gen(), rng.gen());
            let (Some(lip), Some(floor)) = (z[r][c], z.get(r + 1).and_then(|row| row[c])) else { continue };
            if exceeds(lip, floor, MIXED_JUMP) && hit(u, p) {
                d.set_missing(if v < 0.5 { r } else { r + 1 }, c);
            }
        }
    }
}

/// `drop-holes`: at a drop, with probability p, the lip (v < 0.5) or the
/// floor loses the cell.
fn operators(b: &mut Builder, c: &Cells, u: &str, p: f64) -> Cells {
    let (u, v) = cell_pairs(b, u);
    let drop = ops::drop_ahead(b, c);
    let hit = below(b, &u, p);
    let lost = b.all(&[&drop, &hit]);
    let lip = b.lt_const(&v, 0.5);
    let lip_lost = b.all(&[&lost, &lip]);
    let not_lip = b.un("Not", &lip);
    let floor_lost = b.all(&[&lost, &not_lip]);
    // The floor is the cell ahead of the boundary's row: shift it on.
    let floor_lost = b.to_float(&floor_lost);
    let floor_lost = nb(b, &floor_lost, Side::Behind, 0.0);
    let floor_lost = b.gt_const(&floor_lost, 0.5);
    let miss = b.any(&[&lip_lost, &floor_lost]);
    drop_cells(b, c, &miss)
}

/// The evidence for `drop-holes`.
fn sentence(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = {
        let (rs, bs) = (real.mean_over("shadow", 0..20), before.mean_over("shadow", 0..20));
        let (rj, bj) = (real.mean_over("jump-missing", 0..20), before.mean_over("jump-missing", 0..20));
        format!(
            "missing cells behind cells at least 0.08 m taller: real {} vs model {}; between valid cells of their column that differ by 5 cm or more: real {} vs model {}: {}",
            pct(rs),
            pct(bs),
            pct(rj),
            pct(bj),
            if rs > bs && rj > bj {
                "holes where the terrain drops away, one cell at its edge"
            } else {
                "no more holes at drops in real: holes at drop edges are the closest effect, not a clear one"
            }
        )
    };
    c.fitted(body)
}
