//! Holes drawn from a generator's raw masks (`dem-apply --sample-masks`).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use dem_core::format::Dem;
use dem_core::seeded::mix;

/// Turn a generator's raw masks into holes drawn at random: cell (r, c) of
/// `out` (the model's output for `input`, record `index` of the whole data
/// set) is valid with probability (m + 1) / 2, m its raw mask in [-1, 1]
/// (clamped). A valid cell keeps the model's height where the model called
/// it valid (m > 0), else takes the input's height (a gated head writes
/// about 0 there); a missing cell is height 0, mask -1. Masks come out as
/// +-1, as a sensor's do.
///
/// Why: a deterministic generator trained on paired data writes the
/// expected mask, e.g. 0.6 where a cell is missing 20 % of the time;
/// thresholding at 0 then never drops it, and the holes a downstream model
/// must learn to cope with disappear. Drawing keeps their rate. Draws: 100
/// uniforms per record from (seed, index), so shards equal the whole.
pub fn sample_masks(input: &Dem, out: &mut Dem, seed: u64, index: u64) {
    use dem_core::format::{DemCells, COLS, GRID_ROWS};
    use rand::Rng;
    let mut rng = ChaCha8Rng::seed_from_u64(mix(seed ^ 0x6d61_736b_5f73_616d));
    rng.set_stream(index);
    for r in 0..GRID_ROWS {
        for c in 0..COLS {
            let u: f64 = rng.gen();
            let m = f64::from(out.mask(r, c)).clamp(-1.0, 1.0);
            if u < (m + 1.0) / 2.0 {
                let h = if m > 0.0 || !input.is_valid(r, c) { out.height(r, c) } else { input.height(r, c) };
                out.set_valid(r, c, h);
            } else {
                out.set_missing(r, c);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sampled_masks_keep_the_rate_and_are_plus_minus_one() {
        use dem_core::format::{empty_dem, DemCells};
        let mut input = empty_dem();
        (0..100).for_each(|i| input.set_valid(i / 5, i % 5, -0.07));
        let mut valid = 0;
        for index in 0..200 {
            let mut out = input;
            (0..100).for_each(|i| out[2 * i + 1] = 0.6); // p(valid) = 0.8
            out[1] = -1.0; // never valid
            out[3] = 1.0; // always valid
            sample_masks(&input, &mut out, 7, index);
            assert!((0..20).all(|r| (0..5).all(|c| out.mask(r, c).abs() == 1.0)));
            assert!(!out.is_valid(0, 0) && out.is_valid(0, 1));
            valid += (0..100).filter(|&i| out.is_valid(i / 5, i % 5)).count();
            let mut again = input;
            (0..100).for_each(|i| again[2 * i + 1] = 0.6);
            again[1] = -1.0;
            again[3] = 1.0;
            sample_masks(&input, &mut again, 7, index);
            assert_eq!(again, out, "the same seed and index draw the same holes");
        }
        let rate = valid as f64 / 20_000.0;
        assert!((rate - (0.01 + 0.98 * 0.8)).abs() < 0.01, "{rate}");
    }
}
