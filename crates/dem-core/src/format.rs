//! The DEM record of `docs/format.md`: `float32` of shape `(21, 5, 2)`.
//!
//! A record is stored flat in C order, so cell `(row, col, channel)` sits at
//! `(row * 5 + col) * 2 + channel`. Rows `0..20` are the grid (row 0 is 0.6 m
//! behind the robot centre C, row 19 ends 1.4 m ahead), row 20 holds the
//! attitude. Channel 0 is height in metres, channel 1 the mask (+1 valid,
//! -1 missing).

/// Grid rows along the robot's forward axis (the attitude row is extra).
pub const GRID_ROWS: usize = 20;
/// Rows in a record: the grid plus the attitude row.
pub const ROWS: usize = 21;
/// Columns across the robot.
pub const COLS: usize = 5;
/// Channels: height and mask.
pub const CHANNELS: usize = 2;
/// `f32` values in one record.
pub const RECORD_LEN: usize = ROWS * COLS * CHANNELS;
/// Cells in the grid (rows 0..20 by 5 columns).
pub const GRID_CELLS: usize = GRID_ROWS * COLS;
/// Values of the grid (rows 0..19, both channels): a record without its
/// attitude row, what a generator predicts.
pub const GRID_LEN: usize = GRID_CELLS * CHANNELS;
/// Edge of a grid cell in metres.
pub const CELL: f64 = 0.1;
/// x of the grid's back edge, metres from C (row 0 starts here).
pub const GRID_BACK: f64 = -0.6;
/// x of the grid's front edge, metres from C (row 19 ends here): GRID_BACK
/// plus GRID_ROWS cells, written out so that messages print it as 1.4.
pub const GRID_FRONT: f64 = 1.4;
/// Index of the attitude row.
pub const ATTITUDE_ROW: usize = 20;
/// Height of flat ground under the robot, relative to C.
pub const FLAT_GROUND: f32 = -0.07;
/// Mask value of a valid cell.
pub const VALID: f32 = 1.0;
/// Mask value of a missing cell.
pub const MISSING: f32 = -1.0;

/// One DEM record, flat in C order.
pub type Dem = [f32; RECORD_LEN];

/// Flat index of `(row, col, channel)` in a [`Dem`].
#[inline]
pub const fn at(row: usize, col: usize, channel: usize) -> usize {
    (row * COLS + col) * CHANNELS + channel
}

/// Centre of grid row `row` along x, metres from C (row 0: -0.55 m).
#[inline]
pub fn row_center_x(row: usize) -> f64 {
    GRID_BACK + CELL * (row as f64 + 0.5)
}

/// Centre of column `col` along y, metres from C (y positive to the left).
#[inline]
pub fn col_center_y(col: usize) -> f64 {
    (2.0 - col as f64) * CELL
}

/// Cell accessors on a [`Dem`]; a cell is valid when its mask is > 0.
pub trait DemCells {
    /// Height channel of a grid cell.
    fn height(&self, row: usize, col: usize) -> f32;
    /// Mask channel of a grid cell.
    fn mask(&self, row: usize, col: usize) -> f32;
    /// True when the mask is > 0.
    fn is_valid(&self, row: usize, col: usize) -> bool {
        self.mask(row, col) > 0.0
    }
    /// Number of valid grid cells (rows 0..20).
    fn valid_cells(&self) -> usize;
    /// Set a cell valid with height `h`.
    fn set_valid(&mut self, row: usize, col: usize, h: f32);
    /// Set a cell missing (height 0, mask -1), as the contract stores it.
    fn set_missing(&mut self, row: usize, col: usize);
    /// The five attitude numbers of channel 0 of row 20:
    /// pitch, flipper front-left, front-right, rear-left, rear-right (rad).
    fn attitude(&self) -> [f32; 5];
    /// Write the attitude row (channel 1 is set to 1.0, as the contract says).
    fn set_attitude(&mut self, attitude: [f32; 5]);
}

impl DemCells for Dem {
    #[inline]
    fn height(&self, row: usize, col: usize) -> f32 {
        self[at(row, col, 0)]
    }
    #[inline]
    fn mask(&self, row: usize, col: usize) -> f32 {
        self[at(row, col, 1)]
    }
    fn valid_cells(&self) -> usize {
        (0..GRID_CELLS).filter(|i| self[i * 2 + 1] > 0.0).count()
    }
    #[inline]
    fn set_valid(&mut self, row: usize, col: usize, h: f32) {
        self[at(row, col, 0)] = h;
        self[at(row, col, 1)] = VALID;
    }
    #[inline]
    fn set_missing(&mut self, row: usize, col: usize) {
        self[at(row, col, 0)] = 0.0;
        self[at(row, col, 1)] = MISSING;
    }
    fn attitude(&self) -> [f32; 5] {
        std::array::from_fn(|c| self[at(ATTITUDE_ROW, c, 0)])
    }
    fn set_attitude(&mut self, attitude: [f32; 5]) {
        for (c, a) in attitude.into_iter().enumerate() {
            self[at(ATTITUDE_ROW, c, 0)] = a;
            self[at(ATTITUDE_ROW, c, 1)] = 1.0;
        }
    }
}

/// A record with every grid cell missing and a zero attitude.
pub fn empty_dem() -> Dem {
    let mut d = [0.0; RECORD_LEN];
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            d.set_missing(r, c);
        }
    }
    d.set_attitude([0.0; 5]);
    d
}

/// A record with every grid cell valid at height `h` (m, relative to C) and
/// a zero attitude: level ground, the simplest DEM a test builds on.
pub fn level_dem(h: f32) -> Dem {
    let mut d = empty_dem();
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            d.set_valid(r, c, h);
        }
    }
    d
}

/// Apply the contract's input rule: a NaN height is a missing cell, stored
/// as height 0 and mask -1; a NaN attitude reads as 0 ("not recorded").
/// Everything else is kept bit for bit, so tools that do not touch a record
/// pass it through unchanged.
///
/// Returns whether the record had a NaN height or attitude, or the reason it
/// is bad input: an infinite value anywhere, a NaN in a mask or in row 20's
/// channel 1 (the contract refuses these; nothing may guess what they meant).
pub fn canonicalize(d: &mut Dem) -> Result<bool, String> {
    if let Some(bad) = first_unreadable(d) {
        return Err(bad);
    }
    let mut changed = false;
    for c in 0..COLS {
        let v = &mut d[at(ATTITUDE_ROW, c, 0)];
        if v.is_nan() {
            *v = 0.0;
            changed = true;
        }
    }
    for i in 0..GRID_CELLS {
        let (h, m) = (i * 2, i * 2 + 1);
        if d[h].is_nan() {
            d[h] = 0.0;
            d[m] = MISSING;
            changed = true;
        }
    }
    Ok(changed)
}

/// (row, column, channel) of flat index `j` of a record: the inverse of [`at`].
pub fn cell_of(j: usize) -> (usize, usize, usize) {
    debug_assert!(j < RECORD_LEN);
    (j / (COLS * CHANNELS), j % (COLS * CHANNELS) / CHANNELS, j % CHANNELS)
}

/// Where a record breaks the contract's value rule, said as a reason.
fn first_unreadable(d: &Dem) -> Option<String> {
    let (j, v) = d.iter().enumerate().find(|&(j, v)| v.is_infinite() || (v.is_nan() && j % 2 == 1))?;
    let (row, col, ch) = cell_of(j);
    let what = if ch == 0 {
        "height"
    } else if row == ATTITUDE_ROW {
        "attitude mask"
    } else {
        "mask"
    };
    Some(format!(
        "{v} in the {what} at row {row}, column {col}, channel {ch} (the contract allows no infinite value, and NaN only as a height)"
    ))
}

/// Where a record about to be written holds a value the contract forbids on
/// output (NaN or infinity), said as a reason; None when it is writable.
pub fn unwritable(d: &Dem) -> Option<String> {
    let j = d.iter().position(|v| !v.is_finite())?;
    let (row, col, ch) = cell_of(j);
    Some(format!("{} at row {row}, column {col}, channel {ch}: tools never write NaN or infinity", d[j]))
}

/// Terrain classes of the labels CSV.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Terrain {
    /// Level ground.
    Flat,
    /// A flight of stairs climbed.
    StairsUp,
    /// A flight of stairs descended.
    StairsDown,
    /// A pallet of planks with gaps.
    Pallet,
    /// Anything else (ramps, rubble); data preparation drops it.
    Other,
}

impl Terrain {
    /// Every terrain, in label order.
    pub const ALL: [Terrain; 5] = [Terrain::Flat, Terrain::StairsUp, Terrain::StairsDown, Terrain::Pallet, Terrain::Other];

    /// The label spelling (`flat`, `stairs-up`, ...).
    pub fn as_str(self) -> &'static str {
        match self {
            Terrain::Flat => "flat",
            Terrain::StairsUp => "stairs-up",
            Terrain::StairsDown => "stairs-down",
            Terrain::Pallet => "pallet",
            Terrain::Other => "other",
        }
    }
}

impl std::fmt::Display for Terrain {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for Terrain {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Terrain::ALL
            .into_iter()
            .find(|t| t.as_str() == s)
            .ok_or_else(|| format!("unknown terrain {s:?} (expected flat, stairs-up, stairs-down, pallet or other)"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_matches_c_order_of_21_5_2() {
        assert_eq!(RECORD_LEN, 210);
        assert_eq!(at(0, 0, 1), 1);
        assert_eq!(at(0, 1, 0), 2);
        assert_eq!(at(1, 0, 0), 10);
        assert_eq!(at(20, 4, 1), 209);
    }

    #[test]
    fn rows_span_the_contract_extent() {
        assert!((row_center_x(0) + 0.55).abs() < 1e-12);
        assert!((row_center_x(19) - 1.35).abs() < 1e-12);
        assert!((col_center_y(0) - 0.2).abs() < 1e-12);
        assert!((col_center_y(4) + 0.2).abs() < 1e-12);
    }

    #[test]
    fn nan_height_reads_as_missing() {
        let mut d = empty_dem();
        d.set_valid(3, 2, f32::NAN);
        assert_eq!(canonicalize(&mut d), Ok(true));
        assert_eq!(d.height(3, 2), 0.0);
        assert_eq!(d.mask(3, 2), MISSING);
    }

    #[test]
    fn nan_attitude_reads_as_not_recorded() {
        let mut d = empty_dem();
        d[at(ATTITUDE_ROW, 2, 0)] = f32::NAN;
        assert_eq!(canonicalize(&mut d), Ok(true));
        assert_eq!(d, empty_dem());
    }

    #[test]
    fn infinities_and_nan_masks_are_refused_naming_the_cell() {
        for (j, v, says) in [
            (at(3, 2, 0), f32::INFINITY, "inf in the height at row 3, column 2"),
            (at(4, 1, 1), f32::NEG_INFINITY, "-inf in the mask at row 4, column 1"),
            (at(5, 0, 1), f32::NAN, "NaN in the mask at row 5, column 0"),
            (at(ATTITUDE_ROW, 3, 1), f32::NAN, "NaN in the attitude mask at row 20, column 3"),
            (at(ATTITUDE_ROW, 1, 0), f32::INFINITY, "inf in the height at row 20, column 1"),
        ] {
            let mut d = empty_dem();
            d[j] = v;
            let e = canonicalize(&mut d).unwrap_err();
            assert!(e.contains(says), "{e}");
            assert!(unwritable(&d).is_some());
        }
        assert_eq!(unwritable(&empty_dem()), None);
    }

    #[test]
    fn terrain_labels_round_trip() {
        for t in Terrain::ALL {
            assert_eq!(t.as_str().parse::<Terrain>().unwrap(), t);
        }
        assert!("ramp".parse::<Terrain>().is_err());
    }
}
