//! `dem-train curves`: the training curves of a run as a PNG, from its
//! `losses.csv` (per step, averaged per epoch) and `val.csv` (the val split's
//! pair error and, in runs that record them, its height error).

use std::collections::BTreeMap;

use dem_core::render::plot::{line_plot, stack, Series, PALETTE};
use dem_core::{output, DemError};

/// Columns of a CSV by header name; every value parsed as f64.
fn read_columns(path: &str) -> anyhow::Result<BTreeMap<String, Vec<f64>>> {
    let text = std::fs::read_to_string(path).map_err(|source| DemError::Open { path: path.into(), source })?;
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap_or("").split(',').map(str::to_string).collect();
    let mut cols: BTreeMap<String, Vec<f64>> = header.iter().map(|h| (h.clone(), Vec::new())).collect();
    for (n, line) in lines.enumerate().filter(|(_, l)| !l.is_empty()) {
        let cells: Vec<&str> = line.split(',').collect();
        if cells.len() != header.len() {
            return Err(DemError::Table { path: path.into(), line: n as u64 + 2, reason: format!("{} fields, the header has {}", cells.len(), header.len()) }.into());
        }
        for (h, c) in header.iter().zip(cells) {
            let v = c.parse::<f64>().map_err(|e| DemError::Table { path: path.into(), line: n as u64 + 2, reason: format!("{h}: {e}") })?;
            cols.get_mut(h).expect("header column").push(v);
        }
    }
    Ok(cols)
}

/// Draw the curves of the run in `dir` into `out` (PNG, atomically).
pub fn run(dir: &str, out: &str) -> anyhow::Result<()> {
    let file = |name: &str| std::path::Path::new(dir).join(name).to_string_lossy().into_owned();
    let losses = read_columns(&file("losses.csv"))?;
    let epochs = losses.get("epoch").filter(|e| !e.is_empty()).ok_or_else(|| DemError::input(file("losses.csv"), "holds no steps"))?;
    let last = epochs.iter().fold(0.0f64, |a, &b| a.max(b)) as usize;
    let xs: Vec<f64> = (1..=last).map(|e| e as f64).collect();
    let per_epoch = |v: &[f64]| -> Vec<f64> {
        let mut sum = vec![0.0; last];
        let mut n = vec![0.0; last];
        for (e, x) in epochs.iter().zip(v) {
            sum[*e as usize - 1] += x;
            n[*e as usize - 1] += 1.0;
        }
        sum.iter().zip(&n).map(|(s, n)| if *n > 0.0 { s / n } else { f64::NAN }).collect()
    };
    let names = ["gan", "cycle", "pair_y", "pair_x", "height", "disc"];
    let series: Vec<Series> = names
        .iter()
        .zip(PALETTE)
        .filter_map(|(n, c)| losses.get(*n).filter(|v| v.iter().any(|x| *x > 0.0)).map(|v| (n.to_string(), c, per_epoch(v))))
        .collect();
    let mut plots = vec![line_plot("losses (mean per epoch, log scale)", "epoch", &xs, &series, true)];
    let val = read_columns(&file("val.csv"))?;
    if let Some(ve) = val.get("epoch").filter(|v| !v.is_empty()) {
        let vs: Vec<Series> = [("mean", PALETTE[0]), ("median", PALETTE[2])]
            .into_iter()
            .filter_map(|(n, c)| val.get(n).map(|v| (format!("pair error {n}"), c, v.clone())))
            .collect();
        plots.push(line_plot("validation: pair error (equation 7.1) of G_Y on the val split", "epoch", ve, &vs, false));
    }
    let picture = stack(&plots);
    output::write_atomic(out, |w| picture.write_png(w))?;
    Ok(())
}
