//! `dem-eval transfer`: does training on generated DEMs help a robot on
//! measured ones? The downstream test of a virtual sensor.
//!
//! Two small models a robot would run on its DEM are fitted on each training
//! set ([`linear`]): a ridge regression of the four flipper angles (row 20,
//! channel 0, columns 1..4, which `dem-synth` computes from the terrain
//! under the tracks) from the 20x5 grid, and a linear terrain classifier
//! (labels' `terrain`). Every model is tested on the same measured DEMs of
//! held-out runs. Per training set the table gives the flipper mean absolute
//! error (radians) and the terrain error rate, and, for every set between
//! the first (the baseline: sim DEMs) and the last (the oracle: measured DEMs
//! of other runs), the share of the baseline -> oracle drop it closes:
//!
//! ```text
//! closed(X) = (e(baseline) - e(X)) / (e(baseline) - e(oracle))
//! ```
//!
//! 1 means as good as training on measured data, 0 no better than sim, < 0
//! worse than sim. Its 90 % interval comes from `--bootstrap` resamples of
//! the test runs (labels' `sequence`; records when absent), drawn from
//! `--seed`: the only random choice, the fits themselves are closed-form.

pub mod linear;

use std::collections::BTreeMap;
use std::io::Write;

use clap::Args as ClapArgs;
use dem_core::format::{at, ATTITUDE_ROW};
use dem_core::table::{self, Label};
use dem_core::{cli, npy, Dem, DemError, Terrain};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::table::forms::{self as report, Format, Grid};
use linear::{features, Linear, FEATURES};

/// The arguments of `dem-eval transfer`.
#[derive(ClapArgs)]
pub struct TransferArgs {
    /// A training set: a name, its NPY and its labels CSV. Give two or more:
    /// the first is the baseline (sim DEMs), the last the oracle (measured
    /// DEMs of other runs than --test's).
    #[arg(long = "train", num_args = 3, value_names = ["NAME", "NPY", "LABELS"], required = true)]
    train: Vec<String>,
    /// Measured DEMs of held-out runs, the test set.
    #[arg(long)]
    test: String,
    /// Labels CSV of --test (terrain; `sequence` groups the bootstrap).
    #[arg(long)]
    test_labels: String,
    /// Ridge penalty per record, on standardised features.
    #[arg(long, default_value_t = 1.0, value_parser = dem_core::cli::value::positive::<f64>)]
    ridge: f64,
    /// Bootstrap resamples of the test runs for the interval of `closed`.
    #[arg(long, default_value_t = 200, value_parser = dem_core::cli::value::at_least_one::<usize>)]
    bootstrap: usize,
    /// Seed of the bootstrap.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Also one row per test terrain.
    #[arg(long)]
    by_terrain: bool,
    /// Table format.
    #[arg(long, value_enum, default_value = "text")]
    format: Format,
    /// Table output (`-` for stdout).
    #[arg(short, long = "out", default_value = "-")]
    output: String,
}

/// One data set: its records' features, flipper angles and terrains.
struct Set {
    name: String,
    x: Vec<[f64; FEATURES]>,
    flippers: Vec<Vec<f64>>,
    terrain: Vec<Terrain>,
    run: Vec<u64>,
}

fn load(name: &str, npy_path: &str, labels_path: &str) -> anyhow::Result<Set> {
    let dems: Vec<Dem> = npy::read_all(npy_path)?;
    let labels: Vec<Label> = table::read_labels(labels_path)?;
    table::check_labels_cover(labels_path, labels.len(), npy_path, dems.len() as u64)?;
    if dems.is_empty() {
        return Err(DemError::input(npy_path, "holds no records").into());
    }
    Ok(Set {
        name: name.into(),
        x: dems.iter().map(features).collect(),
        flippers: dems.iter().map(|d| (1..5).map(|c| d[at(ATTITUDE_ROW, c, 0)] as f64).collect()).collect(),
        terrain: labels.iter().map(|l| l.terrain).collect(),
        run: labels.iter().enumerate().map(|(i, l)| l.sequence.unwrap_or(i as u64)).collect(),
    })
}

fn one_hot(t: Terrain) -> Vec<f64> {
    Terrain::ALL.iter().map(|&c| (c == t) as u8 as f64).collect()
}

fn argmax(v: &[f64]) -> usize {
    v.iter().enumerate().fold(0, |b, (i, x)| if *x > v[b] { i } else { b })
}

/// Per test record: the flipper error and whether the terrain was wrong.
struct Scores {
    flipper: Vec<f64>,
    wrong: Vec<f64>,
    records: usize,
}

fn score(train: &Set, test: &Set, ridge: f64) -> anyhow::Result<Scores> {
    let fail = |what: &str| anyhow::anyhow!("transfer: the {what} fit on {} failed (singular system)", train.name);
    let flip = Linear::fit(&train.x, &train.flippers, ridge).ok_or_else(|| fail("flipper"))?;
    let targets: Vec<Vec<f64>> = train.terrain.iter().map(|&t| one_hot(t)).collect();
    let class = Linear::fit(&train.x, &targets, ridge).ok_or_else(|| fail("terrain"))?;
    let mut s = Scores { flipper: Vec::new(), wrong: Vec::new(), records: train.x.len() };
    for ((x, y), t) in test.x.iter().zip(&test.flippers).zip(&test.terrain) {
        let p = flip.predict(x);
        s.flipper.push(p.iter().zip(y).map(|(a, b)| (a - b).abs()).sum::<f64>() / y.len() as f64);
        s.wrong.push((Terrain::ALL[argmax(&class.predict(x))] != *t) as u8 as f64);
    }
    Ok(s)
}

fn mean(v: &[f64], idx: &[usize]) -> f64 {
    idx.iter().map(|&i| v[i]).sum::<f64>() / idx.len().max(1) as f64
}

/// `(e_base - e) / (e_base - e_oracle)`; None when sim is no worse than the oracle.
fn closed(base: f64, e: f64, oracle: f64) -> Option<f64> {
    let drop = base - oracle;
    (drop > 1e-12).then(|| (base - e) / drop)
}

/// Lower and upper 5 % quantiles of `v` (None when empty).
fn interval(mut v: Vec<f64>) -> Option<(f64, f64)> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
    Some((q(0.05), q(0.95)))
}

/// One row of the table.
struct Row {
    train: String,
    terrain: String,
    records: usize,
    test: usize,
    flipper: f64,
    flipper_closed: Option<f64>,
    flipper_ci: Option<(f64, f64)>,
    terrain_error: f64,
    terrain_closed: Option<f64>,
}

fn rows_for(sets: &[Set], scores: &[Scores], test: &Set, idx: &[usize], terrain: &str, a: &TransferArgs) -> Vec<Row> {
    let last = scores.len() - 1;
    let f: Vec<f64> = scores.iter().map(|s| mean(&s.flipper, idx)).collect();
    let w: Vec<f64> = scores.iter().map(|s| mean(&s.wrong, idx)).collect();
    // Bootstrap over the runs of these test records.
    let mut runs: BTreeMap<u64, Vec<usize>> = BTreeMap::new();
    idx.iter().for_each(|&i| runs.entry(test.run[i]).or_default().push(i));
    let groups: Vec<&Vec<usize>> = runs.values().collect();
    let mut rng = ChaCha8Rng::seed_from_u64(a.seed);
    let mut draws: Vec<Vec<f64>> = vec![Vec::new(); scores.len()];
    for _ in 0..a.bootstrap {
        let sample: Vec<usize> = (0..groups.len()).flat_map(|_| groups[rng.gen_range(0..groups.len())].iter().copied()).collect();
        let e: Vec<f64> = scores.iter().map(|s| mean(&s.flipper, &sample)).collect();
        for k in 1..last {
            draws[k].extend(closed(e[0], e[k], e[last]));
        }
    }
    (0..scores.len())
        .map(|k| {
            let middle = k > 0 && k < last;
            Row {
                train: sets[k].name.clone(),
                terrain: terrain.into(),
                records: scores[k].records,
                test: idx.len(),
                flipper: f[k],
                flipper_closed: if middle { closed(f[0], f[k], f[last]) } else { None },
                flipper_ci: if middle { interval(std::mem::take(&mut draws[k])) } else { None },
                terrain_error: w[k],
                terrain_closed: if middle { closed(w[0], w[k], w[last]) } else { None },
            }
        })
        .collect()
}

/// Fit, test and write the table.
pub fn run(a: TransferArgs) -> anyhow::Result<()> {
    if a.train.len() < 6 {
        return Err(cli::usage("transfer needs at least two --train sets: the baseline (sim) first, the oracle (measured) last"));
    }
    let mut inputs: Vec<&str> = a.train.chunks(3).flat_map(|t| [t[1].as_str(), t[2].as_str()]).collect();
    inputs.extend([a.test.as_str(), a.test_labels.as_str()]);
    dem_core::output::check_outputs(&inputs, &[&a.output])?;
    let sets: Vec<Set> = a.train.chunks(3).map(|t| load(&t[0], &t[1], &t[2])).collect::<anyhow::Result<_>>()?;
    let test = load("test", &a.test, &a.test_labels)?;
    if test.flippers.iter().all(|f| f.iter().all(|v| *v == 0.0)) {
        return Err(DemError::input(a.test.as_str(), "records no flipper angles (row 20 is all zeros): nothing to regress").into());
    }
    let scores: Vec<Scores> = sets.iter().map(|s| score(s, &test, a.ridge)).collect::<anyhow::Result<_>>()?;
    let all: Vec<usize> = (0..test.x.len()).collect();
    let mut rows = rows_for(&sets, &scores, &test, &all, crate::table::ALL, &a);
    if a.by_terrain {
        for t in Terrain::ALL {
            let idx: Vec<usize> = all.iter().copied().filter(|&i| test.terrain[i] == t).collect();
            if !idx.is_empty() {
                rows.extend(rows_for(&sets, &scores, &test, &idx, t.as_str(), &a));
            }
        }
    }
    write(&a.output, &rows, a.format)
}

fn write(path: &str, rows: &[Row], f: Format) -> anyhow::Result<()> {
    let num = |v: f64, d: usize| report::opt(Some(v), d, false, f);
    let opt = |v: Option<f64>| report::opt(v, 2, false, f);
    if f == Format::Json {
        let js: Vec<serde_json::Value> = rows
            .iter()
            .map(|r| {
                serde_json::json!({
                    "train": r.train, "terrain": r.terrain, "records": r.records, "test": r.test,
                    "flipper_mae_rad": r.flipper, "flipper_closed": r.flipper_closed,
                    "flipper_closed_lo": r.flipper_ci.map(|c| c.0), "flipper_closed_hi": r.flipper_ci.map(|c| c.1),
                    "terrain_error": r.terrain_error, "terrain_closed": r.terrain_closed,
                })
            })
            .collect();
        let text = serde_json::to_string_pretty(&js)?;
        return Ok(report::emit(path, |w| writeln!(w, "{text}"))?);
    }
    let cols = vec![
        ("", "train"),
        ("", "terrain"),
        ("", "records"),
        ("", "test"),
        ("flipper", "mae_rad"),
        ("flipper", "closed"),
        ("flipper", "closed_lo"),
        ("flipper", "closed_hi"),
        ("terrain", "error"),
        ("terrain", "closed"),
    ];
    let grid_rows = rows
        .iter()
        .map(|r| {
            vec![
                r.train.clone(),
                r.terrain.clone(),
                r.records.to_string(),
                r.test.to_string(),
                num(r.flipper, 4),
                opt(r.flipper_closed),
                opt(r.flipper_ci.map(|c| c.0)),
                opt(r.flipper_ci.map(|c| c.1)),
                num(r.terrain_error, 3),
                opt(r.terrain_closed),
            ]
        })
        .collect();
    Ok(report::emit(path, |w| Grid { cols, rows: grid_rows }.write(w, f))?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_is_the_share_of_the_drop() {
        assert_eq!(closed(0.2, 0.2, 0.1), Some(0.0));
        assert_eq!(closed(0.2, 0.1, 0.1), Some(1.0));
        assert!((closed(0.2, 0.12, 0.1).unwrap() - 0.8).abs() < 1e-12);
        assert!(closed(0.2, 0.3, 0.1).unwrap() < 0.0);
        assert_eq!(closed(0.1, 0.1, 0.2), None);
        assert_eq!(interval(vec![]), None);
        let v: Vec<f64> = (0..101).map(f64::from).collect();
        assert_eq!(interval(v), Some((5.0, 95.0)));
    }
}
