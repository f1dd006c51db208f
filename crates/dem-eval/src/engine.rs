//! What an evaluation reads, in bounded memory: the sim stream (and a
//! prediction stream beside it) is read a block of selected records at a
//! time; the real records a block's pairs name are read by index from the
//! file (held only when the real stream is stdin); what is kept is the
//! pairs (16 bytes each), one pair error per selected record (8 bytes, for
//! the exact median), one terrain byte per sim record, and for the gap a
//! deterministic sample of at most [`GAP_SAMPLE`] pairs per table row.
//! Per-record results and `--emit-*` records are written as blocks finish.
//! The frame columns wait for the other frame of each step
//! ([`crate::frames`]): in a file in run order, a block's worth.
//! Each input is checked against the others with a one-line error.

use std::collections::{BTreeMap, BTreeSet, HashMap};

use crate::frames::{row_keys, PredFrames, RealFrames, Runs};
use crate::table::{self as validation, RowAcc, Selection, TableRow};
use dem_core::distribution;
use dem_core::npy::{self, ByIndex, RecordIndex, CHUNK_RECORDS};
use dem_core::table::{self, Split};
use dem_core::temporal::FrameStats;
use dem_core::{cli, Dem, DemError, Terrain};
use dem_onnx::apply::AttitudeCheck;
use rayon::prelude::*;

/// How the predictions are made.
pub enum Method {
    /// The sim record as is (the thesis's Identity row).
    Identity,
    /// Record i of this NPY file is the prediction for sim record i.
    Pred(String),
    /// Run this ONNX generator on the selected sim records.
    Model(String),
}

/// Selected sim records evaluated together: memory is this many records
/// (and their predictions and paired real records) at a time.
pub const BLOCK: usize = 4096;

/// Most pairs a table row's gap is computed on. Above it, the gap of a row
/// is that of a sample chosen by a hash of the pair's indices (the same
/// sample on every run), and dem-eval says so on stderr.
pub const GAP_SAMPLE: u64 = 20_000;

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
    /// Labels of the real file: its runs give the `real_frame_*` columns.
    pub labels_real: Option<String>,
    /// Where predictions come from.
    pub method: Method,
    /// Records per model call.
    pub batch: usize,
    /// Refuse a model that changes row 20.
    pub strict: bool,
    /// Run a model's network without the residual sensor model it carries.
    pub network_only: bool,
    /// Seed of the residual sensor model's draws.
    pub seed: u64,
    /// Also one table row per terrain (needs the labels).
    pub by_terrain: bool,
    /// Write the per-record results here (CSV), in index order.
    pub records: Option<String>,
    /// Write the sim record of each result here, in result order.
    pub emit_input: Option<String>,
    /// Write the prediction of each result here.
    pub emit_pred: Option<String>,
    /// Write the closest real record of each result here.
    pub emit_closest: Option<String>,
    /// Index of the sim file's first record in the whole data set (a shard
    /// of `dem-split`): the pairs name whole-set indices, and only those of
    /// this shard's records are evaluated.
    pub first_index: Option<u64>,
}

/// The outcome: each table row's accumulated results and gap.
pub struct Evaluation {
    /// The row over every record (None) and each terrain's row.
    rows: std::collections::BTreeMap<Option<Terrain>, RowAcc>,
    gaps: HashMap<Option<Terrain>, f64>,
    /// Each row's frame statistics of the predictions and of the real records.
    frames: [BTreeMap<Option<Terrain>, FrameStats>; 2],
}

impl Evaluation {
    /// The outcome of rows accumulated elsewhere (`dem-eval merge`).
    pub(crate) fn new(
        rows: std::collections::BTreeMap<Option<Terrain>, RowAcc>,
        gaps: HashMap<Option<Terrain>, f64>,
        frames: [BTreeMap<Option<Terrain>, FrameStats>; 2],
    ) -> Self {
        Evaluation { rows, gaps, frames }
    }

    /// The table of `method`: the row over all records, then with
    /// `by_terrain` one per terrain present, in label order.
    pub fn table(&self, method: &str, by_terrain: bool) -> Vec<TableRow> {
        let row = |key: Option<Terrain>, name: &str| {
            let row = self.rows.get(&key).and_then(|acc| acc.row(method, name, self.gaps.get(&key).copied()))?;
            Some(row.with_frames(self.frames[0].get(&key), self.frames[1].get(&key)))
        };
        let mut rows: Vec<TableRow> = row(None, validation::ALL).into_iter().collect();
        if by_terrain {
            rows.extend(Terrain::ALL.into_iter().filter_map(|t| row(Some(t), t.as_str())));
        }
        rows
    }
}

/// The first line of the pairs CSV holding the largest index of a column,
/// and that index: what a range check needs once the file's length is known.
#[derive(Clone, Copy, Default)]
pub(crate) struct Largest {
    index: u64,
    line: u64,
}

impl Largest {
    pub(crate) fn check(&self, pairs_path: &str, len: u64, file: &str, col: &str) -> anyhow::Result<()> {
        if self.line > 0 && self.index >= len {
            return Err(DemError::Table {
                path: pairs_path.into(),
                line: self.line,
                reason: format!("{col} {} is past the end of {file} ({len} records)", self.index),
            }
            .into());
        }
        Ok(())
    }
}

/// The pairs to evaluate ([`validation::select`]), sorted by sim index.
pub(crate) struct Pairs {
    pub(crate) pairs: Vec<(u64, u64)>,
}

impl Pairs {
    /// Read the pairs CSV; every row is range-checked later, also those of
    /// the split not evaluated.
    pub(crate) fn read(path: &str, split: Option<Split>) -> anyhow::Result<(Pairs, Largest, Largest)> {
        let all = table::read_pairs_for(path, split)?;
        let (mut sim_max, mut real_max) = (Largest::default(), Largest::default());
        for (n, p) in all.iter().enumerate() {
            let line = n as u64 + 2;
            if sim_max.line == 0 || p.sim_index > sim_max.index {
                sim_max = Largest { index: p.sim_index, line };
            }
            if real_max.line == 0 || p.real_index > real_max.index {
                real_max = Largest { index: p.real_index, line };
            }
        }
        let kept = validation::select(&all, split);
        drop(all);
        Ok((Pairs { pairs: kept }, sim_max, real_max))
    }

    /// The pairs of the sims with indices in `range`.
    pub(crate) fn within(&self, range: std::ops::Range<u64>) -> &[(u64, u64)] {
        let lo = self.pairs.partition_point(|p| p.0 < range.start);
        let hi = self.pairs.partition_point(|p| p.0 < range.end);
        &self.pairs[lo..hi]
    }
}

/// splitmix64 of a pair's indices: the gap sample keeps pair (i, j) when
/// this falls below its rate.
fn sample_hash(i: u64, j: u64) -> u64 {
    use dem_core::seeded::mix;
    mix(mix(i ^ 0x6761_705f_7361_6d70) ^ j)
}

/// Keeps pair (i, j) of a row of `n` pairs with probability GAP_SAMPLE / n, by hash.
fn in_sample(i: u64, j: u64, n: u64) -> bool {
    n <= GAP_SAMPLE || (sample_hash(i, j) as f64) < GAP_SAMPLE as f64 / n as f64 * u64::MAX as f64
}

/// The writers of --emit-records and --emit-input, --emit-pred, --emit-closest:
/// each gets a block's rows as it finishes; files appear only on success.
struct Emit {
    records: Option<crate::records::RecordsWriter>,
    input: Option<npy::NpyWriter>,
    pred: Option<npy::NpyWriter>,
    closest: Option<npy::NpyWriter>,
}

impl Emit {
    fn create(q: &Request) -> anyhow::Result<Self> {
        let open = |p: &Option<String>| p.as_deref().map(npy::create).transpose();
        Ok(Emit {
            records: q.records.as_deref().map(crate::records::RecordsWriter::create).transpose()?,
            input: open(&q.emit_input)?,
            pred: open(&q.emit_pred)?,
            closest: open(&q.emit_closest)?,
        })
    }

    fn finish(self) -> anyhow::Result<()> {
        if let Some(r) = self.records {
            r.finish()?;
        }
        for w in [self.input, self.pred, self.closest].into_iter().flatten() {
            w.finish()?;
        }
        Ok(())
    }
}

/// One table row's gap sample: a prediction and its real partner per pair.
///
/// The gap compares the two sides over the evaluated *pairs*, not over the
/// unique sim and real records: a sim key that `dem-pair` found for many
/// measured records (the one flat sim of a run, say) stands for each of
/// them, as its real partners do. Over unique records the two sides'
/// terrain mixes differ (on `make demo`'s val split, 0.3 % of the sim keys
/// are flat against 22 % of their partners), and a model fitted to that
/// difference would be rewarded for it. With pairs 1:1 both forms agree.
#[derive(Default)]
pub(crate) struct GapSample {
    preds: Vec<Dem>,
    reals: Vec<u64>,
}

impl GapSample {
    /// Add sim record `index` of a row of `row_pairs` pairs: its
    /// prediction and real partner for each of its pairs the sample keeps.
    pub(crate) fn add(&mut self, index: u64, pred: &Dem, partners: impl Iterator<Item = u64>, row_pairs: u64) {
        for j in partners {
            if in_sample(index, j, row_pairs) {
                self.preds.push(*pred);
                self.reals.push(j);
            }
        }
    }
}

/// The gap of each table row from its sample: the sampled predictions
/// against their real partners; `sizes` are the rows' pair counts, for the
/// note on stderr when a row was sampled.
pub(crate) fn row_gaps(
    samples: HashMap<Option<Terrain>, GapSample>,
    sizes: &HashMap<Option<Terrain>, u64>,
    reals: &mut ByIndex,
) -> anyhow::Result<HashMap<Option<Terrain>, f64>> {
    let mut gaps = HashMap::new();
    for (key, mut sample) in samples {
        let n = sizes.get(&key).copied().unwrap_or(0);
        if n > GAP_SAMPLE {
            let row = key.map_or("all".to_string(), |t| t.to_string());
            cli::log(format_args!(
                "gap of row {row}: a sample of {} of its {n} pairs (at most {GAP_SAMPLE}, chosen by index)",
                sample.preds.len()
            ));
        }
        // In index order (the summation order of the statistics): with
        // pairs 1:1 the set is the one the sims' partners always gave.
        sample.reals.sort_unstable();
        let real_records: Vec<Dem> = {
            let m = reals.fetch(&sample.reals.iter().copied().collect())?;
            sample.reals.iter().map(|j| m[j]).collect()
        };
        gaps.insert(key, distribution::gap(&distribution::stats(&sample.preds, None), &distribution::stats(&real_records, None)));
    }
    Ok(gaps)
}

/// Everything accumulated over the blocks.
#[derive(Default)]
struct Acc {
    rows: std::collections::BTreeMap<Option<Terrain>, RowAcc>,
    samples: HashMap<Option<Terrain>, GapSample>,
    attitude: AttitudeCheck,
    frames: PredFrames,
    real_frames: Option<RealFrames>,
    /// A residual's map memory, stepped over the scored records in stream order.
    memory: Option<dem_sensor::fusion::Runs>,
}

/// Run the evaluation.
pub fn run(q: &Request) -> anyhow::Result<Evaluation> {
    let pred = match &q.method {
        Method::Pred(p) => Some(p),
        _ => None,
    };
    cli::one_stdin(
        [Some(&q.sim), Some(&q.real), Some(&q.pairs), q.labels_sim.as_ref(), q.labels_real.as_ref(), pred]
            .into_iter()
            .flatten()
            .map(String::as_str),
    )?;
    let (pairs, sim_max, real_max) = Pairs::read(&q.pairs, q.split)?;
    if pairs.pairs.is_empty() {
        return Err(table::no_pairs(&q.pairs, q.split, "evaluate").into());
    }
    let mut reals = open_reals(q, &pairs)?;
    real_max.check(&q.pairs, reals.len(), &q.real, "real_index")?;
    let mut labels = SimLabels::read(q)?;
    let scored = scored_pairs(q, &pairs, &labels)?;
    let row_sizes = row_sizes(q, scored, &labels);
    let network = Network::load(q, labels.moments.as_deref())?;
    let mut acc = Acc::default();
    if let (Some(m), true) = (network.residual.as_ref().and_then(|r| r.map_memory()), dem_sensor::any_in_run(labels.moments.as_deref())) {
        // Pairs of one sim record are scored on one prediction of it.
        let scored_records = scored.chunk_by(|a, b| a.0 == b.0).count() as u64;
        if scored_records != labels.moments.as_ref().map_or(0, |m| m.len() as u64) {
            cli::log(
                "note: the model's residual has map-memory: it steps the runs over the scored records only (dem-apply --labels \
                 steps every record; dem-eval --pred scores its output)",
            );
        }
        acc.memory = Some(dem_sensor::fusion::Runs::new(m, labels.first_index));
    }
    // The whole labels only until the runs are made: the stream keeps a
    // terrain byte and a time per record, and the steps.
    let runs = match (labels.labels.take(), &q.labels_sim) {
        (Some(l), Some(path)) => {
            let scored_sims: BTreeSet<u64> = scored.iter().map(|p| p.0).collect();
            Runs::of(&l, labels.first_index, path, |i| scored_sims.contains(&i))
        }
        _ => None,
    };
    acc.real_frames = q.labels_real.as_deref().map(|path| RealFrames::new(path, reals.len(), scored)).transpose()?.flatten();
    let mut emit = Emit::create(q)?;
    let ctx = BlockCtx {
        q,
        pairs: &pairs,
        model: network.model.as_ref(),
        residual: network.residual.as_ref(),
        heights: network.heights,
        labels: &labels,
        row_sizes: &row_sizes,
        runs: runs.as_ref(),
    };
    let n_sim = evaluate_stream(&ctx, &sim_max, &mut reals, &mut emit, &mut acc)?;
    if let (Some(t), Some(path)) = (&labels.terrains, &q.labels_sim) {
        table::check_labels_cover(path, t.len(), &q.sim, n_sim)?;
    }
    if let Method::Model(path) = &q.method {
        if let Some(w) = acc.attitude.warning(path, &q.sim) {
            cli::log(w);
        }
    }
    emit.finish()?;
    let pred_frames = if runs.is_some() { acc.frames.stats() } else { BTreeMap::new() };
    let real_frames = match &acc.real_frames {
        Some(rf) => rf.stats(|want| Ok(reals.fetch(want)?), q.by_terrain)?,
        None => BTreeMap::new(),
    };
    let gaps = row_gaps(acc.samples, &row_sizes, &mut reals)?;
    // After the run: a refused input still gets exactly one line.
    if let Some(note) = network.model.as_ref().and_then(|m| m.note()) {
        cli::log(note);
    }
    Ok(Evaluation { rows: acc.rows, gaps, frames: [pred_frames, real_frames] })
}

/// The real file, read by index; held whole only when it is stdin, and
/// then only the records some pair names.
fn open_reals(q: &Request, pairs: &Pairs) -> anyhow::Result<ByIndex> {
    let all_reals: BTreeSet<u64> = if q.real == "-" { pairs.pairs.iter().map(|p| p.1).collect() } else { BTreeSet::new() };
    Ok(ByIndex::open(&q.real, |i| all_reals.contains(&i))?)
}

/// What the engine keeps of the sim file's labels: one terrain byte and one
/// moment (run and time) per record. Labels are the sim file's own, so a shard's are indexed
/// from its first record.
struct SimLabels {
    terrains: Option<Vec<Terrain>>,
    moments: Option<Vec<dem_sensor::Moment>>,
    first_index: u64,
    /// The labels, until the runs (`frame_*` columns) are made of them.
    labels: Option<Vec<table::Label>>,
}

impl SimLabels {
    fn read(q: &Request) -> anyhow::Result<SimLabels> {
        let labels = q.labels_sim.as_deref().map(table::read_labels).transpose()?;
        Ok(SimLabels {
            terrains: labels.as_ref().map(|l| l.iter().map(|l| l.terrain).collect()),
            moments: labels.as_deref().map(dem_sensor::moments),
            first_index: q.first_index.unwrap_or(0),
            labels,
        })
    }

    fn terrain(&self, i: u64) -> Option<Terrain> {
        self.terrains.as_ref().and_then(|t| t.get((i - self.first_index) as usize)).copied()
    }

    fn moment(&self, i: u64) -> dem_sensor::Moment {
        dem_sensor::moment_at(self.moments.as_deref(), (i - self.first_index) as usize)
    }
}

/// The pairs this run scores: the whole set, or a shard's range (its length
/// from the labels or the file; a shard on stdin runs to the end).
fn scored_pairs<'p>(q: &Request, pairs: &'p Pairs, labels: &SimLabels) -> anyhow::Result<&'p [(u64, u64)]> {
    let Some(first_index) = q.first_index else {
        return Ok(pairs.pairs.as_slice());
    };
    let len = match (&labels.terrains, q.sim.as_str()) {
        (Some(t), _) => t.len() as u64,
        (None, "-") => u64::MAX - first_index,
        (None, path) => RecordIndex::build(path)?.len(),
    };
    Ok(pairs.within(first_index..first_index.saturating_add(len)))
}

/// Rows of the table and their pair counts, for the gap samples' rates.
fn row_sizes(q: &Request, scored: &[(u64, u64)], labels: &SimLabels) -> HashMap<Option<Terrain>, u64> {
    let mut sizes: HashMap<Option<Terrain>, u64> = HashMap::new();
    for g in scored.chunk_by(|a, b| a.0 == b.0) {
        *sizes.entry(None).or_default() += g.len() as u64;
        if q.by_terrain {
            *sizes.entry(labels.terrain(g[0].0)).or_default() += g.len() as u64;
        }
    }
    sizes
}

/// A `--model` run's generator and what dem-apply runs around it: where its
/// valid cells take their heights from (`--heights input`), then its
/// residual sensor model.
struct Network {
    model: Option<dem_onnx::OnnxModel>,
    residual: Option<dem_sensor::SensorModel>,
    heights: dem_onnx::Heights,
}

impl Network {
    fn load(q: &Request, moments: Option<&[dem_sensor::Moment]>) -> anyhow::Result<Network> {
        let Method::Model(path) = &q.method else {
            return Ok(Network { model: None, residual: None, heights: dem_onnx::Heights::Network });
        };
        let model = Some(dem_onnx::OnnxModel::load(path)?);
        let stored = dem_apply::stored(path)?;
        let residual = stored.residual.filter(|_| !q.network_only);
        if residual.as_ref().is_some_and(|r| r.uses_time()) && moments.is_none() {
            cli::log("note: the model's residual has `startup` but no --sim-labels gave the records' times: startup frames are drawn at its rate p instead of by time");
        }
        if let Some(why) = residual.as_ref().and_then(|r| dem_sensor::runs_unknown(r, moments)) {
            cli::log(format_args!("note: the model's residual: {why}"));
        }
        Ok(Network { model, residual, heights: stored.heights })
    }
}

/// Read the sim stream (and a prediction stream beside it) a chunk at a
/// time and evaluate the paired records in blocks; checks both streams'
/// lengths and returns the number of sim records.
fn evaluate_stream(ctx: &BlockCtx, sim_max: &Largest, reals: &mut ByIndex, emit: &mut Emit, acc: &mut Acc) -> anyhow::Result<u64> {
    let q = ctx.q;
    let mut sim_rdr = npy::open(&q.sim)?;
    let mut pred_rdr = match &q.method {
        Method::Pred(path) => Some((path, npy::open(path)?)),
        _ => None,
    };
    let (mut chunk, mut pchunk) = (Vec::with_capacity(CHUNK_RECORDS), Vec::with_capacity(CHUNK_RECORDS));
    let mut block: Vec<(u64, Dem, Dem)> = Vec::with_capacity(BLOCK);
    loop {
        chunk.clear();
        let first = ctx.labels.first_index + sim_rdr.records_read();
        let n = sim_rdr.read_chunk(&mut chunk, CHUNK_RECORDS)?;
        if let Some((path, r)) = &mut pred_rdr {
            pchunk.clear();
            let got = r.read_up_to(&mut pchunk, n)?;
            if got < n {
                return Err(DemError::input(
                    path.as_str(),
                    format!("has {} records but {} has more: a prediction file holds one record per sim record", r.records_read(), q.sim),
                )
                .into());
            }
        }
        for g in ctx.pairs.within(first..first + n as u64).chunk_by(|a, b| a.0 == b.0) {
            let k = (g[0].0 - first) as usize;
            let pred = if pred_rdr.is_some() { pchunk[k] } else { chunk[k] };
            block.push((g[0].0, chunk[k], pred));
        }
        if block.len() >= BLOCK || (n == 0 && !block.is_empty()) {
            evaluate_block(ctx, std::mem::take(&mut block), reals, emit, acc)?;
        }
        if n == 0 {
            break;
        }
    }
    let n_sim = sim_rdr.records_read();
    // A shard's pairs name the whole set, most of it in other shards.
    if q.first_index.is_none() {
        sim_max.check(&q.pairs, n_sim, &q.sim, "sim_index")?;
    }
    if let Some((path, r)) = &mut pred_rdr {
        let mut rest = Vec::new();
        if r.read_up_to(&mut rest, 1)? > 0 {
            return Err(DemError::input(
                path.as_str(),
                format!("has more records than the {n_sim} of {}: a prediction file holds one record per sim record", q.sim),
            )
            .into());
        }
    }
    Ok(n_sim)
}

/// What every block needs to know.
struct BlockCtx<'a> {
    q: &'a Request,
    pairs: &'a Pairs,
    model: Option<&'a dem_onnx::OnnxModel>,
    residual: Option<&'a dem_sensor::SensorModel>,
    heights: dem_onnx::Heights,
    labels: &'a SimLabels,
    row_sizes: &'a HashMap<Option<Terrain>, u64>,
    /// The steps of the sim runs whose both frames are scored.
    runs: Option<&'a Runs>,
}

/// Evaluate one block of (sim index, sim record, prediction); a model's
/// predictions are made here.
fn evaluate_block(
    ctx: &BlockCtx,
    mut block: Vec<(u64, Dem, Dem)>,
    reals: &mut ByIndex,
    emit: &mut Emit,
    acc: &mut Acc,
) -> anyhow::Result<()> {
    if let (Some(model), Method::Model(path)) = (ctx.model, &ctx.q.method) {
        let keys: Vec<u64> = block.iter().map(|b| b.0).collect();
        let inputs: Vec<Dem> = block.iter().map(|b| b.1).collect();
        let preds = crate::model::predict(model, path, &keys, &inputs, &ctx.q.sim, ctx.q.batch, ctx.q.strict, &mut acc.attitude)?;
        block.iter_mut().zip(preds).for_each(|(b, p)| b.2 = p);
        block.iter_mut().for_each(|b| ctx.heights.apply(&b.1, &mut b.2));
        if let Some(r) = ctx.residual {
            // Keyed by the record's index in the whole sim set, as dem-apply
            // keys it: the same draws as `dem-apply | dem-eval --pred`.
            block.par_iter_mut().for_each(|b| r.apply_at(&mut b.2, ctx.q.seed, b.0, ctx.labels.moment(b.0)));
            if let (Some(runs), Some(path)) = (&mut acc.memory, &ctx.q.labels_sim) {
                let records: Vec<u64> = block.iter().map(|b| b.0).collect();
                let moments: Vec<dem_sensor::Moment> = records.iter().map(|&i| ctx.labels.moment(i)).collect();
                let mut outs: Vec<Dem> = block.iter().map(|b| b.2).collect();
                let in_stream: Vec<u64> = records.iter().map(|&i| i - ctx.labels.first_index).collect();
                let u = |i: usize| r.memory_uniforms(ctx.q.seed, records[i]);
                runs.step_records(path, &in_stream, &mut outs, &inputs, &moments, u)?;
                block.iter_mut().zip(outs).for_each(|(b, o)| b.2 = o);
            }
        }
    }
    for b in &block {
        if let Some(runs) = ctx.runs {
            acc.frames.add(runs, b.0, &b.1, &b.2, |i| ctx.labels.terrain(i), ctx.q.by_terrain);
        }
        if let Some(rf) = &mut acc.real_frames {
            rf.see_sim(b.0, &b.1);
        }
    }
    let (lo, hi) = (block[0].0, block[block.len() - 1].0 + 1);
    let mut sub = Selection::new();
    for &(s, r) in ctx.pairs.within(lo..hi) {
        sub.entry(s).or_default().push(r);
    }
    let wanted: BTreeSet<u64> = sub.values().flatten().copied().collect();
    let real = reals.fetch(&wanted)?;
    let pred: HashMap<u64, Dem> = block.iter().map(|b| (b.0, b.2)).collect();
    let results = validation::evaluate(&sub, |i| &pred[&i], |j| &real[&j], |i| ctx.labels.terrain(i));
    for (r, b) in results.iter().zip(&block) {
        debug_assert_eq!(r.sim_index, b.0);
        if let Some(w) = &mut emit.records {
            w.write(r)?;
        }
        for (w, d) in [(&mut emit.input, &b.1), (&mut emit.pred, &b.2), (&mut emit.closest, &real[&r.real_index])] {
            if let Some(w) = w {
                w.write(std::slice::from_ref(d))?;
            }
        }
        for key in row_keys(ctx.labels.terrain(b.0), ctx.q.by_terrain) {
            acc.rows.entry(key).or_default().add(r);
            let size = ctx.row_sizes.get(&key).copied().unwrap_or(0);
            acc.samples.entry(key).or_default().add(b.0, &b.2, sub[&b.0].iter().copied(), size);
        }
    }
    Ok(())
}
