//! dem-gap: find where sim and real disagree, name the missing effect, add
//! it to a sensor model and show the gap shrink.

use std::process::ExitCode;

use clap::Parser;
use dem_core::cli::{self, value};
use dem_core::output;
use dem_core::table::Split;
use dem_gap::{self as gap, report, GapConfig};
use dem_sensor::SensorModel;

/// Measure the gap between model(sim) and real, name the effect that
/// closes most of it (noise, dropout, row-dropout, occlusion, fov,
/// view-top, smoothing, bias, quantization, startup, patch-dropout,
/// edge-holes, rim-holes, pit-fill, mixed-cells, hole-growth, drop-blend, riser-blend, floor-lift, drop-holes,
/// tilt, shake, step-jitter, lag, drift, map-memory), fit it, add it, repeat while an effect still
/// helps and the gap left is not negligible. What no effect explains is
/// reported with where it lives (statistic, rows, side, terrain), and a
/// gap below the sampling floor with the records (runs) that would show it. A fit at the edge of its
/// search box is flagged (stderr, report.md, report.json `at_edge`, and
/// the warnings of sensor.json, which an export carries into its file); a
/// model that hides far more cells than real misses is never accepted. Writes DIR/report.json, DIR/sensor.json (usable by
/// `dem-sensor apply`), DIR/report.md with pictures; progress on stderr.
///
/// Labels and pairs are optional: without pairs the distributions of the
/// records are compared, with pairs the residuals per position, and with
/// pairs and --unpaired the distributions of the pairs' records.
#[derive(Parser)]
#[command(
    version,
    after_long_help = "Examples:
  dem-gap --sim testdata/sim.npy --real testdata/real.npy --out gap/
  dem-gap --sim testdata/sim.npy --real testdata/real.npy --pairs testdata/pairs.csv \\
      --sim-labels testdata/sim_labels.csv --real-labels testdata/real_labels.csv --out gap/ --seed 1
  dem-gap --sim sim.npy --real real.npy --sensor start.json --max-steps 2 --out gap2/
  dem-gap --sim no_fov/real.npy --real all/real.npy --sim-labels no_fov/real_labels.csv \
      --real-labels all/real_labels.csv --out gap3/     # labels' time lets `startup` fit its speed
  dem-gap --sim prep/sim.npy --real prep/real.npy --pairs prep/pairs.csv --split train --unpaired \
      --sim-labels prep/sim_labels.csv --real-labels prep/real_labels.csv --out gap4/   # dem-pair's keys
  dem-sensor apply --sensor gap/sensor.json sim.npy -o sim_as_measured.npy   # use the result"
)]
struct Args {
    /// Sim NPY file.
    #[arg(long)]
    sim: String,
    /// Real (measured) NPY file.
    #[arg(long)]
    real: String,
    /// Pairs CSV (sim_index,real_index): compare per position.
    #[arg(long)]
    pairs: Option<String>,
    /// Labels CSV of the sim file (per-terrain tables).
    #[arg(long = "sim-labels", value_name = "CSV")]
    labels_sim: Option<String>,
    /// Labels CSV of the real file.
    #[arg(long = "real-labels", value_name = "CSV")]
    labels_real: Option<String>,
    /// Sensor model to start from (JSON); default: no effects.
    #[arg(long = "sensor", value_name = "JSON")]
    model: Option<String>,
    /// Output folder.
    #[arg(short, long)]
    out: String,
    /// Most effects to add.
    #[arg(long, default_value_t = 8, value_parser = value::at_least_one::<usize>)]
    max_steps: usize,
    /// Seed of the model's random effects and of the fitting subsample.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Records the candidates are fitted on (a subsample; all when fewer).
    #[arg(long, default_value_t = 1000)]
    fit_records: usize,
    /// Smallest fraction of the gap an added effect must remove.
    #[arg(long, default_value_t = 0.05, value_parser = value::fraction::<f64>)]
    min_gain: f64,
    /// Unpaired, with both label files: draw the sim records (by --seed) to
    /// the real set's terrain mix before comparing, so that a different mix
    /// is not read as sensor effects. The default with both label files;
    /// the flag says so explicitly (and refuses to run without them).
    #[arg(long, conflicts_with = "no_match_terrain_mix")]
    match_terrain_mix: bool,
    /// Unpaired, with both label files: compare the sim records as they
    /// are, whatever their terrain mix. The effects that move whole
    /// records (bias, tilt, shake) are then left out unless
    /// --whole-record-effects.
    #[arg(long)]
    no_match_terrain_mix: bool,
    /// Fit the effects that move whole records (bias, tilt, shake) also
    /// where the terrain mixes are not known to match (unpaired without
    /// both label files, or with --no-match-terrain-mix). A set with more
    /// stairs has other record means, and such an effect takes that
    /// terrain for a sensor's error; the model's warnings say so.
    #[arg(long)]
    whole_record_effects: bool,
    /// With --pairs: only the pairs of this split (train or val).
    #[arg(long, value_enum)]
    split: Option<Split>,
    /// With --pairs: compare the pairs' records as two sets, each record
    /// once per pair it is in (dem-eval's gap), not per position. For pairs
    /// that repeat records, as dem-pair's do: both sides keep the pairs'
    /// terrain mix, which the unique records would not.
    #[arg(long)]
    unpaired: bool,
    /// When no candidate removes enough of the gap alone, try the best three
    /// again, and two an earlier effect displaced, each with the effects
    /// already named re-fitted beside it (a displaced one fitted in its
    /// displacer's place first): an early effect can stand in for a later
    /// one, which then adds little alone. Slower (two and a half times the
    /// time on exact sim against all of dem-synth's stages); each effect so
    /// added passes the same checks as the others.
    #[arg(long)]
    joint_refit: bool,
    /// Leave the frame terms out of the gap (how consecutive frames of a
    /// run move, from both label files' runs and poses): compare frame by
    /// frame only.
    #[arg(long)]
    no_frame_terms: bool,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,
    /// Do not warn when --sim misses clearly more cells than --real (the
    /// sign of swapped inputs: measured DEMs have holes, sim DEMs few).
    #[arg(long)]
    no_swap_check: bool,
}

fn main() -> ExitCode {
    cli::run(|| {
        let a: Args = cli::parse();
        if let Some(n) = a.threads {
            rayon::ThreadPoolBuilder::new().num_threads(n as usize).build_global()?;
        }
        if a.min_gain >= 1.0 {
            return Err(cli::usage("--min-gain must be a fraction in 0..1 (below 1)"));
        }
        if a.fit_records < 50 {
            return Err(cli::usage("--fit-records must be at least 50"));
        }
        if a.match_terrain_mix && (a.pairs.is_some() || a.labels_sim.is_none() || a.labels_real.is_none()) {
            return Err(cli::usage(
                "--match-terrain-mix draws the sim side of an unpaired comparison: give --sim-labels and --real-labels, and no --pairs",
            ));
        }
        if (a.unpaired || a.split.is_some()) && a.pairs.is_none() {
            return Err(cli::usage("--unpaired and --split choose among the pairs: give --pairs"));
        }
        if a.sim == "-" || a.real == "-" {
            return Err(cli::usage("--sim and --real are read more than once; give files, not `-`"));
        }
        // Check the folder and every file the report will write before the
        // analysis, which takes minutes.
        if std::path::Path::new(&a.out).exists() && !std::path::Path::new(&a.out).is_dir() {
            return Err(cli::usage(format!("--out {} is a file, not a folder", a.out)));
        }
        // Made to probe it, and removed again until there is a report to put
        // in it: a refused input leaves no folder.
        let inputs: Vec<&str> =
            [Some(&a.sim), Some(&a.real), a.pairs.as_ref(), a.labels_sim.as_ref(), a.labels_real.as_ref(), a.model.as_ref()]
                .into_iter()
                .flatten()
                .map(String::as_str)
                .collect();
        output::OutputFolder::create(&a.out)?.check(&inputs, &report::FILES)?;
        dem_core::swap::check_files(&a.sim, &a.real, a.no_swap_check);
        let start = a.model.as_deref().map(SensorModel::read).transpose()?.unwrap_or_default();
        let cfg = GapConfig {
            sim: a.sim,
            real: a.real,
            pairs: a.pairs,
            labels_sim: a.labels_sim,
            labels_real: a.labels_real,
            start,
            out: a.out,
            max_steps: a.max_steps,
            seed: a.seed,
            fit_records: a.fit_records,
            min_gain: a.min_gain,
            match_terrain: !a.no_match_terrain_mix,
            whole_record: a.whole_record_effects,
            split: a.split,
            over_pairs: a.unpaired,
            joint_refit: a.joint_refit,
            frame_terms: !a.no_frame_terms,
        };
        let t = std::time::Instant::now();
        let sets = gap::load(&cfg)?;
        if let Some((kept, of)) = sets.terrain_mix {
            cli::log(format_args!("{kept} sim records drawn from {of} to the real set's terrain mix"));
        }
        // Candidates fitted: the whole vocabulary at the first step, one fewer at each next.
        let n = dem_sensor::effects::NAMES.len();
        let fits = (0..cfg.max_steps.min(n)).map(|k| (n - k) as u64).sum();
        let bar = cli::progress(fits, "fits");
        let outcome = gap::run(&cfg, &sets, &|line| bar.suspend(|| cli::log(line)), &|| bar.inc(1));
        bar.finish_and_clear();
        report::write(&cfg.out, &outcome, &sets, &cfg.start, cfg.seed)?;
        cli::log(format_args!(
            "gap {:.3} -> {:.3} ({:.3} with unseen draws) with {}; {} written in {:.1} s",
            outcome.gap_initial,
            outcome.gap_final,
            outcome.gap_final_unseen,
            outcome.model.summary(),
            cfg.out,
            t.elapsed().as_secs_f64()
        ));
        Ok(())
    })
}
