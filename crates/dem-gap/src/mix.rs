//! What terrain the two sets hold, read from the heights alone: the share
//! of level records (the sd of a record's valid heights under
//! [`LEVEL_SD`]) and of records with tall terrain (over [`TALL_SD`]).
//! Sensor effects change neither share much (noise and a miscalibrated
//! mount add millimetres to a record's sd, holes remove cells), so sets
//! whose shares differ by more than [`MIX_MARGIN`] hold different terrain;
//! then an effect that moves whole records (`tilt`'s offset, `shake`,
//! `bias`) can stand in for the terrain, and the report says so whatever
//! effect was named. Works without labels, where the fit cannot draw sim
//! to real's terrain mix.

use dem_core::distribution::mean_sd;
use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};

/// A record is level when its valid heights' sd is below this (m).
pub const LEVEL_SD: f64 = 0.02;
/// A record holds tall terrain when its valid heights' sd is above this (m).
pub const TALL_SD: f64 = 0.1;
/// Shares that differ by more than this (absolute) are flagged.
pub const MIX_MARGIN: f64 = 0.1;

/// The shares of level and of tall records, sim and real.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordKinds {
    /// Share of level records: [sim, real].
    pub level: [f64; 2],
    /// Share of records with tall terrain: [sim, real].
    pub tall: [f64; 2],
}

impl RecordKinds {
    /// True when the sets hold different terrain.
    pub fn differs(&self) -> bool {
        (self.level[0] - self.level[1]).abs() > MIX_MARGIN || (self.tall[0] - self.tall[1]).abs() > MIX_MARGIN
    }

    /// One sentence: the shares, and when they differ what that means.
    pub fn sentence(&self) -> String {
        let shares = format!(
            "level records (height sd under {:.0} cm) sim {:.1}% vs real {:.1}%, records with tall terrain (sd over {:.0} cm) sim {:.1}% vs real {:.1}%",
            100.0 * LEVEL_SD,
            100.0 * self.level[0],
            100.0 * self.level[1],
            100.0 * TALL_SD,
            100.0 * self.tall[0],
            100.0 * self.tall[1]
        );
        if self.differs() {
            format!(
                "the sets hold different terrain: {shares}. No sensor effect makes or removes terrain, so the gap is partly terrain, and effects that move \
                 whole records (tilt, shake, bias) can stand in for it: read the model as unreliable, and compare sets of the same terrain (both label \
                 files, which draw sim to real's mix, or --pairs; dem-filter --unique keeps one of many identical level records)"
            )
        } else {
            format!("the sets hold the same kinds of terrain: {shares}")
        }
    }
}

/// An effect that moves whole records may make the model's level records
/// spread at most this many times as much as real's (plus
/// [`LEVEL_PLANE_SLACK`]).
pub const LEVEL_PLANE_RATIO: f64 = 1.5;
/// Slack (m) of [`LEVEL_PLANE_RATIO`]: a millimetre, below what a sensor
/// resolves on level ground and above a float's rounding of the fit.
pub const LEVEL_PLANE_SLACK: f64 = 0.001;

/// How much level records move as a whole, model(sim) against real:
/// each level record's valid cells fitted by the plane h = m + a x + b y,
/// and the spread of the planes over the records, sqrt(var m + var a +
/// var b) (m: the slopes as the heights they give 1 m away). On level
/// ground a record-wide offset or tilt (`bias`, `tilt`, `shake`) shows
/// directly, and no terrain stands in for it; unpaired, it is the one
/// place where the data says whether the sensor moves whole records.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LevelPlanes {
    /// Spread of the model's level records (sim's level records after the model).
    pub model: f64,
    /// Spread of real's level records.
    pub real: f64,
    /// Level records: model side, real side.
    pub records: (usize, usize),
    /// What was fitted: `level records` (unpaired) or `the pairs'
    /// residuals` (paired).
    pub what: &'static str,
}

impl LevelPlanes {
    /// The spreads of the level records of `sim` as `out` (model(sim),
    /// aligned with `sim`) has them and of `real`'s; None when either side
    /// has fewer than 10 level records.
    pub fn of(sim: &[Dem], out: &[Dem], real: &[Dem]) -> Option<LevelPlanes> {
        let level = |d: &Dem| height_sd(d).is_some_and(|s| s < LEVEL_SD);
        let model: Vec<[f64; 3]> = sim.iter().zip(out).filter(|(s, _)| level(s)).filter_map(|(_, o)| plane(o)).collect();
        let real: Vec<[f64; 3]> = real.iter().filter(|d| level(d)).filter_map(plane).collect();
        LevelPlanes::spreads(&model, &real, "level records")
    }

    /// Paired: the planes of each pair's residual (the record less its
    /// sim record, on the cells valid in both), of model(sim) (`out`,
    /// aligned with `sim`) and of `real` (aligned too). A sensor that moves
    /// whole records moves the residuals' planes, on every terrain; one
    /// that does not leaves them where its noise puts them.
    pub fn of_residuals(sim: &[Dem], out: &[Dem], real: &[Dem]) -> Option<LevelPlanes> {
        let residual = |d: &Dem, s: &Dem| {
            let mut r = dem_core::format::empty_dem();
            for row in 0..GRID_ROWS {
                for c in (0..COLS).filter(|&c| d.is_valid(row, c) && s.is_valid(row, c)) {
                    r.set_valid(row, c, d.height(row, c) - s.height(row, c));
                }
            }
            plane(&r)
        };
        let model: Vec<[f64; 3]> = out.iter().zip(sim).filter_map(|(o, s)| residual(o, s)).collect();
        let real: Vec<[f64; 3]> = real.iter().zip(sim).filter_map(|(d, s)| residual(d, s)).collect();
        LevelPlanes::spreads(&model, &real, "the pairs' residuals")
    }

    /// The spreads of two sets of planes; None when either has fewer than 10.
    fn spreads(model: &[[f64; 3]], real: &[[f64; 3]], what: &'static str) -> Option<LevelPlanes> {
        (model.len() >= 10 && real.len() >= 10).then(|| LevelPlanes {
            model: plane_spread(model),
            real: plane_spread(real),
            records: (model.len(), real.len()),
            what,
        })
    }

    /// Why an effect that moves whole records does not belong in the
    /// model: its level records spread more than real's allow.
    pub fn too_wide(&self) -> Option<String> {
        (self.model > LEVEL_PLANE_RATIO * self.real + LEVEL_PLANE_SLACK).then(|| {
            format!(
                "it moves {} as a whole by {:.1} mm (the spread of their fitted planes, {} records) where real's move {:.1} mm ({} records): \
                 the sensor does not move whole records that much, so the gap it fills is another effect's",
                self.what,
                1000.0 * self.model,
                self.records.0,
                1000.0 * self.real,
                self.records.1
            )
        })
    }
}

/// The plane h = m + a x + b y (x, y the cells' centres, m) fitted to the
/// valid cells of `d` by least squares; None with a degenerate layout
/// (fewer than three cells, or all in one row or column).
fn plane(d: &Dem) -> Option<[f64; 3]> {
    use dem_core::format::{col_center_y, row_center_x};
    // Normal equations of [1 x y] against h, centred for conditioning.
    let cells: Vec<(f64, f64, f64)> = (0..GRID_ROWS)
        .flat_map(|r| (0..COLS).map(move |c| (r, c)))
        .filter(|&(r, c)| d.is_valid(r, c))
        .map(|(r, c)| (row_center_x(r), col_center_y(c), d.height(r, c) as f64))
        .collect();
    if cells.len() < 3 {
        return None;
    }
    let n = cells.len() as f64;
    let (mx, my, mh) = cells.iter().fold((0.0, 0.0, 0.0), |a, &(x, y, h)| (a.0 + x / n, a.1 + y / n, a.2 + h / n));
    let (mut sxx, mut syy, mut sxy, mut sxh, mut syh) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(x, y, h) in &cells {
        let (x, y, h) = (x - mx, y - my, h - mh);
        sxx += x * x;
        syy += y * y;
        sxy += x * y;
        sxh += x * h;
        syh += y * h;
    }
    let det = sxx * syy - sxy * sxy;
    if det <= 1e-9 * (sxx * syy).max(1e-12) {
        return None;
    }
    let a = (sxh * syy - syh * sxy) / det;
    let b = (syh * sxx - sxh * sxy) / det;
    // The height at C (x = y = 0).
    Some([mh - a * mx - b * my, a, b])
}

/// sqrt of the summed variances of the planes' three terms.
fn plane_spread(planes: &[[f64; 3]]) -> f64 {
    (0..3)
        .map(|k| {
            let v: Vec<f32> = planes.iter().map(|p| p[k] as f32).collect();
            mean_sd(&v).1.powi(2)
        })
        .sum::<f64>()
        .sqrt()
}

/// The sd of a record's valid heights; `None` when no cell is valid.
fn height_sd(d: &Dem) -> Option<f64> {
    let h: Vec<f32> = (0..GRID_ROWS)
        .flat_map(|r| (0..COLS).map(move |c| (r, c)))
        .filter(|&(r, c)| d.is_valid(r, c))
        .map(|(r, c)| d.height(r, c))
        .collect();
    (!h.is_empty()).then(|| mean_sd(&h).1)
}

/// Shares of level and tall records among those with a valid cell.
fn shares(set: &[Dem]) -> (f64, f64) {
    let sds: Vec<f64> = set.iter().filter_map(height_sd).collect();
    let n = sds.len().max(1) as f64;
    (sds.iter().filter(|&&s| s < LEVEL_SD).count() as f64 / n, sds.iter().filter(|&&s| s > TALL_SD).count() as f64 / n)
}

/// The record kinds of `sim` (as it comes, before any effect) and `real`.
pub fn record_kinds(sim: &[Dem], real: &[Dem]) -> RecordKinds {
    let (s, r) = (shares(sim), shares(real));
    RecordKinds { level: [s.0, r.0], tall: [s.1, r.1] }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::format::empty_dem;

    fn terrain(step: f32) -> Dem {
        let mut d = empty_dem();
        for r in 0..GRID_ROWS {
            for c in 0..COLS {
                d.set_valid(r, c, if r >= 10 { step } else { 0.0 });
            }
        }
        d
    }

    /// A level record has sd 0, a 0.3 m step sd 0.15 (tall), a 0.1 m step
    /// neither; half level against none level is flagged, the same sets
    /// are not, and a record with no valid cell counts for neither.
    #[test]
    fn level_and_tall_records_are_counted_and_a_different_mix_is_flagged() {
        let (level, tall, mid) = (terrain(0.0), terrain(0.3), terrain(0.1));
        assert!((height_sd(&tall).unwrap() - 0.15).abs() < 1e-6);
        assert_eq!(height_sd(&empty_dem()), None);
        let sim = vec![tall, mid, tall, mid, empty_dem()];
        let real = vec![level, tall, level, mid];
        let k = record_kinds(&sim, &real);
        assert_eq!(k, RecordKinds { level: [0.0, 0.5], tall: [0.5, 0.25] });
        assert!(
            k.differs() && k.sentence().contains("different terrain") && k.sentence().contains("sim 0.0% vs real 50.0%"),
            "{}",
            k.sentence()
        );
        let same = record_kinds(&real, &real);
        assert!(!same.differs() && same.sentence().contains("the same kinds"), "{}", same.sentence());
    }

    /// A plane h = m + a x + b y is fitted exactly, holes or not; level
    /// records tilted by 0.01 rad spread by about that, and are refused
    /// against level records that do not move; tilted alike, they pass.
    #[test]
    fn level_records_planes_are_fitted_and_a_record_wide_tilt_is_seen() {
        use dem_core::format::{col_center_y, row_center_x};
        let tilted = |m: f64, a: f64, b: f64| {
            let mut d = empty_dem();
            for r in 0..GRID_ROWS {
                for c in 0..COLS {
                    if (r + c) % 7 != 3 {
                        d.set_valid(r, c, (m + a * row_center_x(r) + b * col_center_y(c)) as f32);
                    }
                }
            }
            d
        };
        let p = plane(&tilted(-0.07, 0.01, -0.005)).unwrap();
        assert!((p[0] + 0.07).abs() < 1e-6 && (p[1] - 0.01).abs() < 1e-6 && (p[2] + 0.005).abs() < 1e-6, "{p:?}");
        let level: Vec<Dem> = (0..40).map(|_| tilted(-0.07, 0.0, 0.0)).collect();
        let rocked: Vec<Dem> = (0..40).map(|i| tilted(-0.07, if i % 2 == 0 { 0.01 } else { -0.01 }, 0.0)).collect();
        let l = LevelPlanes::of(&level, &rocked, &level).unwrap();
        assert!((l.model - 0.01).abs() < 1e-4 && l.real < 1e-6 && l.records == (40, 40), "{l:?}");
        let why = l.too_wide().unwrap();
        assert!(why.contains("by 10.0 mm") && why.contains("real's move 0.0 mm"), "{why}");
        assert_eq!(LevelPlanes::of(&level, &rocked, &rocked).unwrap().too_wide(), None);
        // Paired, the residuals' planes: rocked against sim, real not.
        let paired = LevelPlanes::of_residuals(&level, &rocked, &level).unwrap();
        assert!((paired.model - 0.01).abs() < 1e-4 && paired.real < 1e-6, "{paired:?}");
        assert!(paired.too_wide().unwrap().contains("moves the pairs' residuals as a whole"));
        assert_eq!(LevelPlanes::of_residuals(&level, &rocked, &rocked).unwrap().too_wide(), None);
        assert_eq!(LevelPlanes::of(&level[..5], &rocked[..5], &level), None, "too few level records");
    }
}
