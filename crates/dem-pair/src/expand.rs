//! `dem-pair expand`: one record per pair, so a random sensor model is drawn
//! once per pair, at the pair's own time.
//!
//! A content-matched sim key stands for many measured records (on `make
//! demo`'s data, the one flat sim key for 347 of them), and `dem-filter
//! --unique` keeps the labels of the key's *first* pose, so its `time` is
//! that pose's (0.0 for the flat key: a startup frame). A model with a
//! time-based effect (`startup`) fitted or applied on the keys then blinds
//! the key for every partner, and one random draw stands for all of them.
//! Expanded, pair i is sim record i and real record i of the output: the
//! key's DEM once per pair, labelled with the key's terrain and the *real
//! partner's* pose, sequence and time (the pose the pair stands for), so
//! dem-gap fits and dem-sensor / dem-apply draw per pair. With pairs 1:1 by
//! pose the expansion is the pairs' records in pairs order.
//!
//! Outputs (in `--out`): `sim.npy`, `real.npy`, `pairs.csv` (`i,i,split[,distance]`),
//! and with labels `sim_labels.csv` and `real_labels.csv`. Nothing is
//! written unless every input checks out. Without labels, label files an
//! earlier expansion left in `--out` are removed: they describe other
//! records, and a fit that read them would pair times with the wrong DEMs.

use std::path::Path;

use dem_core::npy::{self, ByIndex};
use dem_core::table::{self, Label, Pair, RowWriter, Split};
use dem_core::DemError;

/// What to expand.
#[derive(Debug, Clone)]
pub struct ExpandConfig {
    /// Pairs CSV.
    pub pairs: String,
    /// Sim NPY the pairs index.
    pub sim: String,
    /// Real NPY the pairs index.
    pub real: String,
    /// Labels of the sim file (terrain of each pair's output sim record).
    pub sim_labels: Option<String>,
    /// Labels of the real file (pose, sequence and time of each pair).
    pub real_labels: Option<String>,
    /// Only the pairs of this split.
    pub split: Option<Split>,
    /// Output folder.
    pub out: String,
}

/// What was written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Expanded {
    /// Pairs written (records in each NPY).
    pub pairs: u64,
    /// Distinct sim records among them.
    pub sim_keys: u64,
    /// Label files of an earlier expansion removed (run without labels).
    pub stale_removed: Vec<String>,
}

/// The labels row of an expanded pair's sim record: the sim's terrain, the
/// real partner's pose, sequence and time where the real labels have them
/// (else the sim's).
pub fn pair_label(index: u64, sim: Option<&Label>, real: Option<&Label>) -> Option<Label> {
    let base = sim.or(real)?;
    let pose = real.unwrap_or(base);
    Some(Label {
        index,
        terrain: base.terrain,
        x: pose.x.or(base.x),
        y: pose.y.or(base.y),
        yaw: pose.yaw.or(base.yaw),
        sequence: pose.sequence.or(base.sequence),
        time: pose.time.or(base.time),
    })
}

/// Expand the pairs of `cfg` into one record per pair (module docs), in
/// the existing folder `cfg.out`.
pub fn run(cfg: &ExpandConfig) -> anyhow::Result<Expanded> {
    let all = table::read_pairs_for(&cfg.pairs, cfg.split)?;
    // Stdin (one input at most) is held whole: the pairs may name any record.
    let (mut sim, mut real) = (ByIndex::open(&cfg.sim, |_| true)?, ByIndex::open(&cfg.real, |_| true)?);
    for (n, p) in all.iter().enumerate() {
        for (index, src, file, col) in [(p.sim_index, &sim, &cfg.sim, "sim_index"), (p.real_index, &real, &cfg.real, "real_index")] {
            if index >= src.len() {
                return Err(DemError::Table {
                    path: cfg.pairs.clone(),
                    line: n as u64 + 2,
                    reason: format!("{col} {index} is past the end of {file} ({} records)", src.len()),
                }
                .into());
            }
        }
    }
    let kept: Vec<&Pair> = all.iter().filter(|p| cfg.split.is_none() || p.split == cfg.split).collect();
    if kept.is_empty() {
        return Err(table::no_pairs(&cfg.pairs, cfg.split, "expand").into());
    }
    let sim_labels = cfg.sim_labels.as_deref().map(table::read_labels).transpose()?;
    let real_labels = cfg.real_labels.as_deref().map(table::read_labels).transpose()?;
    for (labels, path, records, file) in
        [(&sim_labels, &cfg.sim_labels, sim.len(), &cfg.sim), (&real_labels, &cfg.real_labels, real.len(), &cfg.real)]
    {
        if let (Some(l), Some(p)) = (labels, path) {
            table::check_labels_cover(p, l.len(), file, records)?;
        }
    }

    let path = |name: &str| Path::new(&cfg.out).join(name).to_string_lossy().into_owned();
    let (mut sim_out, mut real_out) = (npy::create(&path("sim.npy"))?, npy::create(&path("real.npy"))?);
    let mut pairs_out = RowWriter::create(&path("pairs.csv"))?;
    let labelled = sim_labels.is_some() || real_labels.is_some();
    let mut labels_out =
        if labelled { Some((RowWriter::create(&path("sim_labels.csv"))?, RowWriter::create(&path("real_labels.csv"))?)) } else { None };
    let mut keys = std::collections::BTreeSet::new();
    for (i, p) in kept.iter().enumerate() {
        let i = i as u64;
        sim_out.write(&[sim.get(p.sim_index)?])?;
        real_out.write(&[real.get(p.real_index)?])?;
        pairs_out.write(&Pair { sim_index: i, real_index: i, split: p.split, distance: p.distance })?;
        if let Some((s, r)) = &mut labels_out {
            let (sl, rl) = (sim_labels.as_ref().map(|l| &l[p.sim_index as usize]), real_labels.as_ref().map(|l| &l[p.real_index as usize]));
            if let Some(row) = pair_label(i, sl, rl) {
                s.write(&row)?;
            }
            // The real side keeps its own labels (a real record's terrain is its own).
            if let Some(row) = pair_label(i, rl.or(sl), rl) {
                r.write(&row)?;
            }
        }
        keys.insert(p.sim_index);
    }
    // Everything checked and written: move the files into place.
    sim_out.finish()?;
    real_out.finish()?;
    pairs_out.commit()?;
    let mut stale_removed = Vec::new();
    if let Some((s, r)) = labels_out {
        s.commit()?;
        r.commit()?;
    } else {
        for name in ["sim_labels.csv", "real_labels.csv"] {
            let p = path(name);
            match std::fs::remove_file(&p) {
                Ok(()) => stale_removed.push(p),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(source) => return Err(DemError::Io { path: p, source }.into()),
            }
        }
    }
    Ok(Expanded { pairs: kept.len() as u64, sim_keys: keys.len() as u64, stale_removed })
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::Terrain;

    fn label(terrain: Terrain, x: f64, time: Option<f64>) -> Label {
        Label { index: 9, terrain, x: Some(x), y: Some(0.0), yaw: Some(0.0), sequence: Some(3), time }
    }

    /// The sim's terrain, the real partner's pose and time.
    #[test]
    fn a_pair_takes_the_sim_s_terrain_and_the_real_s_pose_and_time() {
        let (s, r) = (label(Terrain::Flat, 1.0, Some(0.0)), label(Terrain::StairsUp, 2.0, Some(7.5)));
        let l = pair_label(4, Some(&s), Some(&r)).unwrap();
        assert_eq!((l.index, l.terrain, l.x, l.time), (4, Terrain::Flat, Some(2.0), Some(7.5)));
        // Without real labels the sim's own; without a real time the sim's time.
        assert_eq!(pair_label(0, Some(&s), None).unwrap().time, Some(0.0));
        let r_untimed = label(Terrain::Flat, 2.0, None);
        assert_eq!(pair_label(0, Some(&s), Some(&r_untimed)).unwrap().time, Some(0.0));
        assert!(pair_label(0, None, None).is_none());
    }
}
