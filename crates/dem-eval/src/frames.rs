//! The frame columns of a table (`frame_*`, `real_frame_*`): how the
//! predictions of consecutive frames of a run move, and how the real
//! records of the row's pairs move in their own runs
//! ([`dem_core::temporal`]).
//!
//! The predictions stream by in blocks; a frame waits until the other
//! frame of its step comes by (in a file in run order, one block at most),
//! so the columns do not depend on the file's order.

use std::collections::{BTreeMap, BTreeSet, HashMap};

use dem_core::format::{Dem, Terrain, GRID_ROWS};
use dem_core::temporal::{self, FrameStats, FrameSums, Step};
use dem_core::{cli, table};

/// The rows of a table a record (or a step, by its later frame) counts in:
/// the row over all records, and with `by_terrain` its terrain's.
pub(crate) fn row_keys(terrain: Option<Terrain>, by_terrain: bool) -> Vec<Option<Terrain>> {
    if by_terrain {
        vec![None, terrain]
    } else {
        vec![None]
    }
}

/// The steps of the runs in a labels file, looked up by either frame.
pub(crate) struct Runs {
    steps: Vec<Step>,
    of_record: HashMap<u64, Vec<usize>>,
}

impl Runs {
    /// The steps of `labels` (records indexed from `first`) whose both
    /// frames `keep` keeps, or None with one line on stderr saying why
    /// (`what` names the file).
    pub(crate) fn of(labels: &[table::Label], first: u64, what: &str, keep: impl Fn(u64) -> bool) -> Option<Runs> {
        let steps = match temporal::steps(labels) {
            Ok(s) => s,
            Err(why) => {
                cli::log(format_args!("frame columns of {what} left out: {why}"));
                return None;
            }
        };
        let first = first as usize;
        let steps = steps
            .into_iter()
            .map(|s| Step { from: s.from + first, to: s.to + first, shift: s.shift })
            .filter(|s| keep(s.from as u64) && keep(s.to as u64))
            .collect();
        Some(Runs::of_steps(steps))
    }

    fn of_steps(steps: Vec<Step>) -> Runs {
        let mut of_record: HashMap<u64, Vec<usize>> = HashMap::new();
        for (k, s) in steps.iter().enumerate() {
            of_record.entry(s.from as u64).or_default().push(k);
            of_record.entry(s.to as u64).or_default().push(k);
        }
        Runs { steps, of_record }
    }

    fn of_record(&self, i: u64) -> &[usize] {
        self.of_record.get(&i).map_or(&[], Vec::as_slice)
    }
}

/// The predictions' side: frames waiting for the other frame of their
/// step, and each row's sums.
#[derive(Default)]
pub(crate) struct PredFrames {
    /// (sim, prediction) of a frame and how many of its steps still wait.
    waiting: HashMap<u64, (Dem, Dem, usize)>,
    sums: BTreeMap<Option<Terrain>, FrameSums>,
}

impl PredFrames {
    /// Add scored record `i` (its sim input and its prediction), each
    /// scored record once; `terrain` gives each record's terrain.
    pub(crate) fn add(&mut self, runs: &Runs, i: u64, sim: &Dem, pred: &Dem, terrain: impl Fn(u64) -> Option<Terrain>, by_terrain: bool) {
        let mut waits = 0;
        for &k in runs.of_record(i) {
            let s = runs.steps[k];
            let other = if s.from as u64 == i { s.to as u64 } else { s.from as u64 };
            let Some((osim, opred, left)) = self.waiting.get_mut(&other) else {
                waits += 1;
                continue;
            };
            let (a, b) = if s.from as u64 == i { ((sim, pred), (&*osim, &*opred)) } else { ((&*osim, &*opred), (sim, pred)) };
            for key in row_keys(terrain(s.to as u64), by_terrain) {
                self.sums.entry(key).or_default().add((a.1, b.1), Some((a.0, b.0)), s.shift, 0..GRID_ROWS);
            }
            *left -= 1;
            if *left == 0 {
                self.waiting.remove(&other);
            }
        }
        if waits > 0 {
            self.waiting.insert(i, (*sim, *pred, waits));
        }
    }

    /// Each row's statistics; one line on stderr when no step had both
    /// frames scored.
    pub(crate) fn stats(&self) -> BTreeMap<Option<Terrain>, FrameStats> {
        if self.sums.is_empty() {
            cli::log("frame columns left out: no two consecutive frames of a run among the scored sim records");
        }
        self.sums.iter().map(|(k, s)| (*k, s.stats())).collect()
    }
}

/// The real side: the steps of the real runs whose both frames are real
/// partners of scored pairs, and for each real record its one sim partner
/// (the reference of `real_frame_rcorr`), where it has exactly one.
pub(crate) struct RealFrames {
    runs: Runs,
    partner: HashMap<u64, u64>,
    /// The sim partners to keep, and those seen while the sims stream by.
    wanted: BTreeSet<u64>,
    sims: HashMap<u64, Dem>,
    terrain: Vec<Terrain>,
}

impl RealFrames {
    /// The real side of `scored` pairs (sim, real) over the real labels at
    /// `path`, one for each of the `n_real` real records.
    pub(crate) fn new(path: &str, n_real: u64, scored: &[(u64, u64)]) -> anyhow::Result<Option<RealFrames>> {
        let labels = table::read_labels(path)?;
        if labels.len() as u64 != n_real {
            return Err(dem_core::DemError::input(path, format!("{} labels for {n_real} real records", labels.len())).into());
        }
        let mut partners: HashMap<u64, Vec<u64>> = HashMap::new();
        for &(s, r) in scored {
            partners.entry(r).or_default().push(s);
        }
        let Some(runs) = Runs::of(&labels, 0, path, |r| partners.contains_key(&r)) else { return Ok(None) };
        let partner: HashMap<u64, u64> = partners.into_iter().filter(|(_, v)| v.len() == 1).map(|(r, v)| (r, v[0])).collect();
        let wanted = runs.of_record.keys().filter_map(|r| partner.get(r)).copied().collect();
        let terrain = labels.iter().map(|l| l.terrain).collect();
        Ok(Some(RealFrames { runs, partner, wanted, sims: HashMap::new(), terrain }))
    }

    /// Keep sim record `i` when it is a real frame's one partner.
    pub(crate) fn see_sim(&mut self, i: u64, sim: &Dem) {
        if self.wanted.contains(&i) {
            self.sims.insert(i, *sim);
        }
    }

    /// Each row's statistics (a row's terrain is the real labels'): `fetch`
    /// gives real records by index. One line on stderr when no step of a
    /// real run had both frames among the pairs' real records.
    pub(crate) fn stats(
        &self,
        mut fetch: impl FnMut(&BTreeSet<u64>) -> anyhow::Result<HashMap<u64, Dem>>,
        by_terrain: bool,
    ) -> anyhow::Result<BTreeMap<Option<Terrain>, FrameStats>> {
        if self.runs.steps.is_empty() {
            cli::log("real frame columns left out: no two consecutive frames of a real run among the scored pairs' real records");
        }
        let mut sums: BTreeMap<Option<Terrain>, FrameSums> = BTreeMap::new();
        for chunk in self.runs.steps.chunks(4096) {
            let want: BTreeSet<u64> = chunk.iter().flat_map(|s| [s.from as u64, s.to as u64]).collect();
            let real = fetch(&want)?;
            for s in chunk {
                let (a, b) = (&real[&(s.from as u64)], &real[&(s.to as u64)]);
                let sim = |r: usize| self.partner.get(&(r as u64)).and_then(|i| self.sims.get(i));
                let reference = sim(s.from).zip(sim(s.to));
                for key in row_keys(self.terrain.get(s.to).copied(), by_terrain) {
                    sums.entry(key).or_default().add((a, b), reference, s.shift, 0..GRID_ROWS);
                }
            }
        }
        Ok(sums.iter().map(|(k, s)| (*k, s.stats())).collect())
    }
}
