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
                 files with --match-terrain-mix, or --pairs; dem-filter --unique keeps one of many identical level records)"
            )
        } else {
            format!("the sets hold the same kinds of terrain: {shares}")
        }
    }
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
}
