//! `dem-train curves`: the training curves of a run as a PNG, from its
//! `losses.csv` (per step, averaged per epoch) and `val.csv` (the val split's
//! pair error per epoch).

use std::path::Path;

use dem_core::{output, table, DemError};
use dem_render::plot::{line_plot, stack, Series, PALETTE};
use serde::Deserialize;

/// A row of `losses.csv` (runs from before the height term lack `height`).
#[derive(Deserialize)]
struct LossRow {
    epoch: u64,
    gan: f64,
    cycle: f64,
    pair_y: f64,
    pair_x: f64,
    disc: f64,
    #[serde(default)]
    height: f64,
}

/// A loss term: its name and its value in a row.
type Term = (&'static str, fn(&LossRow) -> f64);

/// A row of `val.csv`.
#[derive(Deserialize)]
struct ValRow {
    epoch: f64,
    mean: f64,
    median: f64,
}

/// Draw the curves of the run in `dir` into `out` (PNG, atomically).
pub fn run(dir: &str, out: &str) -> anyhow::Result<()> {
    let file = |name: &str| Path::new(dir).join(name).to_string_lossy().into_owned();
    let losses: Vec<LossRow> = table::read_rows(&file("losses.csv"), &["step", "epoch", "gan", "cycle", "pair_y", "pair_x"])?;
    let last =
        losses.iter().map(|r| r.epoch).max().filter(|&e| e > 0).ok_or_else(|| DemError::input(file("losses.csv"), "holds no steps"))?;
    let xs: Vec<f64> = (1..=last).map(|e| e as f64).collect();
    let per_epoch = |f: fn(&LossRow) -> f64| -> Vec<f64> {
        let mut sum = vec![0.0; last as usize];
        let mut n = vec![0.0; last as usize];
        for r in losses.iter().filter(|r| r.epoch > 0) {
            sum[r.epoch as usize - 1] += f(r);
            n[r.epoch as usize - 1] += 1.0;
        }
        sum.iter().zip(&n).map(|(s, n)| if *n > 0.0 { s / n } else { f64::NAN }).collect()
    };
    let terms: [Term; 6] = [
        ("gan", |r| r.gan),
        ("cycle", |r| r.cycle),
        ("pair_y", |r| r.pair_y),
        ("pair_x", |r| r.pair_x),
        ("height", |r| r.height),
        ("disc", |r| r.disc),
    ];
    let series: Vec<Series> = terms
        .iter()
        .zip(PALETTE)
        .filter(|((_, f), _)| losses.iter().any(|r| f(r) > 0.0))
        .map(|((name, f), color)| (name.to_string(), color, per_epoch(*f)))
        .collect();
    let mut plots = vec![line_plot("losses (mean per epoch, log scale)", "epoch", &xs, &series, true)];
    let val: Vec<ValRow> = table::read_rows(&file("val.csv"), &["epoch", "step", "count"])?;
    if !val.is_empty() {
        let ve: Vec<f64> = val.iter().map(|r| r.epoch).collect();
        let vs: Vec<Series> = vec![
            ("pair error mean".into(), PALETTE[0], val.iter().map(|r| r.mean).collect()),
            ("pair error median".into(), PALETTE[2], val.iter().map(|r| r.median).collect()),
        ];
        plots.push(line_plot("validation: pair error (equation 7.1) of G_Y on the val split", "epoch", &ve, &vs, false));
    }
    let picture = stack(&plots);
    output::write_atomic(out, |w| picture.write_png(w))?;
    Ok(())
}
