//! What sampling alone does to the gap. A perfect model still shows a gap
//! from its own random draws ([`draw_floor`]) and, unpaired, from which
//! records happen to be in each set ([`sampling_floor`], from two halves
//! of real). The halves ([`halves`]) are also the replicates at half the
//! size that a named effect's gain must hold on; the seeds of the draws
//! that a fit did not see (`other_draws`, `unseen_draws`) are here too.

use dem_core::distribution::{gap, Stats};
use dem_core::format::{Dem, Terrain};
use dem_sensor::SensorModel;

use crate::load::{pick, Sets};
use crate::measurement::{measure_at, summarise};
use dem_core::temporal::Step;
use dem_sensor::Moment;

/// Records per block of [`real_halves`]: neighbouring frames of a run
/// look alike, so they go to the same half.
const HALF_BLOCK: usize = 50;

/// Fewest real runs for halves of whole runs: with fewer, one run more or
/// less in a half is most of its difference, and blocks are dealt instead.
pub const MIN_RUNS_FOR_HALVES: usize = 8;

/// Two halves of the real records, for the sampling checks ([`halves`]).
pub fn real_halves(sets: &Sets) -> [Vec<usize>; 2] {
    halves(sets.real.len(), sets.real_runs.as_deref(), sets.real_terrain.as_deref())
}

/// Two halves of the sim records, dealt as [`real_halves`] deals real's,
/// so that sim half k against real half k is the comparison again at half
/// the size. Over pairs, sim record i is real record i's pair, and the
/// halves are real's.
pub fn sim_halves(sets: &Sets) -> [Vec<usize>; 2] {
    if sets.over_pairs {
        return real_halves(sets);
    }
    halves(sets.sim.len(), sets.sim_runs.as_deref(), sets.sim_terrain.as_deref())
}

/// Two halves of `n` records. The units
/// dealt are whole runs when the labels give each record's run
/// (`sequence`) and there are at least `MIN_RUNS_FOR_HALVES` (8) runs, else
/// blocks of consecutive records, so that neighbouring
/// frames of a run stay together: a run's first frames (the startup rows)
/// then go with the rest of it, not into one half. With terrain labels the
/// units are dealt per terrain (a run by the terrain of most of its
/// records), each to the half with fewer records of that terrain so far,
/// so both halves have the set's terrain mix: halves of 10 runs each differ
/// in stairs and pallets by chance, and an effect that only shows at steps
/// then "gains on one half and loses on the other" for that reason alone.
/// The deal is deterministic, so two sets with the same runs and terrains
/// in the same order (a sim and a real recording of the same poses) are
/// split alike.
pub fn halves(n: usize, runs: Option<&[u64]>, terrain: Option<&[Terrain]>) -> [Vec<usize>; 2] {
    halves_of_runs(n, runs, terrain, MIN_RUNS_FOR_HALVES)
}

/// [`halves`], dealing whole runs from `min_runs` runs on (the sampling
/// floor at half the size deals a half's runs as the whole set's were).
pub fn halves_of_runs(n: usize, runs: Option<&[u64]>, terrain: Option<&[Terrain]>, min_runs: usize) -> [Vec<usize>; 2] {
    let blocks = |idx: Vec<usize>| idx.chunks(HALF_BLOCK).map(<[usize]>::to_vec).collect::<Vec<_>>();
    // Runs in order of first appearance.
    let mut by_run: Vec<(u64, Vec<usize>)> = Vec::new();
    for (i, &r) in runs.iter().copied().flatten().enumerate() {
        match by_run.iter_mut().find(|(k, _)| *k == r) {
            Some((_, v)) => v.push(i),
            None => by_run.push((r, vec![i])),
        }
    }
    let units: Vec<Vec<usize>> = if by_run.len() >= min_runs.max(2) {
        by_run.into_iter().map(|(_, v)| v).collect()
    } else {
        // Blocks within each terrain's records, so a block has one terrain.
        match terrain {
            Some(t) => Terrain::ALL.iter().flat_map(|&k| blocks((0..n).filter(|&i| t[i] == k).collect())).collect(),
            None => blocks((0..n).collect()),
        }
    };
    let terrain_of = |u: &[usize]| -> usize {
        let Some(t) = terrain else { return 0 };
        let count = |k: Terrain| u.iter().filter(|&&i| t[i] == k).count();
        (0..Terrain::ALL.len()).max_by_key(|&j| (count(Terrain::ALL[j]), usize::MAX - j)).unwrap_or(0)
    };
    let mut halves = [Vec::new(), Vec::new()];
    let mut count = vec![[0usize; 2]; Terrain::ALL.len()];
    for u in units {
        let c = &mut count[terrain_of(&u)];
        let h = usize::from(c[1] < c[0]);
        c[h] += u.len();
        halves[h].extend(u);
    }
    halves.iter_mut().for_each(|h| h.sort_unstable());
    halves
}

/// The gap two halves of real show from sampling alone ([`real_halves`]),
/// scaled to the sizes compared: var of a difference of means goes as
/// 1/n_a + 1/n_b, so floor = split gap x (1/n_sim + 1/n_real) / (4/n_real).
pub fn sampling_floor(sets: &Sets) -> f64 {
    let n = sets.real.len();
    if n < 100 {
        return 0.0;
    }
    let [a, b] = real_halves(sets);
    let side = |idx: &[usize]| {
        let sim = sets.paired.then(|| pick(&sets.sim, idx));
        let steps = sets.real_steps_in(idx);
        summarise(&pick(&sets.real, idx), sim.as_deref(), steps.as_deref())
    };
    let split = gap(&side(&a), &side(&b));
    split * (1.0 / sets.sim.len() as f64 + 1.0 / n as f64) / (4.0 / n as f64)
}

/// The gap a perfect model would still show from its own random draws:
/// model(sim) with the run's seed against model(sim) with another seed.
pub fn draw_floor(model: &SensorModel, sim: &[Dem], moments: Option<&[Moment]>, steps: Option<&[Step]>, paired: bool, seed: u64) -> f64 {
    let [(_, a), (_, b)] = two_draws(model, sim, moments, steps, paired, seed);
    gap(&a, &b)
}

/// model(sim) and its statistics with the draws of `seed` and of
/// `other_draws`: the two outputs [`draw_floor`] compares.
pub fn two_draws(
    model: &SensorModel,
    sim: &[Dem],
    moments: Option<&[Moment]>,
    steps: Option<&[Step]>,
    paired: bool,
    seed: u64,
) -> [(Vec<Dem>, Stats); 2] {
    [measure_at(model, sim, moments, steps, paired, seed), measure_at(model, sim, moments, steps, paired, other_draws(seed))]
}

/// The seed of a model's second set of random draws: the draw floor and
/// the check that an effect's gain repeats both use it.
pub(crate) fn other_draws(seed: u64) -> u64 {
    dem_core::seeded::mix(seed ^ 0xf100_f100)
}

/// Seed of draws that neither the fits nor the checks use: the final
/// model's gap on them is the one a user gets applying it with a new seed.
pub(crate) fn unseen_draws(seed: u64) -> u64 {
    dem_core::seeded::mix(seed ^ 0x0b5e_57ed)
}

/// What a gap below the sampling floor means, in one sentence (the log's
/// first line and report.md say it).
pub fn below_floor(gap: f64, floor: f64) -> String {
    format!(
        "the gap is below the sampling floor ({:.0}% of it): a perfect model's own random draws or, unpaired, two halves of real \
         differ as much, so what separates the sets may be sampling; an effect is named only where it also helps on other draws \
         and on both halves, and more records (runs) lower the floor",
        100.0 * gap / floor
    )
}

/// One half of a comparison (`comparison_halves`): sim half k against
/// real half k.
pub(crate) struct Half {
    /// Its sim-side records.
    pub sim: Vec<usize>,
    /// Their runs' steps (positions in `sim`), when the frame terms count.
    pub steps: Option<Vec<Step>>,
    /// Real's statistics on it.
    pub real: Stats,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The halves deal whole runs, per terrain, each half getting its share
    /// of every terrain; two sets with the same runs and terrains (a sim
    /// and a real recording of the same poses) are split alike, and a sim
    /// side without runs falls back to blocks.
    #[test]
    fn halves_deal_whole_runs_per_terrain_and_split_like_sets_alike() {
        use Terrain::{Flat, StairsUp};
        // 12 runs of 30 records: runs 0-3 stairs, the rest flat.
        let runs: Vec<u64> = (0..360).map(|i| i / 30).collect();
        let terrain: Vec<Terrain> = runs.iter().map(|&r| if r < 4 { StairsUp } else { Flat }).collect();
        let [a, b] = halves(360, Some(&runs), Some(&terrain));
        assert_eq!((a.len(), b.len()), (180, 180));
        for h in [&a, &b] {
            assert!(h.iter().all(|&i| h.contains(&(i - i % 30))), "whole runs");
            assert_eq!(h.iter().filter(|&&i| terrain[i] == StairsUp).count(), 60, "half the stairs");
        }
        assert_eq!(halves(360, Some(&runs), Some(&terrain)), [a, b]);
        // Too few runs: blocks of HALF_BLOCK consecutive records.
        let few: Vec<u64> = (0..360).map(|i| i / 120).collect();
        let [a, b] = halves(360, Some(&few), None);
        assert_eq!((a[..HALF_BLOCK].to_vec(), b[..HALF_BLOCK].to_vec()), ((0..50).collect(), (50..100).collect()));
    }
}
