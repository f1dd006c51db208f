//! What the named effects leave unexplained, where it lives, and how much
//! data would show a gap that is still below the sampling floor.
//!
//! Everything here is statistics of the final model's output (two random
//! draws of it, already made for the sampling floor) and of real, on
//! subsets of records and cells: no fitting.
//!
//! - **Unexplained** ([`Unexplained`]): the final gap above the sampling
//!   floor, split by statistic ([`gap_components`]: each term's share of the
//!   gap, minus the floor's share of the same term), by band of rows
//!   (behind the robot x < 0, near 0 <= x < 0.5 m, far x >= 0.5 m, and the
//!   terms that are not per row), by side (the left columns 0-1 against the
//!   right columns 3-4, each compared as a record of its own: [`side_view`])
//!   and by terrain (labels), each against its own floor.
//! - **Weak steps**: a named effect that removed less than [`WEAK`] of the
//!   gap it was given is flagged; what it left is read as unexplained.
//! - **More data** ([`MoreData`]): the floor is a sum of squared
//!   standardised differences, each with a variance ~ 1/n, so it falls as
//!   n^-a (a = 1 in theory) while a true gap stays: with the floor at the
//!   current size F and at half size F_2 (the sampling halves), a =
//!   log2(F_2 / F), and floor(n) = gap at n = N (F / gap)^(1 / a).
//! - **Missing cells per band and terrain** ([`BandRow`]).

use dem_core::distribution::{Stats, MIN_SUPPORT, UNSUPPORTED_Z};
use dem_core::format::{row_center_x, Dem, DemCells, Terrain, COLS, GRID_ROWS};
use dem_core::temporal::{within, Step};

use crate::load::pick;
use crate::measurement::summarise;

/// A step that removes less than this share of the gap before it is weak:
/// it is not the explanation of that gap.
pub const WEAK: f64 = 0.2;

/// Bands of rows, by the x of their centre: behind the robot, near (under
/// its front half and just ahead), far ahead.
pub const BANDS: [(&str, std::ops::Range<usize>); 3] =
    [("behind (x < 0)", 0..6), ("near (0 <= x < 0.5 m)", 6..11), ("far (x >= 0.5 m)", 11..20)];

/// Short names of [`BANDS`], for report.json.
pub const BAND_KEYS: [&str; 3] = ["behind", "near", "far"];

/// The part of the gap of terms that are not per row (height steps by
/// size, the step sides).
pub const GRID_WIDE: &str = "grid-wide";

/// Bands of the missing-cell table: behind the robot and ahead.
pub const HALF_BANDS: [(&str, std::ops::Range<usize>); 2] = [("behind", 0..6), ("ahead", 6..20)];

/// A band's missing rates differing by more than this between the model
/// and real are flagged.
pub const MISSING_FLAG: f64 = 0.05;

/// One piece of the remaining gap: the gap of model(sim) against real
/// there, the sampling floor there, and what is above it.
#[derive(Debug, Clone, PartialEq)]
pub struct Part {
    /// Statistic, band, side or terrain.
    pub name: String,
    /// Gap there (model against real).
    pub gap: f64,
    /// Sampling floor there.
    pub floor: f64,
    /// max(0, gap - floor).
    pub excess: f64,
    /// excess / sum of the excesses of the same split (0 when none).
    pub share: f64,
    /// For terrains: records on the real side; for the others 0.
    pub records: usize,
    /// For terrains: the statistic and band with most of the excess there.
    pub top: Option<(String, String)>,
}

/// What the named effects leave.
#[derive(Debug, Clone, PartialEq)]
pub struct Unexplained {
    /// Final gap.
    pub gap: f64,
    /// Sampling floor of the final model.
    pub floor: f64,
    /// max(0, gap - floor): the part no effect of the vocabulary explains.
    pub excess: f64,
    /// excess / gap.
    pub share: f64,
    /// excess / the start model's gap.
    pub of_initial: f64,
    /// Per statistic, largest excess first.
    pub by_statistic: Vec<Part>,
    /// Per band of rows ([`BANDS`]), then [`GRID_WIDE`].
    pub by_row_band: Vec<Part>,
    /// Per side: left (columns 0-1), right (columns 3-4).
    pub by_side: Vec<Part>,
    /// Per terrain (labels), largest excess first.
    pub by_terrain: Vec<Part>,
    /// Per row: gap, floor.
    pub by_row: Vec<(f64, f64)>,
    /// Per row, the gap of the statistics with most of the excess (up to
    /// four), for the picture.
    pub rows_of_top: Vec<(String, Vec<f64>)>,
    /// Per terrain, per row gap, for the picture.
    pub rows_of_terrain: Vec<(String, Vec<f64>)>,
    /// Weak steps: (step number from 1, effect, share of the gap removed).
    pub weak_steps: Vec<(usize, String, f64)>,
    /// Where most of the excess lives: statistic, row band, side, terrain.
    pub location: Location,
}

/// The largest piece of each split ([`Unexplained`]); None where there is
/// nothing above the floor or no such split.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Location {
    /// The statistic.
    pub statistic: Option<String>,
    /// The band key ([`BAND_KEYS`] or [`GRID_WIDE`]).
    pub row_band: Option<String>,
    /// `left`, `right` (one side has more than twice the other's excess) or
    /// `both`.
    pub side: Option<String>,
    /// The terrains with at least half the largest terrain's excess,
    /// largest first, joined by `+`; `all` when every terrain has that much.
    pub terrain: Option<String>,
}

/// Records (and runs) that would lift a gap below the sampling floor above it.
#[derive(Debug, Clone, PartialEq)]
pub struct MoreData {
    /// The gap (start model).
    pub gap: f64,
    /// Its sampling floor at the current size.
    pub floor: f64,
    /// The floor at half the size (mean of the two halves).
    pub floor_half: f64,
    /// log2(floor_half / floor): how fast the floor itself falls.
    pub exponent_measured: f64,
    /// beta: each component's z^2 scales as n^-beta (1: pure sampling),
    /// fitted so the floor moved to half the size is `floor_half`
    /// (within 0.5..2).
    pub exponent: f64,
    /// Factor on the current size.
    pub factor: f64,
    /// Real records needed.
    pub records: u64,
    /// Sim records needed (the sim side grows alike).
    pub sim_records: u64,
    /// Runs needed (real labels with `sequence`).
    pub runs: Option<u64>,
    /// Runs now (real labels with `sequence`).
    pub runs_now: Option<u64>,
}

/// One row of the missing-cell table ([`HALF_BANDS`]).
#[derive(Debug, Clone, PartialEq)]
pub struct BandRow {
    /// Terrain, or None for all records.
    pub terrain: Option<Terrain>,
    /// The band name.
    pub band: &'static str,
    /// Real records.
    pub records: usize,
    /// Missing-cell rate: sim, final model(sim), real.
    pub missing: [f64; 3],
    /// |model - real| > [`MISSING_FLAG`], with the reason when one is known.
    pub flag: Option<String>,
}

/// Each term's contribution to [`distribution::gap`] per component (the
/// same rules: ln(1 + z^2) over the term's supported components, or
/// [`UNSUPPORTED_Z`] where one side has the samples and the other next to
/// none), divided by the term's count of components, so that all of them
/// sum to the gap.
pub fn gap_components(a: &Stats, b: &Stats) -> Vec<(&'static str, Vec<f64>)> {
    a.terms
        .iter()
        .filter_map(|ta| {
            let tb = b.term(ta.name)?;
            let (ra, rb) = (a.records.max(1) as f64, b.records.max(1) as f64);
            let mut c = vec![0.0; ta.values.len()];
            let mut n = 0usize;
            for (i, ci) in c.iter_mut().enumerate().take(ta.values.len().min(tb.values.len())) {
                let (sa, sb) = (ta.support[i], tb.support[i]);
                if sa >= MIN_SUPPORT && sb >= MIN_SUPPORT {
                    *ci = ((ta.values[i] - tb.values[i]) / ta.scale).powi(2).ln_1p();
                    n += 1;
                } else if sa.max(sb) >= MIN_SUPPORT {
                    let (pa, pb) = (sa as f64 / ra, sb as f64 / rb);
                    if pa.min(pb) < 0.25 * pa.max(pb) {
                        *ci = UNSUPPORTED_Z.powi(2).ln_1p();
                        n += 1;
                    }
                }
            }
            c.iter_mut().for_each(|x| *x /= n.max(1) as f64);
            Some((ta.name, c))
        })
        .collect()
}

/// Per row and the rest ([`GRID_WIDE`]) of per-component contributions:
/// terms with one component per row go to their row, the edge terms (one
/// per pair of rows) half to each row of the pair, the others to the rest.
pub fn by_row(c: &[(&'static str, Vec<f64>)]) -> ([f64; GRID_ROWS], f64) {
    let mut rows = [0.0; GRID_ROWS];
    let mut rest = 0.0;
    for (_, v) in c {
        add_rows(v, &mut rows, &mut rest);
    }
    (rows, rest)
}

fn add_rows(v: &[f64], rows: &mut [f64; GRID_ROWS], rest: &mut f64) {
    if v.len() == GRID_ROWS {
        rows.iter_mut().zip(v).for_each(|(r, x)| *r += x);
    } else if v.len() == GRID_ROWS - 1 {
        for (i, x) in v.iter().enumerate() {
            rows[i] += 0.5 * x;
            rows[i + 1] += 0.5 * x;
        }
    } else {
        *rest += v.iter().sum::<f64>();
    }
}

/// A record seen from one side: the columns of that side (0-1 left, 4-3
/// right) repeated across the grid (1, 0, 1, 0, 1 order keeps every
/// across-robot pair a pair of neighbours of the record), so that the
/// statistics describe that side's cells only.
pub fn side_view(d: &Dem, left: bool) -> Dem {
    let cols: [usize; COLS] = if left { [0, 1, 0, 1, 0] } else { [4, 3, 4, 3, 4] };
    let mut o = *d;
    for r in 0..GRID_ROWS {
        for (c, &from) in cols.iter().enumerate() {
            if d.is_valid(r, from) {
                o.set_valid(r, c, d.height(r, from));
            } else {
                o.set_missing(r, c);
            }
        }
    }
    o
}

/// Missing-cell rate of rows `rows` over `records`.
pub fn missing_rate<'a>(records: impl Iterator<Item = &'a Dem>, rows: std::ops::Range<usize>) -> f64 {
    let (mut miss, mut all) = (0usize, 0usize);
    for d in records {
        for r in rows.clone() {
            for c in 0..COLS {
                miss += usize::from(!d.is_valid(r, c));
                all += 1;
            }
        }
    }
    if all > 0 {
        miss as f64 / all as f64
    } else {
        0.0
    }
}

/// The part above zero of `gap - floor`.
pub fn excess(gap: f64, floor: f64) -> f64 {
    (gap - floor).max(0.0)
}

/// Share each part's excess is of the sum of them.
pub fn set_shares(parts: &mut [Part]) {
    let total: f64 = parts.iter().map(|p| p.excess).sum();
    for p in parts {
        p.share = if total > 0.0 { p.excess / total } else { 0.0 };
    }
}

/// The sample (size-dependent) part of a comparison of a subset: the
/// statistics of model(sim) with its two draws and of real with its two
/// halves.
pub struct Compared {
    /// Model (run's draws) against real, per component.
    pub gap: Vec<(&'static str, Vec<f64>)>,
    /// The floor per component: the larger of the draw floor and,
    /// unpaired, the real halves' gap scaled to the sizes.
    pub floor: Vec<(&'static str, Vec<f64>)>,
}

impl Compared {
    /// Total gap.
    pub fn gap(&self) -> f64 {
        total(&self.gap)
    }
    /// Total floor.
    pub fn floor(&self) -> f64 {
        total(&self.floor)
    }
    /// Per-term gap, floor.
    pub fn terms(&self) -> Vec<(&'static str, f64, f64)> {
        self.gap
            .iter()
            .map(|(n, v)| (*n, v.iter().sum::<f64>(), self.floor.iter().find(|f| f.0 == *n).map_or(0.0, |f| f.1.iter().sum())))
            .collect()
    }
    /// The term with the largest excess, and the band (or grid-wide) with
    /// the largest excess.
    pub fn top(&self) -> (String, String) {
        let terms = self.terms();
        let stat = terms.iter().max_by(|a, b| excess(a.1, a.2).total_cmp(&excess(b.1, b.2))).map_or("", |t| t.0).to_string();
        let bands = self.bands();
        let band = bands.iter().max_by(|a, b| excess(a.1, a.2).total_cmp(&excess(b.1, b.2))).map_or("", |b| b.0).to_string();
        (stat, band)
    }
    /// Per band key ([`BAND_KEYS`], then [`GRID_WIDE`]): gap, floor, from
    /// the per-row excess (each row's gap minus its floor).
    pub fn bands(&self) -> Vec<(&'static str, f64, f64)> {
        let (g, gr) = by_row(&self.gap);
        let (f, fr) = by_row(&self.floor);
        let mut v: Vec<(&'static str, f64, f64)> = BANDS
            .iter()
            .zip(BAND_KEYS)
            .map(|((_, rows), k)| (k, rows.clone().map(|r| g[r]).sum(), rows.clone().map(|r| f[r]).sum()))
            .collect();
        v.push((GRID_WIDE, gr, fr));
        v
    }
}

fn total(c: &[(&'static str, Vec<f64>)]) -> f64 {
    c.iter().flat_map(|(_, v)| v.iter()).sum()
}

/// Compare model(sim) (`out_a`, `out_b`: two draws) against real on the
/// records `si` (sim side) and `ri` (real side; paired: the same), seen
/// through `view`. `halves`: real's sampling halves (unpaired), whose parts
/// in `ri` give the split floor. `steps`: the runs' steps of the sim and
/// the real side (positions in `sim` and `real`), when the frame terms
/// count.
#[allow(clippy::too_many_arguments)]
pub fn compare(
    out_a: &[Dem],
    out_b: &[Dem],
    sim: &[Dem],
    real: &[Dem],
    paired: bool,
    si: &[usize],
    ri: &[usize],
    halves: Option<&[Vec<usize>; 2]>,
    view: &dyn Fn(&Dem) -> Dem,
    steps: Option<(&[Step], &[Step])>,
) -> Compared {
    let take = |v: &[Dem], idx: &[usize]| -> Vec<Dem> { idx.iter().map(|&i| view(&v[i])).collect() };
    let sims = paired.then(|| take(sim, si));
    let st = |v: &[Dem], idx: &[usize], side: Option<&[Step]>| {
        let steps = side.map(|s| within(s, idx));
        // Paired, the sims are the records `si`, as `idx` is.
        summarise(&take(v, idx), sims.as_deref(), steps.as_deref())
    };
    let (sim_steps, real_steps) = (steps.map(|s| s.0), steps.map(|s| s.1));
    let (a, b, r) = (st(out_a, si, sim_steps), st(out_b, si, sim_steps), st(real, ri, real_steps));
    let gap = gap_components(&a, &r);
    let mut floor = gap_components(&a, &b);
    if let (false, Some(h)) = (paired, halves) {
        let parts: Vec<Vec<usize>> = h.iter().map(|h| ri.iter().copied().filter(|i| h.binary_search(i).is_ok()).collect()).collect();
        if parts.iter().all(|p| p.len() >= 20) {
            let (ha, hb) = (st(real, &parts[0], real_steps), st(real, &parts[1], real_steps));
            let scale = (1.0 / si.len() as f64 + 1.0 / ri.len() as f64) / (1.0 / parts[0].len() as f64 + 1.0 / parts[1].len() as f64);
            let mut split = gap_components(&ha, &hb);
            split.iter_mut().for_each(|(_, v)| v.iter_mut().for_each(|x| *x *= scale));
            if total(&split) > total(&floor) {
                floor = split;
            }
        }
    }
    Compared { gap, floor }
}

/// Everything [`analyse`] needs.
pub struct Inputs<'a> {
    /// Final model(sim), the run's draws.
    pub out_a: &'a [Dem],
    /// Final model(sim), other draws.
    pub out_b: &'a [Dem],
    /// Sim records compared.
    pub sim: &'a [Dem],
    /// Real records compared.
    pub real: &'a [Dem],
    /// Per position.
    pub paired: bool,
    /// Terrains of the sim and real records (both known).
    pub terrains: Option<(&'a [Terrain], &'a [Terrain])>,
    /// Real's sampling halves (unpaired).
    pub halves: Option<&'a [Vec<usize>; 2]>,
    /// The final gap and floor, as the run measured them.
    pub gap: f64,
    /// Final floor.
    pub floor: f64,
    /// Start gap.
    pub gap_initial: f64,
    /// Steps: (effect, gap before, gap after).
    pub steps: Vec<(String, f64, f64)>,
    /// The runs' steps of the sim and the real side, when the frame terms
    /// count.
    pub frames: Option<(&'a [Step], &'a [Step])>,
}

/// What the final model leaves, where ([`Unexplained`]).
pub fn analyse(i: &Inputs) -> Unexplained {
    let all_s: Vec<usize> = (0..i.sim.len()).collect();
    let all_r: Vec<usize> = (0..i.real.len()).collect();
    let whole = compare(i.out_a, i.out_b, i.sim, i.real, i.paired, &all_s, &all_r, i.halves, &|d| *d, i.frames);
    let mut by_statistic: Vec<Part> = whole.terms().into_iter().map(|(n, g, f)| Part::new(n, g, f)).collect();
    set_shares(&mut by_statistic);
    by_statistic.sort_by(|a, b| b.excess.total_cmp(&a.excess));
    let mut by_row_band: Vec<Part> = whole.bands().into_iter().map(|(n, g, f)| Part::new(n, g, f)).collect();
    set_shares(&mut by_row_band);
    let (rg, _) = by_row(&whole.gap);
    let (rf, _) = by_row(&whole.floor);
    let rows: Vec<(f64, f64)> = rg.iter().zip(rf).map(|(&g, f)| (g, f)).collect();
    let rows_of_top = rows_of_top(&whole, &by_statistic);
    let mut by_side: Vec<Part> = [("left", true), ("right", false)]
        .into_iter()
        .map(|(n, left)| {
            let c = compare(i.out_a, i.out_b, i.sim, i.real, i.paired, &all_s, &all_r, i.halves, &|d| side_view(d, left), None);
            Part::new(n, c.gap(), c.floor())
        })
        .collect();
    set_shares(&mut by_side);
    let (by_terrain, rows_of_terrain) = by_terrain(i);
    // A negligible gap (crate::NEGLIGIBLE_GAP) is explained, whatever the
    // floor: no statistic differs by a fifth of its scale.
    let ex = if i.gap < crate::NEGLIGIBLE_GAP { 0.0 } else { excess(i.gap, i.floor) };
    let location = if ex > 0.0 { locate(&by_statistic, &by_row_band, &by_side, &by_terrain) } else { Location::default() };
    let weak_steps = i
        .steps
        .iter()
        .enumerate()
        .filter(|(_, (_, b, a))| crate::share_removed(*b, *a) < WEAK)
        .map(|(k, (e, b, a))| (k + 1, e.clone(), crate::share_removed(*b, *a)))
        .collect();
    Unexplained {
        gap: i.gap,
        floor: i.floor,
        excess: ex,
        share: if i.gap > 0.0 { ex / i.gap } else { 0.0 },
        of_initial: if i.gap_initial > 0.0 { ex / i.gap_initial } else { 0.0 },
        by_statistic,
        by_row_band,
        by_side,
        by_terrain,
        by_row: rows,
        rows_of_top,
        rows_of_terrain,
        weak_steps,
        location,
    }
}

impl Part {
    fn new(name: &str, gap: f64, floor: f64) -> Part {
        Part { name: name.to_string(), gap, floor, excess: excess(gap, floor), share: 0.0, records: 0, top: None }
    }
}

/// The per-row gap of the (at most four) statistics with the largest
/// excess, for those whose gap lives in the grid's rows alone.
fn rows_of_top(whole: &Compared, by_statistic: &[Part]) -> Vec<(String, Vec<f64>)> {
    by_statistic
        .iter()
        .filter(|p| p.excess > 0.0)
        .take(4)
        .filter_map(|p| {
            let v = &whole.gap.iter().find(|c| c.0 == p.name)?.1;
            let mut r = [0.0; GRID_ROWS];
            let mut rest = 0.0;
            add_rows(v, &mut r, &mut rest);
            (rest == 0.0).then(|| (p.name.clone(), r.to_vec()))
        })
        .collect()
}

/// The gap per terrain held by at least 20 records on each side, largest
/// excess first, and each terrain's gap per row.
fn by_terrain(i: &Inputs) -> (Vec<Part>, Vec<(String, Vec<f64>)>) {
    let mut parts = Vec::new();
    let mut rows = Vec::new();
    let Some((ts, tr)) = i.terrains else {
        return (parts, rows);
    };
    for t in Terrain::ALL {
        let si: Vec<usize> = (0..ts.len()).filter(|&k| ts[k] == t).collect();
        let ri: Vec<usize> = (0..tr.len()).filter(|&k| tr[k] == t).collect();
        if si.len() < 20 || ri.len() < 20 {
            continue;
        }
        let c = compare(i.out_a, i.out_b, i.sim, i.real, i.paired, &si, &ri, i.halves, &|d| *d, i.frames);
        let mut p = Part::new(t.as_str(), c.gap(), c.floor());
        p.records = ri.len();
        p.top = (p.excess > 0.0).then(|| c.top());
        rows.push((t.as_str().to_string(), by_row(&c.gap).0.to_vec()));
        parts.push(p);
    }
    set_shares(&mut parts);
    parts.sort_by(|a, b| b.excess.total_cmp(&a.excess));
    (parts, rows)
}

/// Where the unexplained part lives: the statistic and row band of the
/// largest excess, the side(s) and the terrain(s).
fn locate(by_statistic: &[Part], by_row_band: &[Part], by_side: &[Part], by_terrain: &[Part]) -> Location {
    let first = |v: &[Part]| v.iter().filter(|p| p.excess > 0.0).max_by(|a, b| a.excess.total_cmp(&b.excess)).map(|p| p.name.clone());
    let side = match (by_side.first(), by_side.get(1)) {
        (Some(l), Some(r)) if l.excess + r.excess > 0.0 => Some(
            if l.excess > 2.0 * r.excess {
                "left"
            } else if r.excess > 2.0 * l.excess {
                "right"
            } else {
                "both"
            }
            .to_string(),
        ),
        _ => None,
    };
    // The terrains with at least half the largest excess, largest first
    // (`pallet+stairs-down`); `all` when every terrain has that much.
    let terrain = by_terrain.first().filter(|a| a.excess > 0.0).map(|a| {
        let held: Vec<&str> = by_terrain.iter().filter(|p| p.excess >= 0.5 * a.excess).map(|p| p.name.as_str()).collect();
        if held.len() == by_terrain.len() && held.len() > 1 {
            "all".to_string()
        } else {
            held.join("+")
        }
    });
    Location { statistic: first(by_statistic), row_band: first(by_row_band), side, terrain }
}

impl Unexplained {
    /// One line for stderr.
    pub fn summary(&self) -> String {
        let weak = if self.weak_steps.is_empty() {
            String::new()
        } else {
            format!(
                "; WEAK (removed less than {:.0}% of the gap they were given, not the explanation): {}",
                100.0 * WEAK,
                self.weak_steps.iter().map(|(k, e, s)| format!("step {k} {e} {:.0}%", 100.0 * s)).collect::<Vec<_>>().join(", ")
            )
        };
        if self.excess <= 0.0 {
            return format!(
                "unexplained: nothing above the sampling floor or the negligible gap {} (gap {:.3}, floor {:.3}){weak}",
                crate::NEGLIGIBLE_GAP,
                self.gap,
                self.floor
            );
        }
        let l = &self.location;
        let mut at = Vec::new();
        if let Some(s) = &l.statistic {
            at.push(format!("statistic {s}"));
        }
        if let Some(b) = &l.row_band {
            at.push(format!("rows {b}"));
        }
        if let Some(s) = &l.side {
            at.push(format!("side {s}"));
        }
        if let Some(t) = &l.terrain {
            at.push(if t == "all" { "every terrain alike".to_string() } else { format!("terrain {t}") });
        }
        format!(
            "unexplained: {:.3} of the gap {:.3} is above the sampling floor {:.3} ({:.0}% of it) and no effect of the vocabulary explains it; most in {}{weak}",
            self.excess,
            self.gap,
            self.floor,
            100.0 * self.share,
            at.join(", ")
        )
    }
}

/// Each included component's ln(1 + z^2) per term, as [`distribution::gap`]
/// counts them (the gap is the sum over terms of their mean).
pub fn raw_components(a: &Stats, b: &Stats) -> Vec<Vec<f64>> {
    a.terms
        .iter()
        .filter_map(|ta| {
            let tb = b.term(ta.name)?;
            let (ra, rb) = (a.records.max(1) as f64, b.records.max(1) as f64);
            let mut v = Vec::new();
            for i in 0..ta.values.len().min(tb.values.len()) {
                let (sa, sb) = (ta.support[i], tb.support[i]);
                if sa >= MIN_SUPPORT && sb >= MIN_SUPPORT {
                    v.push(((ta.values[i] - tb.values[i]) / ta.scale).powi(2).ln_1p());
                } else if sa.max(sb) >= MIN_SUPPORT {
                    let (pa, pb) = (sa as f64 / ra, sb as f64 / rb);
                    if pa.min(pb) < 0.25 * pa.max(pb) {
                        v.push(UNSUPPORTED_Z.powi(2).ln_1p());
                    }
                }
            }
            Some(v)
        })
        .collect()
}

/// A floor's components at size N, moved to size n: each z^2 scaled by
/// (N / n)^beta (sampling: var ~ 1/n, beta = 1 in theory).
pub fn floor_at(raw: &[Vec<f64>], ratio: f64, beta: f64) -> f64 {
    let k = ratio.powf(beta);
    raw.iter().filter(|t| !t.is_empty()).map(|t| t.iter().map(|&c| (c.exp_m1() * k).ln_1p()).sum::<f64>() / t.len() as f64).sum()
}

/// The sampling floor of `model` on the sim records `si` against the real
/// records `ri` (paired: the same), as [`crate::sampling_floor`] and
/// [`crate::draw_floor`] take it on all records: the larger of the model's
/// two draws' gap and, unpaired with at least 100 real records, the gap of
/// two halves of `ri` (whole runs from `min_runs` runs on) scaled to the
/// sizes. Returns the floor's components ([`raw_components`]), already
/// scaled.
pub fn floor_on(
    sets: &crate::Sets,
    model: &dem_sensor::SensorModel,
    si: &[usize],
    ri: &[usize],
    seed: u64,
    min_runs: usize,
) -> Vec<Vec<f64>> {
    let sim: Vec<Dem> = si.iter().map(|&k| sets.sim[k]).collect();
    let moments: Option<Vec<dem_sensor::Moment>> = sets.sim_moments.as_ref().map(|m| si.iter().map(|&k| m[k]).collect());
    let paired = sets.paired;
    let steps = sets.sim_steps_in(si);
    let (_, a) = crate::measure_at(model, &sim, moments.as_deref(), steps.as_deref(), paired, seed);
    let (_, b) = crate::measure_at(model, &sim, moments.as_deref(), steps.as_deref(), paired, crate::other_draws(seed));
    let draw = raw_components(&a, &b);
    if paired || ri.len() < 100 {
        return draw;
    }
    let runs: Option<Vec<u64>> = sets.real_runs.as_ref().map(|r| ri.iter().map(|&k| r[k]).collect());
    let ter: Option<Vec<Terrain>> = sets.real_terrain.as_ref().map(|t| ri.iter().map(|&k| t[k]).collect());
    let [ha, hb] = crate::halves_of_runs(ri.len(), runs.as_deref(), ter.as_deref(), min_runs);
    if ha.is_empty() || hb.is_empty() {
        return draw;
    }
    let st = |h: &[usize]| {
        let idx: Vec<usize> = h.iter().map(|&k| ri[k]).collect();
        let steps = sets.real_steps_in(&idx);
        summarise(&pick(&sets.real, &idx), None, steps.as_deref())
    };
    let scale = (1.0 / si.len() as f64 + 1.0 / ri.len() as f64) / (1.0 / ha.len() as f64 + 1.0 / hb.len() as f64);
    // The split's gap scaled to the sizes, component by component, as the
    // reported floor scales its sum.
    let split: Vec<Vec<f64>> = raw_components(&st(&ha), &st(&hb)).into_iter().map(|t| t.into_iter().map(|c| c * scale).collect()).collect();
    if floor_at(&split, 1.0, 1.0) > floor_at(&draw, 1.0, 1.0) {
        split
    } else {
        draw
    }
}

/// Records that would lift `gap` above the sampling `floor` of `model`
/// ([`MoreData`]); None when the gap is not below the floor, or there is
/// no gap or no halves to measure the floor's fall on.
///
/// The floor is the sum over statistics of the mean of ln(1 + z^2) over
/// components, each z a sampling difference with variance ~ 1/n. Its
/// components at the current size N give each z^2; at size n each is
/// scaled by (N / n)^beta, and beta is fitted so that the floor so moved to
/// N / 2 is the floor measured on the sampling halves (sim half k against
/// real half k, each dealt in halves again as the whole set was): beta = 1
/// is pure sampling. Then floor(n) = gap is solved for n, the gap staying.
pub fn more_data(sets: &crate::Sets, model: &dem_sensor::SensorModel, gap: f64, floor: f64, seed: u64) -> Option<MoreData> {
    if gap.partial_cmp(&floor) != Some(std::cmp::Ordering::Less) || gap <= 0.0 || sets.real.len() < 100 {
        return None;
    }
    let rh = crate::real_halves(sets);
    let sh = if sets.paired || sets.over_pairs { rh.clone() } else { crate::sim_halves(sets) };
    if rh.iter().chain(&sh).any(Vec::is_empty) {
        return None;
    }
    let runs_now = sets.real_runs.as_ref().map(|r| {
        let mut v = r.clone();
        v.sort_unstable();
        v.dedup();
        v.len() as u64
    });
    // The halves of a half are dealt by run when the whole set's were.
    let min_runs = if runs_now.is_some_and(|n| n as usize >= crate::MIN_RUNS_FOR_HALVES) { 2 } else { usize::MAX };
    let all_s: Vec<usize> = (0..sets.sim.len()).collect();
    let all_r: Vec<usize> = (0..sets.real.len()).collect();
    let raw = floor_on(sets, model, &all_s, &all_r, seed, crate::MIN_RUNS_FOR_HALVES);
    let floor_n = floor_at(&raw, 1.0, 1.0);
    let floor_half = (0..2).map(|k| floor_at(&floor_on(sets, model, &sh[k], &rh[k], seed, min_runs), 1.0, 1.0)).sum::<f64>() / 2.0;
    // beta: floor_at(raw, 2, beta) = floor_half, by bisection (increasing in beta).
    let (mut lo, mut hi) = (0.5f64, 2.0f64);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if floor_at(&raw, 2.0, mid) < floor_half {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let beta = 0.5 * (lo + hi);
    if floor_at(&raw, 1e-4, beta) >= gap {
        return None;
    }
    // n / N: floor_at(raw, N / n, beta) = gap, decreasing in n.
    let (mut lo, mut hi) = (0.0f64, 4.0f64); // log10 of n / N
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if floor_at(&raw, 10f64.powf(-mid), beta) > gap {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let factor = 10f64.powf(0.5 * (lo + hi));
    Some(MoreData {
        gap,
        floor: floor_n.max(floor),
        floor_half,
        exponent_measured: (floor_half / floor_n).log2(),
        exponent: beta,
        factor,
        records: (factor * sets.real.len() as f64).ceil() as u64,
        sim_records: (factor * sets.sim.len() as f64).ceil() as u64,
        runs: runs_now.map(|n| (factor * n as f64).ceil() as u64),
        runs_now,
    })
}

impl MoreData {
    /// One line for stderr.
    pub fn sentence(&self, real_now: usize, sim_now: usize) -> String {
        let runs = match (self.runs, self.runs_now) {
            (Some(r), Some(n)) => format!(" ({r} runs instead of {n})"),
            _ => String::new(),
        };
        format!(
            "more data: the gap {:.3} is below the sampling floor {:.3}; about {} real records{runs} and {} sim records instead of {real_now} and {sim_now} \
             (x{:.1}) would lift it above the floor if the gap is a real one (floor {:.3} at half the records: sampling variance ~ n^-{:.2})",
            self.gap, self.floor, self.records, self.sim_records, self.factor, self.floor_half, self.exponent
        )
    }
}

/// Missing-cell rates per terrain (labels on both sides) and for all
/// records, behind and ahead of the robot: sim, model(sim) (`out`), real.
/// `times`: the sim labels carry times (so `startup` is fitted by time);
/// `below_floor`: the final gap is below its sampling floor.
pub fn missing_bands(
    sim: &[Dem],
    out: &[Dem],
    real: &[Dem],
    terrains: Option<(&[Terrain], &[Terrain])>,
    times: bool,
    below_floor: bool,
) -> Vec<BandRow> {
    let mut rows = Vec::new();
    let all_rates: Vec<[f64; 3]> = HALF_BANDS
        .iter()
        .map(|(_, r)| [missing_rate(sim.iter(), r.clone()), missing_rate(out.iter(), r.clone()), missing_rate(real.iter(), r.clone())])
        .collect();
    let reason = |band: &str, terrain: Option<Terrain>, m: [f64; 3], all: [f64; 3]| -> Option<String> {
        if (m[1] - m[2]).abs() <= MISSING_FLAG {
            return None;
        }
        let mut why = Vec::new();
        if band == "behind" && !times {
            why.push("no `time` in the sim labels: `startup` (the rows behind the robot blind in a run's first frames) is fitted per record, not by time".to_string());
        }
        if terrain.is_some() && (all[1] - all[2]).abs() <= MISSING_FLAG {
            why.push("the model's effects act alike on every terrain and match the rate over all records; the difference is this terrain's, which no effect of the vocabulary has".to_string());
        }
        if terrain.is_none() && band == "behind" && times {
            why.push("behind the robot the map keeps cells seen earlier; see the Unexplained section".to_string());
        }
        if terrains.is_none() {
            why.push(
                "no terrain labels on both sides: the rate is over all terrains, and the two sets' terrain mixes may differ".to_string(),
            );
        }
        if below_floor {
            why.push("the gap left is below the sampling floor: the records may not tell this difference from sampling".to_string());
        }
        if why.is_empty() {
            why.push("not known: see the Unexplained section".to_string());
        }
        Some(why.join("; "))
    };
    for (k, (band, _)) in HALF_BANDS.iter().enumerate() {
        rows.push(BandRow {
            terrain: None,
            band,
            records: real.len(),
            missing: all_rates[k],
            flag: reason(band, None, all_rates[k], all_rates[k]),
        });
    }
    if let Some((ts, tr)) = terrains {
        for t in Terrain::ALL {
            let si: Vec<usize> = (0..ts.len()).filter(|&k| ts[k] == t).collect();
            let ri: Vec<usize> = (0..tr.len()).filter(|&k| tr[k] == t).collect();
            if si.is_empty() || ri.is_empty() {
                continue;
            }
            for (k, (band, r)) in HALF_BANDS.iter().enumerate() {
                let m = [
                    missing_rate(si.iter().map(|&i| &sim[i]), r.clone()),
                    missing_rate(si.iter().map(|&i| &out[i]), r.clone()),
                    missing_rate(ri.iter().map(|&i| &real[i]), r.clone()),
                ];
                rows.push(BandRow { terrain: Some(t), band, records: ri.len(), missing: m, flag: reason(band, Some(t), m, all_rates[k]) });
            }
        }
    }
    rows
}

/// x of the centre of each row, for the pictures.
pub fn row_xs() -> Vec<f64> {
    (0..GRID_ROWS).map(row_center_x).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::distribution;
    use dem_core::format::empty_dem;

    fn flat(n: usize, hole: impl Fn(usize, usize, usize) -> bool) -> Vec<Dem> {
        (0..n)
            .map(|k| {
                let mut d = empty_dem();
                for r in 0..GRID_ROWS {
                    for c in 0..COLS {
                        if !hole(k, r, c) {
                            d.set_valid(r, c, -0.07 + 0.001 * ((k * 7 + r * 3 + c) % 5) as f32);
                        }
                    }
                }
                d
            })
            .collect()
    }

    /// The components sum to the gap; per row they land where the
    /// difference is.
    #[test]
    fn components_sum_to_the_gap_and_sit_in_their_rows() {
        let a = distribution::stats(&flat(300, |_, _, _| false), None);
        let real = flat(300, |k, r, c| r >= 15 && c <= 1 && k % 3 == 0);
        let b = distribution::stats(&real, None);
        let c = gap_components(&a, &b);
        assert!((total(&c) - distribution::gap(&a, &b)).abs() < 1e-9);
        let (rows, _) = by_row(&c);
        assert!(rows[..14].iter().all(|&x| x < 1e-9), "{rows:?}");
        assert!(rows[15..].iter().all(|&x| x > 0.1), "{rows:?}");
    }

    /// A hole on the left columns shows on the left view only.
    #[test]
    fn the_side_views_tell_left_from_right() {
        let sim = flat(300, |_, _, _| false);
        let real = flat(300, |k, r, c| r >= 12 && c <= 1 && k % 2 == 0);
        let idx: Vec<usize> = (0..300).collect();
        let gap_of = |left: bool| compare(&sim, &sim, &sim, &real, false, &idx, &idx, None, &|d| side_view(d, left), None).gap();
        assert!(gap_of(true) > 1.0 && gap_of(false) < 1e-9, "{} {}", gap_of(true), gap_of(false));
    }

    /// A band's missing rate is flagged where model and real differ by
    /// more than 5 %, with the reasons: no time behind the robot, no
    /// labels, below the sampling floor.
    #[test]
    fn missing_bands_flag_with_a_reason() {
        let sim = flat(100, |_, _, _| false);
        let real = flat(100, |k, r, _| r < 3 && k % 2 == 0);
        let rows = missing_bands(&sim, &sim, &real, None, false, false);
        assert_eq!(rows.len(), 2);
        let why = rows[0].flag.as_deref().unwrap();
        assert!(why.contains("`time`") && why.contains("no terrain labels") && !why.contains("sampling floor"), "{why}");
        assert!(rows[1].flag.is_none());
        let rows = missing_bands(&sim, &sim, &real, None, true, true);
        let why = rows[0].flag.as_deref().unwrap();
        assert!(!why.contains("`time`") && why.contains("below the sampling floor"), "{why}");
    }
}
