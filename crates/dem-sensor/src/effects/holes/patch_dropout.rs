//! `patch-dropout`: missing blobs (dark or reflective patches).

use super::{darken, PATCH_SLOTS};
use crate::draws::Draws;
use crate::effects::{params, EffectKind, EffectSpec, Family, Limit, Range, Stage};
use crate::evidence::{paired_misses, Context};
use crate::graph::ops::{below, is_valid, neighbour, set_heights, Cells, Side, HALF};
use dem_core::format::{col_center_y, row_center_x, Dem, COLS, GRID_ROWS};
use dem_graph::Builder;

params! {
    /// Missing blobs (dark or reflective patches); a cell the blob only
    /// partly covers loses the points that lifted it beside a step.
    #[serde(expecting = "struct variant Effect::PatchDropout")]
    PatchDropout {
        // A blob loses a cell when it covers three of its quarter-cell
        // centres: r from 4 cm (up to four cells around a corner, by the
        // quarters it covers); smaller is `dropout`'s business. a from none
        // (a partly covered cell keeps its height) to the whole way down to
        // the lower x-neighbour: both natural ends.
        /// Expected blobs per record (0..PATCH_SLOTS).
        n: fit Range::lin(0.0, 4.0), limit Limit::new(0.0, 8.0).natural_lo();
        /// Blob radius (m).
        r: fit Range::lin(0.04, 0.25), limit Limit::new(0.02, 0.5).natural_lo();
        /// Share of the way a partly covered cell moves down toward its lower neighbour along x (0: it keeps
        /// its height).
        // Optional in JSON (0), so that models without it still load.
        #[serde(default)]
        a: fit Range::lin(0.0, 1.0), limit Limit::new(0.0, 1.0).natural_lo().natural_hi();
    }
}

impl EffectKind for PatchDropout {
    const SPEC: EffectSpec = EffectSpec {
        name: "patch-dropout",
        family: Family::Holes,
        emulator: &["dropout", "holes"],
        formula: "blobs: each of PATCH_SLOTS slots holds a blob with probability n / slots, centred uniformly over the grid widened by r; \
            of each cell's four quarter-cell centres (x +- 2.5 cm, y +- 2.5 cm) those within r of a blob centre are covered; three \
            or four covered: the cell is missing (the map needs two of four); one or two: h += a (h_low - h), h_low the lowest of h \
            and its x-neighbours left valid (the points a patch takes from a cell beside a step are those that lifted it)",
        params: Self::PARAMS,
        whole_record: false,
        run_draws: 0,
        stage: Stage::Patches,
        // Per slot: whether it holds a blob, the blob's x, its y.
        draws: 3 * PATCH_SLOTS,
    };

    fn check(&self) -> Result<(), String> {
        let Self { n, r, a } = *self;
        check_patch_dropout(n, r, a)
    }

    fn apply(&self, d: &mut Dem, rng: &mut Draws, _time: Option<f64>) {
        let Self { n, r, a } = *self;
        drop_patches(d, rng, n, r, a)
    }

    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, _time: Option<&str>) -> Cells {
        let Self { n, r, a } = *self;
        operators(b, c, u, n, r, a)
    }

    fn evidence(&self, c: &Context) -> String {
        sentence(c)
    }

    fn examples() -> Vec<Self> {
        vec![PatchDropout { n: 3.0, r: 0.12, a: 0.5 }]
    }
}

fn check_patch_dropout(n: f64, r: f64, a: f64) -> Result<(), String> {
    if !(0.0..=PATCH_SLOTS as f64).contains(&n) || r < 0.0 || !(0.0..=1.0).contains(&a) {
        return Err(format!("n = {n} must be in [0, {PATCH_SLOTS}], r = {r} >= 0 and a = {a} in [0, 1]"));
    }
    Ok(())
}

/// `patch-dropout` (formula in its spec). A DEM cell is the mean of its
/// four 5 cm map cells and needs two of them seen: a blob that covers three
/// or four quarter-cell centres loses the cell. One that covers one or two
/// leaves it fewer points, and beside a step the points it loses are the
/// ones that lifted it (the map keeps the higher of a frame's points in a
/// map cell, and a patch darkens the riser face and the edge with the
/// ground): the cell reads h + a (h_low - h), h_low its lower neighbour
/// along x that the blobs leave valid. Measured on the emulator
/// (`--no-dropout` against all stages): such cells move down, never up,
/// and only where that lower neighbour was seen.
fn drop_patches(d: &mut Dem, rng: &mut Draws, n: f64, radius: f64, a: f64) {
    let (ylo, yhi) = (col_center_y(COLS - 1) - HALF, col_center_y(0) + HALF);
    let (xlo, xhi) = (row_center_x(0) - HALF, row_center_x(GRID_ROWS - 1) + HALF);
    let mut blobs = Vec::with_capacity(PATCH_SLOTS);
    // Centres anywhere a blob can touch the grid, in float32 as the graph
    // computes them (see `darken`).
    let (span_x, span_y) = ((xhi - xlo + 2.0 * radius) as f32, (yhi - ylo + 2.0 * radius) as f32);
    let (from_x, from_y) = ((xlo - radius) as f32, (ylo - radius) as f32);
    for _ in 0..PATCH_SLOTS {
        let (u, s, t) = (rng.gen() as f32, rng.gen() as f32, rng.gen() as f32);
        if u < (n / PATCH_SLOTS as f64) as f32 {
            blobs.push((s * span_x + from_x, t * span_y + from_y));
        }
    }
    if !blobs.is_empty() {
        darken(d, &blobs, radius, a);
    }
}

/// `patch-dropout`: blobs from slots of three uniforms (present, x, y);
/// a cell's four quarter-cell centres counted under them.
fn operators(b: &mut Builder, c: &Cells, u: &str, n: f64, radius: f64, a: f64) -> Cells {
    let (rows, cols) = (GRID_ROWS, COLS);
    let slots = PATCH_SLOTS as i64;
    let u = b.reshape(u, &[-1, slots, 3]);
    let (ylo, yhi) = (col_center_y(cols - 1) - HALF, col_center_y(0) + HALF);
    let (xlo, xhi) = (row_center_x(0) - HALF, row_center_x(rows - 1) + HALF);
    let present = b.take(&u, 2, 0, 1);
    let present = below(b, &present, n / PATCH_SLOTS as f64);
    let s = b.take(&u, 2, 1, 2);
    let t = b.take(&u, 2, 2, 3);
    let cx = b.mul_const(&s, (xhi - xlo + 2.0 * radius) as f32);
    let cx = b.add_const(&cx, (xlo - radius) as f32);
    let cy = b.mul_const(&t, (yhi - ylo + 2.0 * radius) as f32);
    let cy = b.add_const(&cy, (ylo - radius) as f32);
    // (N, slot, 1, 1, 1) against the quarter centres (1, 1, 20, 5, 4).
    let blob = [-1, slots, 1, 1, 1];
    let present = b.reshape(&present, &blob);
    let cx = b.reshape(&cx, &blob);
    let cy = b.reshape(&cy, &blob);
    let quarters = [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)];
    let qx: Vec<f32> = (0..rows * cols * 4).map(|i| (row_center_x(i / (cols * 4)) + quarters[i % 4].0 * HALF / 2.0) as f32).collect();
    let qy: Vec<f32> = (0..rows * cols * 4).map(|i| (col_center_y(i / 4 % cols) + quarters[i % 4].1 * HALF / 2.0) as f32).collect();
    let qx = b.constant(&[1, 1, rows, cols, 4], &qx);
    let qy = b.constant(&[1, 1, rows, cols, 4], &qy);
    let dx = b.bin("Sub", &qx, &cx);
    let dy = b.bin("Sub", &qy, &cy);
    let dx2 = b.bin("Mul", &dx, &dx);
    let dy2 = b.bin("Mul", &dy, &dy);
    let d2 = b.bin("Add", &dx2, &dy2);
    let r2 = b.scalar((radius * radius) as f32);
    // Not(Greater): onnx2torch has no LessOrEqual.
    let outside = b.bin("Greater", &d2, &r2);
    let inside = b.un("Not", &outside);
    let covered = b.all(&[&inside, &present]);
    let covered = b.to_float(&covered);
    let covered = b.reduce("ReduceMax", &covered, &[1]);
    let covered = b.reduce("ReduceSum", &covered, &[4]);
    let covered = b.reshape(&covered, &[-1, rows as i64, cols as i64]);
    // Seen quarters: 4 - covered; a cell needs two.
    let valid = is_valid(b, &c.v);
    let enough = b.lt_const(&covered, 2.5);
    let keep = b.all(&[&valid, &enough]);
    let keep_f = b.to_float(&keep);
    let zero = b.scalar(0.0);
    let kept = Cells { v: keep_f, h: b.select(&keep, &c.h, &zero) };
    // A partly covered cell moves toward its lowest kept x-neighbour.
    let (v_behind, z_behind) = neighbour(b, &kept, Side::Behind);
    let (v_ahead, z_ahead) = neighbour(b, &kept, Side::Ahead);
    let lb = b.select(&v_behind, &z_behind, &kept.h);
    let la = b.select(&v_ahead, &z_ahead, &kept.h);
    let low = b.bin("Min", &lb, &la);
    let low = b.bin("Min", &low, &kept.h);
    let diff = b.bin("Sub", &low, &kept.h);
    let diff = b.mul_const(&diff, a as f32);
    let moved = b.bin("Add", &kept.h, &diff);
    let partly = b.gt_const(&covered, 0.5);
    let cond = b.all(&[&keep, &partly]);
    set_heights(b, &kept, &cond, &moved)
}

/// The evidence for `patch-dropout`.
fn sentence(c: &Context) -> String {
    let real = c.real;
    let before = c.before;
    let body = paired_misses(
        real,
        before,
        "missing cells come in blobs",
        "no more blobs in real than in the model: blobs are the closest effect, not a clear one",
    );
    c.fitted(body)
}
