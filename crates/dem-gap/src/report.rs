//! What a gap run leaves in its folder: `report.json` (the steps, exact
//! schema below), `sensor.json` (the final model), `report.md` with the
//! pictures `compare.png` (sim, model(sim) before and after, real) and the
//! per-row plots `rows-missing.png` and `rows-height.png`.
//!
//! ```text
//! {"steps": [{"effect": NAME, "params": {...}, "gap_before": x, "gap_after": y, "evidence": "...",
//!             "at_edge": [PARAM, ...], "widened": [PARAM, ...],
//!             "tied_with": [{"effect": NAME, "params": {...}, "gain": g, "gain_on_top": t,
//!                            "gains_halves": [g1, g2], "named_gains_halves": [n1, n2]}]}],
//!  "refits": [{"effect": NAME, "params_named": {...}, "params": {...}, "gap_before": x, "gap_after": y, "at_edge": [...]}],
//!  "gap_initial": x, "gap_final": y, "gap_final_unseen": z,
//!  "gap_terms": [{"term": NAME, "start": x, "final": y}],
//!  "sampling_floor": f, "sampling_floor_initial": f0, ...,
//!  "unexplained": {"gap", "floor", "excess", "share", "of_initial", "location": {"statistic", "row_band", "side", "terrain"},
//!                  "by_statistic": [...], "by_row_band": [...], "by_side": [...], "by_terrain": [...], "by_row": [...],
//!                  "weak_steps": [{"step", "effect", "removed"}]},
//!  "records_needed": n | null, "runs_needed": n | null, "records_estimate": {...} | null,
//!  "missing_by_band": [{"terrain", "band", "records", "sim", "model", "real", "flag", "reason"}],
//!  "record_kinds": {"level_sim", "level_real", "tall_sim", "tall_real", "differs", "level_sd", "tall_sd"}}
//! ```
//!
//! `unexplained`: the final gap above the sampling floor and where it
//! lives ([`crate::unexplained`]); `records_needed`: with the start gap
//! below its floor, the records (runs) that would lift it above.
//!
//! `at_edge` names the parameters fitted on an edge of their search box
//! (after widening it up to the effect's limits, `widened`): such an effect
//! is the closest of the vocabulary, not the right one. `tied_with`: close
//! rivals the data does not order behind the named effect (`gain`: the gap
//! the rival removes on all records in its place, `gain_on_top` added to
//! it; the halves' gains, the rival's and the named effect's): the step
//! names one of them, not the one. `refits`: effects re-fitted with all
//! others in place, before a step below the sampling floor and after the
//! loop, in that order (the final model, `sensor.json`, holds the last
//! parameters of each).
//!
//! ```text
//! ```

use std::fmt::Write as _;
use std::path::Path;

use serde_json::{json, Map, Value};

use dem_core::error::{DemError, Result};
use dem_core::format::{row_center_x, Dem, GRID_ROWS};
use dem_core::{npy, output};
use dem_render::canvas::{Canvas, Rgb, BLACK, GRID, TEXT, WHITE};
use dem_render::font::{draw_text, draw_text_centered, text_height, text_width};
use dem_render::plot::line;
use dem_render::{self as render, Captions, Pick, RenderConfig, Selection, TileStyle};

use super::{Outcome, Sets};
use crate::unexplained::{Part, BANDS, BAND_KEYS, GRID_WIDE, WEAK};
use dem_core::distribution::gap_terms;

/// Every file [`write()`] leaves in its folder.
pub const FILES: [&str; 7] =
    ["report.json", "sensor.json", "report.md", "compare.png", "rows-missing.png", "rows-height.png", "unexplained.png"];

/// `report.json` of an outcome, in the exact schema of the module doc.
pub fn report_json(o: &Outcome) -> Value {
    let steps: Vec<Value> = o
        .steps
        .iter()
        .map(|s| {
            let tied: Vec<Value> = s
                .tied_with
                .iter()
                .map(|t| {
                    json!({"effect": t.effect.name(), "params": params_of(&t.effect), "gain": t.gain, "gain_on_top": t.gain_on_top,
                           "gains_halves": t.gains_halves, "named_gains_halves": t.named_gains_halves})
                })
                .collect();
            json!({"effect": s.effect.name(), "params": params_of(&s.effect), "gap_before": s.gap_before, "gap_after": s.gap_after,
                   "evidence": s.evidence, "at_edge": s.at_edge, "widened": s.widened, "tied_with": tied})
        })
        .collect();
    let refits: Vec<Value> = o
        .refits
        .iter()
        .map(|r| {
            json!({"effect": r.after.name(), "params_named": params_of(&r.before), "params": params_of(&r.after),
                   "gap_before": r.gap_before, "gap_after": r.gap_after, "at_edge": r.at_edge})
        })
        .collect();
    json!({"steps": steps, "refits": refits, "gap_initial": o.gap_initial, "gap_final": o.gap_final,
        "gap_final_unseen": o.gap_final_unseen, "sampling_floor": o.floor, "sampling_floor_initial": o.floor_initial,
        "gap_terms": gap_terms(&o.stats[1], &o.stats[3]).into_iter().zip(gap_terms(&o.stats[2], &o.stats[3]))
            .map(|((term, start), (_, end))| json!({"term": term, "start": start, "final": end})).collect::<Vec<_>>(),
        "sim_records": o.sizes.0, "real_records": o.sizes.1, "over_pairs": o.over_pairs,
        "terrain_mix": o.terrain_mix.map(|(kept, of)| json!({"drawn": kept, "from": of})),
        "unexplained": unexplained_json(&o.unexplained),
        "records_needed": o.more_data.as_ref().map(|m| m.records),
        "runs_needed": o.more_data.as_ref().and_then(|m| m.runs),
        "records_estimate": o.more_data.as_ref().map(|m| json!({"gap": m.gap, "floor": m.floor, "floor_half": m.floor_half,
            "exponent_measured": m.exponent_measured, "exponent": m.exponent, "factor": m.factor, "records": m.records,
            "sim_records": m.sim_records, "runs": m.runs, "runs_now": m.runs_now})),
        "missing_by_band": o.missing_bands.iter().map(|b| json!({"terrain": b.terrain.map(|t| t.as_str()), "band": b.band,
            "records": b.records, "sim": b.missing[0], "model": b.missing[1], "real": b.missing[2],
            "flag": b.flag.is_some(), "reason": b.flag})).collect::<Vec<_>>(),
        "record_kinds": {"level_sim": o.record_kinds.level[0], "level_real": o.record_kinds.level[1], "tall_sim": o.record_kinds.tall[0],
            "tall_real": o.record_kinds.tall[1], "differs": o.record_kinds.differs(), "level_sd": crate::mix::LEVEL_SD,
            "tall_sd": crate::mix::TALL_SD}})
}

/// `unexplained` of report.json.
fn unexplained_json(u: &crate::unexplained::Unexplained) -> Value {
    let parts = |v: &[Part], key: &str| -> Vec<Value> {
        v.iter()
            .map(|p| {
                let mut m = Map::new();
                m.insert(key.into(), json!(p.name));
                for (k, x) in [("gap", p.gap), ("floor", p.floor), ("excess", p.excess), ("share", p.share)] {
                    m.insert(k.into(), json!(x));
                }
                if key == "terrain" {
                    m.insert("records".into(), json!(p.records));
                    m.insert("statistic".into(), json!(p.top.as_ref().map(|t| &t.0)));
                    m.insert("row_band".into(), json!(p.top.as_ref().map(|t| &t.1)));
                }
                Value::Object(m)
            })
            .collect()
    };
    let l = &u.location;
    json!({"gap": u.gap, "floor": u.floor, "excess": u.excess, "share": u.share, "of_initial": u.of_initial,
        "location": {"statistic": l.statistic, "row_band": l.row_band, "side": l.side, "terrain": l.terrain},
        "by_statistic": parts(&u.by_statistic, "statistic"),
        "by_row_band": parts(&u.by_row_band, "band"),
        "by_side": parts(&u.by_side, "side"),
        "by_terrain": parts(&u.by_terrain, "terrain"),
        "by_row": u.by_row.iter().enumerate().map(|(r, (g, f))| json!({"row": r, "x": row_center_x(r), "gap": g, "floor": f})).collect::<Vec<_>>(),
        "weak_steps": u.weak_steps.iter().map(|(k, e, sh)| json!({"step": k, "effect": e, "removed": sh})).collect::<Vec<_>>()})
}

/// The rivals a step is tied with, as a list of `name`s.
fn tied_names(st: &crate::Step) -> String {
    st.tied_with.iter().map(|t| format!("`{}`", t.effect.name())).collect::<Vec<_>>().join(", ")
}

/// An effect's parameters as a JSON object.
fn params_of(e: &dem_sensor::Effect) -> Map<String, Value> {
    e.params().into_iter().map(|(k, v)| (k.to_string(), json!(v))).collect()
}

/// Share of `before` that `after` removes, in percent.
fn removed(before: f64, after: f64) -> f64 {
    100.0 * crate::share_removed(before, after)
}

fn path(dir: &str, name: &str) -> String {
    Path::new(dir).join(name).to_string_lossy().into_owned()
}

/// Write `report.json`, `sensor.json`, the pictures and `report.md` into
/// `dir` (created when missing). Each file appears whole or not at all.
pub fn write(dir: &str, o: &Outcome, sets: &Sets, start: &dem_sensor::SensorModel, seed: u64) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|source| DemError::Open { path: dir.into(), source })?;
    let text = serde_json::to_string_pretty(&report_json(o)).expect("json");
    output::write_atomic(&path(dir, "report.json"), |w| writeln!(w, "{text}"))?;
    o.model.write(&path(dir, "sensor.json"))?;
    pictures(dir, o, sets, start, seed)?;
    plots(dir, o)?;
    unexplained_plot(dir, o)?;
    let md = markdown(o);
    output::write_atomic(&path(dir, "report.md"), |w| w.write_all(md.as_bytes()))
}

use std::io::Write as _;

fn pictures(dir: &str, o: &Outcome, sets: &Sets, start: &dem_sensor::SensorModel, seed: u64) -> Result<()> {
    // Twelve records spread over the set, preferring ones where real has
    // something to show (some but not all cells missing).
    let n = sets.sim.len();
    let interesting: Vec<usize> = (0..n.min(sets.real.len()))
        .filter(|&i| {
            let v = dem_core::format::DemCells::valid_cells(&sets.real[i]);
            (40..100).contains(&v)
        })
        .collect();
    let pool: Vec<usize> = if interesting.len() >= 12 { interesting } else { (0..n.min(sets.real.len())).collect() };
    let idx: Vec<usize> = (0..12.min(pool.len())).map(|k| pool[k * pool.len() / 12.min(pool.len())]).collect();
    let apply = |m: &dem_sensor::SensorModel| -> Vec<Dem> {
        let mut all = sets.sim.clone();
        // The same draws as the measurement: apply with the record's index.
        idx.iter()
            .map(|&i| {
                let mut d = all[i];
                m.apply_at(&mut d, seed, i as u64, dem_sensor::moment_at(sets.sim_moments.as_deref(), i));
                all[i] = d;
                d
            })
            .collect()
    };
    let mut rows: Vec<(String, Vec<Dem>)> = vec![("sim".into(), idx.iter().map(|&i| sets.sim[i]).collect())];
    if !start.effects.is_empty() {
        rows.push(("start model".into(), apply(start)));
    }
    rows.push(("model(sim)".into(), apply(&o.model)));
    rows.push((if sets.paired { "real" } else { "real (other)" }.into(), idx.iter().map(|&i| sets.real[i]).collect()));
    let mut files = Vec::new();
    for (k, (_, recs)) in rows.iter().enumerate() {
        let p = path(dir, &format!(".compare-{k}.npy"));
        npy::write_all(&p, recs)?;
        files.push(p);
    }
    let cfg = RenderConfig {
        inputs: files.clone(),
        compare: true,
        row_labels: rows.iter().map(|r| r.0.clone()).collect(),
        pick: Pick::Direct(Selection::Range { start: 0, count: idx.len() as u64 }),
        columns: None,
        title: Some(format!("sim, model(sim) with {} effect(s) and real", o.model.effects.len())),
        vmin: None,
        vmax: None,
        captions: Captions::None,
        style: TileStyle::default(),
        output: path(dir, "compare.png"),
    };
    let res = render::render(&cfg);
    for f in files {
        let _ = std::fs::remove_file(f);
    }
    res.map(|_| ())
}

const COLORS: [Rgb; 4] = [[150, 150, 150], [230, 150, 40], [30, 90, 200], [200, 30, 30]];
const SERIES: [&str; 4] = ["sim", "start model(sim)", "model(sim)", "real"];

fn plots(dir: &str, o: &Outcome) -> Result<()> {
    let series = |name: &str| -> Vec<(String, Rgb, Vec<f64>)> {
        o.stats
            .iter()
            .enumerate()
            .filter(|(k, _)| *k != 1 || !o.steps.is_empty() && o.stats[1] != o.stats[0])
            .map(|(k, s)| (SERIES[k].to_string(), COLORS[k], s.term(name).map_or(vec![], |t| t.values.clone())))
            .collect()
    };
    let xs: Vec<f64> = (0..GRID_ROWS).map(row_center_x).collect();
    let c = line_plot("missing-cell rate per row", "x of the row (m)", &xs, &series("missing"), false);
    output::write_atomic(&path(dir, "rows-missing.png"), |w| c.write_png(w))?;
    let (h, s) = if o.paired {
        ("mean residual (model or real) - sim per row (m)", "residual sd per row (m)")
    } else {
        ("mean height per row (m)", "across-robot roughness per row (m)")
    };
    let a = line_plot(h, "x of the row (m)", &xs, &series("height"), true);
    let b = line_plot(s, "x of the row (m)", &xs, &series("spread-sd"), false);
    let mut both = Canvas::new(a.width(), a.height() + b.height(), WHITE);
    blit(&mut both, &a, 0);
    blit(&mut both, &b, a.height());
    output::write_atomic(&path(dir, "rows-height.png"), |w| both.write_png(w))
}

/// unexplained.png: per row, the remaining gap and its sampling floor,
/// the gap of the statistics with most of the excess; below, the gap per
/// row on each terrain (labels).
fn unexplained_plot(dir: &str, o: &Outcome) -> Result<()> {
    const PALETTE: [Rgb; 6] = [[200, 30, 30], [30, 90, 200], [40, 160, 60], [150, 60, 180], [230, 150, 40], [0, 150, 160]];
    let u = &o.unexplained;
    let xs = crate::unexplained::row_xs();
    let mut top = vec![
        ("gap left".to_string(), BLACK, u.by_row.iter().map(|r| r.0).collect::<Vec<f64>>()),
        ("sampling floor".to_string(), [150, 150, 150], u.by_row.iter().map(|r| r.1).collect()),
    ];
    top.extend(u.rows_of_top.iter().enumerate().map(|(k, (n, v))| (n.clone(), PALETTE[k % PALETTE.len()], v.clone())));
    let a = line_plot("remaining gap per row (and per statistic)", "x of the row (m)", &xs, &top, false);
    let c = if u.rows_of_terrain.is_empty() {
        a
    } else {
        let per: Vec<(String, Rgb, Vec<f64>)> =
            u.rows_of_terrain.iter().enumerate().map(|(k, (n, v))| (n.clone(), PALETTE[k % PALETTE.len()], v.clone())).collect();
        let b = line_plot("remaining gap per row, per terrain", "x of the row (m)", &xs, &per, false);
        let mut both = Canvas::new(a.width(), a.height() + b.height(), WHITE);
        blit(&mut both, &a, 0);
        blit(&mut both, &b, a.height());
        both
    };
    output::write_atomic(&path(dir, "unexplained.png"), |w| c.write_png(w))
}

/// The "Unexplained" section of report.md.
fn unexplained_md(s: &mut String, o: &Outcome) {
    let u = &o.unexplained;
    let _ = writeln!(s, "\n## Unexplained\n");
    if !u.weak_steps.is_empty() {
        let w: Vec<String> = u.weak_steps.iter().map(|(k, e, sh)| format!("step {k} `{e}` removed {:.0}%", 100.0 * sh)).collect();
        let _ = writeln!(
            s,
            "**Weak:** {}: each removed less than {:.0}% of the gap it was given. It is the closest effect of the vocabulary, not the explanation: read the gap it left as unexplained.\n",
            w.join(", "),
            100.0 * WEAK
        );
    }
    if u.excess <= 0.0 {
        let _ = writeln!(
            s,
            "Nothing unexplained: the gap left, {:.3}, is within the sampling floor {:.3} (a perfect model's own draws or two halves of real differ as much) or below {} (no statistic differs by a fifth of its scale).\n",
            u.gap, u.floor, crate::NEGLIGIBLE_GAP
        );
        return;
    }
    let why = if o.stop.starts_with("stopped after --max-steps") {
        "the run stopped at `--max-steps`: more steps may explain part of it"
    } else {
        "no effect of the vocabulary explains it"
    };
    let l = &u.location;
    let mut at = Vec::new();
    if let Some(x) = &l.statistic {
        at.push(format!("statistic `{x}`"));
    }
    if let Some(x) = &l.row_band {
        let band = BAND_KEYS.iter().position(|k| k == x).map_or(x.as_str(), |i| BANDS[i].0);
        at.push(format!("rows {band}"));
    }
    if let Some(x) = &l.side {
        at.push(format!("side: {x}"));
    }
    if let Some(x) = &l.terrain {
        at.push(if x == "all" { "every terrain alike".to_string() } else { format!("terrain `{x}`") });
    }
    let _ = writeln!(
        s,
        "**{:.3} of the gap {:.3} is above the sampling floor {:.3}** ({:.0}% of what is left, {:.0}% of the start gap {:.3}): {why}. Most of it: {}.\n",
        u.excess,
        u.gap,
        u.floor,
        100.0 * u.share,
        100.0 * u.of_initial,
        o.gap_initial,
        at.join(", ")
    );
    let _ = writeln!(
        s,
        "Each piece is the gap of the final model(sim) against real there and the sampling floor there; `above` = gap - floor (not below 0), `share` = its part of the sum of `above` in the table. Statistics and row bands split the gap itself (terms per row go to their row, edges half to each row of the pair, the rest is `{GRID_WIDE}`); sides and terrains are each compared as sets of their own (a side: its two columns only), against their own floor.\n"
    );
    let _ = writeln!(s, "| split | where | gap | floor | above | share |\n|---|---|---|---|---|---|");
    let mut row = |split: &str, p: &Part, name: String| {
        let _ = writeln!(s, "| {split} | {name} | {:.3} | {:.3} | {:.3} | {:.0}% |", p.gap, p.floor, p.excess, 100.0 * p.share);
    };
    for p in u.by_statistic.iter().filter(|p| p.gap > 0.0).take(6) {
        row("statistic", p, format!("`{}`", p.name));
    }
    for p in &u.by_row_band {
        let band = BAND_KEYS.iter().position(|k| *k == p.name).map_or(p.name.clone(), |i| format!("rows {}", BANDS[i].0));
        row("row band", p, band);
    }
    for p in &u.by_side {
        let cols = if p.name == "left" { "left (columns 0-1)" } else { "right (columns 3-4)" };
        row("side", p, cols.to_string());
    }
    for p in &u.by_terrain {
        let top =
            p.top.as_ref().map_or(format!(" ({} records)", p.records), |(st, b)| format!(" ({} records; mostly `{st}`, {b})", p.records));
        row("terrain", p, format!("`{}`{top}", p.name));
    }
    let _ = writeln!(s, "\n![remaining gap per row](unexplained.png)");
}

fn more_data_md(s: &mut String, o: &Outcome) {
    let Some(m) = &o.more_data else { return };
    let _ = writeln!(
        s,
        "\n## How much data would show it\n\nThe start gap {:.3} is below its sampling floor {:.3}. The floor is a sum over statistics of ln(1 + z^2), each z a sampling difference whose variance falls as 1/n, while a true gap stays. Measured on the sampling halves, the floor is {:.3} at half the records (it falls as n^-{:.2}); each z^2 scales as n^-{:.2} (fitted; 1 is pure sampling). Solving floor(n) = gap: about **{} real records{}** and {} sim records (x{:.1} the {} and {} now) would lift the gap above the floor, if it is a real one; until then what separates the sets cannot be told from sampling.\n",
        m.gap,
        m.floor,
        m.floor_half,
        m.exponent_measured,
        m.exponent,
        m.records,
        match (m.runs, m.runs_now) {
            (Some(r), Some(n)) => format!(" ({r} runs instead of {n})"),
            _ => String::new(),
        },
        m.sim_records,
        m.factor,
        o.sizes.1,
        o.sizes.0
    );
}

fn missing_bands_md(s: &mut String, o: &Outcome) {
    if o.missing_bands.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "\n## Missing cells behind and ahead of the robot\n\nBehind: rows with x < 0; ahead: x >= 0. Missing-cell rate of sim / final model(sim) / real; flagged where model and real differ by more than {:.0} points.{}\n\n| terrain | band | real records | sim | model | real | flag |\n|---|---|---|---|---|---|---|",
        100.0 * crate::unexplained::MISSING_FLAG,
        if o.terrains.is_empty() && o.missing_bands.iter().all(|b| b.terrain.is_none()) { " Without labels of both sides: per band only." } else { "" }
    );
    for b in &o.missing_bands {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.1}% | {:.1}% | {:.1}% | {} |",
            b.terrain.map_or("all records".to_string(), |t| format!("`{t}`")),
            b.band,
            b.records,
            100.0 * b.missing[0],
            100.0 * b.missing[1],
            100.0 * b.missing[2],
            b.flag.as_ref().map_or(String::new(), |f| format!("**yes**: {f}"))
        );
    }
}

fn blit(dst: &mut Canvas, src: &Canvas, y0: u32) {
    for y in 0..src.height() {
        for x in 0..src.width() {
            dst.set(x as i64, (y + y0) as i64, src.get(x, y));
        }
    }
}

/// A line plot of several series over `xs`, with axes, ticks and a legend.
/// `zero_line` draws y = 0.
pub fn line_plot(title: &str, xlabel: &str, xs: &[f64], series: &[(String, Rgb, Vec<f64>)], zero_line: bool) -> Canvas {
    let (w, h) = (900i64, 420i64);
    let (l, r, t, b) = (110i64, 220i64, 40i64, 60i64);
    let mut c = Canvas::new(w as u32, h as u32, WHITE);
    let ys: Vec<f64> = series.iter().flat_map(|s| s.2.iter().copied()).filter(|v| v.is_finite()).collect();
    let (mut lo, mut hi) = ys.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
    if zero_line || !lo.is_finite() {
        lo = lo.min(0.0);
        hi = hi.max(0.0);
    }
    if !lo.is_finite() || hi - lo < 1e-9 {
        (lo, hi) = (lo.min(0.0) - 0.5e-3, hi.max(0.0) + 0.5e-3);
    }
    let pad = 0.05 * (hi - lo);
    let (lo, hi) = (lo - pad, hi + pad);
    let (x0, x1) = (xs[0] - 0.05, xs[xs.len() - 1] + 0.05);
    let px = |x: f64| l + ((x - x0) / (x1 - x0) * (w - l - r) as f64).round() as i64;
    let py = |y: f64| h - b - ((y - lo) / (hi - lo) * (h - t - b) as f64).round() as i64;
    draw_text(&mut c, l, 10, title, 2, TEXT);
    // Axes and ticks.
    for k in 0..=5 {
        let y = lo + (hi - lo) * k as f64 / 5.0;
        let yy = py(y);
        c.hline(l, yy, w - l - r, GRID);
        let label = if hi - lo < 0.05 { format!("{:.4}", y) } else { format!("{:.3}", y) };
        draw_text(&mut c, l - 8 - text_width(&label, 1) as i64, yy - 4, &label, 1, TEXT);
    }
    let mut x = (x0 * 5.0).ceil() / 5.0;
    while x <= x1 {
        let xx = px(x);
        c.vline(xx, t, h - t - b, GRID);
        draw_text_centered(&mut c, xx, h - b + 8, &format!("{x:.1}"), 1, TEXT);
        x += 0.2;
    }
    if zero_line {
        c.hline(l, py(0.0), w - l - r, BLACK);
    }
    c.hline(l, h - b, w - l - r, BLACK);
    c.vline(l, t, h - t - b, BLACK);
    draw_text_centered(&mut c, l + (w - l - r) / 2, h - b + 28, xlabel, 1, TEXT);
    c.vline(px(0.0), t, h - t - b, [120, 120, 120]);
    draw_text(&mut c, px(0.0) + 3, t + 2, "C", 1, TEXT);
    for (k, (name, color, v)) in series.iter().enumerate() {
        let pts: Vec<(i64, i64)> = xs.iter().zip(v).filter(|(_, y)| y.is_finite()).map(|(&x, &y)| (px(x), py(y))).collect();
        for p in pts.windows(2) {
            line(&mut c, p[0], p[1], *color, 3);
        }
        for &(x, y) in &pts {
            c.fill_rect(x - 3, y - 3, 7, 7, *color);
        }
        let ly = t + 10 + k as i64 * (text_height(2) as i64 + 8);
        c.fill_rect(w - r + 15, ly + 2, 20, 10, *color);
        draw_text(&mut c, w - r + 42, ly, name, 1, TEXT);
    }
    c
}

/// The Markdown report.
pub fn markdown(o: &Outcome) -> String {
    let mut s = String::new();
    summary_md(&mut s, o);
    warnings_md(&mut s, o);
    steps_md(&mut s, o);
    terms_md(&mut s, o);
    terrains_md(&mut s, o);
    unexplained_md(&mut s, o);
    more_data_md(&mut s, o);
    missing_bands_md(&mut s, o);
    let _ = writeln!(s, "\n## Pictures\n\n![sim, model(sim), real](compare.png)\n\n![missing rate per row](rows-missing.png)\n\n![heights per row](rows-height.png)");
    s
}

/// The opening: what was compared, the gap before and after, and what the reader must know about the data.
fn summary_md(s: &mut String, o: &Outcome) {
    let _ = writeln!(s, "# dem-gap report\n");
    let _ = writeln!(
        s,
        "{} comparison of model(sim) ({} records) against real ({} records). Gap {:.3} -> {:.3} ({:.0}% removed); sampling floor {:.3}. \
         With random draws of the model's effects that no fit or check saw (a new seed): {:.3} ({:.0}% removed).\n",
        if o.paired { "Paired (per position)" } else { "Unpaired (distributions of records)" },
        o.sizes.0,
        o.sizes.1,
        o.gap_initial,
        o.gap_final,
        removed(o.gap_initial, o.gap_final),
        o.floor,
        o.gap_final_unseen,
        removed(o.gap_initial, o.gap_final_unseen)
    );
    if o.gap_initial < o.floor_initial {
        let _ = writeln!(s, "**Below the sampling floor:** {}.\n", crate::below_floor(o.gap_initial, o.floor_initial));
    }
    if o.over_pairs {
        let _ = writeln!(
            s,
            "Both sides are the records of the pairs, each once per pair it is in (`--unpaired` with `--pairs`): the sets share the pairs' terrain mix.\n"
        );
    }
    if let Some((kept, of)) = o.terrain_mix {
        let _ = writeln!(
            s,
            "The sim side is {kept} records drawn from the {of} sim records per terrain, to the real set's terrain mix (the default with both label files; `--no-match-terrain-mix` compares the sets as they are).\n"
        );
    }
    let _ = writeln!(s, "Final sensor model (`sensor.json`): {}\n", o.model.summary());
    if o.record_kinds.differs() {
        let _ = writeln!(s, "**Warning: {}.**\n", o.record_kinds.sentence());
    } else {
        let _ = writeln!(s, "Terrain: {}.\n", o.record_kinds.sentence());
    }
}

/// Effects fitted at the edge of their box and tied steps, before the table.
fn warnings_md(s: &mut String, o: &Outcome) {
    let flagged: Vec<String> = o
        .steps
        .iter()
        .filter(|st| !st.at_edge.is_empty())
        .map(|st| format!("`{}` ({})", st.effect.name(), st.at_edge.join(", ")))
        .collect();
    if !flagged.is_empty() {
        let _ = writeln!(
            s,
            "**Warning: fitted at the edge of the search box:** {}. Each box was widened up to the effect's physical limits first; an effect still on the edge is only the closest one of the vocabulary, not the right one: read its parameters as a direction, not a measurement.\n",
            flagged.join(", ")
        );
    }
    let tied: Vec<String> = o
        .steps
        .iter()
        .enumerate()
        .filter(|(_, st)| !st.tied_with.is_empty())
        .map(|(k, st)| format!("step {} `{}` with {}", k + 1, st.effect.name(), tied_names(st)))
        .collect();
    if !tied.is_empty() {
        let _ = writeln!(
            s,
            "**Tied:** {}. The rival removes nearly as much of the gap in the named effect's place, the data does not order the named effect ahead of it (on all records and on each half of them), and on top of it the rival removes little: the two leave the same trace in these data, and the step names one of them, not the one.\n",
            tied.join("; ")
        );
    }
}

/// The steps table, why the search stopped, the re-fits and every step's candidates.
fn steps_md(s: &mut String, o: &Outcome) {
    let _ = writeln!(
        s,
        "## Steps\n\n| step | effect | parameters | at box edge | tied with | gap before | gap after | evidence |\n|---|---|---|---|---|---|---|---|"
    );
    for (k, st) in o.steps.iter().enumerate() {
        let p: Vec<String> = st.effect.params().iter().map(|(n, v)| format!("{n} = {v:.4}")).collect();
        let edge = if st.at_edge.is_empty() { "no".to_string() } else { format!("**{}**", st.at_edge.join(", ")) };
        let tie = if st.tied_with.is_empty() { "no".to_string() } else { format!("**{}**", tied_names(st)) };
        let _ = writeln!(
            s,
            "| {} | `{}` | {} | {edge} | {tie} | {:.3} | {:.3} | {} |",
            k + 1,
            st.effect.name(),
            p.join(", "),
            st.gap_before,
            st.gap_after,
            st.evidence
        );
    }
    let _ = writeln!(s, "\nStopped: {}.\n", o.stop);
    if !o.refits.is_empty() {
        let _ = writeln!(s, "Re-fitted, each with all other effects in place, before a step below the sampling floor and after naming (the final model has the last of each):\n");
        for r in &o.refits {
            let edge =
                if r.at_edge.is_empty() { String::new() } else { format!(" **at the edge of its box in {}**", r.at_edge.join(", ")) };
            let _ = writeln!(s, "- {} -> {}{edge}: gap {:.3} -> {:.3}", r.before, r.after, r.gap_before, r.gap_after);
        }
        let _ = writeln!(s);
    }
    if !o.steps.is_empty() {
        let _ = writeln!(s, "### Candidates at each step (share of the gap each removes on the fitting subsample)\n");
        for (k, st) in o.steps.iter().enumerate() {
            let r: Vec<String> = st.ranking.iter().map(|(e, f)| format!("{} {:.0}%", e.name(), 100.0 * f)).collect();
            let _ = writeln!(s, "{}. {}", k + 1, r.join(", "));
            for (e, why) in &st.refused {
                let _ = writeln!(s, "   - refused {e}: {why}");
            }
        }
        let _ = writeln!(s);
    }
}

/// The gap per term, start model against final model.
fn terms_md(s: &mut String, o: &Outcome) {
    let _ = writeln!(s, "## Where the gap is (per term, start model -> final model)\n\n| term | start | final |\n|---|---|---|");
    let (a, b) = (gap_terms(&o.stats[1], &o.stats[3]), gap_terms(&o.stats[2], &o.stats[3]));
    for ((n, x), (_, y)) in a.iter().zip(&b) {
        let _ = writeln!(s, "| {n} | {x:.3} | {y:.3} |");
    }
    if let Some([e0, e1, e2]) = o.eq71 {
        let _ = writeln!(
            s,
            "\nPaired equation 7.1 error (mean), reported beside the gap, not part of it (it grows when correct noise is added): sim as is {e0:.4}, start model {e1:.4}, final model {e2:.4}."
        );
    }
}

/// The gap and its terms per terrain.
fn terrains_md(s: &mut String, o: &Outcome) {
    if !o.terrains.is_empty() {
        let (h, sp) = if o.paired { ("mean residual", "residual sd") } else { ("mean height", "roughness") };
        let _ = writeln!(
            s,
            "\n## Per terrain\n\nEach cell: sim / model(sim) / real. Heights in mm; edges: share of steps between rows above 2 cm.\n\n| terrain | real records | missing | {h} | {sp} | edges | gap start | gap final |\n|---|---|---|---|---|---|---|---|"
        );
        let f = |v: [f64; 3], k: f64, d: usize| v.map(|x| format!("{:.*}", d, k * x)).join(" / ");
        for t in &o.terrains {
            let _ = writeln!(
                s,
                "| {} | {} | {} % | {} | {} | {} % | {:.3} | {:.3} |",
                t.terrain,
                t.records,
                f(t.missing, 100.0, 1),
                f(t.height, 1000.0, 1),
                f(t.spread, 1000.0, 1),
                f(t.edges, 100.0, 1),
                t.gap[0],
                t.gap[1]
            );
        }
        frames_md(s, o);
    }
}

/// The frame statistics per terrain, when the runs' steps counted.
fn frames_md(s: &mut String, o: &Outcome) {
    if o.terrains.iter().all(|t| t.frames.is_none()) {
        return;
    }
    let rcorr = if o.paired { "lag-1 correlation of the residual" } else { "lag-1 correlation of the change" };
    let _ = writeln!(
        s,
        "\n### Per terrain, in time\n\nConsecutive frames of the runs, the same ground matched by the motion between them. Each cell: sim / model(sim) / real (`-`: nothing to take it on, as persistence where a side misses no cell).\n\n| terrain | cells changing validity | P(missing at t+1 \\| missing at t) | mean \\|h(t+1) - h(t)\\| (mm) | {rcorr} |\n|---|---|---|---|---|"
    );
    let f =
        |v: [Option<f64>; 3], k: f64, d: usize| v.map(|x| x.map_or_else(|| "-".to_string(), |x| format!("{:.*}", d, k * x))).join(" / ");
    for t in &o.terrains {
        let Some(fr) = t.frames else { continue };
        let _ = writeln!(
            s,
            "| {} | {} % | {} | {} | {} |",
            t.terrain,
            f(fr.map(|x| x.flip), 100.0, 1),
            f(fr.map(|x| x.persist), 1.0, 2),
            f(fr.map(|x| x.dh), 1000.0, 1),
            f(fr.map(|x| x.rcorr), 1.0, 2)
        );
    }
}
