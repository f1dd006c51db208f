//! What an evaluation reads, in bounded memory: the sim stream (and a
//! prediction stream beside it) is read a block of selected records at a
//! time; the real records a block's pairs name are read by index from the
//! file (held only when the real stream is stdin); what is kept is one
//! result per selected record, and for the gap a deterministic sample of at
//! most [`GAP_SAMPLE`] records per table row. Each input is checked against
//! the others with a one-line error.

use std::collections::{BTreeSet, HashMap};

use dem_core::eval::{self, RecordResult, Selection};
use dem_core::gap::stats;
use dem_core::npy::{self, NpyReader, RecordIndex, CHUNK_RECORDS};
use dem_core::table::{self, Label, Pair, Split};
use dem_core::{cli, Dem, DemError, Terrain};
use dem_onnx::apply::AttitudeCheck;

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

/// Most records a table row's gap is computed on. Above it, the gap of a
/// row is that of a sample chosen by a hash of the record index (the same
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
    /// Where predictions come from.
    pub method: Method,
    /// Records per model call.
    pub batch: usize,
    /// Refuse a model that changes row 20.
    pub strict: bool,
    /// Write the sim record of each result here, in result order.
    pub emit_input: Option<String>,
    /// Write the prediction of each result here.
    pub emit_pred: Option<String>,
    /// Write the closest real record of each result here.
    pub emit_closest: Option<String>,
}

/// The outcome: one result per selected sim record, in index order, and the
/// gap of each table row.
pub struct Evaluation {
    /// Pair error, best real record and terrain of each selected sim record.
    pub results: Vec<RecordResult>,
    /// Gap of the row over every record, and of each terrain's row.
    gaps: HashMap<Option<Terrain>, f64>,
}

impl Evaluation {
    /// The distribution gap (dem-gap's measure, unpaired) of the predictions
    /// of `group` (a table row: all records, or one terrain's) against its
    /// real set: the unique real records paired with its sim records in the
    /// evaluated pairs (not only the closest ones). None for an empty group.
    pub fn gap(&self, group: &[&RecordResult]) -> Option<f64> {
        let first = group.first()?;
        let key = if group.len() == self.results.len() { None } else { first.terrain.as_deref().and_then(|t| t.parse().ok()) };
        self.gaps.get(&key).copied()
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

/// splitmix64 of an index: the gap sample keeps index i when this falls
/// below its rate.
fn sample_hash(i: u64) -> u64 {
    dem_core::sensor::mix(i ^ 0x6761_705f_7361_6d70)
}

/// Keeps index i of a set of `n` with probability GAP_SAMPLE / n, by hash.
fn in_sample(i: u64, n: u64) -> bool {
    n <= GAP_SAMPLE || (sample_hash(i) as f64) < GAP_SAMPLE as f64 / n as f64 * u64::MAX as f64
}

/// The real records the pairs name: by index from a file, or (stdin, which
/// cannot seek) the needed ones read once and held.
enum Reals {
    Indexed(RecordIndex),
    Held(HashMap<u64, Dem>),
}

impl Reals {
    fn open(path: &str, needed: &BTreeSet<u64>) -> anyhow::Result<(Reals, u64)> {
        if path == "-" {
            let (n, held) = read_selected(path, needed)?;
            return Ok((Reals::Held(held), n));
        }
        let idx = RecordIndex::build(path)?;
        let n = idx.len();
        Ok((Reals::Indexed(idx), n))
    }

    fn fetch(&mut self, wanted: &BTreeSet<u64>) -> anyhow::Result<HashMap<u64, Dem>> {
        match self {
            Reals::Indexed(idx) => Ok(wanted.iter().map(|&j| idx.get(j).map(|d| (j, d))).collect::<Result<_, _>>()?),
            Reals::Held(m) => Ok(wanted.iter().map(|j| (*j, m[j])).collect()),
        }
    }
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

/// Append exactly `n` records of `r` to `out` (fewer only at its end).
fn read_n(r: &mut NpyReader<Box<dyn std::io::Read + Send>>, out: &mut Vec<Dem>, n: usize) -> anyhow::Result<usize> {
    let mut got = 0;
    while got < n {
        let k = r.read_chunk(out, n - got)?;
        if k == 0 {
            break;
        }
        got += k;
    }
    Ok(got)
}

/// The writers of --emit-input, --emit-pred and --emit-closest.
struct Emit {
    input: Option<npy::NpyWriter>,
    pred: Option<npy::NpyWriter>,
    closest: Option<npy::NpyWriter>,
}

impl Emit {
    fn create(q: &Request) -> anyhow::Result<Self> {
        let open = |p: &Option<String>| p.as_deref().map(npy::create).transpose();
        Ok(Emit { input: open(&q.emit_input)?, pred: open(&q.emit_pred)?, closest: open(&q.emit_closest)? })
    }

    fn finish(self) -> anyhow::Result<()> {
        for w in [self.input, self.pred, self.closest].into_iter().flatten() {
            w.finish()?;
        }
        Ok(())
    }
}

/// One table row's gap sample: sampled predictions, and the real indices
/// paired with the row's records.
#[derive(Default)]
struct GapSample {
    preds: Vec<Dem>,
    reals: BTreeSet<u64>,
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
    if q.split.is_some() {
        if all_pairs.iter().all(|p| p.split.is_none()) {
            return Err(DemError::input(q.pairs.as_str(), "has no split column for --split (dem-pair writes one)").into());
        }
    }
    let sel: Selection = eval::select(&all_pairs, q.split);
    if sel.is_empty() {
        let which = q.split.map_or(String::new(), |s| format!(" of split {}", if s == Split::Val { "val" } else { "train" }));
        return Err(DemError::input(q.pairs.as_str(), format!("holds no pairs{which} to evaluate")).into());
    }
    let all_reals: BTreeSet<u64> = sel.values().flatten().copied().collect();
    let (mut reals, n_real) = Reals::open(&q.real, &all_reals)?;
    check_range(&q.pairs, &all_pairs, n_real, &q.real, true)?;
    let labels: Option<Vec<Label>> = q.labels_sim.as_deref().map(table::read_labels).transpose()?;
    let terrain_of = |i: u64| -> Option<Terrain> { labels.as_ref().and_then(|l| l.get(i as usize)).map(|l| l.terrain) };
    // Rows of the table and their sizes, for the gap samples' rates.
    let mut row_sizes: HashMap<Option<Terrain>, u64> = HashMap::from([(None, sel.len() as u64)]);
    if labels.is_some() {
        for &s in sel.keys() {
            *row_sizes.entry(terrain_of(s)).or_default() += 1;
        }
    }
    let mut samples: HashMap<Option<Terrain>, GapSample> = HashMap::new();
    let model = match &q.method {
        Method::Model(path) => Some(dem_onnx::OnnxModel::load(path)?),
        _ => None,
    };
    let mut attitude = AttitudeCheck::default();
    let mut emit = Emit::create(q)?;
    let mut sim_rdr = npy::open(&q.sim)?;
    let mut pred_rdr = match &q.method {
        Method::Pred(path) => Some((path, npy::open(path)?)),
        _ => None,
    };
    let mut results = Vec::with_capacity(sel.len());
    let (mut chunk, mut pchunk) = (Vec::with_capacity(CHUNK_RECORDS), Vec::with_capacity(CHUNK_RECORDS));
    let mut block: Vec<(u64, Dem, Dem)> = Vec::with_capacity(BLOCK);
    loop {
        chunk.clear();
        let first = sim_rdr.records_read();
        let n = sim_rdr.read_chunk(&mut chunk, CHUNK_RECORDS)?;
        if let Some((path, r)) = &mut pred_rdr {
            pchunk.clear();
            let got = read_n(r, &mut pchunk, n)?;
            if got < n {
                return Err(DemError::input(path.as_str(), format!("has {} records but {} has more: a prediction file holds one record per sim record", r.records_read(), q.sim)).into());
            }
        }
        for (&i, _) in sel.range(first..first + n as u64) {
            let k = (i - first) as usize;
            let pred = if pred_rdr.is_some() { pchunk[k] } else { chunk[k] };
            block.push((i, chunk[k], pred));
        }
        if block.len() >= BLOCK || (n == 0 && !block.is_empty()) {
            let b = std::mem::take(&mut block);
            let ctx = BlockCtx { q, sel: &sel, model: model.as_ref(), terrain_of: &terrain_of, row_sizes: &row_sizes };
            results.extend(evaluate_block(&ctx, b, &mut reals, &mut emit, &mut samples, &mut attitude)?);
        }
        if n == 0 {
            break;
        }
    }
    let n_sim = sim_rdr.records_read();
    check_range(&q.pairs, &all_pairs, n_sim, &q.sim, false)?;
    if let Some((path, r)) = &mut pred_rdr {
        let mut rest = Vec::new();
        if read_n(r, &mut rest, 1)? > 0 {
            return Err(DemError::input(path.as_str(), format!("has more records than the {n_sim} of {}: a prediction file holds one record per sim record", q.sim)).into());
        }
    }
    if let (Some(l), Some(path)) = (&labels, &q.labels_sim) {
        if l.len() as u64 != n_sim {
            return Err(DemError::input(path.as_str(), format!("has {} rows but {} has {n_sim} records", l.len(), q.sim)).into());
        }
    }
    if let Method::Model(path) = &q.method {
        if let Some(w) = attitude.warning(path, &q.sim) {
            cli::log(w);
        }
    }
    emit.finish()?;
    let mut gaps = HashMap::new();
    for (key, sample) in samples {
        let n = row_sizes.get(&key).copied().unwrap_or(0);
        if n > GAP_SAMPLE {
            let row = key.map_or("all".to_string(), |t| t.to_string());
            cli::log(format_args!("gap of row {row}: a sample of {} of its {n} records (at most {GAP_SAMPLE}, chosen by index)", sample.preds.len()));
        }
        let wanted: BTreeSet<u64> = sample.reals.iter().copied().filter(|&j| in_sample(j, sample.reals.len() as u64)).collect();
        let real_records: Vec<Dem> = {
            let m = reals.fetch(&wanted)?;
            wanted.iter().map(|j| m[j]).collect()
        };
        gaps.insert(key, stats::gap(&stats::stats(&sample.preds, None), &stats::stats(&real_records, None)));
    }
    Ok(Evaluation { results, gaps })
}

/// What every block needs to know.
struct BlockCtx<'a> {
    q: &'a Request,
    sel: &'a Selection,
    model: Option<&'a dem_onnx::OnnxModel>,
    terrain_of: &'a dyn Fn(u64) -> Option<Terrain>,
    row_sizes: &'a HashMap<Option<Terrain>, u64>,
}

/// Evaluate one block of (sim index, sim record, prediction); a model's
/// predictions are made here.
fn evaluate_block(
    ctx: &BlockCtx,
    mut block: Vec<(u64, Dem, Dem)>,
    reals: &mut Reals,
    emit: &mut Emit,
    samples: &mut HashMap<Option<Terrain>, GapSample>,
    attitude: &mut AttitudeCheck,
) -> anyhow::Result<Vec<RecordResult>> {
    if let (Some(model), Method::Model(path)) = (ctx.model, &ctx.q.method) {
        let keys: Vec<u64> = block.iter().map(|b| b.0).collect();
        let inputs: Vec<Dem> = block.iter().map(|b| b.1).collect();
        let preds = crate::model::predict(model, path, &keys, &inputs, &ctx.q.sim, ctx.q.batch, ctx.q.strict, attitude)?;
        block.iter_mut().zip(preds).for_each(|(b, p)| b.2 = p);
    }
    let sub: Selection = block.iter().map(|b| (b.0, ctx.sel[&b.0].clone())).collect();
    let wanted: BTreeSet<u64> = sub.values().flatten().copied().collect();
    let real = reals.fetch(&wanted)?;
    let pred: HashMap<u64, Dem> = block.iter().map(|b| (b.0, b.2)).collect();
    let results = eval::evaluate(&sub, |i| &pred[&i], |j| &real[&j], ctx.terrain_of);
    for (r, b) in results.iter().zip(&block) {
        debug_assert_eq!(r.sim_index, b.0);
        for (w, d) in [(&mut emit.input, &b.1), (&mut emit.pred, &b.2), (&mut emit.closest, &real[&r.real_index])] {
            if let Some(w) = w {
                w.write(std::slice::from_ref(d))?;
            }
        }
        let mut rows = vec![None];
        if ctx.q.labels_sim.is_some() {
            rows.push((ctx.terrain_of)(b.0));
        }
        for key in rows {
            let s = samples.entry(key).or_default();
            if in_sample(b.0, ctx.row_sizes.get(&key).copied().unwrap_or(0)) {
                s.preds.push(b.2);
            }
            s.reals.extend(ctx.sel[&b.0].iter().copied());
        }
    }
    Ok(results)
}
