//! A training run in a directory: the step loop with its progress bar, the
//! per-step losses, the per-epoch validation table, checkpoints, and the
//! exact continuation of an interrupted run.
//!
//! `RUN/losses.csv`: `step,epoch,gan,cycle,pair_y,pair_x,generator,disc,height`;
//! `RUN/val.csv`: `epoch,step,count,lowest,highest,mean,median` (pair error
//! of G_Y over the val split, equation 7.1); `RUN/checkpoint.bin`;
//! `RUN/check_sim.npy`, `RUN/check_real.npy`: the records an export is
//! checked on (the val split, or the first records without one).

use std::fs::{self, File, OpenOptions};
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use dem_core::{cli, metric, npy, Dem, DemError};
use dem_eval::table::ErrorSummary;

use dem_nn::train::checkpoint::{self, Meta};
use dem_nn::train::cyclegan::{CycleGan, Losses};
use dem_nn::train::data::{Sampler, TrainData};

/// Every file a run writes into its folder.
pub const FILES: [&str; 5] = ["checkpoint.bin", "losses.csv", "val.csv", "check_sim.npy", "check_real.npy"];

/// Records an export is checked on when there is no val split.
pub const CHECK_RECORDS: usize = 256;

/// Epochs of a run when `--epochs` is not given, unless an epoch is so long
/// that [`STEP_BUDGET`] caps them.
pub const DEFAULT_EPOCHS: u64 = 30;

/// Steps the default run stays within (rounded up to a whole epoch). The
/// val measures stop improving long before 30 epochs of a large data set
/// (docs/training.md: "How long a default run trains"), so a larger world
/// trains for about as many steps as a small one, not 30 of its epochs.
pub const STEP_BUDGET: u64 = 1_500;

/// Where and how long to train.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// The run directory.
    pub dir: String,
    /// Epochs in all (a resumed run goes on up to this); `None`: the
    /// default, [`default_epochs`] of the data.
    pub epochs: Option<u64>,
    /// Stop after this many steps in all, whatever the epochs.
    pub max_steps: Option<u64>,
    /// Also checkpoint every this many steps (always at each epoch's end).
    pub checkpoint_every: Option<u64>,
    /// When stderr is not a terminal (CI, a log file), log a progress line
    /// this often instead of the hidden bar.
    pub log_every: std::time::Duration,
}

/// The default length of a run with `steps_per_epoch` steps an epoch:
/// [`DEFAULT_EPOCHS`], or, if fewer, as many whole epochs as reach
/// [`STEP_BUDGET`] steps.
pub fn default_epochs(steps_per_epoch: u64) -> u64 {
    DEFAULT_EPOCHS.min(STEP_BUDGET.div_ceil(steps_per_epoch.max(1))).max(1)
}

/// The run's epochs: the ones asked for, or the default of the data.
pub fn epochs_of(opts: &RunOptions, steps_per_epoch: u64) -> u64 {
    opts.epochs.unwrap_or_else(|| default_epochs(steps_per_epoch))
}

/// The pair error table of `preds[i]` (G_Y of key i) against `reals[i]`,
/// summarised as dem-eval does.
pub fn pair_table(preds: &[Dem], reals: &[Vec<&Dem>]) -> Option<ErrorSummary> {
    let e: Vec<f64> = preds.iter().zip(reals).filter_map(|(p, ys)| metric::pair_error(ys.iter().copied(), p).map(|(_, e)| e)).collect();
    ErrorSummary::of(&e)
}

/// G_Y's validation table on the val split, if there is one.
pub fn validate(gan: &CycleGan, data: &TrainData) -> Option<ErrorSummary> {
    if data.val.is_empty() {
        return None;
    }
    let sims: Vec<Dem> = data.val.iter().map(|(k, _)| data.sim[*k]).collect();
    let reals: Vec<Vec<&Dem>> = data.val.iter().map(|(_, rs)| rs.iter().map(|&r| &data.real[r]).collect()).collect();
    pair_table(&gan.generate(true, &sims), &reals)
}

fn path(dir: &str, name: &str) -> String {
    Path::new(dir).join(name).to_string_lossy().into_owned()
}

/// Keep the header and the rows whose first column is <= `last`.
fn truncate_csv(file: &str, last: u64) -> Result<()> {
    if !Path::new(file).exists() {
        return Ok(());
    }
    let lines: Vec<String> = BufReader::new(File::open(file)?).lines().collect::<std::io::Result<_>>()?;
    let kept: Vec<&String> = lines
        .iter()
        .enumerate()
        .filter(|(i, l)| *i == 0 || l.split(',').next().and_then(|v| v.parse::<u64>().ok()).is_some_and(|v| v <= last))
        .map(|(_, l)| l)
        .collect();
    dem_core::output::write_atomic(file, |w| kept.iter().try_for_each(|l| writeln!(w, "{l}")))?;
    Ok(())
}

fn append(file: &str, header: &str) -> Result<BufWriter<File>> {
    let fresh = !Path::new(file).exists();
    let f = OpenOptions::new().create(true).append(true).open(file).with_context(|| format!("open {file}"))?;
    let mut w = BufWriter::new(f);
    if fresh {
        writeln!(w, "{header}")?;
    }
    Ok(w)
}

/// Records of the check files: the val keys (or the first records).
fn check_sets(data: &TrainData) -> (Vec<Dem>, Vec<Dem>) {
    if data.val.is_empty() {
        let n = |v: &Vec<Dem>| v[..v.len().min(CHECK_RECORDS)].to_vec();
        (n(&data.sim), n(&data.real))
    } else {
        let sims = data.val.iter().map(|(k, _)| data.sim[*k]).collect();
        let reals = data.val.iter().flat_map(|(_, rs)| rs.iter().map(|&r| data.real[r])).take(CHECK_RECORDS.max(data.val.len())).collect();
        (sims, reals)
    }
}

/// Take the run folder `dir` (created if missing) for this process: an
/// exclusive lock on `dir/.lock`, held while the returned file lives and
/// released by the OS when the process ends, also by a kill. A second
/// writer (another run, or a `--resume` beside a running one) is refused.
pub fn lock(dir: &str) -> Result<File> {
    fs::create_dir_all(dir).map_err(|source| DemError::Open { path: dir.into(), source })?;
    let p = path(dir, ".lock");
    let f = OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&p)
        .map_err(|source| DemError::Open { path: p.clone(), source })?;
    match f.try_lock() {
        Ok(()) => Ok(f),
        Err(fs::TryLockError::WouldBlock) => Err(DemError::Usage(format!(
            "{dir} is in use by another dem-train (it holds {p}); wait for it to end, or choose another --out"
        ))
        .into()),
        Err(fs::TryLockError::Error(source)) => Err(DemError::Open { path: p, source }.into()),
    }
}

/// Prepare a fresh run directory (refusing one that already holds a run).
pub fn start(opts: &RunOptions, data: &TrainData) -> Result<()> {
    fs::create_dir_all(&opts.dir).with_context(|| format!("create {}", opts.dir))?;
    let ck = path(&opts.dir, "checkpoint.bin");
    if Path::new(&ck).exists() {
        return Err(
            DemError::Usage(format!("{} already holds a run: pass --resume to continue it, or choose another --out", opts.dir)).into()
        );
    }
    for f in ["losses.csv", "val.csv"] {
        let p = path(&opts.dir, f);
        if Path::new(&p).exists() {
            fs::remove_file(&p)?;
        }
    }
    let (sims, reals) = check_sets(data);
    npy::write_all(&path(&opts.dir, "check_sim.npy"), &sims)?;
    npy::write_all(&path(&opts.dir, "check_real.npy"), &reals)?;
    Ok(())
}

/// Load the run's checkpoint and cut its logs back to it.
pub fn resume(opts: &RunOptions) -> Result<(Meta, CycleGan)> {
    let (meta, gan) = checkpoint::load(&path(&opts.dir, "checkpoint.bin"))?;
    truncate_csv(&path(&opts.dir, "losses.csv"), meta.step)?;
    truncate_csv(&path(&opts.dir, "val.csv"), meta.step / meta.steps_per_epoch)?;
    Ok((meta, gan))
}

fn fmt_losses(l: &Losses) -> String {
    format!(
        "G {:.3} (gan {:.3} cyc {:.3} pair {:.3} height {:.3}) D {:.3}",
        l.generator(),
        l.gan,
        l.cycle,
        l.pair_y + l.pair_x,
        l.height,
        l.disc
    )
}

/// Train from `meta.step` to the end of the run; returns the last table.
pub fn run(gan: &mut CycleGan, data: &TrainData, sampler: Sampler, mut meta: Meta, opts: &RunOptions) -> Result<Option<ErrorSummary>> {
    let spe = meta.steps_per_epoch;
    // The schedule is planned over the epochs; --max-steps only cuts it short,
    // so a run stopped early and resumed equals one that was not.
    let planned = epochs_of(opts, spe) * spe;
    let total = planned.min(opts.max_steps.unwrap_or(u64::MAX));
    let mut losses = append(&path(&opts.dir, "losses.csv"), "step,epoch,gan,cycle,pair_y,pair_x,generator,disc,height")?;
    let mut val = append(&path(&opts.dir, "val.csv"), "epoch,step,count,lowest,highest,mean,median")?;
    let bar = cli::progress(total, "steps");
    bar.set_position(meta.step);
    let (t0, s0) = (Instant::now(), meta.step);
    // Without a terminal (CI, nohup, a log file) the bar is hidden: a line
    // every `log_every` instead.
    let stderr_is_terminal = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let mut last_line = Instant::now();
    let mut last = None;
    while meta.step < total {
        let step = meta.step;
        let batch = sampler.batch(data, step, spe);
        gan.set_lr(gan.cfg.lr_at(step, planned));
        let l = gan.step(&batch);
        meta.step += 1;
        let epoch = step / spe + 1;
        writeln!(
            losses,
            "{},{epoch},{},{},{},{},{},{},{}",
            meta.step,
            l.gan,
            l.cycle,
            l.pair_y,
            l.pair_x,
            l.generator(),
            l.disc,
            l.height
        )?;
        // Every step, so `tail -f losses.csv` and a plot of a running run
        // see it; a step takes far longer than the write.
        losses.flush()?;
        let rate = (meta.step - s0) as f64 * sampler.batch as f64 / t0.elapsed().as_secs_f64();
        bar.set_position(meta.step);
        bar.set_message(format!("epoch {epoch} {} {rate:.0} samples/s", fmt_losses(&l)));
        if !stderr_is_terminal && last_line.elapsed() >= opts.log_every {
            last_line = Instant::now();
            let eta = (total - meta.step) as f64 * sampler.batch as f64 / rate.max(1e-9);
            cli::log(format!("step {}/{total} (epoch {epoch}): {} {rate:.0} samples/s, eta {eta:.0} s", meta.step, fmt_losses(&l)));
        }
        let epoch_end = meta.step.is_multiple_of(spe) || meta.step == total;
        if epoch_end {
            if let Some(row) = validate(gan, data) {
                writeln!(val, "{epoch},{},{},{},{},{},{}", meta.step, row.count, row.lowest, row.highest, row.mean, row.median)?;
                bar.suspend(|| {
                    cli::log(format!("epoch {epoch}: val pair error mean {:.4} median {:.4} ({} keys)", row.mean, row.median, row.count))
                });
                last = Some(row);
            }
        }
        if epoch_end || opts.checkpoint_every.is_some_and(|k| meta.step.is_multiple_of(k)) {
            losses.flush()?;
            val.flush()?;
            meta.adam_steps = gan.opts.each_ref().map(|o| o.t);
            checkpoint::save(&path(&opts.dir, "checkpoint.bin"), gan, &meta)?;
        }
    }
    bar.finish_and_clear();
    losses.flush()?;
    val.flush()?;
    let steps = meta.step - s0;
    if steps > 0 {
        let secs = t0.elapsed().as_secs_f64();
        cli::log(format!(
            "{steps} steps of {} in {secs:.1} s: {:.1} samples/s, {} threads; checkpoint {}",
            sampler.batch,
            steps as f64 * sampler.batch as f64 / secs,
            rayon::current_num_threads(),
            path(&opts.dir, "checkpoint.bin")
        ));
    } else {
        cli::log(format!("nothing to do: the run is at step {} of {total}", meta.step));
    }
    Ok(last)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_is_30_epochs_until_they_pass_the_step_budget() {
        // make demo's prepared data: 21 steps an epoch, 630 steps.
        assert_eq!(default_epochs(21), 30);
        assert_eq!(default_epochs(STEP_BUDGET / 30), 30);
        // The larger world of results.md: 127 steps an epoch.
        assert_eq!(default_epochs(127), 12);
        assert!(default_epochs(127) * 127 >= STEP_BUDGET && (default_epochs(127) - 1) * 127 < STEP_BUDGET);
        // An epoch longer than the budget still trains once.
        assert_eq!(default_epochs(STEP_BUDGET * 3), 1);
        assert_eq!(default_epochs(0), 30);
    }

    #[test]
    fn epochs_given_are_epochs_trained() {
        let opts = |epochs| RunOptions {
            dir: "run".into(),
            epochs,
            max_steps: None,
            checkpoint_every: None,
            log_every: std::time::Duration::from_secs(1),
        };
        assert_eq!(epochs_of(&opts(Some(100)), 127), 100);
        assert_eq!(epochs_of(&opts(None), 127), default_epochs(127));
    }
}
