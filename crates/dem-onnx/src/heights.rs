//! Where a generator's valid cells take their heights from
//! (`dem-apply --heights`, `dem-train export --heights`).
//!
//! A deterministic generator learns *where* a measured DEM has holes well,
//! and its height head writes the expected measured height. Expected heights
//! are not measured ones: on flat ground it writes one fixed pattern of
//! millimetres for every record, and at pallet boards it makes edges the
//! measured DEMs do not have. dem-gap's effects (noise, blends at drops,
//! hole growth) model what a sensor does to heights by physics, drawn per
//! record. [`Heights::Input`] combines the two: the network places the
//! holes, the input's heights stay, and a residual sensor model fitted on
//! that output adds the measured heights' effects (docs/results.md, "The
//! network's holes, the sim's heights").

use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};

/// The `metadata_props` key that says where a generator's heights come
/// from (`input`; absent: the network's).
pub const HEIGHTS_KEY: &str = "dem.heights";

/// Where the valid cells of a generator's output take their heights from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Heights {
    /// The network's height head, as it writes them.
    #[default]
    Network,
    /// The input's height on every cell the network keeps valid and the
    /// input has; the network's where the input is missing.
    Input,
}

impl Heights {
    /// The name on the command line and in the model's metadata.
    pub fn as_str(self) -> &'static str {
        match self {
            Heights::Network => "network",
            Heights::Input => "input",
        }
    }

    /// Apply to one output record `out` made from `input`; [`Heights::Network`]
    /// leaves it alone.
    pub fn apply(self, input: &Dem, out: &mut Dem) {
        if self == Heights::Input {
            input_heights(input, out);
        }
    }
}

impl std::fmt::Display for Heights {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for Heights {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "network" => Ok(Heights::Network),
            "input" => Ok(Heights::Input),
            _ => Err(format!("`{s}` is not a height source: network or input")),
        }
    }
}

/// The network's holes with the input's heights: a cell of `out` with
/// mask > 0 becomes valid (mask +1) with the input's height where `input` has
/// the cell valid, else with the network's height; every other cell becomes
/// missing (height 0, mask -1), as the contract stores it. Masks come out
/// +-1, as a sensor's do; row 20 is left alone.
pub fn input_heights(input: &Dem, out: &mut Dem) {
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            if !out.is_valid(r, c) {
                out.set_missing(r, c);
            } else if input.is_valid(r, c) {
                out.set_valid(r, c, input.height(r, c));
            } else {
                out.set_valid(r, c, out.height(r, c));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem_core::format::empty_dem;

    #[test]
    fn input_heights_keep_the_networks_holes_and_the_inputs_heights() {
        let mut input = empty_dem();
        input.set_valid(0, 0, -0.07);
        input.set_valid(0, 1, -0.30);
        input.set_attitude([0.1, 0.2, 0.3, 0.4, 0.5]);
        let mut out = input;
        out[1] = 0.4; // (0, 0): valid by the network, mask 0.4
        out[0] = -0.05;
        out[3] = -0.2; // (0, 1): missing by the network
        out[2] = -0.28;
        out[5] = 0.9; // (0, 2): valid by the network, missing in the input
        out[4] = -0.11;
        out[7] = -1.0; // (0, 3): missing in both
        let att = out.attitude();
        Heights::Input.apply(&input, &mut out);
        assert_eq!((out.height(0, 0), out.mask(0, 0)), (-0.07, 1.0), "the input's height, mask +1");
        assert_eq!((out.height(0, 1), out.mask(0, 1)), (0.0, -1.0), "the network's hole, stored as the contract says");
        assert_eq!((out.height(0, 2), out.mask(0, 2)), (-0.11, 1.0), "the network's height where the input has none");
        assert_eq!((out.height(0, 3), out.mask(0, 3)), (0.0, -1.0));
        assert_eq!(out.attitude(), att, "row 20 passes through");
        let before = out;
        Heights::Network.apply(&input, &mut out);
        assert_eq!(out, before, "network heights change nothing");
    }

    #[test]
    fn names_round_trip() {
        for h in [Heights::Network, Heights::Input] {
            assert_eq!(h.as_str().parse::<Heights>(), Ok(h));
        }
        assert!("sim".parse::<Heights>().unwrap_err().contains("network or input"));
    }
}
