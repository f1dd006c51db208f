//! One pairing run: read the inputs a method needs, check them, find the
//! pairs by pose or by content, and turn them into the pairs CSV's rows.

use dem_core::swap::{self, MissingCells};
use dem_core::table::{self, Label, Pair};
use dem_core::{npy, DemError};

use crate::{by_content, by_pose, first_occurrence, pair_rows, PoseRule};

/// How to pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Same terrain and pose (from the labels CSVs) within tolerances.
    Pose,
    /// The k nearest sim DEMs by the height error over the real record's
    /// valid cells.
    Content,
}

impl Method {
    fn name(self) -> &'static str {
        match self {
            Method::Pose => "pose",
            Method::Content => "content",
        }
    }
}

/// A validated pairing run (dem-pair without a subcommand).
#[derive(Debug, Clone)]
pub struct PairConfig {
    pub by: Method,
    pub sim: Option<String>,
    pub real: Option<String>,
    pub sim_labels: Option<String>,
    pub real_labels: Option<String>,
    /// Pose: the tolerances.
    pub rule: PoseRule,
    /// Content: sim keys per real record.
    pub k: usize,
    /// Content: largest distance (infinite: no limit).
    pub max_distance: f64,
    /// Fraction of sim keys in the val split.
    pub val_fraction: f64,
    /// Seed of the split.
    pub seed: u64,
    /// Do not warn when sim misses clearly more cells than real.
    pub no_swap_check: bool,
}

/// The pairs found, with the sim labels the report counts terrains by.
pub struct Paired {
    pub rows: Vec<Pair>,
    pub sim_labels: Option<Vec<Label>>,
}

/// Read, check and pair. A method without the inputs it needs is a usage
/// error naming the flag; an empty input with `content` is a bad input.
pub fn pair(cfg: &PairConfig) -> anyhow::Result<Paired> {
    let need = |v: &Option<String>, flag: &str| -> Result<String, DemError> {
        v.clone().ok_or_else(|| DemError::Usage(format!("--match {} needs {flag}", cfg.by.name())))
    };
    let sim = cfg.sim.as_deref().map(npy::read_all).transpose()?;
    let sim_labels = cfg.sim_labels.as_deref().map(table::read_labels).transpose()?;
    let real_labels = cfg.real_labels.as_deref().map(table::read_labels).transpose()?;
    if let (Some(r), Some(l), Some(f), Some(lf)) = (&sim, &sim_labels, &cfg.sim, &cfg.sim_labels) {
        table::check_labels_cover(lf, l.len(), f, r.len() as u64)?;
    }
    let keys = sim.as_deref().map(first_occurrence);
    let found = match cfg.by {
        Method::Pose => {
            let (s, r) = (need(&cfg.sim_labels, "--sim-labels")?, need(&cfg.real_labels, "--real-labels")?);
            if let (Some(s), Some(r)) = (&cfg.sim, &cfg.real) {
                swap::check_files(s, r, cfg.no_swap_check);
            }
            let (sl, rl) = (sim_labels.as_deref().unwrap_or_default(), real_labels.as_deref().unwrap_or_default());
            by_pose(sl, rl, cfg.rule).map_err(|e| DemError::input(format!("{s}, {r}"), e))?
        }
        Method::Content => {
            let sim = sim.as_deref().ok_or_else(|| DemError::Usage("--match content needs --sim".into()))?;
            let keys = keys.as_deref().unwrap_or_default();
            let real_path = need(&cfg.real, "--real")?;
            let real = npy::read_all(&real_path)?;
            let sim_path = need(&cfg.sim, "--sim")?;
            swap::check(&sim_path, MissingCells::of(sim), &real_path, MissingCells::of(&real), cfg.no_swap_check);
            for (path, n) in [(&sim_path, sim.len()), (&real_path, real.len())] {
                if n == 0 {
                    return Err(DemError::input(path, "holds no records: --match content needs records to pair").into());
                }
            }
            let unique: Vec<u64> = keys.iter().enumerate().filter(|&(i, &k)| i as u64 == k).map(|(_, &k)| k).collect();
            by_content(sim, &unique, &real, cfg.k, cfg.max_distance)
        }
    };
    Ok(Paired { rows: pair_rows(found, keys.as_deref(), cfg.seed, cfg.val_fraction), sim_labels })
}
