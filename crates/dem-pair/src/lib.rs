//! Pairs of sim keys and real records (the thesis's paired data): one sim
//! key to one or many real records, found by pose (labels) or by content
//! (the nearest sim DEMs), then split into train and val by key.
//!
//! Content distance of a sim DEM x to a real DEM y is the height part of
//! equation 7.1 over y's valid cells:
//!
//! ```text
//! d(y, x) = 1/100 * sum over cells with y_m > 0 of (y_h - x_h)^2
//! ```
//!
//! (the mask term is the same for every all-valid sim candidate, so it
//! cannot rank them).

pub mod expand;
pub mod pairing;

use std::collections::{BTreeMap, BTreeSet, HashMap};

use rayon::prelude::*;

use dem_core::format::{Dem, GRID_CELLS};
use dem_core::seeded::record_uniform;
use dem_core::table::{Label, Pair, Split};

/// Index of the first record identical (bit for bit) to each record: the
/// sim keys, so duplicates pair as one key.
pub fn first_occurrence(records: &[Dem]) -> Vec<u64> {
    let mut seen: HashMap<&[u32], u64> = HashMap::with_capacity(records.len());
    records.iter().enumerate().map(|(i, d)| *seen.entry(bytemuck::cast_slice(d.as_slice())).or_insert(i as u64)).collect()
}

/// Pose tolerances.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseRule {
    /// Largest distance between positions (m).
    pub max_dist: f64,
    /// Largest heading difference (rad).
    pub max_yaw: f64,
    /// Pair only records of the same sequence.
    pub same_sequence: bool,
}

/// A found pair: sim index, real index, distance.
pub type Found = (u64, u64, f64);

/// Pairs by pose: every sim record of the same terrain (and sequence, if
/// asked) within the tolerances of a real record's pose. The distance is
/// the position distance. Labels without x, y or yaw are an error.
pub fn by_pose(sim: &[Label], real: &[Label], rule: PoseRule) -> Result<Vec<Found>, String> {
    let pose = |l: &Label, what: &str| -> Result<(f64, f64, f64), String> {
        match (l.x, l.y, l.yaw) {
            (Some(x), Some(y), Some(yaw)) => Ok((x, y, yaw)),
            _ => Err(format!("{what} labels row {} has no x, y, yaw for pose pairing", l.index)),
        }
    };
    // Grid of sim positions with cells as large as the tolerance: a match
    // lies in the 3 x 3 cells around the real position.
    let cell = rule.max_dist.max(1e-6);
    let key = |x: f64, y: f64| ((x / cell).floor() as i64, (y / cell).floor() as i64);
    let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (i, l) in sim.iter().enumerate() {
        let (x, y, _) = pose(l, "sim")?;
        grid.entry(key(x, y)).or_default().push(i);
    }
    let mut out = Vec::new();
    for r in real {
        let (x, y, yaw) = pose(r, "real")?;
        let (cx, cy) = key(x, y);
        let mut found: Vec<Found> = Vec::new();
        for gx in cx - 1..=cx + 1 {
            for gy in cy - 1..=cy + 1 {
                for &i in grid.get(&(gx, gy)).map_or(&[][..], Vec::as_slice) {
                    let s = &sim[i];
                    let (sx, sy, syaw) = pose(s, "sim")?;
                    let dist = ((sx - x).powi(2) + (sy - y).powi(2)).sqrt();
                    let dyaw = (syaw - yaw + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
                    if s.terrain == r.terrain
                        && dist <= rule.max_dist
                        && dyaw.abs() <= rule.max_yaw
                        && (!rule.same_sequence || s.sequence == r.sequence)
                    {
                        found.push((s.index, r.index, dist));
                    }
                }
            }
        }
        found.sort_by_key(|f| f.0);
        out.extend(found);
    }
    Ok(out)
}

/// Masked squared height sum over cells `range` of a sim record
/// (`real_h` the real heights, `mask` 1 on its valid cells, 0 elsewhere).
#[inline]
fn masked_sum(real_h: &[f32], mask: &[f32], sim_h: &[f32]) -> f32 {
    // Four lanes over chunks of four: the shape LLVM turns into SIMD.
    let mut acc = [0.0f32; 4];
    for ((a, b), m) in real_h.chunks_exact(4).zip(sim_h.chunks_exact(4)).zip(mask.chunks_exact(4)) {
        for l in 0..4 {
            let d = (a[l] - b[l]) * m[l];
            acc[l] += d * d;
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}

/// Masked squared height distance of `sim_h` to a real record, /100.
#[cfg(test)]
fn masked_distance(real_h: &[f32; GRID_CELLS], mask: &[f32; GRID_CELLS], sim_h: &[f32; GRID_CELLS]) -> f32 {
    masked_sum(real_h, mask, sim_h) / GRID_CELLS as f32
}

/// Cells summed before checking whether a candidate can still make the k
/// best (a partial sum only grows).
const PRUNE_AFTER: usize = 40;

fn heights(d: &Dem) -> [f32; GRID_CELLS] {
    std::array::from_fn(|i| d[2 * i])
}

/// Pairs by content: for each real record, the `k` sim keys nearest by the
/// masked height distance, within `max_dist`. `keys` are the sim indices to
/// consider (e.g. unique keys). Parallel over real records; ties go to the
/// lower sim index, so the result is deterministic.
pub fn by_content(sim: &[Dem], keys: &[u64], real: &[Dem], k: usize, max_dist: f64) -> Vec<Found> {
    let sim_h: Vec<[f32; GRID_CELLS]> = keys.iter().map(|&i| heights(&sim[i as usize])).collect();
    real.par_iter()
        .enumerate()
        .flat_map_iter(|(ri, y)| {
            let yh = heights(y);
            let mask: [f32; GRID_CELLS] = std::array::from_fn(|i| if y[2 * i + 1] > 0.0 { 1.0 } else { 0.0 });
            // The k best so far, sorted by (distance, key position).
            let mut best: Vec<(f32, usize)> = Vec::with_capacity(k + 1);
            for (j, sh) in sim_h.iter().enumerate() {
                let worst = if best.len() < k { f32::INFINITY } else { best[best.len() - 1].0 * GRID_CELLS as f32 };
                let head = masked_sum(&yh[..PRUNE_AFTER], &mask[..PRUNE_AFTER], &sh[..PRUNE_AFTER]);
                if head >= worst {
                    continue;
                }
                let d = (head + masked_sum(&yh[PRUNE_AFTER..], &mask[PRUNE_AFTER..], &sh[PRUNE_AFTER..])) / GRID_CELLS as f32;
                if best.len() < k || d < best[best.len() - 1].0 {
                    let at = best.partition_point(|b| b.0 <= d);
                    best.insert(at, (d, j));
                    best.truncate(k);
                }
            }
            best.into_iter().filter(move |b| f64::from(b.0) <= max_dist).map(move |(d, j)| (keys[j], ri as u64, f64::from(d)))
        })
        .collect()
}

/// Train or val for a sim key: a fixed random draw per (seed, key), so a
/// key never lands in both halves and the split is stable as data grows.
pub fn split_of(seed: u64, sim_key: u64, val_fraction: f64) -> Split {
    if record_uniform(seed, sim_key) < val_fraction {
        Split::Val
    } else {
        Split::Train
    }
}

/// The pairs CSV's rows from what a method found: every sim index mapped to
/// its key (`keys[i]`, the first identical record; none: itself), repeated
/// (key, real) pairs kept once with their smallest distance, each key's
/// split drawn by [`split_of`]; sorted by (key, real).
pub fn pair_rows(found: Vec<Found>, keys: Option<&[u64]>, seed: u64, val_fraction: f64) -> Vec<Pair> {
    let mut pairs: BTreeMap<(u64, u64), f64> = BTreeMap::new();
    for (s, r, d) in found {
        let key = keys.and_then(|k| k.get(s as usize).copied()).unwrap_or(s);
        pairs.entry((key, r)).and_modify(|e| *e = e.min(d)).or_insert(d);
    }
    pairs
        .into_iter()
        .map(|((s, r), d)| Pair { sim_index: s, real_index: r, split: Some(split_of(seed, s, val_fraction)), distance: Some(d) })
        .collect()
}

/// Sim keys and pairs per (terrain, split) for the report: terrain from the
/// sim labels (`all` without them), split `train` or `val`.
pub fn counts(rows: &[Pair], labels: Option<&[Label]>) -> BTreeMap<(String, &'static str), (usize, u64)> {
    let mut per: BTreeMap<(String, &'static str), (BTreeSet<u64>, u64)> = BTreeMap::new();
    for p in rows {
        let terrain = labels.and_then(|l| l.get(p.sim_index as usize)).map_or("all".into(), |l| l.terrain.to_string());
        let split = if p.split == Some(Split::Val) { "val" } else { "train" };
        let e = per.entry((terrain, split)).or_default();
        e.0.insert(p.sim_index);
        e.1 += 1;
    }
    per.into_iter().map(|(k, (keys, n))| (k, (keys.len(), n))).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::format::{empty_dem, DemCells, Terrain};

    #[test]
    fn pair_rows_map_to_keys_keep_the_closest_and_split_by_key() {
        // Sim 3 is a copy of sim 1 (key 1); real 7 found from both.
        let keys = [0, 1, 2, 1];
        let found = vec![(3, 7, 0.2), (1, 7, 0.5), (0, 5, 0.1), (2, 5, 0.3)];
        let rows = pair_rows(found, Some(&keys), 4, 0.5);
        let got: Vec<(u64, u64, f64)> = rows.iter().map(|p| (p.sim_index, p.real_index, p.distance.unwrap())).collect();
        assert_eq!(got, [(0, 5, 0.1), (1, 7, 0.2), (2, 5, 0.3)]);
        for p in &rows {
            assert_eq!(p.split, Some(split_of(4, p.sim_index, 0.5)));
        }
        let c = counts(&rows, None);
        let total: u64 = c.values().map(|v| v.1).sum();
        assert_eq!(total, 3);
        assert!(c.keys().all(|(t, _)| t == "all"));
    }
    use dem_core::metric::dem_error;

    fn dem(h: f32) -> Dem {
        let mut d = empty_dem();
        for r in 0..20 {
            for c in 0..5 {
                d.set_valid(r, c, h + 0.01 * r as f32);
            }
        }
        d
    }

    #[test]
    fn content_distance_is_the_height_part_of_equation_7_1() {
        let mut y = dem(0.0);
        y.set_missing(3, 3);
        let x = dem(0.05);
        let yh = heights(&y);
        let mask: [f32; GRID_CELLS] = std::array::from_fn(|i| if y[2 * i + 1] > 0.0 { 1.0 } else { 0.0 });
        let d = masked_distance(&yh, &mask, &heights(&x));
        // Equation 7.1 minus its mask term: one missing cell against a valid one is (−1 − 1)^2 / 100.
        let expected = dem_error(&y, &x) - 4.0 / 100.0;
        assert!((f64::from(d) - expected).abs() < 1e-7, "{d} {expected}");
    }

    #[test]
    fn content_pairs_pick_the_k_nearest_within_range() {
        let sim: Vec<Dem> = [0.0, 0.1, 0.02, 0.5].iter().map(|&h| dem(h)).collect();
        let real = vec![dem(0.015)];
        let keys: Vec<u64> = (0..4).collect();
        let found = by_content(&sim, &keys, &real, 2, 1.0);
        assert_eq!(found.iter().map(|f| f.0).collect::<Vec<_>>(), vec![2, 0]);
        let tight = by_content(&sim, &keys, &real, 2, 0.0001);
        assert_eq!(tight.len(), 1);
    }

    #[test]
    fn duplicates_share_the_first_key() {
        let sim = vec![dem(0.0), dem(0.1), dem(0.0)];
        assert_eq!(first_occurrence(&sim), vec![0, 1, 0]);
    }

    #[test]
    fn pose_pairs_respect_terrain_sequence_and_tolerances() {
        let l = |index, terrain, x: f64, seq| Label {
            index,
            terrain,
            x: Some(x),
            y: Some(0.0),
            yaw: Some(0.0),
            sequence: Some(seq),
            time: None,
        };
        let sim =
            vec![l(0, Terrain::Flat, 1.0, 0), l(1, Terrain::Flat, 1.03, 1), l(2, Terrain::Pallet, 1.0, 0), l(3, Terrain::Flat, 1.2, 0)];
        let real = vec![l(0, Terrain::Flat, 1.01, 0)];
        let rule = PoseRule { max_dist: 0.05, max_yaw: 0.1, same_sequence: false };
        let ids = |f: Vec<Found>| f.iter().map(|p| p.0).collect::<Vec<_>>();
        assert_eq!(ids(by_pose(&sim, &real, rule).unwrap()), vec![0, 1]);
        assert_eq!(ids(by_pose(&sim, &real, PoseRule { same_sequence: true, ..rule }).unwrap()), vec![0]);
    }

    #[test]
    fn split_is_by_key_and_near_the_fraction() {
        let val = (0..10_000).filter(|&k| split_of(7, k, 0.3) == Split::Val).count();
        assert!((2_800..3_200).contains(&val), "{val}");
        assert_eq!(split_of(7, 42, 0.3), split_of(7, 42, 0.3));
    }
}
