//! The measurement effects of `docs/format.md`, each on one DEM.
//!
//! Coordinates: row `r` of the grid is centred at x = -0.55 + 0.1 r m from
//! the robot centre C (forward), column `c` at y = (2 - c) 0.1 m; heights
//! are relative to C. A missing cell is stored as mask -1, height 0; an
//! effect that removes a cell writes exactly that. Effects act on the valid
//! cells only (a missing cell stays missing) and never touch row 20.
//!
//! | effect | formula |
//! |---|---|
//! | `noise` | h += sigma z, z a standard normal (Box-Muller, [`crate::draws`]), sigma = sigma0 + k d^2, d = distance from the nominal sensor mount [`NOISE_ORIGIN`] to the cell's centre at its height (clamped to +-[`NOISE_RANGE_HEIGHT`]) |
//! | `dropout` | each valid cell missing with probability p |
//! | `row-dropout` | each grid row wholly missing with probability p |
//! | `occlusion` | in each column, a sensor at (x0, h) looks at the far edge of each cell's top; the cell is missing when the line of sight passes more than [`OCCLUSION_TOLERANCE`] below the top of a valid cell between, or when its top is more than that above the sensor and its valid neighbour toward the sensor is not more than that lower (a top above the sensor faces away from it; only the cell holding the face is seen) |
//! | `fov` | cells whose centre x is outside [x_min, x_max] missing |
//! | `view-top` | cells whose height lies above the line z = h - t x (the upper edge of the camera's vertical field of view) missing |
//! | `smoothing` | h = (w h + (1-w)/8 sum of valid 3x3 neighbours) / (w + (1-w)/8 n_valid) |
//! | `bias` | h += b + t x |
//! | `quantization` | h = q floor(h / q + [`ROUND_UP_FROM`]) (half steps round up, the same in every runtime) |
//! | `startup` | rows whose centre x < e missing: e = x0 - v t for a record t seconds into its run (labels' `time`, v > 0); without a time, with probability p the record is a startup frame and e = x0 - u (x0 + 0.6), u uniform |
//! | `patch-dropout` | blobs: each of [`PATCH_SLOTS`] slots holds a blob with probability n / slots, centred uniformly over the grid widened by r; of each cell's four quarter-cell centres (x +- 2.5 cm, y +- 2.5 cm) those within r of a blob centre are covered; three or four covered: the cell is missing (the map needs two of four); one or two: h += a (h_low - h), h_low the lowest of h and its x-neighbours left valid (the points a patch takes from a cell beside a step are those that lifted it) |
//! | `edge-holes` | a valid cell whose valid 4-neighbour is higher by more than g is missing with probability p (the foot of a height jump) |
//! | `rim-holes` | a valid cell whose valid 4-neighbour is lower by more than g is missing with probability p (the rim of a height jump) |
//! | `drop-holes` | at a drop along x (valid cells of rows r and r + 1, row r + 1 lower by more than [`MIXED_JUMP`]), with probability p the cell that holds the edge is missing: the lip (row r) or the floor (row r + 1), one of the two with equal chance (the edge lies anywhere between their centres): the map cells over a drop edge get points from the lip and, as the view moves, from the floor below it, outliers of the older ones; their variance grows past the map's threshold |
//! | `hole-growth` | a valid cell with k missing 4-neighbours (inside the grid) is missing with probability 1 - (1 - p)^k (the edge of a hole, where a 10 cm cell holds fewer seen map cells than the two of four the map needs) |
//! | `pit-fill` | a valid cell lower by more than g than both valid neighbours of a line through it (rows r +- 1, or columns c +- 1) reads the lower of the two with probability p |
//! | `drop-blend` | at a drop along x (valid cells of rows r and r + 1, row r + 1 lower by more than [`MIXED_JUMP`]), each of the two cells reads, with probability p, h + u a (h_n - h), u uniform, h_n the other cell (a cell between two drops takes the larger; the one behind only when larger by more than [`TIE_MARGIN`]): the stereo window straddles the jump in range at a drop edge and its mean range puts the cell's points part of the way to the other surface |
//! | `floor-lift` | in rows whose centre x < `x`, a valid cell whose valid neighbour behind (row r - 1) is higher by more than [`MIXED_JUMP`] (the ground just beyond a drop edge) reads, with probability p, h + min(1, u a) (h_n - h), u uniform, h_n that neighbour: the edge hides the floor nearest it, and the cell keeps points lifted toward the edge (x past the grid: every row; x at the cone's lowest ray: the rows where the map keeps that grazing view) |
//! | `riser-blend` | at a riser along x (valid cells of rows r and r + 1, row r + 1 higher by more than [`MIXED_JUMP`]), the cell at its foot reads h + u `foot` (h_n - h) and the cell on its top h + u `top` (h_n - h), u uniform per cell, h_n the other cell (a cell beside two risers takes the larger step; the one behind only when larger by more than [`TIE_MARGIN`]); `foot`, `top` in [-1, 1], negative: away from the other surface: the stereo window over a riser's corners moves the points there along their rays, up or down the step as the view angle gives |
//! | `mixed-cells` | a cell is the mean of its two half cells along x; at a jump of more than [`MIXED_JUMP`] between valid x-neighbours the step lies at s, uniform over the 10 cm between their centres (one draw per row boundary), and the higher surface reaches e = u r past it into the lower cell (u uniform per cell; r = `up` when the higher cell lies ahead, `down` when it lies behind, i.e. beyond a drop): a half of the lower cell whose centre the higher surface reaches reads the higher height, a half of the higher cell the lower surface reaches (the step lies in it, deeper than e) reads the lower height |
//! | `tilt` | per record a = `pitch` z1, b = `roll` z2 (z1, z2 standard normals, one Box-Muller pair; radians, used as slopes), h += a (`range` + max(x, x0) - x0) + b y: the camera's pitch and roll off their calibration (the extrinsic error). A point seen at horizontal range d moves by a d in height, and the map fuses each cell over the ranges it was seen from: a cell past x0 was seen from `range` + (x - x0) on average, the cells behind x0 keep the error of their last views, so the whole DEM rises or falls with the angle and tilts about a pivot `range` behind x0 |
//! | `shake` | per record s = `sigma` + `edge` J, J the largest height step (m, capped at [`SHAKE_MAX_STEP`]) between valid x-neighbours of the rows under the tracks ([`TRACK_ROWS`], \|x\| <= 0.35 m) of the DEM as it comes in; a = s z1, b = s z2 (one Box-Muller pair), h += a x + b y: the body rocks about C, more on edges. Unlike `tilt` it pivots at C (rows behind C move the other way) and its spread follows the terrain under the tracks |
//! | `step-jitter` | per record s = `sigma` + `edge` J (J as in `shake`); each valid cell reads dx = clamp(s z, +-0.1 m) off along x, z a standard normal per cell (as `noise` draws them): h += dx (h(r + 1) - h(r - 1)) / 0.2, a neighbour missing or outside the grid read as the cell's own height ([`jitter_steps`]): each map cell beside a step keeps the points of the few frames whose heights agree, so one frame's horizontal misregistration (the body's vibration) stays in it, a different one in each cell; even ground averages it out and reads nothing |
//! | `lag` | per record shift s_r = `s` (1 + `spread` (2u - 1)), u uniform; h'(x) = h(x - s_r) + s_r tan(pitch), pitch the record's row 20 column 0 (clamped to +-[`MAX_CLIMB_PITCH`], 0 if not finite): the DEM is the map of a frame s_r / v old, cut at that older pose. See [`shift_rows`] for the interpolation; validity is kept |
//! | `drift` | rows whose centre x < `x0` are displaced by a random walk going back from x0: per row r, from the row just behind x0 backward, dx(r) = `rate` sqrt(0.1) sum of xi_j and dz(r) = `zrate` sqrt(0.1) sum of zeta_j over the rows j from r to the last row behind x0 (xi_j, zeta_j the normals of Box-Muller pair j); h'(x) = h(x - dx) + dz by [`shift_rows`]; rows from x0 on are left alone: the map registers older frames at a believed pose that walks at random per metre travelled |

use rand::RngCore;

use crate::draws::Draws;
use serde::{Deserialize, Serialize};

use dem_core::format::{col_center_y, row_center_x, Dem, DemCells, COLS, GRID_ROWS};

/// Where `noise` measures its range from: the nominal depth camera mount,
/// 0.15 m ahead of C and 0.45 m above it (x, z in metres).
pub const NOISE_ORIGIN: (f64, f64) = (0.15, 0.45);
/// The heights (m, either sign) beyond which `noise`'s range stops
/// growing: a cell 2 m above or below the robot is out of any DEM, and the
/// bound keeps every draw finite however many noise effects a model has.
pub const NOISE_RANGE_HEIGHT: f64 = 2.0;
/// How far (m) the line of sight may pass below a cell's top before that
/// cell hides what lies behind it: terrain within a centimetre of the ray
/// grazes it rather than blocks it.
pub const OCCLUSION_TOLERANCE: f64 = 0.01;
/// Largest magnitude of any parameter (metres, metres per metre, 1/m, m/s
/// or a count): a DEM spans 2 m, so a larger value is a typo, and bounding
/// it keeps every output finite.
pub const MAX_PARAM: f64 = 10.0;
/// Smallest `quantization` step (m): a tenth of a millimetre, finer than
/// any depth camera resolves at a metre, and large enough that h / q stays
/// far from float32's range.
pub const MIN_QUANTUM: f64 = 1e-4;
/// `quantization` rounds h / q up from this fraction of a step, not from
/// exactly a half: sim heights often lie on half steps, and there a
/// rounding error of 1e-7 would decide the step, differently in each
/// runtime. A thousandth of a step is far beyond rounding and far below
/// anything a sensor shows.
pub const ROUND_UP_FROM: f64 = 0.501;
/// A cell between two jumps (`drop-blend`, `riser-blend`) takes the one
/// behind only when its step is larger by more than this (m): a cell made
/// the mean of its neighbours (`mixed-cells`, `smoothing`) lies exactly
/// between two equal steps, where rounding alone would choose.
pub const TIE_MARGIN: f64 = 1e-5;
/// Half the edge of a grid cell (m).
const HALF: f64 = 0.05;
/// Blob slots per record of `patch-dropout`: at most this many blobs.
pub const PATCH_SLOTS: usize = 8;
/// Back edge of the grid (m): where a startup frame's blind edge ends.
const X_BACK: f64 = -0.6;
/// Height difference (m) between x-neighbours that `mixed-cells` treats as
/// a step: the distribution gap's `jump-missing` jump, so dem-gap's
/// statistic sees this effect's steps and no others. Below it the terrain
/// is a slope, whose cell mean is the centre's height.
pub const MIXED_JUMP: f64 = dem_core::distribution::JUMP;
/// Largest sd (rad) of `tilt`'s pitch and roll and of `shake`'s `sigma`:
/// a calibration or a body that far off (29 degrees) is no sensor effect.
pub const MAX_TILT: f64 = 0.5;
/// Largest `range` (m) of `tilt`: a depth camera's useful range.
pub const MAX_TILT_RANGE: f64 = 10.0;
/// The rows under the tracks whose x-neighbour steps `shake` reads: rows
/// 2..=9, centres from x = -0.35 to 0.35 m (tracks 0.7 m long about C).
pub const TRACK_ROWS: (usize, usize) = (2, 9);
/// `shake`'s step under the tracks is capped at this (m): a taller step is
/// no edge the tracks ride, and the cap keeps a stack of shakes finite.
pub const SHAKE_MAX_STEP: f64 = 0.5;
/// Largest `lag` shift `s` (m, either sign): a frame 2 s old at 0.25 m/s.
pub const MAX_LAG: f64 = 0.5;
/// Row shifts (`lag`, `drift`) are clamped to +-this many metres (10
/// rows): with `lag`'s box no shift reaches it; `drift` at absurd rates does.
pub const MAX_SHIFT: f64 = 1.0;
/// `lag` reads the record's pitch clamped to +-this (rad, 57 degrees).
pub const MAX_CLIMB_PITCH: f64 = 1.0;

/// One effect with its parameters. JSON: `{"effect": NAME, "params": {...}}`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "effect", content = "params", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Effect {
    /// Height noise growing with range: sigma = sigma0 + k d^2 (m).
    Noise {
        /// Noise at the sensor (m).
        sigma0: f64,
        /// Growth with squared range (1/m).
        k: f64,
    },
    /// Single valid cells missing at random.
    Dropout {
        /// Probability per valid cell.
        p: f64,
    },
    /// Whole grid rows missing at random.
    RowDropout {
        /// Probability per row.
        p: f64,
    },
    /// Cells hidden from the sensor by taller terrain.
    Occlusion {
        /// Sensor height above C (m).
        h: f64,
        /// Sensor position along x (m).
        x0: f64,
    },
    /// Cells outside the field of view along x never observed.
    Fov {
        /// Nearest x observed (m).
        x_min: f64,
        /// Farthest x observed (m).
        x_max: f64,
    },
    /// The upper edge of the vertical field of view: terrain above the top
    /// ray is never seen (far treads of stairs going up, tall obstacles).
    ViewTop {
        /// Height (m) of the top ray above C at x = 0.
        h: f64,
        /// Its fall per metre along x (the tangent of its depression angle).
        t: f64,
    },
    /// Fusion blurs edges: 3x3 kernel with centre weight w.
    Smoothing {
        /// Centre weight in (0, 1]; 1 is no smoothing.
        w: f64,
    },
    /// Calibration offset and tilt: h += b + t x.
    Bias {
        /// Offset (m).
        b: f64,
        /// Tilt (m per m along x).
        t: f64,
    },
    /// Heights rounded to multiples of q.
    Quantization {
        /// Step (m).
        q: f64,
    },
    /// The first frames of a run: the map has not yet seen the ground
    /// behind the nearest ray, and that blind edge recedes as the robot drives.
    Startup {
        /// Blind edge at the start of a run (m along x).
        x0: f64,
        /// Speed at which the blind edge recedes (m/s); 0: unknown.
        v: f64,
        /// Share of records that are startup frames (used without times).
        p: f64,
    },
    /// Missing blobs (dark or reflective patches); a cell the blob only
    /// partly covers loses the points that lifted it beside a step.
    PatchDropout {
        /// Expected blobs per record (0..PATCH_SLOTS).
        n: f64,
        /// Blob radius (m).
        r: f64,
        /// Share of the way a partly covered cell moves down toward its
        /// lower neighbour along x (0: it keeps its height). Absent in
        /// models written before it existed: 0.
        #[serde(default)]
        a: f64,
    },
    /// Holes at the foot of height jumps (stereo consistency check, mixed
    /// heights in one map cell).
    EdgeHoles {
        /// Jump (m) above which the lower cell may be lost.
        g: f64,
        /// Probability that such a cell is lost.
        p: f64,
    },
    /// Holes at the rim of height jumps (the stereo matcher's consistency
    /// check rejects pixels whose window straddles the jump on the near side
    /// too).
    RimHoles {
        /// Jump (m) above which the higher cell may be lost.
        g: f64,
        /// Probability that such a cell is lost.
        p: f64,
    },
    /// Holes at drop edges: the map cells that hold a drop edge get points
    /// from the lip and from the floor below it as the view moves, the
    /// later ones outliers of the older, and each adds variance until the
    /// cell passes the map's threshold and becomes a hole.
    DropHoles {
        /// Probability that the cell holding a drop's edge is lost.
        p: f64,
    },
    /// Holes grow by thin cells at their edges: a 10 cm DEM cell needs two
    /// of its four 5 cm map cells seen, and beside a hole (a shadow, the
    /// blind band of the first frames, a dark patch) some of them were not.
    HoleGrowth {
        /// Probability per missing 4-neighbour that the cell is lost.
        p: f64,
    },
    /// Narrow pits read as their rims: a gap narrower than a map cell (between
    /// pallet boards, say) is never seen to its bottom, and a map cell over it
    /// keeps the tops around it.
    PitFill {
        /// Depth (m) below both neighbours above which a cell is a pit.
        g: f64,
        /// Probability that a pit is filled.
        p: f64,
    },
    /// Cells on both sides of a drop edge read part of the way to the other
    /// side, in some records: the stereo matcher's window straddles the
    /// jump in range there and averages across it.
    DropBlend {
        /// Probability that a cell beside a drop is blended.
        p: f64,
        /// Largest share of the drop it moves across.
        a: f64,
    },
    /// The ground just beyond a drop edge reads part of the way up to it:
    /// the edge hides the floor nearest it from the camera, and the cell
    /// keeps the points it got near the edge. Everywhere where occlusion
    /// acts; in the rows the camera's lowest ray no longer reaches, the map
    /// keeps that grazing view where a closer, steeper look would see the
    /// floor (the field of view).
    FloorLift {
        /// Only rows whose centre lies behind this x (m) (past the grid: all).
        x: f64,
        /// Probability that a cell beyond a drop there reads higher.
        p: f64,
        /// Reach: the share moved is min(1, u a), u uniform (a > 1: some
        /// cells read the edge's height).
        a: f64,
    },
    /// Cells beside a riser read part of the way up or down the step: the
    /// stereo window over the riser's corners moves their points along the
    /// rays, by a share and in a direction that depend on the view angle.
    RiserBlend {
        /// Largest share of the step the cell at the riser's foot moves
        /// toward the top (negative: down, away from it).
        foot: f64,
        /// Largest share of the step the cell on the riser's top moves
        /// toward the foot (negative: up, away from it).
        top: f64,
    },
    /// Cells that straddle a step read part of the way up or down: a DEM
    /// cell is the mean of finer map cells, and a map cell holding a step
    /// keeps the higher surface (lower points hide under tops; the ground
    /// just beyond a drop edge is hidden by the edge).
    MixedCells {
        /// How far (m, at most) a riser's top reaches back into the lower
        /// cell in front of it.
        up: f64,
        /// How far (m, at most) a drop edge's top reaches on into the lower
        /// cell beyond it.
        down: f64,
    },
    /// The camera's pitch and roll off their calibration (extrinsic error):
    /// heights tilted by distance times angle, a new angle per record.
    Tilt {
        /// Sd (rad) of the pitch error.
        pitch: f64,
        /// Sd (rad) of the roll error.
        roll: f64,
        /// Cells behind this x (m) keep the error of x0.
        x0: f64,
        /// Mean horizontal range (m) from which the map's cells at x0 were
        /// seen: the lever of the angle there.
        range: f64,
    },
    /// Vibration: the body's pitch and roll noise, larger on edges.
    Shake {
        /// Sd (rad) on even ground.
        sigma: f64,
        /// Extra sd per metre of step under the tracks (rad per m).
        edge: f64,
    },
    /// Vibration seen at steps: a map cell beside a step holds the points
    /// of the few frames whose heights agree (fusion replaces where they do
    /// not), so one frame's horizontal misregistration stays there, a
    /// different one in each cell; on even ground many frames average out.
    /// Each cell reads at a random distance off along x: h += clamp(s z,
    /// +-0.1 m) times the local slope along x, s = sigma + edge J.
    StepJitter {
        /// Sd (m) of the misregistration on even ground.
        sigma: f64,
        /// Extra sd per metre of step under the tracks (m per m).
        edge: f64,
    },
    /// Latency: the DEM is an older frame's map, cut at that older pose.
    Lag {
        /// Mean shift ahead (m): speed times latency.
        s: f64,
        /// Spread of the shift around s, as a share of s (0..1).
        spread: f64,
    },
    /// Pose drift: rows behind x0 (older frames) displaced along x and in
    /// height by a random walk per 10 cm travelled.
    Drift {
        /// Sd of the x walk (m per sqrt(m) travelled).
        rate: f64,
        /// Sd of the height walk (m per sqrt(m) travelled).
        zrate: f64,
        /// Rows whose centre lies behind this x (m) are displaced.
        x0: f64,
    },
}

/// Every effect name, in the vocabulary's order.
pub const NAMES: [&str; 25] = [
    "noise",
    "dropout",
    "row-dropout",
    "occlusion",
    "fov",
    "smoothing",
    "bias",
    "quantization",
    "startup",
    "patch-dropout",
    "edge-holes",
    "mixed-cells",
    "rim-holes",
    "pit-fill",
    "view-top",
    "hole-growth",
    "drop-blend",
    "riser-blend",
    "floor-lift",
    "drop-holes",
    "tilt",
    "shake",
    "lag",
    "drift",
    "step-jitter",
];

impl Effect {
    /// The vocabulary name (`noise`, `row-dropout`, ...).
    pub fn name(&self) -> &'static str {
        match self {
            Effect::Noise { .. } => "noise",
            Effect::Dropout { .. } => "dropout",
            Effect::RowDropout { .. } => "row-dropout",
            Effect::Occlusion { .. } => "occlusion",
            Effect::Fov { .. } => "fov",
            Effect::Smoothing { .. } => "smoothing",
            Effect::Bias { .. } => "bias",
            Effect::Quantization { .. } => "quantization",
            Effect::Startup { .. } => "startup",
            Effect::PatchDropout { .. } => "patch-dropout",
            Effect::EdgeHoles { .. } => "edge-holes",
            Effect::MixedCells { .. } => "mixed-cells",
            Effect::RimHoles { .. } => "rim-holes",
            Effect::PitFill { .. } => "pit-fill",
            Effect::ViewTop { .. } => "view-top",
            Effect::HoleGrowth { .. } => "hole-growth",
            Effect::DropBlend { .. } => "drop-blend",
            Effect::RiserBlend { .. } => "riser-blend",
            Effect::FloorLift { .. } => "floor-lift",
            Effect::DropHoles { .. } => "drop-holes",
            Effect::Tilt { .. } => "tilt",
            Effect::Shake { .. } => "shake",
            Effect::StepJitter { .. } => "step-jitter",
            Effect::Lag { .. } => "lag",
            Effect::Drift { .. } => "drift",
        }
    }

    /// Parameter names and values, in declaration order.
    pub fn params(&self) -> Vec<(&'static str, f64)> {
        match *self {
            Effect::Noise { sigma0, k } => vec![("sigma0", sigma0), ("k", k)],
            Effect::Dropout { p } | Effect::RowDropout { p } | Effect::HoleGrowth { p } | Effect::DropHoles { p } => vec![("p", p)],
            Effect::Occlusion { h, x0 } => vec![("h", h), ("x0", x0)],
            Effect::Fov { x_min, x_max } => vec![("x_min", x_min), ("x_max", x_max)],
            Effect::ViewTop { h, t } => vec![("h", h), ("t", t)],
            Effect::Smoothing { w } => vec![("w", w)],
            Effect::Bias { b, t } => vec![("b", b), ("t", t)],
            Effect::Quantization { q } => vec![("q", q)],
            Effect::Startup { x0, v, p } => vec![("x0", x0), ("v", v), ("p", p)],
            Effect::PatchDropout { n, r, a } => vec![("n", n), ("r", r), ("a", a)],
            Effect::EdgeHoles { g, p } | Effect::RimHoles { g, p } | Effect::PitFill { g, p } => vec![("g", g), ("p", p)],
            Effect::MixedCells { up, down } => vec![("up", up), ("down", down)],
            Effect::DropBlend { p, a } => vec![("p", p), ("a", a)],
            Effect::RiserBlend { foot, top } => vec![("foot", foot), ("top", top)],
            Effect::FloorLift { x, p, a } => vec![("x", x), ("p", p), ("a", a)],
            Effect::Tilt { pitch, roll, x0, range } => vec![("pitch", pitch), ("roll", roll), ("x0", x0), ("range", range)],
            Effect::Shake { sigma, edge } | Effect::StepJitter { sigma, edge } => vec![("sigma", sigma), ("edge", edge)],
            Effect::Lag { s, spread } => vec![("s", s), ("spread", spread)],
            Effect::Drift { rate, zrate, x0 } => vec![("rate", rate), ("zrate", zrate), ("x0", x0)],
        }
    }

    /// Build the effect `name` from parameter values in [`Effect::params`] order.
    pub fn from_values(name: &str, v: &[f64]) -> Option<Effect> {
        let g = |i: usize| v.get(i).copied();
        Some(match name {
            "noise" => Effect::Noise { sigma0: g(0)?, k: g(1)? },
            "dropout" => Effect::Dropout { p: g(0)? },
            "row-dropout" => Effect::RowDropout { p: g(0)? },
            "occlusion" => Effect::Occlusion { h: g(0)?, x0: g(1)? },
            "fov" => Effect::Fov { x_min: g(0)?, x_max: g(1)? },
            "smoothing" => Effect::Smoothing { w: g(0)? },
            "bias" => Effect::Bias { b: g(0)?, t: g(1)? },
            "quantization" => Effect::Quantization { q: g(0)? },
            "startup" => Effect::Startup { x0: g(0)?, v: g(1)?, p: g(2)? },
            "patch-dropout" => Effect::PatchDropout { n: g(0)?, r: g(1)?, a: g(2)? },
            "edge-holes" => Effect::EdgeHoles { g: g(0)?, p: g(1)? },
            "mixed-cells" => Effect::MixedCells { up: g(0)?, down: g(1)? },
            "rim-holes" => Effect::RimHoles { g: g(0)?, p: g(1)? },
            "pit-fill" => Effect::PitFill { g: g(0)?, p: g(1)? },
            "view-top" => Effect::ViewTop { h: g(0)?, t: g(1)? },
            "hole-growth" => Effect::HoleGrowth { p: g(0)? },
            "drop-blend" => Effect::DropBlend { p: g(0)?, a: g(1)? },
            "riser-blend" => Effect::RiserBlend { foot: g(0)?, top: g(1)? },
            "floor-lift" => Effect::FloorLift { x: g(0)?, p: g(1)?, a: g(2)? },
            "drop-holes" => Effect::DropHoles { p: g(0)? },
            "tilt" => Effect::Tilt { pitch: g(0)?, roll: g(1)?, x0: g(2)?, range: g(3)? },
            "shake" => Effect::Shake { sigma: g(0)?, edge: g(1)? },
            "step-jitter" => Effect::StepJitter { sigma: g(0)?, edge: g(1)? },
            "lag" => Effect::Lag { s: g(0)?, spread: g(1)? },
            "drift" => Effect::Drift { rate: g(0)?, zrate: g(1)?, x0: g(2)? },
            _ => return None,
        })
    }

    /// Place in the physical chain: where the map puts the terrain (lag,
    /// drift), what the sensor can see (fov,
    /// startup, occlusion), what the matcher rejects at jumps (edge-holes),
    /// how fusion and resampling shape heights (mixed-cells, smoothing,
    /// bias, noise, quantization),
    /// what is lost at the end (dropout, patch-dropout, row-dropout).
    pub fn stage(&self) -> u8 {
        match self {
            // The map's geometry at an older or a believed pose: the
            // terrain every later stage sees.
            Effect::Lag { .. } | Effect::Drift { .. } => 0,
            Effect::Fov { .. } | Effect::ViewTop { .. } => 1,
            Effect::Startup { .. } => 2,
            Effect::Occlusion { .. } => 3,
            Effect::EdgeHoles { .. } | Effect::RimHoles { .. } | Effect::DropHoles { .. } => 4,
            Effect::PitFill { .. } => 5,
            Effect::MixedCells { .. } => 6,
            // Both move cells at drops, after the mixed cells; of the two,
            // the one added to a model first is applied first.
            Effect::DropBlend { .. } | Effect::FloorLift { .. } => 7,
            Effect::RiserBlend { .. } => 8,
            Effect::Smoothing { .. } => 9,
            // Registration: heights tilted as the points are placed.
            Effect::Bias { .. } | Effect::Tilt { .. } | Effect::Shake { .. } | Effect::StepJitter { .. } => 10,
            Effect::Noise { .. } => 11,
            Effect::Quantization { .. } => 12,
            Effect::Dropout { .. } => 13,
            Effect::PatchDropout { .. } => 14,
            Effect::HoleGrowth { .. } => 15,
            Effect::RowDropout { .. } => 16,
        }
    }

    /// Check the parameters: finite, probabilities in [0, 1], sigma >= 0,
    /// w in (0, 1], q > 0, h > 0, x_min < x_max.
    pub fn check(&self) -> Result<(), String> {
        if let Some((n, v)) = self.params().into_iter().find(|(_, v)| !v.is_finite()) {
            return Err(format!("{n} = {v} is not a finite number"));
        }
        if let Some((n, v)) = self.params().into_iter().find(|(_, v)| v.abs() > MAX_PARAM) {
            return Err(format!("{n} = {v:e} is outside -{MAX_PARAM}..={MAX_PARAM} (the grid spans 2 m; no sensor effect is that large)"));
        }
        match *self {
            Effect::Noise { sigma0, k } if sigma0 < 0.0 || k < 0.0 => Err("sigma0 and k must be >= 0".into()),
            Effect::Dropout { p }
            | Effect::RowDropout { p }
            | Effect::Startup { p, .. }
            | Effect::EdgeHoles { p, .. }
            | Effect::RimHoles { p, .. }
            | Effect::PitFill { p, .. }
            | Effect::HoleGrowth { p }
            | Effect::DropHoles { p }
            | Effect::DropBlend { p, .. }
            | Effect::FloorLift { p, .. }
                if !(0.0..=1.0).contains(&p) =>
            {
                Err(format!("p = {p} is not a probability"))
            }
            Effect::Startup { v, .. } if v < 0.0 => Err(format!("v = {v} must be >= 0")),
            Effect::PatchDropout { n, r, a } if !(0.0..=PATCH_SLOTS as f64).contains(&n) || r < 0.0 || !(0.0..=1.0).contains(&a) => {
                Err(format!("n = {n} must be in [0, {PATCH_SLOTS}], r = {r} >= 0 and a = {a} in [0, 1]"))
            }
            Effect::EdgeHoles { g, .. } | Effect::RimHoles { g, .. } | Effect::PitFill { g, .. } if g <= 0.0 => {
                Err(format!("g = {g} must be > 0"))
            }
            Effect::DropBlend { a, .. } if !(0.0..=1.0).contains(&a) => Err(format!("a = {a} must be in [0, 1]")),
            Effect::FloorLift { a, .. } if a < 0.0 => Err(format!("a = {a} must be >= 0")),
            Effect::RiserBlend { foot, top } if !(-1.0..=1.0).contains(&foot) || !(-1.0..=1.0).contains(&top) => {
                Err(format!("foot = {foot} and top = {top} must be in [-1, 1]"))
            }
            Effect::MixedCells { up, down } if up < 0.0 || down < 0.0 => Err(format!("up = {up} and down = {down} must be >= 0")),
            Effect::Tilt { pitch, roll, .. } if !(0.0..=MAX_TILT).contains(&pitch) || !(0.0..=MAX_TILT).contains(&roll) => {
                Err(format!("pitch = {pitch} and roll = {roll} must be in [0, {MAX_TILT}] rad"))
            }
            Effect::Tilt { range, .. } if !(0.0..=MAX_TILT_RANGE).contains(&range) => {
                Err(format!("range = {range} must be in [0, {MAX_TILT_RANGE}] m"))
            }
            Effect::Shake { sigma, edge } if !(0.0..=MAX_TILT).contains(&sigma) || edge < 0.0 => {
                Err(format!("sigma = {sigma} must be in [0, {MAX_TILT}] rad and edge = {edge} >= 0"))
            }
            Effect::StepJitter { sigma, edge } if sigma < 0.0 || edge < 0.0 => {
                Err(format!("sigma = {sigma} and edge = {edge} must be >= 0"))
            }
            Effect::Lag { s, spread } if s.abs() > MAX_LAG || !(0.0..=1.0).contains(&spread) => {
                Err(format!("s = {s} must be in [-{MAX_LAG}, {MAX_LAG}] m and spread = {spread} in [0, 1]"))
            }
            Effect::Drift { rate, zrate, .. } if rate < 0.0 || zrate < 0.0 => {
                Err(format!("rate = {rate} and zrate = {zrate} must be >= 0"))
            }
            Effect::Occlusion { h, .. } if h <= 0.0 => Err(format!("sensor height h = {h} must be > 0")),
            Effect::Fov { x_min, x_max } if x_min >= x_max => Err(format!("x_min = {x_min} must be < x_max = {x_max}")),
            Effect::Smoothing { w } if !(w > 0.0 && w <= 1.0) => Err(format!("w = {w} must be in (0, 1]")),
            Effect::Quantization { q } if q < MIN_QUANTUM => Err(format!("q = {q:e} must be >= {MIN_QUANTUM:e} m")),
            _ => Ok(()),
        }
    }

    /// Uniforms this effect reads per record, whatever its parameters
    /// (common random numbers for the fitter; the width of its slice of the
    /// ONNX graph's `uniform` input): 100 (noise: 50 Box-Muller pairs, one
    /// normal per cell; dropout, edge-holes, rim-holes, pit-fill,
    /// hole-growth, riser-blend: one per cell), 200 (drop-blend,
    /// floor-lift, drop-holes: two per cell), 20 (row-dropout: one per
    /// row), 2 (startup), 3 per slot (patch-dropout), 19 x 6 (mixed-cells:
    /// per row boundary a step position, then a reach per column), 2 (tilt,
    /// shake: one Box-Muller pair), 100 (step-jitter: one normal per cell, as
    /// noise), 1 (lag), 40 (drift: a Box-Muller pair
    /// per row, its x and its height step), 0 (the deterministic effects).
    pub fn draws(&self) -> usize {
        match self {
            Effect::Noise { .. }
            | Effect::Dropout { .. }
            | Effect::EdgeHoles { .. }
            | Effect::RimHoles { .. }
            | Effect::PitFill { .. }
            | Effect::HoleGrowth { .. }
            | Effect::RiserBlend { .. }
            | Effect::StepJitter { .. } => GRID_ROWS * COLS,
            Effect::DropBlend { .. } | Effect::FloorLift { .. } | Effect::DropHoles { .. } => 2 * GRID_ROWS * COLS,
            Effect::RowDropout { .. } => GRID_ROWS,
            Effect::Startup { .. } => 2,
            Effect::PatchDropout { .. } => 3 * PATCH_SLOTS,
            Effect::MixedCells { .. } => (GRID_ROWS - 1) * (1 + COLS),
            Effect::Tilt { .. } | Effect::Shake { .. } => 2,
            Effect::Lag { .. } => 1,
            Effect::Drift { .. } => 2 * GRID_ROWS,
            Effect::Occlusion { .. }
            | Effect::Fov { .. }
            | Effect::ViewTop { .. }
            | Effect::Smoothing { .. }
            | Effect::Bias { .. }
            | Effect::Quantization { .. } => 0,
        }
    }

    /// Apply to one DEM, drawing this effect's uniforms from `rng`
    /// ([`crate::draws::uniform`]).
    pub fn apply(&self, d: &mut Dem, rng: &mut impl RngCore) {
        let mut u = vec![0.0f32; self.draws()];
        crate::draws::fill_uniform(rng, &mut u);
        self.apply_drawn(d, &u, None)
    }

    /// Apply to one DEM with this effect's uniforms for the record (`u`,
    /// [`Effect::draws`] of them) and the record's time in its run, when
    /// known (only `startup` uses it).
    pub fn apply_drawn(&self, d: &mut Dem, u: &[f32], time: Option<f64>) {
        assert_eq!(u.len(), self.draws(), "{}: wrong number of uniforms", self.name());
        let rng = &mut Draws::new(u);
        match *self {
            Effect::Noise { sigma0, k } => {
                let (sx, sz) = NOISE_ORIGIN;
                let normals: [f64; GRID_ROWS * COLS] = rng.normals();
                for r in 0..GRID_ROWS {
                    for c in 0..COLS {
                        let z = normals[r * COLS + c];
                        if d.is_valid(r, c) {
                            let h = d.height(r, c) as f64;
                            let (dx, dy, dz) =
                                (row_center_x(r) - sx, col_center_y(c), h.clamp(-NOISE_RANGE_HEIGHT, NOISE_RANGE_HEIGHT) - sz);
                            let sigma = sigma0 + k * (dx * dx + dy * dy + dz * dz);
                            d.set_valid(r, c, (h + sigma * z) as f32);
                        }
                    }
                }
            }
            Effect::Dropout { p } => {
                for r in 0..GRID_ROWS {
                    for c in 0..COLS {
                        let u: f64 = rng.gen();
                        if u < p && d.is_valid(r, c) {
                            d.set_missing(r, c);
                        }
                    }
                }
            }
            Effect::RowDropout { p } => {
                for r in 0..GRID_ROWS {
                    let u: f64 = rng.gen();
                    if u < p {
                        (0..COLS).for_each(|c| d.set_missing(r, c));
                    }
                }
            }
            Effect::Occlusion { h, x0 } => occlude(d, h, x0),
            Effect::Fov { x_min, x_max } => {
                for r in 0..GRID_ROWS {
                    let x = row_center_x(r);
                    if x < x_min || x > x_max {
                        (0..COLS).for_each(|c| d.set_missing(r, c));
                    }
                }
            }
            Effect::ViewTop { h, t } => {
                for r in 0..GRID_ROWS {
                    let top = h - t * row_center_x(r);
                    for c in 0..COLS {
                        if d.is_valid(r, c) && d.height(r, c) as f64 > top {
                            d.set_missing(r, c);
                        }
                    }
                }
            }
            Effect::Smoothing { w } => smooth(d, w),
            Effect::Bias { b, t } => {
                for r in 0..GRID_ROWS {
                    let off = b + t * row_center_x(r);
                    for c in 0..COLS {
                        if d.is_valid(r, c) {
                            d.set_valid(r, c, (d.height(r, c) as f64 + off) as f32);
                        }
                    }
                }
            }
            Effect::Quantization { q } => {
                for r in 0..GRID_ROWS {
                    for c in 0..COLS {
                        if d.is_valid(r, c) {
                            // In float32, the graph's arithmetic: the same rounding everywhere.
                            let (h, q) = (d.height(r, c), q as f32);
                            d.set_valid(r, c, q * (h / q + ROUND_UP_FROM as f32).floor());
                        }
                    }
                }
            }
            Effect::Startup { x0, v, p } => {
                let (u1, u2): (f64, f64) = (rng.gen(), rng.gen());
                let edge = match time {
                    Some(t) if v > 0.0 => Some(x0 - v * t),
                    _ => (u1 < p).then_some(x0 - u2 * (x0 - X_BACK)),
                };
                if let Some(e) = edge {
                    for r in (0..GRID_ROWS).filter(|&r| row_center_x(r) < e) {
                        (0..COLS).for_each(|c| d.set_missing(r, c));
                    }
                }
            }
            Effect::PatchDropout { n, r, a } => drop_patches(d, rng, n, r, a),
            Effect::MixedCells { up, down } => mix_cells(d, rng, up, down),
            Effect::HoleGrowth { p } => grow_holes(d, rng, p),
            Effect::DropHoles { p } => drop_holes(d, rng, p),
            Effect::DropBlend { p, a } => blend_drops(d, rng, p, a),
            Effect::FloorLift { x, p, a } => lift_floors(d, rng, x, p, a),
            Effect::RiserBlend { foot, top } => blend_risers(d, rng, foot, top),
            Effect::Tilt { pitch, roll, x0, range } => {
                let [z1, z2]: [f64; 2] = rng.normals();
                tilt_plane(d, pitch * z1, roll * z2, |x| range + x.max(x0) - x0);
            }
            Effect::Shake { sigma, edge } => {
                let [z1, z2]: [f64; 2] = rng.normals();
                let s = sigma + edge * step_under_tracks(d);
                tilt_plane(d, s * z1, s * z2, |x| x);
            }
            Effect::StepJitter { sigma, edge } => {
                let normals: [f64; GRID_ROWS * COLS] = rng.normals();
                jitter_steps(d, &normals, sigma + edge * step_under_tracks(d));
            }
            Effect::Lag { s, spread } => {
                let shift = s * (1.0 + spread * (2.0 * rng.gen() - 1.0));
                let climb = shift * climb_slope(d);
                shift_rows(d, &[shift; GRID_ROWS], &[climb; GRID_ROWS]);
            }
            Effect::Drift { rate, zrate, x0 } => {
                let z: [f64; 2 * GRID_ROWS] = rng.normals();
                let (dx, dz) = drift_walk(&z, rate, zrate, x0);
                shift_rows(d, &dx, &dz);
            }
            Effect::EdgeHoles { g, p } => jump_holes(d, rng, g, p, 1.0),
            Effect::RimHoles { g, p } => jump_holes(d, rng, g, p, -1.0),
            Effect::PitFill { g, p } => {
                let z = heights(d);
                let at = |r: usize, c: usize| if r < GRID_ROWS && c < COLS { z[r][c] } else { None };
                for (r, row) in z.iter().enumerate() {
                    for (c, &zc) in row.iter().enumerate() {
                        let u: f64 = rng.gen();
                        let Some(zc) = zc else { continue };
                        let rims = [(at(r.wrapping_sub(1), c), at(r + 1, c)), (at(r, c.wrapping_sub(1)), at(r, c + 1))];
                        let fill = rims.into_iter().filter_map(|(a, b)| Some(a?.min(b?))).filter(|&rim| rim - zc > g).reduce(f64::max);
                        if let (Some(rim), true) = (fill, u < p) {
                            d.set_valid(r, c, rim as f32);
                        }
                    }
                }
            }
        }
    }
}

impl std::fmt::Display for Effect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let p: Vec<String> = self.params().iter().map(|(n, v)| format!("{n}={}", short_number(*v))).collect();
        write!(f, "{}({})", self.name(), p.join(", "))
    }
}

/// `v` with four decimals, or in scientific notation when that would hide
/// it (below 1e-3 or from 1e5 on).
fn short_number(v: f64) -> String {
    if v != 0.0 && (v.abs() < 1e-3 || v.abs() >= 1e5) {
        format!("{v:.3e}")
    } else {
        format!("{v:.4}")
    }
}

/// True when cell `(t, c)` of the original heights `z` (None = missing) is
/// hidden from a sensor at `(x0, h)`: see the module table.
pub fn hidden(z: &[[Option<f64>; COLS]; GRID_ROWS], t: usize, c: usize, h: f64, x0: f64) -> bool {
    let Some(zt) = z[t][c] else { return false };
    let xt = row_center_x(t);
    if (xt - x0).abs() <= HALF {
        return false;
    }
    let dir = if xt > x0 { 1.0 } else { -1.0 };
    // A top above the sensor faces away from it: only the cell that holds
    // the face toward the sensor (its near neighbour lower) is seen.
    if zt > h + OCCLUSION_TOLERANCE {
        let near = if dir > 0.0 { t.checked_sub(1) } else { Some(t + 1).filter(|&n| n < GRID_ROWS) };
        if near.and_then(|n| z[n][c]).is_some_and(|zn| zn > zt - OCCLUSION_TOLERANCE) {
            return true;
        }
    }
    let xf = xt + dir * HALF;
    let line = |x: f64| h + (zt - h) * (x - x0) / (xf - x0);
    let rows: Box<dyn Iterator<Item = usize>> = if dir > 0.0 { Box::new(0..t) } else { Box::new(t + 1..GRID_ROWS) };
    for b in rows {
        let Some(zb) = z[b][c] else { continue };
        let xb = row_center_x(b);
        // The blocker's top, clipped to the stretch between sensor and target.
        let (lo, hi) = ((xb - HALF).max(x0.min(xf)), (xb + HALF).min(x0.max(xf)));
        if lo >= hi {
            continue;
        }
        if zb > line(lo).min(line(hi)) + OCCLUSION_TOLERANCE {
            return true;
        }
    }
    false
}

fn heights(d: &Dem) -> [[Option<f64>; COLS]; GRID_ROWS] {
    std::array::from_fn(|r| std::array::from_fn(|c| d.is_valid(r, c).then(|| d.height(r, c) as f64)))
}

/// `patch-dropout` (see the module table). A DEM cell is the mean of its
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
    for _ in 0..PATCH_SLOTS {
        let (u, s, t): (f64, f64, f64) = (rng.gen(), rng.gen(), rng.gen());
        if u < n / PATCH_SLOTS as f64 {
            // Centres anywhere a blob can touch the grid.
            blobs.push((xlo - radius + s * (xhi - xlo + 2.0 * radius), ylo - radius + t * (yhi - ylo + 2.0 * radius)));
        }
    }
    if !blobs.is_empty() {
        darken(d, &blobs, radius, a);
    }
}

/// The cells of `d` under dark blobs of `radius` centred at `blobs` (x, y):
/// see [`drop_patches`].
fn darken(d: &mut Dem, blobs: &[(f64, f64)], radius: f64, a: f64) {
    let covered = |x: f64, y: f64| blobs.iter().any(|&(px, py)| (x - px).powi(2) + (y - py).powi(2) <= radius * radius);
    let seen: [[usize; COLS]; GRID_ROWS] = std::array::from_fn(|r| {
        std::array::from_fn(|c| {
            let (x, y) = (row_center_x(r), col_center_y(c));
            [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)]
                .into_iter()
                .filter(|&(sx, sy)| !covered(x + sx * HALF / 2.0, y + sy * HALF / 2.0))
                .count()
        })
    });
    // The heights the map still holds once the blobs are dark.
    let z: [[Option<f64>; COLS]; GRID_ROWS] =
        std::array::from_fn(|r| std::array::from_fn(|c| (d.is_valid(r, c) && seen[r][c] >= 2).then(|| d.height(r, c) as f64)));
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            match (z[r][c], seen[r][c]) {
                (None, _) => d.set_missing(r, c),
                (Some(_), 4) => {}
                (Some(h), _) => {
                    let low =
                        [r.checked_sub(1), Some(r + 1).filter(|&n| n < GRID_ROWS)].into_iter().filter_map(|n| z[n?][c]).fold(h, f64::min);
                    d.set_valid(r, c, (h + a * (low - h)) as f32);
                }
            }
        }
    }
}

fn occlude(d: &mut Dem, h: f64, x0: f64) {
    let z = heights(d);
    for t in 0..GRID_ROWS {
        for c in 0..COLS {
            if hidden(&z, t, c, h, x0) {
                d.set_missing(t, c);
            }
        }
    }
}

/// `edge-holes` (`sign` 1: a neighbour higher by more than g) and
/// `rim-holes` (`sign` -1: lower by more than g): the cell is lost with
/// probability p.
fn jump_holes(d: &mut Dem, rng: &mut Draws, g: f64, p: f64, sign: f64) {
    let z = heights(d);
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let u: f64 = rng.gen();
            let Some(zc) = z[r][c] else { continue };
            let jump = neighbours4(r, c).any(|(rr, cc)| z[rr][cc].is_some_and(|zn| sign * (zn - zc) > g));
            if jump && u < p {
                d.set_missing(r, c);
            }
        }
    }
}

/// `drop-holes` (formula in the module table): drops are read on the DEM
/// as it comes in, so a lost lip makes no new drop. Two uniforms per row
/// boundary and column (the last row's pair unused): whether the edge's
/// cell is lost, and which of the two holds the edge.
fn drop_holes(d: &mut Dem, rng: &mut Draws, p: f64) {
    let z = heights(d);
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let (u, v): (f64, f64) = (rng.gen(), rng.gen());
            let (Some(lip), Some(floor)) = (z[r][c], z.get(r + 1).and_then(|row| row[c])) else { continue };
            if lip - floor > MIXED_JUMP && u < p {
                d.set_missing(if v < 0.5 { r } else { r + 1 }, c);
            }
        }
    }
}

/// `hole-growth`'s probability that a cell with `k` missing 4-neighbours is
/// lost, 1 - (1 - p)^k, as float32: the graph looks it up in the same table.
pub fn growth_threshold(p: f64, k: usize) -> f32 {
    (1.0 - (1.0 - p).powi(k as i32)) as f32
}

/// `hole-growth`: missing neighbours are counted on the DEM as it comes in,
/// so a hole grows by one ring of cells at most.
fn grow_holes(d: &mut Dem, rng: &mut Draws, p: f64) {
    let z = heights(d);
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

/// `drop-blend`: heights are read on the DEM as it comes in, so a cell
/// between two drops blends toward one of them only. Risers (the higher
/// cell ahead) are left alone: the surface seen is continuous there (a
/// corner, not a jump in range), and the emulator moves their cells by a
/// fifth of the step at most.
fn blend_drops(d: &mut Dem, rng: &mut Draws, p: f64, a: f64) {
    let z = heights(d);
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let (u, v): (f64, f64) = (rng.gen(), rng.gen());
            let Some(zc) = z[r][c] else { continue };
            // The other cell across a drop: ahead and lower, or behind and higher.
            let across = |rr: usize, ahead: bool| {
                let zn = z.get(rr).and_then(|row| row[c])?;
                ((if ahead { zc - zn } else { zn - zc }) > MIXED_JUMP).then_some(zn - zc)
            };
            let step = match (across(r + 1, true), across(r.wrapping_sub(1), false)) {
                (Some(f), Some(b)) => Some(if b.abs() > f.abs() + TIE_MARGIN { b } else { f }),
                (f, b) => f.or(b),
            };
            if let (Some(s), true) = (step, u < p) {
                d.set_valid(r, c, (zc + v * a * s) as f32);
            }
        }
    }
}

/// `floor-lift` (formula in the module table): heights are read on the DEM
/// as it comes in, so a cell beyond two drops (a one-cell tread) moves
/// toward the edge just behind it only.
fn lift_floors(d: &mut Dem, rng: &mut Draws, x: f64, p: f64, a: f64) {
    let z = heights(d);
    for (r, row) in z.iter().enumerate() {
        for (c, &zc) in row.iter().enumerate() {
            let (u, v): (f64, f64) = (rng.gen(), rng.gen());
            let (Some(zc), true) = (zc, r > 0 && row_center_x(r) < x) else { continue };
            let Some(edge) = z[r - 1][c] else { continue };
            if edge - zc > MIXED_JUMP && u < p {
                d.set_valid(r, c, (zc + (v * a).min(1.0) * (edge - zc)) as f32);
            }
        }
    }
}

/// `riser-blend`: heights are read on the DEM as it comes in; a cell beside
/// two risers (a one-cell tread) moves across the larger step only.
fn blend_risers(d: &mut Dem, rng: &mut Draws, foot: f64, top: f64) {
    let z = heights(d);
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let u: f64 = rng.gen();
            let Some(zc) = z[r][c] else { continue };
            // (step to the other cell, share): the riser ahead (this cell
            // at its foot) or behind (this cell on its top).
            let across = |rr: usize, share: f64| {
                let zn = z.get(rr).and_then(|row| row[c])?;
                let step = zn - zc;
                let riser = if rr > r { step > MIXED_JUMP } else { -step > MIXED_JUMP };
                riser.then_some((step, share))
            };
            let moved = match (across(r + 1, foot), across(r.wrapping_sub(1), top)) {
                (Some(f), Some(b)) => Some(if b.0.abs() > f.0.abs() + TIE_MARGIN { b } else { f }),
                (f, b) => f.or(b),
            };
            if let Some((step, share)) = moved {
                d.set_valid(r, c, (zc + u * share * step) as f32);
            }
        }
    }
}

/// The 4-neighbours of cell (r, c) inside the grid.
fn neighbours4(r: usize, c: usize) -> impl Iterator<Item = (usize, usize)> {
    [(r.wrapping_sub(1), c), (r + 1, c), (r, c.wrapping_sub(1)), (r, c + 1)].into_iter().filter(|&(rr, cc)| rr < GRID_ROWS && cc < COLS)
}

/// `mixed-cells` (formula in the module table). Each cell is two halves
/// along x, back (toward row r - 1) and front; a half's centre lies
/// [`HALF`] / 2 from its cell's boundary, the other half's 3/2 [`HALF`].
/// Where neighbours both reach a half, the higher surface wins, as in a
/// map cell that keeps the higher of two heights.
fn mix_cells(d: &mut Dem, rng: &mut Draws, up: f64, down: f64) {
    let z = heights(d);
    // Per half: the height the higher neighbour spills in, the lower one's.
    let mut raise = [[[f64::NEG_INFINITY; 2]; COLS]; GRID_ROWS];
    let mut lower = [[[f64::INFINITY; 2]; COLS]; GRID_ROWS];
    let (near, far) = (0.5 * HALF, 1.5 * HALF);
    for b in 0..GRID_ROWS - 1 {
        // The step's distance past the boundary into row b (negative: into b + 1).
        let s = (1.0 - 2.0 * rng.gen()) * HALF;
        for c in 0..COLS {
            let u: f64 = rng.gen();
            let (Some(z0), Some(z1)) = (z[b][c], z[b + 1][c]) else { continue };
            if (z1 - z0).abs() <= MIXED_JUMP {
                continue;
            }
            // (lower row, its half at the boundary, higher row, its half, step depth into the lower row)
            let (lo, lo_half, hi, hi_half, depth, reach) = if z1 > z0 { (b, 1, b + 1, 0, s, up) } else { (b + 1, 0, b, 1, -s, down) };
            let (zlo, zhi) = (z0.min(z1), z0.max(z1));
            let into_low = depth + u * reach;
            for (dist, h) in [(near, lo_half), (far, 1 - lo_half)] {
                if into_low > dist {
                    raise[lo][c][h] = raise[lo][c][h].max(zhi);
                }
            }
            for (dist, h) in [(near, hi_half), (far, 1 - hi_half)] {
                if -into_low > dist {
                    lower[hi][c][h] = lower[hi][c][h].min(zlo);
                }
            }
        }
    }
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let Some(zc) = z[r][c] else { continue };
            let half = |h: usize| {
                if raise[r][c][h].is_finite() {
                    raise[r][c][h]
                } else if lower[r][c][h].is_finite() {
                    lower[r][c][h]
                } else {
                    zc
                }
            };
            let m = 0.5 * (half(0) + half(1));
            if m != zc {
                d.set_valid(r, c, m as f32);
            }
        }
    }
}

/// h += a lever(x) + b y on the valid cells (`tilt`, `shake`).
fn tilt_plane(d: &mut Dem, a: f64, b: f64, lever: impl Fn(f64) -> f64) {
    for r in 0..GRID_ROWS {
        let ax = a * lever(row_center_x(r));
        for c in 0..COLS {
            if d.is_valid(r, c) {
                d.set_valid(r, c, (d.height(r, c) as f64 + ax + b * col_center_y(c)) as f32);
            }
        }
    }
}

/// `step-jitter` with sd `s`: each valid cell reads dx = clamp(s z, +-0.1
/// m) off along x (`z` its normal, row-major):
/// h += dx (src(r + 1) - src(r - 1)) / 0.2, where src(k) is row k's height
/// where row k lies in the grid and is valid, else the cell's own (a
/// one-sided slope at an edge of what was seen, none on even ground).
pub fn jitter_steps(d: &mut Dem, z: &[f64; GRID_ROWS * COLS], s: f64) {
    let h = heights(d);
    let cell = dem_core::format::CELL;
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let Some(own) = h[r][c] else { continue };
            let src = |k: Option<usize>| k.filter(|&k| k < GRID_ROWS).and_then(|k| h[k][c]).unwrap_or(own);
            let slope = (src(Some(r + 1)) - src(r.checked_sub(1))) / (2.0 * cell);
            let dx = (s * z[r * COLS + c]).clamp(-cell, cell);
            d.set_valid(r, c, (own + dx * slope) as f32);
        }
    }
}

/// `shake`'s J: the largest height step (m) between valid x-neighbours of
/// the rows under the tracks ([`TRACK_ROWS`]), at most [`SHAKE_MAX_STEP`];
/// 0 when no such pair is valid.
pub fn step_under_tracks(d: &Dem) -> f64 {
    let mut j: f64 = 0.0;
    for r in TRACK_ROWS.0..TRACK_ROWS.1 {
        for c in 0..COLS {
            if d.is_valid(r, c) && d.is_valid(r + 1, c) {
                j = j.max((d.height(r + 1, c) as f64 - d.height(r, c) as f64).abs());
            }
        }
    }
    j.min(SHAKE_MAX_STEP)
}

/// `lag`'s climb per metre of shift: tan of the record's pitch (row 20,
/// column 0), clamped to +-[`MAX_CLIMB_PITCH`]; 0 when it is not finite.
pub fn climb_slope(d: &Dem) -> f64 {
    let p = d.attitude()[0] as f64;
    if p.is_finite() {
        p.clamp(-MAX_CLIMB_PITCH, MAX_CLIMB_PITCH).tan()
    } else {
        0.0
    }
}

/// `drift`'s displacements per row from its 40 normals (pair j: `z[2j]`
/// along x, `z[2j + 1]` in height): cumulative sums going back from the
/// last row whose centre lies behind `x0`, one step of sd rate sqrt(0.1)
/// (zrate sqrt(0.1)) per row; 0 for the rows from x0 on.
pub fn drift_walk(z: &[f64; 2 * GRID_ROWS], rate: f64, zrate: f64, x0: f64) -> ([f64; GRID_ROWS], [f64; GRID_ROWS]) {
    let step = dem_core::format::CELL.sqrt();
    let (mut dx, mut dz) = ([0.0; GRID_ROWS], [0.0; GRID_ROWS]);
    let (mut sx, mut sz) = (0.0, 0.0);
    for r in (0..GRID_ROWS).rev().filter(|&r| row_center_x(r) < x0) {
        sx += rate * step * z[2 * r];
        sz += zrate * step * z[2 * r + 1];
        dx[r] = sx;
        dz[r] = sz;
    }
    (dx, dz)
}

/// Row `r` of every column reads the column at x - dx[r], plus dz[r]
/// (`lag`, `drift`), on the valid cells; validity is kept. With q = dx / 0.1
/// (in rows, clamped to +-[`MAX_SHIFT`] / 0.1), m = floor(q), g = q - m:
/// h' = (1 - g) src(r - m) + g src(r - m - 1) + dz, where src(k) is row k's
/// height when row k lies in the grid and is valid there, else the cell's
/// own height (nothing seen there: the cell keeps what it had; row 0 keeps
/// its value when nothing lies behind). The same as weights max(0, 1 - |q -
/// m|) on src(r - m) for every integer m, as the graph computes it:
/// continuous in dx, so no runtime's rounding of q decides a cell.
pub fn shift_rows(d: &mut Dem, dx: &[f64; GRID_ROWS], dz: &[f64; GRID_ROWS]) {
    let z = heights(d);
    let lim = MAX_SHIFT / dem_core::format::CELL;
    for r in 0..GRID_ROWS {
        let q = (dx[r] / dem_core::format::CELL).clamp(-lim, lim);
        let m = q.floor();
        let g = q - m;
        let k = r as i64 - m as i64;
        for (c, own) in z[r].iter().enumerate() {
            let Some(own) = *own else { continue };
            let src = |k: i64| usize::try_from(k).ok().filter(|&k| k < GRID_ROWS).and_then(|k| z[k][c]).unwrap_or(own);
            let h = (1.0 - g) * src(k) + g * src(k - 1);
            d.set_valid(r, c, (h + dz[r]) as f32);
        }
    }
}

fn smooth(d: &mut Dem, w: f64) {
    let z = heights(d);
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

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::format::{empty_dem, FLAT_GROUND};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn flat() -> Dem {
        let mut d = empty_dem();
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                d.set_valid(r, c, FLAT_GROUND);
            }
        }
        d
    }

    fn rng() -> ChaCha8Rng {
        ChaCha8Rng::seed_from_u64(1)
    }

    #[test]
    fn flat_ground_is_never_occluded_and_a_box_casts_a_shadow() {
        let mut d = flat();
        Effect::Occlusion { h: 0.45, x0: 0.15 }.apply(&mut d, &mut rng());
        assert_eq!(d.valid_cells(), 100);
        // A 0.2 m box on rows 10..12 (x 0.45..0.65): shadow behind it.
        let mut d = flat();
        for r in 10..12 {
            (0..COLS).for_each(|c| d.set_valid(r, c, 0.13));
        }
        Effect::Occlusion { h: 0.45, x0: 0.15 }.apply(&mut d, &mut rng());
        assert!(d.is_valid(11, 0) && d.is_valid(9, 0), "the box and what is before it are seen");
        // The box (x 0.4..0.6) is 0.2 m tall, the sensor 0.52 m above the
        // ground: the shadow reaches (0.6 - 0.15) * 0.2 / 0.32 = 0.28 m past
        // the box, to x = 0.88; a cell is seen when its far edge is.
        assert!(!d.is_valid(12, 2) && !d.is_valid(13, 2));
        assert!(d.is_valid(14, 2), "x 0.8..0.9: its far edge is in sight");
    }

    #[test]
    fn fov_bias_quantization_smoothing_follow_their_formulas() {
        let mut d = flat();
        Effect::Fov { x_min: -0.1, x_max: 1.0 }.apply(&mut d, &mut rng());
        assert!(!d.is_valid(4, 0) && d.is_valid(5, 0) && d.is_valid(15, 0) && !d.is_valid(16, 0));
        let mut d = flat();
        Effect::Bias { b: 0.01, t: 0.02 }.apply(&mut d, &mut rng());
        assert!((d.height(0, 0) as f64 - (-0.07 + 0.01 - 0.02 * 0.55)).abs() < 1e-6);
        Effect::Quantization { q: 0.025 }.apply(&mut d, &mut rng());
        assert!(((d.height(0, 0) as f64) / 0.025).fract().abs() < 1e-4 || ((d.height(0, 0) as f64) / 0.025).fract().abs() > 0.9999);
        let mut d = flat();
        d.set_valid(10, 2, 0.73);
        Effect::Smoothing { w: 0.5 }.apply(&mut d, &mut rng());
        assert!((d.height(10, 2) - (0.5 * 0.73 + 0.5 * -0.07)).abs() < 1e-6);
        assert!((d.height(9, 1) - (-0.07 + 0.8 / 16.0 / (0.5 + 0.5))).abs() < 1e-6);
    }

    /// riser-blend on the same terrain (a drop at 9/10, a riser at 14/15):
    /// only the two cells beside the riser move, the foot cell by u foot of
    /// the step toward the top (foot > 0: up), the top cell by u top toward
    /// the foot (top < 0: up, away from it), u uniform: mean share foot / 2
    /// and top / 2.
    #[test]
    fn riser_blend_moves_cells_beside_risers_only() {
        let (foot, top) = (0.5, -0.3);
        let mut r = rng();
        let (mut share, n) = ([0.0f64; 2], 4000);
        for _ in 0..n {
            let mut d = flat();
            for row in (0..10).chain(15..GRID_ROWS) {
                (0..COLS).for_each(|c| d.set_valid(row, c, 0.1));
            }
            let before = d;
            Effect::RiserBlend { foot, top }.apply(&mut d, &mut r);
            for row in 0..GRID_ROWS {
                for c in 0..COLS {
                    let (h0, h1) = (before.height(row, c) as f64, d.height(row, c) as f64);
                    match row {
                        14 => {
                            let toward = (h1 - h0) / 0.17;
                            assert!((-1e-6..=foot + 1e-6).contains(&toward), "foot: {h0} -> {h1}");
                            share[0] += toward;
                        }
                        15 => {
                            let toward = (h0 - h1) / 0.17;
                            assert!((top - 1e-6..=1e-6).contains(&toward), "top: {h0} -> {h1}");
                            share[1] += toward;
                        }
                        _ => assert_eq!(h0, h1, "row {row} is beside no riser (a drop at 9/10)"),
                    }
                }
            }
        }
        let cells = (n * COLS) as f64;
        assert!((share[0] / cells - foot / 2.0).abs() < 0.01, "{share:?}");
        assert!((share[1] / cells - top / 2.0).abs() < 0.01, "{share:?}");
        assert!(Effect::RiserBlend { foot: 1.2, top: 0.0 }.check().is_err());
    }

    /// floor-lift on the same terrain: only the floor beyond the drop (row
    /// 10, x = 0.45 m) moves, and only when its row lies behind x; with p
    /// it reads min(1, u a) of the 0.17 m step up, u uniform: for a = 2 the
    /// mean share is p (1/4 + 1/2) and half the moved cells read the edge.
    #[test]
    fn floor_lift_raises_the_floor_beyond_a_drop_in_the_rows_behind_x_only() {
        let (p, a) = (0.6, 2.0);
        let terrain = || {
            let mut d = flat();
            for row in (0..10).chain(15..GRID_ROWS) {
                (0..COLS).for_each(|c| d.set_valid(row, c, 0.1));
            }
            d
        };
        let mut r = rng();
        let (mut share, mut whole, n) = (0.0f64, 0usize, 4000);
        for _ in 0..n {
            let before = terrain();
            let mut d = before;
            Effect::FloorLift { x: 0.5, p, a }.apply(&mut d, &mut r);
            for row in 0..GRID_ROWS {
                for c in 0..COLS {
                    let (h0, h1) = (before.height(row, c) as f64, d.height(row, c) as f64);
                    if row == 10 {
                        let up = (h1 - h0) / 0.17;
                        assert!((-1e-6..=1.0 + 1e-6).contains(&up), "{h0} -> {h1}");
                        share += up;
                        whole += usize::from(up > 1.0 - 1e-6);
                    } else {
                        assert_eq!(h0, h1, "row {row} lies beyond no drop");
                    }
                }
            }
            // Row 10's centre (0.45 m) is not behind x = 0.4: nothing moves.
            let mut d = before;
            Effect::FloorLift { x: 0.4, p: 1.0, a }.apply(&mut d, &mut r);
            assert_eq!(d, before);
        }
        let cells = (n * COLS) as f64;
        assert!((share / cells - p * 0.75).abs() < 0.01, "{share}");
        assert!((whole as f64 / cells - p * 0.5).abs() < 0.015, "{whole}");
        assert!(Effect::FloorLift { x: 0.5, p: 1.2, a }.check().is_err());
        assert!(Effect::FloorLift { x: 0.5, p, a: -1.0 }.check().is_err());
    }

    #[test]
    fn a_patch_loses_the_cells_it_covers_and_lowers_the_ones_it_partly_covers_beside_a_step() {
        // A riser between rows 9 (0.0 m) and 10 (0.15 m); rows 10.. are its top.
        let stair = || {
            let mut d = flat();
            for r in 10..GRID_ROWS {
                (0..COLS).for_each(|c| d.set_valid(r, c, FLAT_GROUND + 0.15));
            }
            d
        };
        let (x11, y2) = (row_center_x(11), col_center_y(2));
        // Centred on cell (11, 2), radius 9 cm: its four quarters covered
        // (3.5 cm away), and the near two quarters (7.9 cm) of the four
        // cells around it, none of the diagonal cells' (10.6 cm).
        let mut d = stair();
        darken(&mut d, &[(x11, y2)], 0.09, 0.5);
        assert!(!d.is_valid(11, 2));
        // Row 10 (the riser's top) keeps half its quarters: it reads half
        // way down to its lower neighbour, row 9.
        assert!((d.height(10, 2) - (FLAT_GROUND + 0.075)).abs() < 1e-6, "{}", d.height(10, 2));
        // Row 12 and the cells beside along y have no lower x-neighbour
        // left: they keep their heights.
        for (r, c) in [(12, 2), (11, 1), (11, 3)] {
            assert!((d.height(r, c) - (FLAT_GROUND + 0.15)).abs() < 1e-6, "({r}, {c})");
        }
        assert_eq!(d.valid_cells(), 99);
        // Centred on the riser's foot (row 9): the foot is lost, so the top
        // beside it has no lower neighbour left and keeps its height.
        let mut d = stair();
        darken(&mut d, &[(row_center_x(9), y2)], 0.09, 1.0);
        assert!(!d.is_valid(9, 2));
        assert!((d.height(10, 2) - (FLAT_GROUND + 0.15)).abs() < 1e-6);
        // a = 0: the partly covered cells keep their heights.
        let mut d = stair();
        darken(&mut d, &[(x11, y2)], 0.09, 0.0);
        assert!((d.height(10, 2) - (FLAT_GROUND + 0.15)).abs() < 1e-6);
        // Too small to cover three quarters of any cell: nothing is lost.
        let mut d = stair();
        darken(&mut d, &[(x11, y2)], 0.03, 0.0);
        assert_eq!(d.valid_cells(), 100);
    }

    /// drop-blend on a drop (rows 0..10 at 0.1 m, rows 10.. at -0.07 m) and
    /// a riser (rows 15.. back up at 0.1 m): only the two cells beside the
    /// drop move, each with probability p, toward the other by u a of the
    /// drop, u uniform: mean moved share p a / 2.
    #[test]
    fn drop_blend_moves_cells_beside_drops_only() {
        let (p, a) = (0.4, 0.6);
        let mut r = rng();
        let (mut moved, mut share, n) = ([0usize; 2], [0.0f64; 2], 4000);
        for _ in 0..n {
            let mut d = flat();
            for row in (0..10).chain(15..GRID_ROWS) {
                (0..COLS).for_each(|c| d.set_valid(row, c, 0.1));
            }
            let before = d;
            Effect::DropBlend { p, a }.apply(&mut d, &mut r);
            for row in 0..GRID_ROWS {
                for c in 0..COLS {
                    let (h0, h1) = (before.height(row, c) as f64, d.height(row, c) as f64);
                    match row {
                        9 | 10 => {
                            let toward = if row == 9 { h0 - h1 } else { h1 - h0 };
                            assert!((-1e-6..=a * 0.17 + 1e-6).contains(&toward), "row {row}: {h0} -> {h1}");
                            let k = row - 9;
                            moved[k] += usize::from(toward > 0.0);
                            share[k] += toward / 0.17;
                        }
                        _ => assert_eq!(h0, h1, "row {row} is beside no drop (a riser at 14/15)"),
                    }
                }
            }
        }
        for k in 0..2 {
            let cells = (n * COLS) as f64;
            assert!((moved[k] as f64 / cells - p).abs() < 0.02, "{moved:?}");
            assert!((share[k] / cells - p * a / 2.0).abs() < 0.01, "{share:?}");
        }
    }

    /// drop-holes on the same terrain (a drop between rows 9 and 10, a
    /// riser between 14 and 15): per column, with probability p one of the
    /// two cells at the drop is lost, the lip or the floor as often, never
    /// both; nothing else is touched, heights are kept.
    #[test]
    fn drop_holes_lose_one_cell_at_a_drop_and_none_at_a_riser() {
        let p = 0.3;
        let mut r = rng();
        let (mut lost, n) = ([0usize; 2], 4000);
        for _ in 0..n {
            let mut d = flat();
            for row in (0..10).chain(15..GRID_ROWS) {
                (0..COLS).for_each(|c| d.set_valid(row, c, 0.1));
            }
            let before = d;
            Effect::DropHoles { p }.apply(&mut d, &mut r);
            for c in 0..COLS {
                assert!(d.is_valid(9, c) || d.is_valid(10, c), "both cells of the drop lost");
                for row in 0..GRID_ROWS {
                    if d.is_valid(row, c) {
                        assert_eq!(d.height(row, c), before.height(row, c));
                    } else {
                        assert!(row == 9 || row == 10, "row {row} is beside no drop (a riser at 14/15)");
                        lost[row - 9] += 1;
                    }
                }
            }
        }
        let cells = (n * COLS) as f64;
        assert!(((lost[0] + lost[1]) as f64 / cells - p).abs() < 0.02, "{lost:?}");
        assert!((lost[0] as f64 / cells - p / 2.0).abs() < 0.02, "{lost:?}");
        assert!(Effect::DropHoles { p: 1.5 }.check().is_err());
    }

    /// Without reach, mixed-cells is the mean of two half cells with the
    /// step uniform between the centres: the lower cell next to a riser
    /// reads half way up when the step lies in its front quarter
    /// (probability 1/4), else its own height; the higher cell half way down
    /// with probability 1/4; slopes (jumps up to 5 cm) are left alone.
    #[test]
    fn mixed_cells_without_reach_is_the_mean_of_half_cells() {
        let (mut low_half, mut high_half) = (0usize, 0usize);
        let mut r1 = rng();
        let n = 4000;
        for _ in 0..n {
            let mut d = flat();
            for r in 10..GRID_ROWS {
                (0..COLS).for_each(|c| d.set_valid(r, c, 0.13));
            }
            d.set_valid(5, 2, -0.03); // a 4 cm bump: a slope, not a step
            Effect::MixedCells { up: 0.0, down: 0.0 }.apply(&mut d, &mut r1);
            let (lo, hi) = (d.height(9, 0) as f64, d.height(10, 0) as f64);
            assert!([-0.07, 0.03].iter().any(|v| (lo - v).abs() < 1e-6), "lower cell reads {lo}");
            assert!([0.13, 0.03].iter().any(|v| (hi - v).abs() < 1e-6), "higher cell reads {hi}");
            low_half += usize::from((lo - 0.03).abs() < 1e-6);
            high_half += usize::from((hi - 0.03).abs() < 1e-6);
            assert_eq!(d.height(5, 2), -0.03);
            assert_eq!(d.height(8, 0), FLAT_GROUND);
            assert!((0..COLS).all(|c| d.height(9, c) == d.height(9, 0)), "one step position per row boundary");
        }
        for k in [low_half, high_half] {
            assert!((k as f64 / n as f64 - 0.25).abs() < 0.03, "{k} of {n}");
        }
        // A long reach past a drop: the cell beyond the edge reads the top
        // unless the step lies deep in it and the reach is short.
        let mut full = 0;
        for _ in 0..n {
            let mut d = flat();
            for r in 0..10 {
                (0..COLS).for_each(|c| d.set_valid(r, c, 0.13));
            }
            Effect::MixedCells { up: 0.0, down: 1.0 }.apply(&mut d, &mut r1);
            full += usize::from((d.height(10, 0) - 0.13).abs() < 1e-6);
            assert_eq!(d.height(11, 0), FLAT_GROUND);
        }
        assert!(full as f64 / n as f64 > 0.85, "{full}");
    }

    #[test]
    fn pit_fill_rim_holes_and_view_top_follow_their_formulas() {
        let mut d = flat();
        d.set_valid(8, 1, -0.2); // a pallet gap: a pit along x and y
        d.set_valid(12, 2, 0.2); // a post: its rim cell is lost
        Effect::PitFill { g: 0.05, p: 1.0 }.apply(&mut d, &mut rng());
        assert_eq!(d.height(8, 1), FLAT_GROUND);
        Effect::RimHoles { g: 0.05, p: 1.0 }.apply(&mut d, &mut rng());
        assert!(!d.is_valid(12, 2) && d.is_valid(11, 2) && d.is_valid(12, 1));
        let mut d = flat();
        d.set_valid(15, 0, 0.2); // x = 0.95: above 0.4 - 0.3 x = 0.115
        d.set_valid(5, 0, 0.2); // x = -0.05: below 0.415
        Effect::ViewTop { h: 0.4, t: 0.3 }.apply(&mut d, &mut rng());
        assert!(!d.is_valid(15, 0) && d.is_valid(5, 0) && d.valid_cells() == 99);
    }

    /// Heights of `d` as f64 (None where missing), for the references below.
    fn grid(d: &Dem) -> Vec<Vec<Option<f64>>> {
        (0..GRID_ROWS).map(|r| (0..COLS).map(|c| d.is_valid(r, c).then(|| d.height(r, c) as f64)).collect()).collect()
    }

    /// A slow reference of a row shift: the column read at x_r - dx[r] by
    /// finding the two row centres around it (x_k = -0.55 + 0.1 k, any
    /// integer k) and interpolating, a row outside the grid or missing
    /// reading the cell's own height; plus dz[r].
    fn reference_shift(z: &[Vec<Option<f64>>], dx: &[f64], dz: &[f64]) -> Vec<Vec<Option<f64>>> {
        let xk = |k: i64| -0.55 + 0.1 * k as f64;
        (0..GRID_ROWS)
            .map(|r| {
                (0..COLS)
                    .map(|c| {
                        let own = z[r][c]?;
                        let p = xk(r as i64) - dx[r].clamp(-MAX_SHIFT, MAX_SHIFT);
                        let k = (-40..40).filter(|&k| xk(k) <= p + 1e-12).max().unwrap();
                        let w = ((p - xk(k)) / 0.1).clamp(0.0, 1.0);
                        let val = |k: i64| if (0..GRID_ROWS as i64).contains(&k) { z[k as usize][c].unwrap_or(own) } else { own };
                        Some((1.0 - w) * val(k) + w * val(k + 1) + dz[r])
                    })
                    .collect()
            })
            .collect()
    }

    fn assert_close(got: &Dem, want: &[Vec<Option<f64>>], tol: f64, what: &str) {
        for (r, row) in want.iter().enumerate().take(GRID_ROWS) {
            for (c, &cell) in row.iter().enumerate().take(COLS) {
                match cell {
                    None => assert!(!got.is_valid(r, c), "{what}: ({r}, {c}) stays missing"),
                    Some(h) => {
                        assert!(got.is_valid(r, c), "{what}: ({r}, {c}) stays valid");
                        assert!((got.height(r, c) as f64 - h).abs() <= tol, "{what}: ({r}, {c}) {} vs {h}", got.height(r, c));
                    }
                }
            }
        }
    }

    /// A DEM of varied heights (a riser, a drop, a slope) with a few
    /// missing cells.
    fn rough() -> Dem {
        let mut d = empty_dem();
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                let h = match r {
                    0..=6 => -0.07 + 0.01 * c as f64,
                    7..=11 => 0.1 + 0.02 * r as f64,
                    _ => -0.2 + 0.03 * (r as f64 - 12.0),
                };
                d.set_valid(r, c, h as f32);
            }
        }
        for (r, c) in [(0, 1), (5, 2), (6, 2), (12, 4), (19, 0), (10, 3)] {
            d.set_missing(r, c);
        }
        d
    }

    /// tilt on flat ground is exactly the plane h + a (range + max(x, x0) -
    /// x0) + b y, a = pitch z1, b = roll z2 from the record's Box-Muller
    /// pair; a missing cell stays missing.
    #[test]
    fn tilt_on_flat_ground_is_the_plane() {
        for (u, x0, range) in [([0.3f32, 0.1f32], 0.45, 0.0), ([0.93, 0.71], -0.6, 2.5), ([0.01, 0.5], 1.2, 0.8)] {
            let (pitch, roll) = (0.02, 0.015);
            let (z1, z2) = crate::draws::box_muller(u[0], u[1]);
            let mut d = flat();
            d.set_missing(3, 3);
            Effect::Tilt { pitch, roll, x0, range }.apply_drawn(&mut d, &u, None);
            let mut want = grid(&flat());
            want[3][3] = None;
            for (r, row) in want.iter_mut().enumerate() {
                for (c, h) in row.iter_mut().enumerate() {
                    let x = row_center_x(r);
                    *h = h.map(|h| h + pitch * z1 * (range + x.max(x0) - x0) + roll * z2 * col_center_y(c));
                }
            }
            assert_close(&d, &want, 1e-7, "tilt");
            // Behind x0 every row reads the same as x0's: no pitch there.
            if x0 > -0.5 {
                assert_eq!(d.height(0, 0), d.height(1, 0));
            }
        }
        assert!(Effect::Tilt { pitch: 0.6, roll: 0.0, x0: 0.0, range: 0.0 }.check().is_err());
        assert!(Effect::Tilt { pitch: 0.01, roll: -0.01, x0: 0.0, range: 0.0 }.check().is_err());
        assert!(Effect::Tilt { pitch: 0.01, roll: 0.01, x0: 0.0, range: -0.1 }.check().is_err());
    }

    /// shake: the same plane about C (x from C, every row) with sd sigma +
    /// edge J, J the largest step between x-neighbours of rows 2..=9; a
    /// step farther ahead is not under the tracks.
    #[test]
    fn shake_rocks_about_c_with_the_step_under_the_tracks() {
        let u = [0.2f32, 0.3f32];
        let (z1, z2) = crate::draws::box_muller(u[0], u[1]);
        let (sigma, edge) = (0.003, 0.07);
        for (step_row, rise, j) in [(8, 0.12, 0.12), (13, 0.12, 0.0), (6, 0.9, SHAKE_MAX_STEP), (2, 0.1, 0.0)] {
            let mut d = flat();
            for r in step_row..GRID_ROWS {
                (0..COLS).for_each(|c| d.set_valid(r, c, FLAT_GROUND + rise as f32));
            }
            let before = grid(&d);
            assert!((step_under_tracks(&d) - j).abs() < 1e-6, "step at {step_row}: {}", step_under_tracks(&d));
            Effect::Shake { sigma, edge }.apply_drawn(&mut d, &u, None);
            let s = sigma + edge * j;
            let want: Vec<Vec<Option<f64>>> = (0..GRID_ROWS)
                .map(|r| (0..COLS).map(|c| before[r][c].map(|h| h + s * z1 * row_center_x(r) + s * z2 * col_center_y(c))).collect())
                .collect();
            assert_close(&d, &want, 1e-6, "shake");
        }
        assert!(Effect::Shake { sigma: 0.01, edge: -0.1 }.check().is_err());
    }

    /// step-jitter on a 0.12 m riser between rows 8 and 9 (under the
    /// tracks, so s = sigma + edge 0.12): flat cells away from the step keep
    /// their heights; the foot and the top move by dx 0.12 / 0.2 each, dx
    /// their own draw clamped to one cell; a missing neighbour reads as the
    /// cell's own height; row 0 and row 19 use the one-sided slope.
    #[test]
    fn step_jitter_moves_only_cells_beside_steps() {
        let (sigma, edge) = (0.01, 0.2);
        let u: Vec<f32> = (0..GRID_ROWS * COLS).map(|i| ((i * 37 % 97) as f32 + 0.5) / 97.0).collect();
        let z: [f64; GRID_ROWS * COLS] = Draws::new(&u).normals();
        let mut d = flat();
        for r in 9..GRID_ROWS {
            (0..COLS).for_each(|c| d.set_valid(r, c, FLAT_GROUND + 0.12));
        }
        d.set_missing(8, 4);
        d.set_valid(19, 0, FLAT_GROUND + 0.2);
        let before = grid(&d);
        Effect::StepJitter { sigma, edge }.apply_drawn(&mut d, &u, None);
        let s = sigma + edge * 0.12;
        let dx = |r: usize, c: usize| (s * z[r * COLS + c]).clamp(-0.1, 0.1);
        let mut want = before.clone();
        for c in 0..COLS {
            if c != 4 {
                want[8][c] = Some(before[8][c].unwrap() + dx(8, c) * 0.12 / 0.2);
            }
            // Row 9's foot neighbour at (8, 4) is missing: it reads its own height.
            let drop = if c == 4 { 0.0 } else { 0.12 };
            want[9][c] = Some(before[9][c].unwrap() + dx(9, c) * drop / 0.2);
        }
        want[19][0] = Some(before[19][0].unwrap() + dx(19, 0) * (0.2 - 0.12) / 0.2);
        want[18][0] = Some(before[18][0].unwrap() + dx(18, 0) * (0.2 - 0.12) / 0.2);
        assert_close(&d, &want, 1e-6, "step-jitter");
        assert!(!d.is_valid(8, 4), "a missing cell stays missing");
        assert!((0..COLS).any(|c| (d.height(8, c) as f64 - before[8][c].unwrap_or(0.0)).abs() > 1e-3), "the foot moves");
        assert!(Effect::StepJitter { sigma: 0.01, edge: -0.1 }.check().is_err());
    }

    /// lag of a step moves it by s: at s = 0.1 m the row beyond the riser
    /// reads the lower surface; at 0.05 m it reads the mean; the climb
    /// s tan(pitch) is added from row 20; row 0 keeps its value; a missing
    /// cell behind is read as the cell's own height; validity is kept.
    #[test]
    fn lag_moves_a_step_by_s_and_adds_the_climb() {
        let step = || {
            let mut d = flat();
            for r in 10..GRID_ROWS {
                (0..COLS).for_each(|c| d.set_valid(r, c, 0.1));
            }
            d
        };
        let mut d = step();
        Effect::Lag { s: 0.1, spread: 0.0 }.apply_drawn(&mut d, &[0.77], None);
        assert!((d.height(10, 0) - FLAT_GROUND).abs() < 1e-6 && (d.height(11, 0) - 0.1).abs() < 1e-6);
        assert!((d.height(0, 0) - FLAT_GROUND).abs() < 1e-6, "row 0 keeps its value");
        let mut d = step();
        Effect::Lag { s: 0.05, spread: 0.0 }.apply_drawn(&mut d, &[0.3], None);
        assert!((d.height(10, 2) as f64 - (0.1 + -0.07) / 2.0).abs() < 1e-6 && (d.height(11, 2) - 0.1).abs() < 1e-6);
        // The climb: pitch 0.3 rad, u = 0.75 with spread 0.4: s_r = 0.06 (1 + 0.2).
        let mut d = step();
        let mut att = d.attitude();
        att[0] = 0.3;
        d.set_attitude(att);
        d.set_missing(4, 1);
        Effect::Lag { s: 0.06, spread: 0.4 }.apply_drawn(&mut d, &[0.75], None);
        let sr = 0.06 * 1.2;
        let mut z = grid(&step());
        z[4][1] = None;
        let want = reference_shift(&z, &[sr; GRID_ROWS], &[sr * 0.3f64.tan(); GRID_ROWS]);
        assert_close(&d, &want, 1e-6, "lag with a climb");
        assert!(!d.is_valid(4, 1) && d.attitude()[0] == 0.3);
        // A missing cell behind a valid one: the valid one reads its own
        // height in its place (row 5, column 1: row 4 is missing).
        assert!((d.height(5, 1) as f64 - (FLAT_GROUND as f64 + sr * 0.3f64.tan())).abs() < 1e-6);
        assert!(Effect::Lag { s: 0.6, spread: 0.0 }.check().is_err() && Effect::Lag { s: 0.1, spread: 1.5 }.check().is_err());
    }

    /// lag against the slow reference on a rough DEM, shifts either way
    /// and across whole rows.
    #[test]
    fn lag_equals_the_reference() {
        let mut r = rng();
        for (s, spread) in [(0.04, 0.5), (0.15, 1.0), (-0.12, 0.3), (0.5, 1.0), (-0.5, 1.0), (0.1, 0.0)] {
            for _ in 0..50 {
                let u = [crate::draws::uniform(&mut r)];
                let mut d = rough();
                let mut att = d.attitude();
                att[0] = -0.4;
                d.set_attitude(att);
                Effect::Lag { s, spread }.apply_drawn(&mut d, &u, None);
                let sr = s * (1.0 + spread * (2.0 * f64::from(u[0]) - 1.0));
                let want = reference_shift(&grid(&rough()), &[sr; GRID_ROWS], &[sr * (-0.4f64).tan(); GRID_ROWS]);
                assert_close(&d, &want, 1e-6, &format!("lag s {s} spread {spread} u {}", u[0]));
            }
        }
    }

    /// drift with rates 0 is the identity; rows from x0 on never move; the
    /// rest equals the slow reference (walks summed by hand), and the
    /// height walk's spread grows as the square root of the rows behind x0.
    #[test]
    fn drift_is_a_walk_back_from_x0() {
        let mut r = rng();
        let mut u = vec![0.0f32; 40];
        for x0 in [-1.0, 0.3, 0.45, 2.0] {
            crate::draws::fill_uniform(&mut r, &mut u);
            let mut d = rough();
            Effect::Drift { rate: 0.0, zrate: 0.0, x0 }.apply_drawn(&mut d, &u, None);
            assert_eq!(d, rough(), "rates 0: the identity");
        }
        for (rate, zrate, x0) in [(0.05, 0.02, 0.3), (0.2, 0.0, 1.5), (3.0, 0.1, 0.0), (0.1, 0.05, -0.7)] {
            for _ in 0..50 {
                crate::draws::fill_uniform(&mut r, &mut u);
                let mut d = rough();
                Effect::Drift { rate, zrate, x0 }.apply_drawn(&mut d, &u, None);
                let normals: Vec<(f64, f64)> = u.chunks(2).map(|p| crate::draws::box_muller(p[0], p[1])).collect();
                let (mut dx, mut dz) = (vec![0.0; GRID_ROWS], vec![0.0; GRID_ROWS]);
                for row in 0..GRID_ROWS {
                    if row_center_x(row) < x0 {
                        for (j, n) in normals.iter().enumerate().take(GRID_ROWS).skip(row) {
                            if row_center_x(j) < x0 {
                                dx[row] += rate * 0.1f64.sqrt() * n.0;
                                dz[row] += zrate * 0.1f64.sqrt() * n.1;
                            }
                        }
                    }
                }
                let want = reference_shift(&grid(&rough()), &dx, &dz);
                assert_close(&d, &want, 2e-6, &format!("drift {rate} {zrate} {x0}"));
                for row in (0..GRID_ROWS).filter(|&row| row_center_x(row) >= x0) {
                    (0..COLS).for_each(|c| assert_eq!(d.height(row, c), rough().height(row, c)));
                }
            }
        }
        // On flat ground the height walk alone shows: sd zrate sqrt(0.1 k)
        // in the k-th row behind x0 = 0.3 (rows 8, 7, ...: k = 1, 2, ...).
        let (zrate, n) = (0.02, 4000);
        let mut sq = [0.0f64; GRID_ROWS];
        for _ in 0..n {
            crate::draws::fill_uniform(&mut r, &mut u);
            let mut d = flat();
            Effect::Drift { rate: 0.05, zrate, x0: 0.3 }.apply_drawn(&mut d, &u, None);
            (0..GRID_ROWS).for_each(|row| sq[row] += (d.height(row, 0) as f64 - FLAT_GROUND as f64).powi(2));
        }
        for (row, &s2) in sq.iter().enumerate() {
            let sd = (s2 / n as f64).sqrt();
            let k = (0..GRID_ROWS).filter(|&j| j >= row && row_center_x(j) < 0.3).count() as f64;
            let want = zrate * (0.1 * k).sqrt();
            assert!((sd - want).abs() <= 0.04 * want + 1e-9, "row {row}: sd {sd} vs {want}");
        }
    }

    #[test]
    fn random_effects_have_their_rates_and_spread() {
        let (mut miss, mut rows, mut sq) = (0usize, 0usize, 0.0);
        let mut r1 = rng();
        for _ in 0..200 {
            let mut d = flat();
            Effect::Dropout { p: 0.2 }.apply(&mut d, &mut r1);
            miss += 100 - d.valid_cells();
            let mut d = flat();
            Effect::RowDropout { p: 0.3 }.apply(&mut d, &mut r1);
            rows += (100 - d.valid_cells()) / 5;
            let mut d = flat();
            Effect::Noise { sigma0: 0.01, k: 0.0 }.apply(&mut d, &mut r1);
            sq += (0..100).map(|i| (d[2 * i] as f64 + 0.07).powi(2)).sum::<f64>();
        }
        assert!((miss as f64 / 20000.0 - 0.2).abs() < 0.02);
        assert!((rows as f64 / 4000.0 - 0.3).abs() < 0.03);
        assert!(((sq / 20000.0).sqrt() - 0.01).abs() < 0.0005);
    }
}
