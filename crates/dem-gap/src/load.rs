//! The inputs of a run and how they become the compared sets: the sim
//! and real records, aligned by the pairs when given, with each record's
//! terrain, time and run from the labels. Unpaired, the sim side can be
//! drawn to the real set's terrain mix first ([`terrain_mix`]), so a
//! different mix is not read as sensor effects.

use rand::seq::index::sample;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use dem_core::error::{DemError, Result};
use dem_core::format::{Dem, Terrain};
use dem_core::table::{Label, Split};
use dem_core::temporal::{self, Step};
use dem_core::{npy, table};
use dem_sensor::{Moment, SensorModel};

/// Everything one run needs.
#[derive(Debug, Clone)]
pub struct GapConfig {
    /// Sim NPY file.
    pub sim: String,
    /// Real NPY file.
    pub real: String,
    /// Pairs CSV (sim_index,real_index): compare per position.
    pub pairs: Option<String>,
    /// Labels CSV of the sim file.
    pub labels_sim: Option<String>,
    /// Labels CSV of the real file.
    pub labels_real: Option<String>,
    /// The model to start from.
    pub start: SensorModel,
    /// Output folder.
    pub out: String,
    /// Most effects added.
    pub max_steps: usize,
    /// Seed of the model's random effects and of the subsample.
    pub seed: u64,
    /// Records (pairs, or sim records) the candidates are fitted on.
    pub fit_records: usize,
    /// Smallest fraction of the gap an added effect must remove.
    pub min_gain: f64,
    /// Unpaired, with terrain labels on both sides: draw the sim records
    /// to the real set's terrain mix first (see [`terrain_mix`]); the
    /// command line's default.
    pub match_terrain: bool,
    /// Fit the effects that move whole records ([`EffectSpec::whole_record`])
    /// also where the sets' terrain mixes are not known to match (unpaired
    /// without both label files, or not drawn to one mix); the model then
    /// says so in its warnings.
    ///
    /// [`EffectSpec::whole_record`]: dem_sensor::effects::EffectSpec::whole_record
    pub whole_record: bool,
    /// Only the pairs of this split.
    pub split: Option<Split>,
    /// With pairs: compare the pairs' records as two sets (each record once
    /// per pair it is in), not per position: the gap over the pairs, as
    /// dem-eval's.
    pub over_pairs: bool,
    /// When no candidate holds up alone, try the best ones again with the
    /// named effects re-fitted beside them (`joint`).
    pub joint_refit: bool,
    /// Put how consecutive frames move in the gap when both label files
    /// give runs in time with poses (the frame terms); the command line's
    /// default.
    pub frame_terms: bool,
}

/// The compared sets: model side (sim) and real side, aligned when paired.
pub struct Sets {
    /// Sim records (one per pair when paired).
    pub sim: Vec<Dem>,
    /// Real records (one per pair when paired).
    pub real: Vec<Dem>,
    /// Compared per position.
    pub paired: bool,
    /// Terrain of each sim-side record, when known.
    pub sim_terrain: Option<Vec<Terrain>>,
    /// Terrain of each real-side record, when known.
    pub real_terrain: Option<Vec<Terrain>>,
    /// Each sim-side record's run and time in it (labels), when the sim
    /// labels give either: the draws a run keeps and `startup`'s times.
    pub sim_moments: Option<Vec<Moment>>,
    /// Run (labels' `sequence`) of each real record, when every real label
    /// has one: the sampling halves (unpaired) and the halves that order a
    /// named effect and its rival (both modes) deal whole runs.
    pub real_runs: Option<Vec<u64>>,
    /// Run of each sim record, likewise (unpaired only).
    pub sim_runs: Option<Vec<u64>>,
    /// Sim records compared after drawing them to the real set's terrain
    /// mix, and sim records read, when the draw changed anything.
    pub terrain_mix: Option<(usize, usize)>,
    /// Unpaired over the records of pairs: each record once per pair it is
    /// in, so both sides share the pairs' terrain mix.
    pub over_pairs: bool,
    /// The runs' steps between sim-side records (positions in `sim`), when
    /// both sides' labels give runs in time with poses: the frame terms of
    /// model(sim) ([`dem_core::distribution::frame_terms`]).
    pub sim_steps: Option<Vec<Step>>,
    /// The steps between real-side records (positions in `real`); paired,
    /// the steps both sides' labels agree on, the same as `sim_steps`
    /// (over pairs there are none).
    pub real_steps: Option<Vec<Step>>,
    /// Why the frame terms are left out, when they are.
    pub frames_left_out: Option<String>,
    /// Why the two sides' terrain mixes are not known to match, when they
    /// are not (unpaired, without both label files or not drawn to one
    /// mix); None paired, over pairs or drawn to one mix.
    pub unmatched_mix: Option<&'static str>,
}

/// What the labels give per record.
struct RecordLabels {
    /// Terrain of each record.
    terrain: Vec<Terrain>,
    /// Run and time in it, when any label gives one.
    moments: Option<Vec<Moment>>,
    /// Run (`sequence`), when every label has one.
    runs: Option<Vec<u64>>,
    /// The labels themselves (their runs' steps are taken after the
    /// records are picked).
    labels: Vec<Label>,
}

/// Terrain, time and run of each of the `n` records labelled at `path`.
fn read_record_labels(path: &Option<String>, n: usize) -> Result<Option<RecordLabels>> {
    let Some(p) = path else { return Ok(None) };
    let l = table::read_labels(p)?;
    if l.len() != n {
        return Err(DemError::input(p, format!("{} labels for {n} records", l.len())));
    }
    let moments = l.iter().any(|l| l.time.is_some() || l.sequence.is_some()).then(|| dem_sensor::moments(&l));
    let runs = l.iter().map(|l| l.sequence).collect::<Option<Vec<u64>>>();
    Ok(Some(RecordLabels { terrain: l.iter().map(|l| l.terrain).collect(), moments, runs, labels: l }))
}

/// One side's records with what its labels say of each.
struct Side {
    records: Vec<Dem>,
    terrain: Option<Vec<Terrain>>,
    moments: Option<Vec<Moment>>,
    runs: Option<Vec<u64>>,
    labels: Option<Vec<Label>>,
}

impl Side {
    fn new(records: Vec<Dem>, labels: Option<RecordLabels>) -> Side {
        match labels {
            Some(l) => Side { records, terrain: Some(l.terrain), moments: l.moments, runs: l.runs, labels: Some(l.labels) },
            None => Side { records, terrain: None, moments: None, runs: None, labels: None },
        }
    }

    /// The records at `idx` (in that order, repeats allowed), labels alike.
    fn pick(&self, idx: &[usize]) -> Side {
        Side {
            records: pick(&self.records, idx),
            terrain: self.terrain.as_ref().map(|t| pick(t, idx)),
            moments: self.moments.as_ref().map(|m| pick(m, idx)),
            runs: self.runs.as_ref().map(|r| pick(r, idx)),
            labels: self.labels.as_ref().map(|l| idx.iter().map(|&i| l[i].clone()).collect()),
        }
    }

    /// The steps of this side's runs, or why there are none.
    fn steps(&self, side: &str) -> std::result::Result<Vec<Step>, String> {
        let labels = self.labels.as_ref().ok_or_else(|| format!("no {side} labels, so its runs are not known"))?;
        let steps = temporal::steps(labels).map_err(|why| format!("{side}: {why}"))?;
        if steps.is_empty() {
            return Err(format!("the {side} labels' runs hold no consecutive frames"));
        }
        Ok(steps)
    }
}

/// The steps of each side, each its own (unpaired), or why there are none.
fn steps_apart(sim: &Side, real: &Side) -> std::result::Result<(Vec<Step>, Vec<Step>), String> {
    Ok((sim.steps("sim")?, real.steps("real")?))
}

/// The steps both aligned sides agree on (paired, over pairs: position i of
/// one is position i of the other), or why there are none.
fn steps_together(sim: &Side, real: &Side) -> std::result::Result<Vec<Step>, String> {
    let (s, r) = steps_apart(sim, real)?;
    let r: std::collections::HashSet<Step> = r.into_iter().collect();
    let both: Vec<Step> = s.into_iter().filter(|st| r.contains(st)).collect();
    if both.is_empty() {
        return Err("no consecutive frames of the sim runs are consecutive frames of the real runs at the pairs' positions".into());
    }
    Ok(both)
}

impl Sets {
    /// The sim-side steps between the records `idx`, renumbered to their
    /// positions in `idx` ([`temporal::within`]), when the frame terms count.
    pub fn sim_steps_in(&self, idx: &[usize]) -> Option<Vec<Step>> {
        self.sim_steps.as_deref().map(|s| temporal::within(s, idx))
    }

    /// The real-side steps between the records `idx`, likewise.
    pub fn real_steps_in(&self, idx: &[usize]) -> Option<Vec<Step>> {
        self.real_steps.as_deref().map(|s| temporal::within(s, idx))
    }

    /// These sets with the steps of `steps` (or why they are left out).
    fn with_steps(self, steps: std::result::Result<(Vec<Step>, Vec<Step>), String>) -> Sets {
        match steps {
            Ok((s, r)) => Sets { sim_steps: Some(s), real_steps: Some(r), frames_left_out: None, ..self },
            Err(why) => Sets { sim_steps: None, real_steps: None, frames_left_out: Some(why), ..self },
        }
    }
}

/// Read the inputs of `cfg` into the compared sets.
pub fn load(cfg: &GapConfig) -> Result<Sets> {
    let sim = npy::read_all(&cfg.sim)?;
    let real = npy::read_all(&cfg.real)?;
    for (p, v) in [(&cfg.sim, &sim), (&cfg.real, &real)] {
        if v.is_empty() {
            return Err(DemError::input(p.as_str(), "no records"));
        }
    }
    let (n_sim, n_real) = (sim.len(), real.len());
    let sim = Side::new(sim, read_record_labels(&cfg.labels_sim, n_sim)?);
    let real = Side::new(real, read_record_labels(&cfg.labels_real, n_real)?);
    let sets = match &cfg.pairs {
        None => unpaired_sets(cfg, sim, real),
        Some(pp) => paired_or_over_pairs(cfg, pp, sim, real, (n_sim, n_real))?,
    };
    Ok(if cfg.frame_terms { sets } else { sets.with_steps(Err("--no-frame-terms".into())) })
}

/// The sets of `cfg`'s pairs at `pp`: per position, or over pairs.
fn paired_or_over_pairs(cfg: &GapConfig, pp: &str, sim: Side, real: Side, (n_sim, n_real): (usize, usize)) -> Result<Sets> {
    let (si, ri) = pair_indices(cfg.split, pp, n_sim, n_real)?;
    let (sim, real) = (sim.pick(&si), real.pick(&ri));
    if cfg.over_pairs {
        // Each record once per pair it is in: dem-eval's gap, whose frame
        // columns give how the frames move.
        let why = "over pairs each record counts once per pair, as dem-eval's gap (its frame columns give the frames)";
        return Ok(over_pairs_sets(sim, real).with_steps(Err(why.to_string())));
    }
    let steps = steps_together(&sim, &real).map(|s| (s.clone(), s));
    Ok(paired_sets(sim, real).with_steps(steps))
}

/// The sim and real record of each pair of `cfg` (of its split, when one
/// is chosen), checked against the records read.
fn pair_indices(split: Option<Split>, pp: &str, n_sim: usize, n_real: usize) -> Result<(Vec<usize>, Vec<usize>)> {
    // Each pair with its line in the CSV (the header is line 1), kept
    // before the split is chosen so an error names the file's own line.
    let pairs: Vec<(u64, table::Pair)> = table::read_pairs(pp)?
        .into_iter()
        .zip(2..)
        .map(|(p, line)| (line, p))
        .filter(|(_, p)| split.is_none() || p.split == split)
        .collect();
    if pairs.is_empty() {
        let of = split.map_or(String::new(), |s| format!(" of split {s}"));
        return Err(DemError::input(pp, format!("no pairs{of}")));
    }
    let mut sim_idx = Vec::with_capacity(pairs.len());
    let mut real_idx = Vec::with_capacity(pairs.len());
    for (line, p) in &pairs {
        let (si, ri) = (p.sim_index as usize, p.real_index as usize);
        if si >= n_sim || ri >= n_real {
            return Err(DemError::Table {
                path: pp.to_string(),
                line: *line,
                reason: format!("pair ({si}, {ri}) past the data ({n_sim} sim, {n_real} real records)"),
            });
        }
        sim_idx.push(si);
        real_idx.push(ri);
    }
    Ok((sim_idx, real_idx))
}

/// Without pairs: the records' own distributions, the sim side drawn to
/// real's terrain mix when `cfg` asks for it and the mixes differ.
fn unpaired_sets(cfg: &GapConfig, mut sim: Side, real: Side) -> Sets {
    let mut mix = None;
    let unmatched_mix = match (&sim.terrain, &real.terrain) {
        (Some(s), Some(r)) if cfg.match_terrain => {
            let keep = terrain_mix(s, r, cfg.seed);
            if !keep.iter().copied().eq(0..sim.records.len()) {
                mix = Some((keep.len(), sim.records.len()));
                sim = sim.pick(&keep);
            }
            None
        }
        (Some(_), Some(_)) => Some("the sim records were not drawn to the real set's terrain mix (--no-match-terrain-mix)"),
        _ => Some("without both label files (--sim-labels, --real-labels) the two sets' terrain mixes cannot be matched"),
    };
    let steps = steps_apart(&sim, &real);
    Sets { terrain_mix: mix, unmatched_mix, ..Sets::unpaired(sim, real) }.with_steps(steps)
}

impl Sets {
    /// The two sides compared as distributions of records, each with its
    /// own labels and runs.
    fn unpaired(sim: Side, real: Side) -> Sets {
        Sets {
            sim: sim.records,
            real: real.records,
            paired: false,
            sim_terrain: sim.terrain,
            real_terrain: real.terrain,
            sim_moments: sim.moments,
            real_runs: real.runs,
            sim_runs: sim.runs,
            terrain_mix: None,
            over_pairs: false,
            unmatched_mix: None,
            sim_steps: None,
            real_steps: None,
            frames_left_out: None,
        }
    }
}

/// The pairs' records compared as two sets, each record once per pair it
/// is in (`sim` and `real` aligned by pair).
fn over_pairs_sets(sim: Side, real: Side) -> Sets {
    // Over pairs the i-th sim record is the i-th real record's pair: the
    // halves split both sides alike by the real runs.
    Sets { sim_runs: None, over_pairs: true, ..Sets::unpaired(sim, real) }
}

/// The pairs compared per position (`sim` and `real` aligned by pair).
fn paired_sets(sim: Side, real: Side) -> Sets {
    // Both sides share the pair's terrain; prefer the real label.
    let terrain = real.terrain.or(sim.terrain);
    Sets {
        sim: sim.records,
        real: real.records,
        paired: true,
        sim_terrain: terrain.clone(),
        real_terrain: terrain,
        sim_moments: sim.moments,
        real_runs: real.runs,
        sim_runs: None,
        terrain_mix: None,
        over_pairs: false,
        unmatched_mix: None,
        sim_steps: None,
        real_steps: None,
        frames_left_out: None,
    }
}

/// The sim records (indices, ascending, a record may repeat) to compare
/// unpaired when both sides carry terrain labels: as many records as sim
/// has, shared among the terrains as real's records are, each terrain's
/// share drawn from its sim records (seeded; without replacement while
/// they last, then with). Sim terrains that real lacks are left out. A
/// distribution comparison otherwise reads a difference of terrain mix as
/// a sensor effect: more stairs on the sim side looks like more holes and
/// a height bias, and the fit names those. Prepared sims deduplicated to
/// unique keys (one flat record) are the extreme case. Equal mixes keep
/// every record once.
pub fn terrain_mix(sim: &[Terrain], real: &[Terrain], seed: u64) -> Vec<usize> {
    let mut by_terrain: Vec<(Terrain, Vec<usize>, usize)> = Vec::new();
    for (i, &t) in sim.iter().enumerate() {
        match by_terrain.iter_mut().find(|(u, _, _)| *u == t) {
            Some(e) => e.1.push(i),
            None => by_terrain.push((t, vec![i], 0)),
        }
    }
    for &t in real {
        if let Some(e) = by_terrain.iter_mut().find(|(u, _, _)| *u == t) {
            e.2 += 1;
        }
    }
    let shared: usize = by_terrain.iter().map(|e| e.2).sum();
    if shared == 0 {
        return (0..sim.len()).collect();
    }
    let mut rng = ChaCha8Rng::seed_from_u64(dem_core::seeded::mix(seed ^ 0x7e22a1));
    let mut keep = Vec::with_capacity(sim.len());
    for (_, idx, n_real) in &by_terrain {
        let n = (sim.len() as f64 * *n_real as f64 / shared as f64).round() as usize;
        if n >= idx.len() {
            keep.extend_from_slice(idx);
            keep.extend((idx.len()..n).map(|_| idx[rng.gen_range(0..idx.len())]));
        } else {
            keep.extend(sample(&mut rng, idx.len(), n).into_iter().map(|j| idx[j]));
        }
    }
    keep.sort_unstable();
    keep
}

/// The items of `v` at `idx`, in that order.
pub(crate) fn pick<T: Copy>(v: &[T], idx: &[usize]) -> Vec<T> {
    idx.iter().map(|&i| v[i]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pair past the data is named by its line in the file, also when
    /// `--split` leaves out the lines before it.
    #[test]
    fn a_pair_past_the_data_names_its_line_in_the_file() {
        let dir = dem_testkit::tempdir();
        let pp = dir.path().join("pairs.csv");
        std::fs::write(&pp, "sim_index,real_index,split\n0,0,val\n1,1,val\n2,2,train\n9,3,train\n").unwrap();
        let pp = pp.to_str().unwrap();
        for split in [None, Some(Split::Train)] {
            let e = pair_indices(split, pp, 5, 5).unwrap_err().to_string();
            assert!(e.contains("line 5") && e.contains("pair (9, 3) past the data"), "{split:?}: {e}");
        }
        assert_eq!(pair_indices(Some(Split::Val), pp, 5, 5).unwrap(), (vec![0, 1], vec![0, 1]));
    }

    /// Equal mixes keep every record once; a sim set heavy in stairs is
    /// drawn to real's shares: a terrain real lacks is left out, one with
    /// too few sim records is taken whole and then repeated.
    #[test]
    fn sim_records_are_drawn_to_the_real_terrain_mix() {
        use Terrain::{Flat, Pallet, StairsUp};
        let real = [vec![Flat; 50], vec![StairsUp; 50]].concat();
        assert_eq!(terrain_mix(&real, &real, 1), (0..100).collect::<Vec<_>>());
        let sim = [vec![StairsUp; 120], vec![Flat; 10], vec![Pallet; 40], vec![StairsUp; 30]].concat();
        let keep = terrain_mix(&sim, &real, 1);
        assert_eq!(keep.len(), sim.len());
        assert!(keep.windows(2).all(|w| w[0] <= w[1]), "ascending");
        let distinct = |t: Terrain| {
            let mut k: Vec<usize> = keep.iter().copied().filter(|&i| sim[i] == t).collect();
            let n = k.len();
            k.dedup();
            (n, k.len())
        };
        assert_eq!(distinct(Flat), (100, 10));
        assert_eq!(distinct(StairsUp), (100, 100));
        assert_eq!(distinct(Pallet), (0, 0));
        assert_eq!(keep, terrain_mix(&sim, &real, 1), "by seed");
        assert_ne!(keep, terrain_mix(&sim, &real, 2));
        // No terrain in common: nothing to match, every record as it is.
        assert_eq!(terrain_mix(&[Pallet; 5], &real, 1), (0..5).collect::<Vec<_>>());
    }
}
