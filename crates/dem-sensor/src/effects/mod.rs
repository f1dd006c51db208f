//! The measurement effects of `docs/format.md`: one registry, one module
//! per family of physics, each effect defined once.
//!
//! An effect is an [`Effect`] variant (its JSON form) plus an
//! [`EffectSpec`] in its family's module: name, parameters with their doc
//! line, fit box and physical limits, formula, stage in the physical chain,
//! draw count and the emulator stages it models (`dem-sensor effects`
//! prints them); beside the spec, the family module holds the effect's
//! validity check and the function that applies it. [`SPECS`] lists every
//! spec in the vocabulary's order, and [`Effect::spec`], [`Effect::params`]
//! and [`Effect::from_values`] come from one table (`registry!` below), so
//! a variant without a spec, a check or an apply function does not compile,
//! and `tests/registry.rs` fails for a spec that disagrees with its variant.
//!
//! - [`holes`]: cells lost or filled where the map is thin.
//! - [`view`]: what the sensor can see.
//! - [`steps`]: heights moved at steps.
//! - [`heights`]: heights moved everywhere (range, calibration, pose).
//!
//! Coordinates: row `r` of the grid is centred at x = -0.55 + 0.1 r m from
//! the robot centre C (forward), column `c` at y = (2 - c) 0.1 m; heights
//! are relative to C. A missing cell is stored as mask -1, height 0; an
//! effect that removes a cell writes exactly that. Effects act on the valid
//! cells only (a missing cell stays missing) and never touch row 20.

use rand::RngCore;
use serde::{Deserialize, Serialize};

use crate::draws::Draws;
use crate::evidence;
use dem_core::distribution::Stats;
use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};

pub mod heights;
pub mod holes;
pub mod steps;
pub mod view;

#[cfg(test)]
mod tests;

pub use heights::{
    climb_slope, drift_walk, shift_rows, step_under_tracks, MAX_CLIMB_PITCH, MAX_LAG, MAX_SHIFT, MAX_TILT, MAX_TILT_RANGE, MIN_QUANTUM,
    NOISE_ORIGIN, NOISE_RANGE_HEIGHT, ROUND_UP_FROM, SHAKE_MAX_STEP, TRACK_ROWS,
};
pub use holes::{growth_threshold, PATCH_SLOTS};
pub use steps::{jitter_steps, TIE_MARGIN};
pub use view::{hidden, OCCLUSION_TOLERANCE};

/// Largest magnitude of any parameter (metres, metres per metre, 1/m, m/s
/// or a count): a DEM spans 2 m, so a larger value is a typo, and bounding
/// it keeps every output finite.
pub const MAX_PARAM: f64 = 10.0;
/// Height difference (m) between x-neighbours that `mixed-cells` treats as
/// a step: the distribution gap's `jump-missing` jump, so dem-gap's
/// statistic sees this effect's steps and no others. Below it the terrain
/// is a slope, whose cell mean is the centre's height.
pub const MIXED_JUMP: f64 = dem_core::distribution::JUMP;
/// Half the edge of a grid cell (m).
const HALF: f64 = 0.05;

/// The family of physics an effect belongs to: the module that defines it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// Cells lost or filled where the map is thin ([`holes`]).
    Holes,
    /// What the sensor can see ([`view`]).
    View,
    /// Heights moved at steps ([`steps`]).
    Steps,
    /// Heights moved everywhere ([`heights`]).
    Heights,
}

impl Family {
    /// The family's module name.
    pub fn name(self) -> &'static str {
        match self {
            Family::Holes => "holes",
            Family::View => "view",
            Family::Steps => "steps",
            Family::Heights => "heights",
        }
    }
}

/// An effect's place in the physical chain, first to last: where the map
/// puts the terrain, what the sensor can see, what the matcher rejects at
/// jumps, how fusion and resampling shape heights, what is lost at the
/// end. [`crate::SensorModel::with`] inserts an effect after every effect
/// of an earlier or equal stage, so of two effects of one stage the one
/// added to a model first is applied first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Stage {
    /// The map's geometry at an older or a believed pose: the terrain every
    /// later stage sees (`lag`, `drift`).
    Pose,
    /// The field of view (`fov`, `view-top`).
    FieldOfView,
    /// The first frames of a run (`startup`).
    Startup,
    /// Shadows (`occlusion`).
    Occlusion,
    /// What the matcher and the map's variance reject at jumps (`edge-holes`, `rim-holes`, `drop-holes`).
    JumpHoles,
    /// Narrow pits never seen to the bottom (`pit-fill`).
    PitFill,
    /// Cells that straddle a step (`mixed-cells`).
    MixedCells,
    /// Cells moved at drops, after the mixed cells (`drop-blend`, `floor-lift`).
    DropMoves,
    /// Cells moved at risers (`riser-blend`).
    RiserMoves,
    /// Fusion's blur (`smoothing`).
    Smoothing,
    /// Registration: heights tilted and moved as the points are placed
    /// (`bias`, `tilt`, `shake`, `step-jitter`).
    Registration,
    /// Range noise (`noise`).
    Noise,
    /// Height resolution (`quantization`).
    Quantization,
    /// Single cells lost (`dropout`).
    Dropout,
    /// Blobs lost (`patch-dropout`).
    Patches,
    /// Holes grown at their edges (`hole-growth`).
    HoleGrowth,
    /// Whole rows lost (`row-dropout`).
    RowDropout,
}

impl Stage {
    /// The stage's name in `dem-sensor effects`.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Pose => "pose",
            Stage::FieldOfView => "field-of-view",
            Stage::Startup => "startup",
            Stage::Occlusion => "occlusion",
            Stage::JumpHoles => "jump-holes",
            Stage::PitFill => "pit-fill",
            Stage::MixedCells => "mixed-cells",
            Stage::DropMoves => "drop-moves",
            Stage::RiserMoves => "riser-moves",
            Stage::Smoothing => "smoothing",
            Stage::Registration => "registration",
            Stage::Noise => "noise",
            Stage::Quantization => "quantization",
            Stage::Dropout => "dropout",
            Stage::Patches => "patches",
            Stage::HoleGrowth => "hole-growth",
            Stage::RowDropout => "row-dropout",
        }
    }
}

/// The stages dem-synth's emulator switches off with `--no-<stage>`.
pub const EMULATOR_STAGES: [&str; 10] =
    ["fov", "occlusion", "smoothing", "noise", "dropout", "holes", "drift", "latency", "extrinsic", "vibration"];

/// The effects that model emulator stage `stage`, in the vocabulary's order.
pub fn modelling(stage: &str) -> Vec<&'static str> {
    SPECS.iter().filter(|s| s.emulator.contains(&stage)).map(|s| s.name).collect()
}

/// The vocabulary as CSV, one effect a line in the vocabulary's order:
/// `effect,family,stage,draws,params,emulator_stages`, lists separated by
/// spaces.
pub fn csv() -> String {
    let mut out = String::from("effect,family,stage,draws,params,emulator_stages\n");
    for s in SPECS {
        let params: Vec<&str> = s.params.iter().map(|p| p.name).collect();
        let line = [s.name, s.family.name(), s.stage.name(), &s.draws.to_string(), &params.join(" "), &s.emulator.join(" ")].join(",");
        out.push_str(&line);
        out.push('\n');
    }
    out
}

/// One parameter's fit box for dem-gap; `log` searches log(value).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Range {
    /// Smallest value searched.
    pub lo: f64,
    /// Largest value searched.
    pub hi: f64,
    /// Search on a log scale.
    pub log: bool,
}

impl Range {
    /// A box searched on a linear scale.
    pub const fn lin(lo: f64, hi: f64) -> Self {
        Range { lo, hi, log: false }
    }

    /// A box searched on a log scale (`lo` > 0).
    pub const fn log(lo: f64, hi: f64) -> Self {
        Range { lo, hi, log: true }
    }

    /// The value at `u` in [0, 1] of the box (clamped), on its scale.
    pub fn at(&self, u: f64) -> f64 {
        let u = u.clamp(0.0, 1.0);
        if self.log {
            (self.lo.ln() + u * (self.hi.ln() - self.lo.ln())).exp()
        } else {
            self.lo + u * (self.hi - self.lo)
        }
    }
}

/// How far dem-gap may widen a parameter's box when a fit lands on its
/// edge (the physical limits), and which ends are natural: the effect
/// fades out there or covers the whole grid, so a fit that ends there is
/// no sign of a wrong effect.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limit {
    /// Hard low limit.
    pub lo: f64,
    /// Hard high limit.
    pub hi: f64,
    /// The low end of the box is a natural end.
    pub natural_lo: bool,
    /// The high end of the box is a natural end.
    pub natural_hi: bool,
}

impl Limit {
    /// Hard limits, neither end of the box natural.
    pub const fn new(lo: f64, hi: f64) -> Self {
        Limit { lo, hi, natural_lo: false, natural_hi: false }
    }

    /// The same limits with a natural low end.
    pub const fn natural_lo(self) -> Self {
        Limit { natural_lo: true, ..self }
    }

    /// The same limits with a natural high end.
    pub const fn natural_hi(self) -> Self {
        Limit { natural_hi: true, ..self }
    }
}

/// One parameter of an effect.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamSpec {
    /// Its name in JSON and in [`Effect::params`].
    pub name: &'static str,
    /// What it is, with its unit.
    pub doc: &'static str,
    /// The box dem-gap searches.
    pub fit: Range,
    /// How far dem-gap may widen the box, and its natural ends.
    pub limit: Limit,
}

/// Everything about one effect but its variant and its code.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EffectSpec {
    /// The vocabulary name (`noise`, `row-dropout`, ...).
    pub name: &'static str,
    /// The module that defines it.
    pub family: Family,
    /// What it does to one DEM, in one line of formula.
    pub formula: &'static str,
    /// Its parameters, in [`Effect::params`] order.
    pub params: &'static [ParamSpec],
    /// Its place in the physical chain.
    pub stage: Stage,
    /// The stages of dem-synth's emulator ([`EMULATOR_STAGES`]) whose
    /// absence it models: dem-synth `--no-<stage>` against all stages
    /// names one of the effects that list the stage (docs/dem-sensor.md).
    pub emulator: &'static [&'static str],
    /// Uniforms it reads per record, whatever its parameters (common random
    /// numbers for the fitter; the width of its slice of the ONNX graph's
    /// `uniform` input).
    pub draws: usize,
}

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

/// The one table from variants to specs: [`SPECS`], [`Effect::spec`],
/// [`Effect::params`] and [`Effect::from_values`] all come from it. Each
/// line is a variant with its fields in [`Effect::params`] order and the
/// spec that defines it; the lines are in the vocabulary's order.
macro_rules! registry {
    ($($variant:ident { $($field:ident),+ } => $spec:path,)+) => {
        /// Every effect's spec, in the vocabulary's order: dem-gap tries
        /// candidates in this order, so it decides its ties and its output.
        pub const SPECS: [&EffectSpec; [$(registry!(@one $variant)),+].len()] = [$(&$spec),+];

        impl Effect {
            /// The effect's definition.
            pub fn spec(&self) -> &'static EffectSpec {
                match self {
                    $(Effect::$variant { .. } => &$spec,)+
                }
            }

            /// Parameter names and values, in declaration order.
            pub fn params(&self) -> Vec<(&'static str, f64)> {
                match *self {
                    $(Effect::$variant { $($field),+ } => vec![$((stringify!($field), $field)),+],)+
                }
            }

            /// Build the effect `name` from parameter values in [`Effect::params`] order.
            pub fn from_values(name: &str, v: &[f64]) -> Option<Effect> {
                let mut v = v.iter().copied();
                $(
                    if name == $spec.name {
                        return Some(Effect::$variant { $($field: v.next()?),+ });
                    }
                )+
                None
            }
        }
    };
    (@one $variant:ident) => {
        ()
    };
}

registry! {
    Noise { sigma0, k } => heights::NOISE,
    Dropout { p } => holes::DROPOUT,
    RowDropout { p } => holes::ROW_DROPOUT,
    Occlusion { h, x0 } => view::OCCLUSION,
    Fov { x_min, x_max } => view::FOV,
    Smoothing { w } => steps::SMOOTHING,
    Bias { b, t } => heights::BIAS,
    Quantization { q } => heights::QUANTIZATION,
    Startup { x0, v, p } => view::STARTUP,
    PatchDropout { n, r, a } => holes::PATCH_DROPOUT,
    EdgeHoles { g, p } => holes::EDGE_HOLES,
    MixedCells { up, down } => steps::MIXED_CELLS,
    RimHoles { g, p } => holes::RIM_HOLES,
    PitFill { g, p } => holes::PIT_FILL,
    ViewTop { h, t } => view::VIEW_TOP,
    HoleGrowth { p } => holes::HOLE_GROWTH,
    DropBlend { p, a } => steps::DROP_BLEND,
    RiserBlend { foot, top } => steps::RISER_BLEND,
    FloorLift { x, p, a } => steps::FLOOR_LIFT,
    DropHoles { p } => holes::DROP_HOLES,
    Tilt { pitch, roll, x0, range } => heights::TILT,
    Shake { sigma, edge } => heights::SHAKE,
    Lag { s, spread } => heights::LAG,
    Drift { rate, zrate, x0 } => heights::DRIFT,
    StepJitter { sigma, edge } => steps::STEP_JITTER,
}

/// Every effect name, in the vocabulary's order ([`SPECS`]' names).
pub const NAMES: [&str; SPECS.len()] = {
    let mut names = [""; SPECS.len()];
    let mut i = 0;
    while i < SPECS.len() {
        names[i] = SPECS[i].name;
        i += 1;
    }
    names
};

/// The spec of the effect called `name`, if the vocabulary has one.
pub fn spec_named(name: &str) -> Option<&'static EffectSpec> {
    SPECS.iter().copied().find(|s| s.name == name)
}

impl Effect {
    /// The vocabulary name (`noise`, `row-dropout`, ...).
    pub fn name(&self) -> &'static str {
        self.spec().name
    }

    /// Place in the physical chain ([`Stage`]).
    pub fn stage(&self) -> Stage {
        self.spec().stage
    }

    /// Uniforms this effect reads per record ([`EffectSpec::draws`]).
    pub fn draws(&self) -> usize {
        self.spec().draws
    }

    /// Check the parameters: finite, within +-[`MAX_PARAM`], then the
    /// effect's own rule (probabilities in [0, 1], sigma >= 0, w in (0, 1],
    /// q > 0, h > 0, x_min < x_max, ...).
    pub fn check(&self) -> Result<(), String> {
        if let Some((n, v)) = self.params().into_iter().find(|(_, v)| !v.is_finite()) {
            return Err(format!("{n} = {v} is not a finite number"));
        }
        if let Some((n, v)) = self.params().into_iter().find(|(_, v)| v.abs() > MAX_PARAM) {
            return Err(format!("{n} = {v:e} is outside -{MAX_PARAM}..={MAX_PARAM} (the grid spans 2 m; no sensor effect is that large)"));
        }
        match *self {
            Effect::Noise { sigma0, k } => heights::check_noise(sigma0, k),
            Effect::Dropout { p } | Effect::RowDropout { p } | Effect::HoleGrowth { p } | Effect::DropHoles { p } => probability(p),
            Effect::Occlusion { h, .. } => view::check_occlusion(h),
            Effect::Fov { x_min, x_max } => view::check_fov(x_min, x_max),
            Effect::ViewTop { .. } | Effect::Bias { .. } => Ok(()),
            Effect::Smoothing { w } => steps::check_smoothing(w),
            Effect::Quantization { q } => heights::check_quantization(q),
            Effect::Startup { v, p, .. } => view::check_startup(v, p),
            Effect::PatchDropout { n, r, a } => holes::check_patch_dropout(n, r, a),
            Effect::EdgeHoles { g, p } | Effect::RimHoles { g, p } | Effect::PitFill { g, p } => holes::check_jump(g, p),
            Effect::MixedCells { up, down } => steps::check_mixed_cells(up, down),
            Effect::DropBlend { p, a } => steps::check_drop_blend(p, a),
            Effect::RiserBlend { foot, top } => steps::check_riser_blend(foot, top),
            Effect::FloorLift { p, a, .. } => steps::check_floor_lift(p, a),
            Effect::Tilt { pitch, roll, range, .. } => heights::check_tilt(pitch, roll, range),
            Effect::Shake { sigma, edge } => heights::check_shake(sigma, edge),
            Effect::StepJitter { sigma, edge } => steps::check_step_jitter(sigma, edge),
            Effect::Lag { s, spread } => heights::check_lag(s, spread),
            Effect::Drift { rate, zrate, .. } => heights::check_drift(rate, zrate),
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
            Effect::Noise { sigma0, k } => heights::add_noise(d, rng, sigma0, k),
            Effect::Dropout { p } => holes::drop_cells(d, rng, p),
            Effect::RowDropout { p } => holes::drop_rows(d, rng, p),
            Effect::Occlusion { h, x0 } => view::occlude(d, h, x0),
            Effect::Fov { x_min, x_max } => view::cut_to_fov(d, x_min, x_max),
            Effect::ViewTop { h, t } => view::cut_above_top_ray(d, h, t),
            Effect::Smoothing { w } => steps::smooth(d, w),
            Effect::Bias { b, t } => heights::offset(d, b, t),
            Effect::Quantization { q } => heights::quantize(d, q),
            Effect::Startup { x0, v, p } => view::blind_startup_rows(d, rng, time, x0, v, p),
            Effect::PatchDropout { n, r, a } => holes::drop_patches(d, rng, n, r, a),
            Effect::EdgeHoles { g, p } => holes::jump_holes(d, rng, g, p, 1.0),
            Effect::RimHoles { g, p } => holes::jump_holes(d, rng, g, p, -1.0),
            Effect::PitFill { g, p } => holes::fill_pits(d, rng, g, p),
            Effect::DropHoles { p } => holes::drop_holes(d, rng, p),
            Effect::HoleGrowth { p } => holes::grow_holes(d, rng, p),
            Effect::MixedCells { up, down } => steps::mix_cells(d, rng, up, down),
            Effect::DropBlend { p, a } => steps::blend_drops(d, rng, p, a),
            Effect::FloorLift { x, p, a } => steps::lift_floors(d, rng, x, p, a),
            Effect::RiserBlend { foot, top } => steps::blend_risers(d, rng, foot, top),
            Effect::StepJitter { sigma, edge } => steps::jitter(d, rng, sigma, edge),
            Effect::Tilt { pitch, roll, x0, range } => heights::tilt(d, rng, pitch, roll, x0, range),
            Effect::Shake { sigma, edge } => heights::shake(d, rng, sigma, edge),
            Effect::Lag { s, spread } => heights::lag(d, rng, s, spread),
            Effect::Drift { rate, zrate, x0 } => heights::drift(d, rng, rate, zrate, x0),
        }
    }
    /// One sentence of evidence for the effect as fitted, from the
    /// statistics of the model before it was added and of real, and the
    /// gap before and after ([`crate::evidence`]).
    pub fn evidence(&self, before: &Stats, real: &Stats, gap_before: f64, gap_after: f64) -> String {
        let c = evidence::Context { effect: self, before, real, gap_before, gap_after };
        match *self {
            Effect::Noise { .. } => evidence::heights::noise(&c),
            Effect::Dropout { .. } => evidence::holes::dropout(&c),
            Effect::RowDropout { .. } => evidence::holes::row_dropout(&c),
            Effect::Occlusion { .. } => evidence::view::occlusion(&c),
            Effect::Fov { x_min, x_max } => evidence::view::fov(&c, x_min, x_max),
            Effect::Startup { x0, v, p } => evidence::view::startup(&c, x0, v, p),
            Effect::PatchDropout { .. } => evidence::holes::patch_dropout(&c),
            Effect::EdgeHoles { .. } => evidence::holes::edge_holes(&c),
            Effect::DropHoles { .. } => evidence::holes::drop_holes(&c),
            Effect::HoleGrowth { .. } => evidence::holes::hole_growth(&c),
            Effect::ViewTop { h, t } => evidence::view::view_top(&c, h, t),
            Effect::RimHoles { .. } => evidence::holes::rim_holes(&c),
            Effect::PitFill { .. } => evidence::holes::pit_fill(&c),
            Effect::MixedCells { .. } => evidence::steps::mixed_cells(&c),
            Effect::DropBlend { .. } => evidence::steps::drop_blend(&c),
            Effect::FloorLift { x, .. } => evidence::steps::floor_lift(&c, x),
            Effect::RiserBlend { foot, top } => evidence::steps::riser_blend(&c, foot, top),
            Effect::Tilt { pitch, roll, x0, range } => evidence::heights::tilt(&c, pitch, roll, x0, range),
            Effect::Shake { sigma, edge } => evidence::heights::shake(&c, sigma, edge),
            Effect::Drift { rate, zrate, x0 } => evidence::heights::drift(&c, rate, zrate, x0),
            Effect::Lag { s, .. } => evidence::heights::lag(&c, s),
            Effect::StepJitter { sigma, edge } => evidence::steps::step_jitter(&c, sigma, edge),
            Effect::Smoothing { .. } => evidence::steps::smoothing(&c),
            Effect::Bias { .. } => evidence::heights::bias(&c),
            Effect::Quantization { q } => evidence::heights::quantization(&c, q),
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

/// The check every probability parameter `p` gets.
fn probability(p: f64) -> Result<(), String> {
    if !(0.0..=1.0).contains(&p) {
        return Err(format!("p = {p} is not a probability"));
    }
    Ok(())
}

/// The heights of `d`'s grid, None where missing: a snapshot of the DEM as
/// it comes in, which the effects that look at neighbours read.
fn cell_heights(d: &Dem) -> [[Option<f64>; COLS]; GRID_ROWS] {
    std::array::from_fn(|r| std::array::from_fn(|c| d.is_valid(r, c).then(|| d.height(r, c) as f64)))
}

/// The 4-neighbours of cell (r, c) inside the grid.
fn neighbours4(r: usize, c: usize) -> impl Iterator<Item = (usize, usize)> {
    [(r.wrapping_sub(1), c), (r + 1, c), (r, c.wrapping_sub(1)), (r, c + 1)].into_iter().filter(|&(rr, cc)| rr < GRID_ROWS && cc < COLS)
}
