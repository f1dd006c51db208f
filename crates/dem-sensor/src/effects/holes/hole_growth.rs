//! `hole-growth`: holes grow by thin cells at their edges.

use super::{growth_threshold, RATE};
use crate::draws::Draws;
use crate::effects::{cell_heights, neighbours4, params, probability, EffectKind, EffectSpec, Family, Stage};
use crate::evidence::{paired_misses, Context};
use crate::graph::ops::{drop_cells, is_valid, nb, Cells, Side};
use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Holes grow by thin cells at their edges: a 10 cm DEM cell needs two
    /// of its four 5 cm map cells seen, and beside a hole (a shadow, the
    /// blind band of the first frames, a dark patch) some of them were not.
    #[serde(expecting = "struct variant Effect::HoleGrowth")]
    HoleGrowth {
        /// Probability per missing 4-neighbour that the cell is lost.
        p: fit RATE.0, limit RATE.1;
    }
}

impl EffectKind for HoleGrowth {
    const SPEC: EffectSpec = EffectSpec {
        name: "hole-growth",
        family: Family::Holes,
        emulator: &["smoothing", "holes"],
        formula: "a valid cell with k missing 4-neighbours (inside the grid) is missing with probability 1 - (1 - p)^k (the edge of a \
            hole, where a 10 cm cell holds fewer seen map cells than the two of four the map needs)",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::HoleGrowth,
        // One per cell.
        draws: GRID_ROWS * COLS,
    };

    fn check(&self) -> Result<(), String> {
        let Self { p } = *self;
        probability(p)
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, _time: Option<f64>) {
        let Self { p } = *self;
        grow_holes(d, rng, p)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, _time: Option<&str>) -> Cells {
        let Self { p } = *self;
        operators(b, c, u, p)
    }

    fn evidence(&self, c: &Context) -> String {
        sentence(c)
    }

    fn examples() -> Vec<Self> {
        vec![HoleGrowth { p: 0.3 }]
    }
}

/// `hole-growth`: missing neighbours are counted on the DEM as it comes in,
/// so a hole grows by one ring of cells at most.
fn grow_holes(d: &mut Dem, rng: &mut Draws, p: f64) {
    let z = cell_heights(d);
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let u: f64 = rng.gen();
            if z[r][c].is_none() {
                continue;
            }
            let k = neighbours4(r, c).filter(|&(rr, cc)| z[rr][cc].is_none()).count();
            if (u as f32) < growth_threshold(p, k) {
                d.set_missing(r, c);
            }
        }
    }
}

/// `hole-growth`: k missing 4-neighbours inside the grid lose the cell with
/// probability 1 - (1 - p)^k (a table of k = 0..4, computed as the native
/// code does, selected by k).
fn operators(b: &mut Builder, c: &Cells, u: &str, p: f64) -> Cells {
    let u = b.reshape(u, &[-1, GRID_ROWS as i64, COLS as i64]);
    let mut k = b.scalar(0.0);
    for side in [Side::Behind, Side::Ahead, Side::Left, Side::Right] {
        // Outside the grid counts as valid.
        let vn = nb(b, &c.v, side, 1.0);
        let one = b.scalar(1.0);
        let missing = b.bin("Sub", &one, &vn);
        k = b.bin("Add", &k, &missing);
    }
    // The table as a chain of selections (onnx2torch's Gather cannot take it).
    let mut thr = b.scalar(crate::effects::growth_threshold(p, 0));
    for n in 1..=4 {
        let is_n = b.lt_const(&k, n as f32 - 0.5);
        let not_below = b.un("Not", &is_n);
        let t = b.scalar(crate::effects::growth_threshold(p, n));
        thr = b.select(&not_below, &t, &thr);
    }
    let hit = b.bin("Less", &u, &thr);
    let valid = is_valid(b, &c.v);
    let miss = b.all(&[&valid, &hit]);
    drop_cells(b, c, &miss)
}

/// The evidence for `hole-growth`.
fn sentence(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = paired_misses(
        real,
        before,
        "holes are wider in real: cells at their edges are lost",
        "no more paired misses in real: grown holes are the closest effect, not a clear one",
    );
    c.fitted(body)
}
