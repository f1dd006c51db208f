//! How consecutive frames of a run move: the frame-to-frame statistics of
//! DEM runs.
//!
//! The labels order records into runs (`sequence`, then `time`); two
//! records next to each other in a run are a *step*. Between them the robot
//! moved; projected on the first frame's heading, the motion is a whole
//! number of cells `k`, and row `r` of the later frame sees the ground row
//! `r + k` of the earlier one saw. Over those rows of every step:
//!
//! | statistic | what |
//! |---|---|
//! | `flip` | share of cells whose validity changes from one frame to the next |
//! | `persist` | P(missing at t+1 \| missing at t) |
//! | `dh` | mean \|h(t+1) - h(t)\| over cells valid in both (m) |
//! | `rcorr` | correlation of the error against a reference (h - h_ref, e.g. against sim) at t and at t+1, cells valid in all four |
//!
//! A sensor that draws fresh noise and holes for every record flips many
//! cells and has `rcorr` near 0; a fused elevation map keeps its holes and
//! its errors from frame to frame. `scripts/peers/temporal.py` is the
//! numpy reference these are tested against.

use std::ops::Range;

use crate::format::{Dem, DemCells, CELL, COLS, GRID_ROWS};
use crate::table::Label;

/// Largest motion (whole cells) between two frames still compared: a
/// quarter of the grid. Beyond it the labels jump (a run cut, records
/// left out between the two), and the rows that would match are few.
pub const MAX_SHIFT: i64 = 5;

/// A time step more than this many times the runs' frame period is a gap
/// (records filtered out between the two frames), not a step. The period
/// is the 10th percentile of the steps in time: the frame rate even when
/// a filter (`dem-filter --unique`) dropped most frames, robust to a
/// recording's jitter.
pub const MAX_STEP_RATIO: f64 = 1.5;

/// Two consecutive frames of a run: record indices and the whole cells the
/// robot moved forward between them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Step {
    /// The earlier frame.
    pub from: usize,
    /// The later frame.
    pub to: usize,
    /// Cells moved forward along the earlier frame's heading.
    pub shift: i64,
}

/// The steps of the runs in `labels`, or why there are none to take: the
/// labels must give every record a run, a time and a pose.
pub fn steps(labels: &[Label]) -> Result<Vec<Step>, String> {
    let missing = |what: &str| format!("the labels give no {what} for some records, so their runs cannot be ordered in time");
    let mut frames = Vec::with_capacity(labels.len());
    for (i, l) in labels.iter().enumerate() {
        let seq = l.sequence.ok_or_else(|| missing("`sequence`"))?;
        let time = l.time.filter(|t| t.is_finite()).ok_or_else(|| missing("`time`"))?;
        let (Some(x), Some(y), Some(yaw)) = (l.x, l.y, l.yaw) else { return Err(missing("pose (`x`, `y`, `yaw`)")) };
        frames.push((seq, time, i, (x, y, yaw)));
    }
    frames.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)).then(a.2.cmp(&b.2)));
    let consecutive: Vec<_> = frames.windows(2).filter(|w| w[0].0 == w[1].0).map(|w| (w[0], w[1])).collect();
    let mut dts: Vec<f64> = consecutive.iter().map(|(a, b)| b.1 - a.1).filter(|&dt| dt > 0.0).collect();
    dts.sort_by(f64::total_cmp);
    let Some(&period) = dts.get(dts.len() / 10) else { return Ok(Vec::new()) };
    Ok(consecutive
        .into_iter()
        // The same time twice (a record repeated, as a terrain-mix draw
        // repeats one) is no motion of the sensor.
        .filter(|(a, b)| b.1 > a.1 && b.1 - a.1 <= MAX_STEP_RATIO * period)
        .filter_map(|(a, b)| {
            let ((xa, ya, wa), (xb, yb, _)) = (a.3, b.3);
            let forward = (xb - xa) * wa.cos() + (yb - ya) * wa.sin();
            let shift = (forward / CELL).round() as i64;
            (shift.abs() <= MAX_SHIFT).then_some(Step { from: a.2, to: b.2, shift })
        })
        .collect())
}

/// The steps of `steps` between records that are both in `idx` (indices
/// ascending or not, each once), renumbered to their positions in `idx`:
/// the steps of a subset taken with [`crate::distribution`]'s statistics
/// of the same subset.
pub fn within(steps: &[Step], idx: &[usize]) -> Vec<Step> {
    let position: std::collections::HashMap<usize, usize> = idx.iter().enumerate().map(|(p, &i)| (i, p)).collect();
    steps.iter().filter_map(|s| Some(Step { from: *position.get(&s.from)?, to: *position.get(&s.to)?, shift: s.shift })).collect()
}

/// Two steps one after the other (the first's later frame is the second's
/// earlier one): three frames of a run, for the correlation of the change
/// with the next change.
pub fn chains(steps: &[Step]) -> Vec<(Step, Step)> {
    let by_from: std::collections::HashMap<usize, Step> = steps.iter().map(|s| (s.from, *s)).collect();
    steps.iter().filter_map(|a| Some((*a, *by_from.get(&a.to)?))).collect()
}

/// The sums behind [`FrameStats`]; sums of parts add up to the whole.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FrameSums {
    /// Steps summed.
    pub steps: usize,
    /// Cells compared (the same ground in both frames).
    pub cells: usize,
    /// Cells whose validity changes.
    pub flips: usize,
    /// Cells missing at t.
    pub missing: usize,
    /// Cells missing at t and at t+1.
    pub still_missing: usize,
    /// Cells valid in both.
    pub both: usize,
    /// Sum of |h(t+1) - h(t)| over them.
    pub dh: f64,
    /// Cells valid in both frames and in both reference frames.
    pub n: usize,
    /// Sums of the errors at t (a) and t+1 (b): a, b, a^2, b^2, a b.
    pub moments: [f64; 5],
}

impl FrameSums {
    /// Add the frames `a` (earlier) and `b` (later), `shift` cells apart,
    /// over the later frame's rows `rows`; with `reference` (its frames at
    /// the same two times), the errors against it too.
    pub fn add(&mut self, (a, b): (&Dem, &Dem), reference: Option<(&Dem, &Dem)>, shift: i64, rows: Range<usize>) {
        let k = shift;
        let lo = (rows.start as i64).max(-k).max(0) as usize;
        let hi = (rows.end as i64).min(GRID_ROWS as i64 - k).max(lo as i64) as usize;
        self.steps += 1;
        for r in lo..hi {
            let ra = (r as i64 + k) as usize;
            for c in 0..COLS {
                let (va, vb) = (a.is_valid(ra, c), b.is_valid(r, c));
                self.cells += 1;
                self.flips += usize::from(va != vb);
                if !va {
                    self.missing += 1;
                    self.still_missing += usize::from(!vb);
                }
                if !(va && vb) {
                    continue;
                }
                let (ha, hb) = (f64::from(a.height(ra, c)), f64::from(b.height(r, c)));
                self.both += 1;
                self.dh += (hb - ha).abs();
                let Some((qa, qb)) = reference else { continue };
                if qa.is_valid(ra, c) && qb.is_valid(r, c) {
                    let (ea, eb) = (ha - f64::from(qa.height(ra, c)), hb - f64::from(qb.height(r, c)));
                    self.n += 1;
                    for (m, v) in self.moments.iter_mut().zip([ea, eb, ea * ea, eb * eb, ea * eb]) {
                        *m += v;
                    }
                }
            }
        }
    }

    /// Add the lag-1 moments of the change along the chain `(a, b, c)`
    /// (steps `s1` from a to b, `s2` from b to c): over the ground the three
    /// frames share, the changes b - a and c - b, cells valid in all three.
    /// Fills the moments [`FrameStats::rcorr`] is made of, where no
    /// reference gives an error (the change of a fresh draw every frame
    /// correlates at -0.5 with the next; a map that holds its estimate, near 0).
    pub fn add_change(&mut self, (a, b, c): (&Dem, &Dem, &Dem), (s1, s2): (i64, i64), rows: Range<usize>) {
        for r in rows {
            let (rb, ra) = (r as i64 + s2, r as i64 + s2 + s1);
            if !(0..GRID_ROWS as i64).contains(&rb) || !(0..GRID_ROWS as i64).contains(&ra) {
                continue;
            }
            let (ra, rb) = (ra as usize, rb as usize);
            for col in 0..COLS {
                if !(a.is_valid(ra, col) && b.is_valid(rb, col) && c.is_valid(r, col)) {
                    continue;
                }
                let (ha, hb, hc) = (f64::from(a.height(ra, col)), f64::from(b.height(rb, col)), f64::from(c.height(r, col)));
                let (d1, d2) = (hb - ha, hc - hb);
                self.n += 1;
                for (m, v) in self.moments.iter_mut().zip([d1, d2, d1 * d1, d2 * d2, d1 * d2]) {
                    *m += v;
                }
            }
        }
    }

    /// [`Self::add_change`] along every chain of `chains` (of `x`'s steps).
    pub fn add_changes(&mut self, x: &[Dem], chains: &[(Step, Step)], rows: Range<usize>) {
        for (s1, s2) in chains {
            self.add_change((&x[s1.from], &x[s1.to], &x[s2.to]), (s1.shift, s2.shift), rows.clone());
        }
    }

    /// The sums of `self` and `o` together.
    pub fn merged(mut self, o: &FrameSums) -> FrameSums {
        self.steps += o.steps;
        self.cells += o.cells;
        self.flips += o.flips;
        self.missing += o.missing;
        self.still_missing += o.still_missing;
        self.both += o.both;
        self.dh += o.dh;
        self.n += o.n;
        for (m, v) in self.moments.iter_mut().zip(o.moments) {
            *m += v;
        }
        self
    }

    /// The statistics of these sums.
    pub fn stats(&self) -> FrameStats {
        let ratio = |a: usize, b: usize| (b > 0).then(|| a as f64 / b as f64);
        let [sa, sb, saa, sbb, sab] = self.moments;
        let n = self.n as f64;
        let (va, vb) = (n * saa - sa * sa, n * sbb - sb * sb);
        // As the reference: more than 10 cells, and neither side constant.
        let rcorr = (self.n > 10 && va > 0.0 && vb > 0.0).then(|| (n * sab - sa * sb) / (va.sqrt() * vb.sqrt()));
        FrameStats {
            steps: self.steps,
            cells: self.cells,
            flip: ratio(self.flips, self.cells),
            persist: ratio(self.still_missing, self.missing),
            dh: (self.both > 0).then(|| self.dh / self.both as f64),
            rcorr,
        }
    }
}

/// How consecutive frames move (module table); None where no cell counts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameStats {
    /// Steps compared.
    pub steps: usize,
    /// Cells compared.
    pub cells: usize,
    /// Share of cells whose validity changes.
    pub flip: Option<f64>,
    /// P(missing at t+1 | missing at t).
    pub persist: Option<f64>,
    /// Mean |h(t+1) - h(t)| over cells valid in both (m).
    pub dh: Option<f64>,
    /// Correlation of the error against the reference at t and t+1.
    pub rcorr: Option<f64>,
}

/// The frame-to-frame statistics of `x` over `steps` (errors against
/// `reference`, record for record, when given), over the later frame's
/// rows `rows`.
pub fn frame_stats(x: &[Dem], reference: Option<&[Dem]>, steps: &[Step], rows: Range<usize>) -> FrameStats {
    let mut sums = FrameSums::default();
    for &s in steps {
        let reference = reference.map(|q| (&q[s.from], &q[s.to]));
        sums.add((&x[s.from], &x[s.to]), reference, s.shift, rows.clone());
    }
    sums.stats()
}

/// The lag-1 correlation of the change h(t+1) - h(t) of `x` with the next
/// change, over the chains of `steps` ([`FrameSums::add_change`]), over
/// the last frame's rows `rows`: where no reference gives an error.
pub fn change_rcorr(x: &[Dem], steps: &[Step], rows: Range<usize>) -> Option<f64> {
    let mut sums = FrameSums::default();
    sums.add_changes(x, &chains(steps), rows);
    sums.stats().rcorr
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::{empty_dem, Terrain};

    fn label(i: usize, seq: u64, time: f64, x: f64) -> Label {
        Label { index: i as u64, terrain: Terrain::Flat, x: Some(x), y: Some(0.0), yaw: Some(0.0), sequence: Some(seq), time: Some(time) }
    }

    /// Runs in any order of records, sorted by time; the motion in whole
    /// cells; a gap in time and a jump in pose are not steps.
    #[test]
    fn steps_follow_the_runs_in_time() {
        let labels = vec![
            label(0, 1, 0.4, 0.2),
            label(1, 0, 0.0, 0.0),
            label(2, 1, 0.0, 0.0),
            label(3, 0, 0.4, 0.31),
            label(4, 0, 0.8, 0.52),
            label(5, 0, 2.0, 0.7),
            label(6, 1, 0.8, 2.0),
        ];
        let got = steps(&labels).unwrap();
        assert_eq!(got, vec![Step { from: 1, to: 3, shift: 3 }, Step { from: 3, to: 4, shift: 2 }, Step { from: 2, to: 0, shift: 2 }]);
        let mut no_pose = labels.clone();
        no_pose[4].yaw = None;
        assert!(steps(&no_pose).unwrap_err().contains("pose"));
        let mut no_time = labels;
        no_time[0].time = None;
        assert!(steps(&no_time).unwrap_err().contains("`time`"));
    }

    /// A frame moved by its step reads the same ground: no change at all;
    /// noise drawn afresh flips and changes, with errors uncorrelated.
    #[test]
    fn the_same_ground_moved_by_the_step_does_not_change() {
        let ground = |x0: usize, r: usize| 0.01 * ((x0 + r) % 7) as f32;
        let mut frames = Vec::new();
        for t in 0..30 {
            let mut d = empty_dem();
            for r in 0..GRID_ROWS {
                for c in 0..COLS {
                    if (t * 2 + r + c) % 5 != 0 || r + 2 * t < 25 {
                        d.set_valid(r, c, ground(2 * t, r));
                    }
                }
            }
            frames.push(d);
        }
        let steps: Vec<Step> = (0..29).map(|t| Step { from: t, to: t + 1, shift: 2 }).collect();
        let s = frame_stats(&frames, None, &steps, 0..GRID_ROWS);
        assert_eq!(s.dh, Some(0.0));
        assert_eq!(s.steps, 29);
        assert_eq!(s.cells, 29 * 18 * COLS);
        // Heights: a wrong shift sees other ground.
        let wrong: Vec<Step> = steps.iter().map(|s| Step { shift: 0, ..*s }).collect();
        assert!(frame_stats(&frames, None, &wrong, 0..GRID_ROWS).dh.unwrap() > 0.005);
        // The parts' sums are the whole's.
        let (mut a, mut b) = (FrameSums::default(), FrameSums::default());
        for (i, &st) in steps.iter().enumerate() {
            let sums = if i % 3 == 0 { &mut a } else { &mut b };
            sums.add((&frames[st.from], &frames[st.to]), None, st.shift, 0..GRID_ROWS);
        }
        assert_eq!(a.merged(&b).stats(), s);
    }

    /// Noise drawn afresh every frame changes by b - a, then by c - b:
    /// the two changes correlate at -0.5; chains follow the steps, a subset
    /// keeps the steps within it, renumbered.
    #[test]
    fn fresh_noise_changes_back_the_next_frame() {
        let mut state = 12345u64;
        let mut noise = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 33) as f32 / (1u64 << 31) as f32) - 0.5
        };
        let frames: Vec<Dem> = (0..400)
            .map(|_| {
                let mut d = empty_dem();
                for r in 0..GRID_ROWS {
                    for c in 0..COLS {
                        d.set_valid(r, c, 0.01 * noise());
                    }
                }
                d
            })
            .collect();
        let steps: Vec<Step> = (0..399).map(|t| Step { from: t, to: t + 1, shift: 1 }).collect();
        let chained = chains(&steps);
        assert_eq!(chained.len(), 398);
        assert!(chained.iter().all(|(a, b)| a.to == b.from));
        let mut sums = FrameSums::default();
        for (s1, s2) in &chained {
            sums.add_change((&frames[s1.from], &frames[s1.to], &frames[s2.to]), (s1.shift, s2.shift), 0..GRID_ROWS);
        }
        let r = sums.stats().rcorr.unwrap();
        assert!((r + 0.5).abs() < 0.02, "{r}");
        let sub = within(&steps, &[5, 9, 6, 7]);
        assert_eq!(sub, vec![Step { from: 0, to: 2, shift: 1 }, Step { from: 2, to: 3, shift: 1 }]);
    }
}
