//! `dem-eval merge`: the table of the whole from the shards' per-record
//! results. Medians and the gap do not merge from shard tables, so a shard
//! run keeps what they are made of: its `--emit-records` CSV (errors and the
//! exact height and roughness sums) and, for the gap, its `--emit-pred`
//! records. Added in index order, they give the one-run table bit for bit.

use std::collections::{BTreeMap, BTreeSet, HashMap};

use crate::table::{RecordResult, RowAcc};
use clap::Args as ClapArgs;
use dem_core::npy::{self, CHUNK_RECORDS};
use dem_core::table::Split;
use dem_core::{cli, DemError, Terrain};

use crate::engine::{row_gaps, Evaluation, GapSample, Pairs};
use crate::evaluate::TableOut;
use crate::frames::{row_keys, PredFrames, RealFrames, Runs};
use dem_core::npy::ByIndex;
use dem_core::table;
use dem_core::temporal::FrameStats;

/// The arguments of `dem-eval merge`.
#[derive(ClapArgs)]
pub struct MergeArgs {
    /// The shards' per-record results (`dem-eval --first-index N --emit-records
    /// FILE`), in shard order.
    #[arg(required = true, value_name = "RECORDS")]
    records: Vec<String>,
    /// Name of the table row (the method; a shard table's `method`).
    #[arg(long)]
    name: String,
    /// The shards' `--emit-pred` files joined in the same order (`dem-cat`,
    /// or `-` for a pipe): record j is the prediction of row j of the
    /// records. With --real and --pairs it gives the gap column.
    #[arg(long, value_name = "FILE", requires_all = ["real", "pairs"])]
    emitted_pred: Option<String>,
    /// Real NPY of the evaluation (for the gap).
    #[arg(long, requires = "emitted_pred")]
    real: Option<String>,
    /// Pairs CSV of the evaluation (for the gap: every partner of a sim is in its row's real set).
    #[arg(long, requires = "emitted_pred")]
    pairs: Option<String>,
    /// Labels CSV of the whole sim set (the shards' --sim-labels joined):
    /// with --sim, its runs give the frame columns as one run gives them.
    #[arg(long = "sim-labels", value_name = "CSV", requires_all = ["emitted_pred", "sim"])]
    labels_sim: Option<String>,
    /// The whole sim NPY (each prediction's input, for frame_rcorr).
    #[arg(long, requires = "labels_sim")]
    sim: Option<String>,
    /// Labels CSV of the real file: the real_frame_* columns.
    #[arg(long = "real-labels", value_name = "CSV", requires_all = ["emitted_pred", "sim"])]
    labels_real: Option<String>,
    /// The split the shards evaluated.
    #[arg(long, value_enum, requires = "pairs")]
    split: Option<Split>,
    /// Do not warn when --sim misses clearly more cells than --real (the
    /// sign of swapped inputs, as `dem-eval` warns).
    #[arg(long)]
    no_swap_check: bool,
    #[command(flatten)]
    table: TableOut,
}

/// Read every records file, in order; sim indices must rise across them
/// (shards in order, none twice).
fn read_all(paths: &[String]) -> anyhow::Result<Vec<RecordResult>> {
    let mut all: Vec<RecordResult> = Vec::new();
    for path in paths {
        let rows = crate::records::read(path)?;
        for (k, r) in rows.into_iter().enumerate() {
            if let Some(prev) = all.last().filter(|p| p.sim_index >= r.sim_index) {
                return Err(DemError::Table {
                    path: path.clone(),
                    line: k as u64 + 2,
                    reason: format!(
                        "sim_index {} does not follow {} of the records before it: give the shards in order, each once",
                        r.sim_index, prev.sim_index
                    ),
                }
                .into());
            }
            all.push(r);
        }
    }
    Ok(all)
}

/// A record's terrain, as its records file names it.
fn terrain_of(r: &RecordResult) -> Option<Terrain> {
    r.terrain.as_deref().and_then(|t| t.parse().ok())
}

/// The table rows a record belongs to.
fn keys(r: &RecordResult, by_terrain: bool) -> Vec<Option<Terrain>> {
    row_keys(terrain_of(r), by_terrain)
}

/// What the emitted predictions give: each row's gap and frame columns.
type FromPreds = (HashMap<Option<Terrain>, f64>, [BTreeMap<Option<Terrain>, FrameStats>; 2]);

/// The gap of every row: the emitted predictions sampled as one run samples
/// them, against the real partners the pairs give the rows' sims; with the
/// sim labels and the sims, the frame columns, fed the records in the order
/// one run feeds them.
fn gaps(a: &MergeArgs, recs: &[RecordResult]) -> anyhow::Result<FromPreds> {
    let (Some(pred_path), Some(real), Some(pairs_path)) = (&a.emitted_pred, &a.real, &a.pairs) else {
        cli::log("gap not computed: give --emitted-pred (the shards' --emit-pred joined), --real and --pairs");
        return Ok(Default::default());
    };
    let (pairs, _, real_max) = Pairs::read(pairs_path, a.split)?;
    let sims: Vec<u64> = pairs.pairs.chunk_by(|x, y| x.0 == y.0).map(|g| g[0].0).collect();
    if !sims.iter().copied().eq(recs.iter().map(|r| r.sim_index)) {
        return Err(DemError::input(
            pairs_path.as_str(),
            format!(
                "pairs {} sims{} but the records hold {}, or other ones: a shard is missing, or the pairs or split differ from the shards'",
                sims.len(),
                if a.split.is_some() { " of the split" } else { "" },
                recs.len()
            ),
        )
        .into());
    }
    let needed: BTreeSet<u64> = if real == "-" { pairs.pairs.iter().map(|p| p.1).collect() } else { BTreeSet::new() };
    let mut reals = ByIndex::open(real, |i| needed.contains(&i))?;
    let n_real = reals.len();
    real_max.check(pairs_path, n_real, real, "real_index")?;
    // Pairs per row, for the samples' rates (as one run counts them).
    let mut row_pairs: HashMap<Option<Terrain>, u64> = HashMap::new();
    for r in recs {
        let n = pairs.within(r.sim_index..r.sim_index + 1).len() as u64;
        for key in keys(r, a.table.by.is_some()) {
            *row_pairs.entry(key).or_default() += n;
        }
    }
    let by_terrain = a.table.by.is_some();
    let scored: BTreeSet<u64> = recs.iter().map(|r| r.sim_index).collect();
    let terrain: HashMap<u64, Option<Terrain>> = recs.iter().map(|r| (r.sim_index, terrain_of(r))).collect();
    let runs = match &a.labels_sim {
        Some(path) => Runs::of(&table::read_labels(path)?, 0, path, |i| scored.contains(&i)),
        None => None,
    };
    let mut real_frames = a.labels_real.as_deref().map(|path| RealFrames::new(path, n_real, &pairs.pairs)).transpose()?.flatten();
    let mut sims = a.sim.as_deref().map(|p| ByIndex::open(p, |i| scored.contains(&i))).transpose()?;
    let mut frames = PredFrames::default();
    let mut samples: HashMap<Option<Terrain>, GapSample> = HashMap::new();
    let mut rows = recs.iter();
    let n_pred = npy::open(pred_path)?.for_each_chunk(CHUNK_RECORDS, |_, chunk| {
        let mut inputs = match &mut sims {
            Some(s) => s.fetch(&rows.clone().take(chunk.len()).map(|r| r.sim_index).collect())?,
            None => HashMap::new(),
        };
        for pred in chunk.iter() {
            let Some(r) = rows.next() else {
                return Err(DemError::input(
                    pred_path.as_str(),
                    format!("has more records than the {} rows of the records files", recs.len()),
                ));
            };
            if let Some(sim) = inputs.remove(&r.sim_index) {
                if let Some(runs) = &runs {
                    frames.add(runs, r.sim_index, &sim, pred, |i| terrain.get(&i).copied().flatten(), by_terrain);
                }
                if let Some(rf) = &mut real_frames {
                    rf.see_sim(r.sim_index, &sim);
                }
            }
            for key in keys(r, a.table.by.is_some()) {
                let partners = pairs.within(r.sim_index..r.sim_index + 1).iter().map(|p| p.1);
                samples.entry(key).or_default().add(r.sim_index, pred, partners, row_pairs.get(&key).copied().unwrap_or(0));
            }
        }
        Ok(())
    })?;
    if rows.next().is_some() {
        return Err(DemError::input(
            pred_path.as_str(),
            format!("has {n_pred} records but the records files {} rows: join every shard's --emit-pred, in order", recs.len()),
        )
        .into());
    }
    let pred_frames = if runs.is_some() { frames.stats() } else { BTreeMap::new() };
    let real_frames = match &real_frames {
        Some(rf) => rf.stats(|want| Ok(reals.fetch(want)?), by_terrain)?,
        None => BTreeMap::new(),
    };
    Ok((row_gaps(samples, &row_pairs, &mut reals)?, [pred_frames, real_frames]))
}

/// Merge as `a` asks and write the table.
pub fn run(a: MergeArgs) -> anyhow::Result<()> {
    let inputs: Vec<&str> = a
        .records
        .iter()
        .chain([&a.emitted_pred, &a.real, &a.pairs, &a.labels_sim, &a.sim, &a.labels_real].into_iter().flatten())
        .map(String::as_str)
        .collect();
    cli::one_stdin(inputs.iter().copied())?;
    dem_core::output::check_outputs(&inputs, &[a.table.output.as_str()])?;
    if let (Some(sim), Some(real)) = (&a.sim, &a.real) {
        dem_core::swap::check_files(sim, real, a.no_swap_check);
    }
    let recs = read_all(&a.records)?;
    if recs.is_empty() {
        return Err(cli::usage("the records files hold no records"));
    }
    if a.table.by.is_some() {
        if let Some(r) = recs.iter().find(|r| terrain_of(r).is_none()) {
            return Err(cli::usage(format!(
                "--by terrain: sim record {} has no terrain in its records file (run the shards with --sim-labels)",
                r.sim_index
            )));
        }
    }
    let mut rows: BTreeMap<Option<Terrain>, RowAcc> = BTreeMap::new();
    // The counts each row pools, added checked: an overflow is an error,
    // never a wrapped count.
    let mut counts: BTreeMap<Option<Terrain>, [u64; 5]> = BTreeMap::new();
    for r in &recs {
        for key in keys(r, a.table.by.is_some()) {
            let total = counts.entry(key).or_default();
            let add = [r.height, r.rough_across, r.rough_along, r.real_rough_across, r.real_rough_along].map(|s| s.count);
            for (k, (t, n)) in total.iter_mut().zip(add).enumerate() {
                *t = t.checked_add(n).ok_or_else(|| {
                    let column = ["height_n", "rough_across_n", "rough_along_n", "real_rough_across_n", "real_rough_along_n"][k];
                    let row = key.map_or(crate::table::ALL, |t| t.as_str());
                    DemError::input(a.records.join(", "), format!("the {column} of the {row} row add up past {}", u64::MAX))
                })?;
            }
            rows.entry(key).or_default().add(r);
        }
    }
    // A gap that is not a number (heights near float32's limit overflow its
    // statistics) is left out, as a table reader would refuse it.
    let (mut gaps, frames) = gaps(&a, &recs)?;
    gaps.retain(|key, g| {
        let keep = g.is_finite();
        if !keep {
            cli::log(format_args!(
                "gap of the {} row not computed: its statistics overflow (heights near float32's limit)",
                key.map_or(crate::table::ALL, |t| t.as_str())
            ));
        }
        keep
    });
    a.table.write(&Evaluation::new(rows, gaps, frames), &a.name)
}
