//! What an evaluation reads: the selected sim records (streamed, only the
//! selection is kept), their predictions, the paired real records and the
//! sim labels, each checked against the others with a one-line error.

use std::collections::{BTreeSet, HashMap};

use dem_core::eval::{self, RecordResult, Selection};
use dem_core::gap::stats;
use dem_core::npy::{self, CHUNK_RECORDS};
use dem_core::table::{self, Pair, Split};
use dem_core::{cli, Dem, DemError, Terrain};

/// How the predictions are made.
pub enum Method {
    /// The sim record as is (the thesis's Identity row).
    Identity,
    /// Record i of this NPY file is the prediction for sim record i.
    Pred(String),
    /// Run this ONNX generator on the selected sim records.
    Model(String),
}

/// A validated evaluation request.
pub struct Request {
    /// Sim NPY.
    pub sim: String,
    /// Real NPY.
    pub real: String,
    /// Pairs CSV.
    pub pairs: String,
    /// Only pairs of this split.
    pub split: Option<Split>,
    /// Labels CSV of the sim file.
    pub labels_sim: Option<String>,
    /// Where predictions come from.
    pub method: Method,
    /// Records per model call.
    pub batch: usize,
    /// Refuse a model that changes row 20.
    pub strict: bool,
    /// Keep the input, prediction and closest real record of each result.
    pub keep: bool,
}

/// The outcome: one result per selected sim record, in index order, and,
/// when asked for, the records behind each result in the same order.
pub struct Evaluation {
    /// The selection evaluated: each sim record's real partners.
    sel: Selection,
    /// Prediction of each selected sim record.
    pred_of: HashMap<u64, Dem>,
    /// Each real record paired in the selection.
    real_of: HashMap<u64, Dem>,
    /// Pair error, best real record and terrain of each selected sim record.
    pub results: Vec<RecordResult>,
    /// The sim records (empty unless `keep`).
    pub input: Vec<Dem>,
    /// Their predictions (empty unless `keep`).
    pub pred: Vec<Dem>,
    /// The closest real record of each (empty unless `keep`).
    pub closest: Vec<Dem>,
}

/// Read the records of `path` whose indices are in `wanted`; returns the
/// number of records in the file and the kept ones.
fn read_selected(path: &str, wanted: &BTreeSet<u64>) -> anyhow::Result<(u64, HashMap<u64, Dem>)> {
    let mut r = npy::open(path)?;
    let (mut chunk, mut kept, mut first) = (Vec::new(), HashMap::new(), 0u64);
    loop {
        chunk.clear();
        let n = r.read_chunk(&mut chunk, CHUNK_RECORDS)? as u64;
        if n == 0 {
            return Ok((first, kept));
        }
        for &i in wanted.range(first..first + n) {
            kept.insert(i, chunk[(i - first) as usize]);
        }
        first += n;
    }
}

/// Refuse a pairs row that points past a file of `len` records.
fn check_range(pairs_path: &str, pairs: &[Pair], len: u64, file: &str, real: bool) -> anyhow::Result<()> {
    let col = if real { "real_index" } else { "sim_index" };
    if let Some((n, p)) = pairs.iter().enumerate().find(|(_, p)| (if real { p.real_index } else { p.sim_index }) >= len) {
        let i = if real { p.real_index } else { p.sim_index };
        return Err(DemError::Table {
            path: pairs_path.into(),
            line: n as u64 + 2,
            reason: format!("{col} {i} is past the end of {file} ({len} records)"),
        }
        .into());
    }
    Ok(())
}

/// Run the evaluation.
pub fn run(q: &Request) -> anyhow::Result<Evaluation> {
    let stdin_users = [Some(&q.sim), Some(&q.real), Some(&q.pairs), q.labels_sim.as_ref()]
        .into_iter()
        .chain([match &q.method {
            Method::Pred(p) => Some(p),
            _ => None,
        }])
        .filter(|p| p.is_some_and(|p| p == "-"))
        .count();
    if stdin_users > 1 {
        return Err(cli::usage("only one input can be `-` (stdin)"));
    }
    // Every row is range-checked, also those of the split not evaluated.
    let all_pairs = table::read_pairs(&q.pairs)?;
    let mut pairs = all_pairs.clone();
    if let Some(s) = q.split {
        if pairs.iter().all(|p| p.split.is_none()) {
            return Err(DemError::input(q.pairs.as_str(), "has no split column for --split (dem-pair writes one)").into());
        }
        pairs.retain(|p| p.split == Some(s));
    }
    let sel: Selection = eval::select(&pairs, None);
    if sel.is_empty() {
        let which = q.split.map_or(String::new(), |s| format!(" of split {}", if s == Split::Val { "val" } else { "train" }));
        return Err(DemError::input(q.pairs.as_str(), format!("holds no pairs{which} to evaluate")).into());
    }
    let sims: BTreeSet<u64> = sel.keys().copied().collect();
    let reals: BTreeSet<u64> = sel.values().flatten().copied().collect();
    let (n_sim, sim) = read_selected(&q.sim, &sims)?;
    check_range(&q.pairs, &all_pairs, n_sim, &q.sim, false)?;
    let (n_real, real) = read_selected(&q.real, &reals)?;
    check_range(&q.pairs, &all_pairs, n_real, &q.real, true)?;
    let labels = match &q.labels_sim {
        Some(path) => {
            let l = table::read_labels(path)?;
            if l.len() as u64 != n_sim {
                return Err(DemError::input(path.as_str(), format!("has {} rows but {} has {n_sim} records", l.len(), q.sim)).into());
            }
            Some(l)
        }
        None => None,
    };
    let pred: HashMap<u64, Dem> = match &q.method {
        Method::Identity => sim.clone(),
        Method::Pred(path) => {
            let (n, pred) = read_selected(path, &sims)?;
            if n != n_sim {
                return Err(DemError::input(path.as_str(), format!("has {n} records but {} has {n_sim}: a prediction file holds one record per sim record", q.sim)).into());
            }
            pred
        }
        Method::Model(path) => crate::model::predict(path, &sim, &q.sim, q.batch, q.strict)?,
    };
    let terrain = |i: u64| -> Option<Terrain> { labels.as_ref().map(|l| l[i as usize].terrain) };
    let results = eval::evaluate(&sel, |i| &pred[&i], |j| &real[&j], terrain);
    let gather = |m: &HashMap<u64, Dem>, real: bool| -> Vec<Dem> {
        if !q.keep {
            return Vec::new();
        }
        results.iter().map(|r| m[&if real { r.real_index } else { r.sim_index }]).collect()
    };
    let (input, pred_kept, closest) = (gather(&sim, false), gather(&pred, false), gather(&real, true));
    Ok(Evaluation { sel, pred_of: pred, real_of: real, results, input, pred: pred_kept, closest })
}

impl Evaluation {
    /// The distribution gap (dem-gap's measure, unpaired) of the predictions
    /// of `group` against its real set: the unique real records paired with
    /// its sim records in the evaluated pairs (not only the closest ones),
    /// in index order. None for an empty group.
    pub fn gap(&self, group: &[&RecordResult]) -> Option<f64> {
        if group.is_empty() {
            return None;
        }
        let preds: Vec<Dem> = group.iter().map(|r| self.pred_of[&r.sim_index]).collect();
        let reals: BTreeSet<u64> = group.iter().flat_map(|r| self.sel[&r.sim_index].iter().copied()).collect();
        let reals: Vec<Dem> = reals.iter().map(|j| self.real_of[j]).collect();
        Some(stats::gap(&stats::stats(&preds, None), &stats::stats(&reals, None)))
    }
}
