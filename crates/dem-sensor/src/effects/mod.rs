//! The measurement effects of `docs/format.md`: one registry, one file
//! per effect, each effect defined once.
//!
//! An effect is one file, `effects/<family>/<effect>.rs`: its parameter
//! struct (made by `params!`: each field's `///` line is also its
//! [`ParamSpec::doc`]) and the struct's [`EffectKind`] impl: its
//! [`EffectSpec`] (name, formula, stage in the physical chain, draw count,
//! the emulator stages it models, parameters with fit box and physical
//! limits; `dem-sensor effects` prints them), its validity check, the
//! function that applies it to one DEM, its ONNX operators
//! ([`crate::graph`]), its sentence of evidence ([`crate::evidence`]) and
//! example parameters where it acts. One line per effect in `registry!`
//! below makes [`Effect`] (a newtype variant per effect), [`SPECS`] in the
//! vocabulary's order and every dispatch from an [`Effect`] to its file,
//! so an effect without a part does not compile, and `tests/registry.rs`
//! fails for parts that disagree.
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
use crate::evidence::Context;
use crate::graph::ops::Cells;
use dem_core::distribution::Stats;
use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};
use dem_graph::Builder;

pub mod heights;
pub mod holes;
pub mod steps;
pub mod view;

#[cfg(test)]
mod tests;

pub use heights::{
    climb_slope, drift_walk, record_pitch, shift_rows, step_under_tracks, MAX_CLIMB_PITCH, MAX_LAG, MAX_SHIFT, MAX_TILT, MAX_TILT_RANGE,
    MIN_QUANTUM, NOISE_ORIGIN, NOISE_RANGE_HEIGHT, ROUND_UP_FROM, SHAKE_MAX_STEP, TRACK_ROWS,
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

/// `a - b > t`, decided in float32 operation for operation as the graph
/// decides it (heights are float32, so `a` and `b` are exact): a step of
/// exactly a threshold (sim's stairs have them) is then the same step in
/// every runtime that computes IEEE float32.
pub(crate) fn exceeds(a: f64, b: f64, t: f64) -> bool {
    (a as f32 - b as f32) > t as f32
}

/// A uniform `u` (float32) below the probability `p`, as the graph's `below`
/// decides it: against `p` rounded to float32.
pub(crate) fn hit(u: f64, p: f64) -> bool {
    (u as f32) < p as f32
}

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
    /// The fused map across frames (`map-memory`): last, on the frame
    /// every other stage made.
    Memory,
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
            Stage::Memory => "memory",
        }
    }
}

/// The stages dem-synth's emulator switches off with `--no-<stage>`.
pub const EMULATOR_STAGES: [&str; 11] =
    ["fov", "occlusion", "smoothing", "noise", "dropout", "holes", "drift", "latency", "extrinsic", "vibration", "memory"];

/// The effects that model emulator stage `stage`, in the vocabulary's order.
pub fn modelling(stage: &str) -> Vec<&'static str> {
    SPECS.iter().filter(|s| s.emulator.contains(&stage)).map(|s| s.name).collect()
}

/// The vocabulary as CSV, one effect a line in the vocabulary's order:
/// `effect,family,stage,draws,run_draws,params,emulator_stages,limits`, lists
/// separated by spaces; `limits` each parameter's physical box
/// (`name=lo..hi`, [`ParamSpec::limit`]), which every model is held to.
pub fn csv() -> String {
    let mut out = String::from("effect,family,stage,draws,run_draws,params,emulator_stages,limits\n");
    for s in SPECS {
        let params: Vec<&str> = s.params.iter().map(|p| p.name).collect();
        let limits: Vec<String> = s.params.iter().map(|p| format!("{}={}..{}", p.name, p.limit.lo, p.limit.hi)).collect();
        let line = [
            s.name,
            s.family.name(),
            s.stage.name(),
            &s.draws.to_string(),
            &s.run_draws.to_string(),
            &params.join(" "),
            &s.emulator.join(" "),
            &limits.join(" "),
        ]
        .join(",");
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
    /// What it is, with its unit: the doc comment of the parameter's
    /// field, on one line.
    pub doc: &'static str,
    /// The box dem-gap searches.
    pub fit: Range,
    /// How far dem-gap may widen the box, and its natural ends.
    pub limit: Limit,
}

/// Everything about one effect but its parameter struct and its code.
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
    /// It moves every valid cell of a record together by one draw or one
    /// constant (an offset or a plane: `bias`, `tilt`, `shake`). Fitted
    /// between sets of different terrain, such an effect stands in for the
    /// terrain (a set with more stairs has other record means), so dem-gap
    /// fits it only where both sides hold the same terrain mix.
    pub whole_record: bool,
    /// How many of its [`EffectSpec::draws`], the first ones, belong to a
    /// run: a record whose labels name its run (`sequence`) reads them from
    /// the run's stream, the same in every frame of the run, as what a run
    /// keeps (a mount's miscalibration, a pipeline's latency at the run's
    /// speed) stays the same from frame to frame. The others are new every
    /// frame. Without runs every draw is the record's own.
    pub run_draws: usize,
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

/// What every effect's file provides, beside its parameter struct (made by
/// `params!`, which also gives the struct's `PARAMS`, `params()` and
/// `from_values()`): a missing part does not compile.
pub trait EffectKind: Sized {
    /// Everything about the effect but its code.
    const SPEC: EffectSpec;

    /// The effect's own rule for its parameters (the checks every
    /// parameter gets are [`Effect::check`]'s).
    fn check(&self) -> Result<(), String>;

    /// Apply to one DEM with the record's uniforms (`rng`, [`EffectSpec::draws`]
    /// of them) and its time in its run, when known.
    fn apply(&self, d: &mut Dem, rng: &mut Draws, time: Option<f64>);

    /// The effect as ONNX operators on `c` ([`crate::graph`]); `u` its
    /// uniforms `(N, draws)` (empty when it draws none), `time` the
    /// records' times `(N,)`.
    fn graph(&self, b: &mut Builder, c: &Cells, u: &str, time: Option<&str>) -> Cells;

    /// One sentence of evidence for the effect as fitted ([`crate::evidence`]).
    fn evidence(&self, c: &Context) -> String;

    /// Parameters where the effect acts on the test records: the graph
    /// tests run each, and `testdata/effects.json` lists them.
    fn examples() -> Vec<Self>;
}

/// One line of doc from a field's doc comment (`///` lines arrive as
/// `" text"` and are joined without a separator): without the leading
/// space.
pub const fn doc_line(doc: &'static str) -> &'static str {
    match doc.as_bytes() {
        [b' ', rest @ ..] => match std::str::from_utf8(rest) {
            Ok(s) => s,
            Err(_) => panic!("a doc comment is UTF-8"),
        },
        _ => doc,
    }
}

/// An effect's parameter struct from its doc, the wording of serde's
/// error for `params` of the wrong type, and its fields: each field's doc
/// comment, then `name: fit RANGE, limit LIMIT;`. The struct's JSON form
/// is the effect's `params`; its `PARAMS` are the [`ParamSpec`]s, whose
/// `doc` is the field's doc comment on one line.
macro_rules! params {
    (
        $(#[doc = $sdoc:literal])*
        #[serde(expecting = $expecting:literal)]
        $name:ident {
            $(
                $(#[doc = $doc:literal])+
                $(#[serde($serde:meta)])?
                $field:ident: fit $fit:expr, limit $limit:expr;
            )+
        }
    ) => {
        $(#[doc = $sdoc])*
        #[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
        #[serde(deny_unknown_fields, expecting = $expecting)]
        pub struct $name {
            $(
                $(#[doc = $doc])+
                $(#[serde($serde)])?
                pub $field: f64,
            )+
        }

        impl $name {
            /// Its parameters, in declaration order.
            pub const PARAMS: &'static [$crate::effects::ParamSpec] = &[$(
                $crate::effects::ParamSpec {
                    name: stringify!($field),
                    doc: $crate::effects::doc_line(concat!($($doc),+)),
                    fit: $fit,
                    limit: $limit,
                },
            )+];

            /// Parameter names and values, in declaration order.
            pub fn params(&self) -> Vec<(&'static str, f64)> {
                vec![$((stringify!($field), self.$field)),+]
            }

            /// The effect from values in declaration order (None when short).
            pub fn from_values(v: &mut impl Iterator<Item = f64>) -> Option<Self> {
                Some($name { $($field: v.next()?),+ })
            }
        }
    };
}
pub(crate) use params;

/// The one table of effects: each line a variant and the module that
/// defines it, in the vocabulary's order. It makes [`Effect`] (one newtype
/// variant per effect, named as its parameter struct), [`SPECS`] and every
/// dispatch from an [`Effect`] to its module.
macro_rules! registry {
    ($($variant:ident => $family:ident::$module:ident,)+) => {
        /// One effect with its parameters. JSON: `{"effect": NAME, "params": {...}}`.
        #[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
        #[serde(tag = "effect", content = "params", rename_all = "kebab-case", deny_unknown_fields)]
        pub enum Effect {
            $(
                #[doc = concat!("[`", stringify!($family), "::", stringify!($module), "`].")]
                $variant($family::$module::$variant),
            )+
        }

        $(
            pub use $family::$module::$variant;

            impl From<$variant> for Effect {
                fn from(e: $variant) -> Effect {
                    Effect::$variant(e)
                }
            }
        )+

        /// Every effect's spec, in the vocabulary's order: dem-gap tries
        /// candidates in this order, so it decides its ties and its output.
        pub const SPECS: [&EffectSpec; [$(stringify!($variant)),+].len()] = [$(&<$variant as EffectKind>::SPEC),+];

        impl Effect {
            /// The effect's definition.
            pub fn spec(&self) -> &'static EffectSpec {
                match self {
                    $(Effect::$variant(_) => &<$variant as EffectKind>::SPEC,)+
                }
            }

            /// Parameter names and values, in declaration order.
            pub fn params(&self) -> Vec<(&'static str, f64)> {
                match self {
                    $(Effect::$variant(e) => e.params(),)+
                }
            }

            /// Build the effect `name` from parameter values in [`Effect::params`] order.
            pub fn from_values(name: &str, v: &[f64]) -> Option<Effect> {
                let mut v = v.iter().copied();
                $(
                    if name == <$variant as EffectKind>::SPEC.name {
                        return $variant::from_values(&mut v).map(Effect::$variant);
                    }
                )+
                None
            }

            /// Every effect's examples ([`EffectKind::examples`]), in the
            /// vocabulary's order.
            pub fn examples() -> Vec<Effect> {
                let mut all = Vec::new();
                $(all.extend($variant::examples().into_iter().map(Effect::$variant));)+
                all
            }

            /// The effect's own check ([`EffectKind::check`]).
            fn check_own(&self) -> Result<(), String> {
                match self {
                    $(Effect::$variant(e) => e.check(),)+
                }
            }

            /// [`EffectKind::apply`].
            fn apply_own(&self, d: &mut Dem, rng: &mut Draws, time: Option<f64>) {
                match self {
                    $(Effect::$variant(e) => e.apply(d, rng, time),)+
                }
            }

            /// The effect as ONNX operators on `c` ([`EffectKind::graph`]).
            pub fn graph(&self, b: &mut Builder, c: &Cells, u: &str, time: Option<&str>) -> Cells {
                match self {
                    $(Effect::$variant(e) => e.graph(b, c, u, time),)+
                }
            }

            /// [`EffectKind::evidence`].
            fn sentence(&self, c: &Context) -> String {
                match self {
                    $(Effect::$variant(e) => e.evidence(c),)+
                }
            }
        }
    };
}

registry! {
    Noise => heights::noise,
    Dropout => holes::dropout,
    RowDropout => holes::row_dropout,
    Occlusion => view::occlusion,
    Fov => view::fov,
    Smoothing => steps::smoothing,
    Bias => heights::bias,
    Quantization => heights::quantization,
    Startup => view::startup,
    PatchDropout => holes::patch_dropout,
    EdgeHoles => holes::edge_holes,
    MixedCells => steps::mixed_cells,
    RimHoles => holes::rim_holes,
    PitFill => holes::pit_fill,
    ViewTop => view::view_top,
    HoleGrowth => holes::hole_growth,
    DropBlend => steps::drop_blend,
    RiserBlend => steps::riser_blend,
    FloorLift => steps::floor_lift,
    DropHoles => holes::drop_holes,
    Tilt => heights::tilt,
    Shake => heights::shake,
    Lag => heights::lag,
    Drift => heights::drift,
    StepJitter => steps::step_jitter,
    MapMemory => view::map_memory,
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

    /// The time constant (s) of the map's memory this effect's draws
    /// follow over the same ground ([`crate::memory`]), when it has one.
    pub fn memory(&self) -> Option<f64> {
        match self {
            Effect::Noise(n) if n.tau > 0.0 => Some(n.tau),
            _ => None,
        }
    }

    /// The normals a record at `moment` of a run draws from the run's
    /// world rather than its own stream (`key` keys the effect and run), in
    /// the order its Box-Muller pairs give them: `noise`'s with a memory,
    /// of the ground each cell sees ([`crate::memory::ground_normals`]);
    /// `drift`'s, of the path travelled ([`crate::memory::path_steps`]).
    /// None: the record's own draws.
    pub fn normals_in_run(&self, key: u64, moment: crate::Moment) -> Option<Vec<f64>> {
        match self {
            Effect::Noise(_) => {
                let (tau, (_, time, pose)) = (self.memory()?, moment.in_run()?);
                Some(crate::memory::ground_normals(key, tau, time, pose).to_vec())
            }
            Effect::Drift(_) => Some(crate::memory::path_steps(key, moment.travelled()?).to_vec()),
            _ => None,
        }
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
        self.check_own()?;
        self.check_physical()
    }

    /// Every parameter inside its physical box ([`ParamSpec::limit`]):
    /// what the sensor can do, whoever wrote the file (dem-gap's search
    /// never leaves the box; a hand-written or edited model is held to it
    /// alike by every tool that reads one).
    fn check_physical(&self) -> Result<(), String> {
        for (p, (n, v)) in self.spec().params.iter().zip(self.params()) {
            let Limit { lo, hi, .. } = p.limit;
            if !(lo..=hi).contains(&v) {
                return Err(format!("{n} = {v} is outside its physical box {lo}..={hi} ({})", p.doc));
            }
        }
        Ok(())
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
        self.apply_own(d, &mut Draws::new(u), time)
    }

    /// One sentence of evidence for the effect as fitted, from the
    /// statistics of the model before it was added and of real, and the
    /// gap before and after ([`crate::evidence`]).
    pub fn evidence(&self, before: &Stats, real: &Stats, gap_before: f64, gap_after: f64) -> String {
        self.sentence(&Context { effect: self, before, real, gap_before, gap_after })
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
// Kept out of line: inlined into each effect that reads it, `dem-sensor
// apply` of a 25-effect model ran 11 % slower (user time, one thread).
#[inline(never)]
fn cell_heights(d: &Dem) -> [[Option<f64>; COLS]; GRID_ROWS] {
    std::array::from_fn(|r| std::array::from_fn(|c| d.is_valid(r, c).then(|| d.height(r, c) as f64)))
}

/// The 4-neighbours of cell (r, c) inside the grid.
fn neighbours4(r: usize, c: usize) -> impl Iterator<Item = (usize, usize)> {
    [(r.wrapping_sub(1), c), (r + 1, c), (r, c.wrapping_sub(1)), (r, c + 1)].into_iter().filter(|&(rr, cc)| rr < GRID_ROWS && cc < COLS)
}
