//! matplotlib's `jet` colormap and the height range a picture maps onto it.
//!
//! jet is piecewise linear in each channel between these `(x, value)` knots
//! (matplotlib's `_jet_data`):
//!
//! ```text
//! red:   (0, 0)   (0.35, 0)  (0.66, 1)  (0.89, 1)  (1, 0.5)
//! green: (0, 0)   (0.125, 0) (0.375, 1) (0.64, 1)  (0.91, 0) (1, 0)
//! blue:  (0, 0.5) (0.11, 1)  (0.34, 1)  (0.65, 0)  (1, 0)
//! ```
//!
//! so 0 is dark blue (0, 0, 0.5) and 1 dark red (0.5, 0, 0). matplotlib
//! samples it into a table of 256 entries at x = i / 255 and maps a value t
//! to entry `min(floor(256 t), 255)`; [`jet`] does the same, so its colours
//! equal `matplotlib.cm.jet(t)` to rounding, not just roughly.
//!
//! A height h maps to t = (h - min) / (max - min), clamped to [0, 1], with
//! one [`HeightRange`] shared by every DEM of a picture so equal colours mean
//! equal heights across it.

use super::canvas::Rgb;

/// `(x, value)` knots of one channel.
type Knots = &'static [(f64, f64)];

const RED: Knots = &[(0.0, 0.0), (0.35, 0.0), (0.66, 1.0), (0.89, 1.0), (1.0, 0.5)];
const GREEN: Knots = &[(0.0, 0.0), (0.125, 0.0), (0.375, 1.0), (0.64, 1.0), (0.91, 0.0), (1.0, 0.0)];
const BLUE: Knots = &[(0.0, 0.5), (0.11, 1.0), (0.34, 1.0), (0.65, 0.0), (1.0, 0.0)];

/// Linear interpolation between the knots around `x` (x in [0, 1]).
fn channel(knots: Knots, x: f64) -> f64 {
    let i = knots.iter().rposition(|&(k, _)| k <= x).unwrap_or(0).min(knots.len() - 2);
    let ((x0, y0), (x1, y1)) = (knots[i], knots[i + 1]);
    y0 + (y1 - y0) * ((x - x0) / (x1 - x0)).clamp(0.0, 1.0)
}

/// `matplotlib.cm.jet(t)` as RGB fractions in [0, 1]; t outside [0, 1] is
/// clamped (NaN reads as 0).
pub fn jet(t: f64) -> [f64; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = ((t * 256.0).floor() as usize).min(255) as f64 / 255.0;
    [channel(RED, x), channel(GREEN, x), channel(BLUE, x)]
}

/// [`jet`] as 8-bit RGB, each channel rounded to the nearest of 0..=255.
pub fn jet_rgb(t: f64) -> Rgb {
    jet(t).map(|v| (v * 255.0).round() as u8)
}

/// The heights a picture's colours span: `min` maps to dark blue, `max` to
/// dark red.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeightRange {
    /// Height in metres drawn dark blue (and everything below it).
    pub min: f32,
    /// Height in metres drawn dark red (and everything above it).
    pub max: f32,
}

/// Half width of the range around a single height (all heights equal).
pub const FLAT_HALF_WIDTH: f32 = 0.05;

impl HeightRange {
    /// The range from `vmin`/`vmax` where given, else from the smallest and
    /// largest of `heights`. When they are all equal (or there are none,
    /// around -0.07 m, flat ground), the range is +-0.05 m around that
    /// height. Errors when the result is empty or not finite, with a message
    /// naming the flag at fault.
    pub fn resolve(vmin: Option<f32>, vmax: Option<f32>, heights: impl IntoIterator<Item = f32>) -> Result<Self, String> {
        let (lo, hi) =
            heights.into_iter().filter(|h| h.is_finite()).fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), h| (lo.min(h), hi.max(h)));
        let (lo, hi) = if lo > hi { (dem_core::format::FLAT_GROUND, dem_core::format::FLAT_GROUND) } else { (lo, hi) };
        let (lo, hi) = if lo == hi { (lo - FLAT_HALF_WIDTH, hi + FLAT_HALF_WIDTH) } else { (lo, hi) };
        let range = HeightRange { min: vmin.unwrap_or(lo), max: vmax.unwrap_or(hi) };
        if !(range.min.is_finite() && range.max.is_finite()) {
            return Err("--vmin and --vmax must be finite numbers".into());
        }
        if range.min >= range.max {
            return Err(match (vmin, vmax) {
                (Some(a), Some(b)) => format!("--vmin {a} must be below --vmax {b}"),
                (Some(a), None) => format!("--vmin {a} is not below the highest height shown ({hi}); give --vmax too"),
                _ => format!("--vmax {} is not above the lowest height shown ({lo}); give --vmin too", range.max),
            });
        }
        Ok(range)
    }

    /// Where `h` falls in the range: (h - min) / (max - min), clamped to [0, 1].
    pub fn fraction(&self, h: f32) -> f64 {
        ((h as f64 - self.min as f64) / (self.max as f64 - self.min as f64)).clamp(0.0, 1.0)
    }

    /// The colour of height `h`.
    pub fn color(&self, h: f32) -> Rgb {
        jet_rgb(self.fraction(h))
    }

    /// Tick marks for a colour bar, low to high: both ends of the range and
    /// the "nice" values between them (multiples of 1, 2, 2.5 or 5 times a
    /// power of ten, chosen so there are about six intervals), as matplotlib
    /// picks them. Nice values closer than 3/4 of a step to an end are
    /// dropped so labels never crowd. Labels are in metres with at least 2 decimals
    /// (centimetres) and as many as the step needs, so the ends read
    /// exactly (`-0.07`, `0.20`).
    pub fn ticks(&self) -> Vec<(f32, String)> {
        let (lo, hi) = (self.min as f64, self.max as f64);
        let raw = (hi - lo) / 6.0;
        let mag = 10f64.powf(raw.log10().floor());
        let nice = [1.0, 2.0, 2.5, 5.0, 10.0].into_iter().find(|&m| m * mag >= raw * (1.0 - 1e-6)).unwrap_or(10.0);
        let step = nice * mag;
        let extra = usize::from(nice == 2.5);
        let decimals = ((-step.log10().floor()).max(0.0) as usize + extra).clamp(2, 6);
        let eps = step * 1e-6;
        let mut values = vec![lo];
        for k in (lo / step).ceil() as i64..=(hi / step).floor() as i64 {
            let v = k as f64 * step;
            if v - lo >= 0.75 * step - eps && hi - v >= 0.75 * step - eps {
                values.push(v);
            }
        }
        values.push(hi);
        values
            .into_iter()
            .map(|v| {
                let s = format!("{v:.decimals$}");
                // "-0.00" reads as a sign error; zero has no sign.
                let zero = s.trim_start_matches('-').chars().all(|c| c == '0' || c == '.');
                (v as f32, if zero { s.trim_start_matches('-').to_string() } else { s })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // matplotlib.cm.jet(t)[:3] for t = k/16, printed by matplotlib 3.x:
    //   import matplotlib; [matplotlib.colormaps["jet"](k / 16) for k in range(17)]
    const MPL: [(f64, [f64; 3]); 9] = [
        (0.0, [0.0, 0.0, 0.5]),
        (0.0625, [0.0, 0.0, 0.785204991087344]),
        (0.125, [0.0, 0.00196078431372549, 1.0]),
        (0.25, [0.0, 0.503921568627451, 1.0]),
        (0.375, [0.08538899430740036, 1.0, 0.8823529411764706]),
        (0.5, [0.4901960784313725, 1.0, 0.4775458570524984]),
        (0.75, [1.0, 0.5816993464052289, 0.0]),
        (0.9375, [0.7673796791443852, 0.0, 0.0]),
        (1.0, [0.5, 0.0, 0.0]),
    ];

    #[test]
    fn jet_matches_matplotlib() {
        // Tolerance 1e-12: the same table arithmetic in f64 as matplotlib's.
        for (t, want) in MPL {
            let got = jet(t);
            for ch in 0..3 {
                assert!((got[ch] - want[ch]).abs() < 1e-12, "jet({t}) = {got:?}, matplotlib {want:?}");
            }
        }
    }

    #[test]
    fn jet_ends_are_dark_blue_and_dark_red() {
        assert_eq!(jet_rgb(0.0), [0, 0, 128]);
        assert_eq!(jet_rgb(1.0), [128, 0, 0]);
        assert_eq!(jet_rgb(-3.0), jet_rgb(0.0));
        assert_eq!(jet_rgb(7.0), jet_rgb(1.0));
        assert_eq!(jet_rgb(0.5), [125, 255, 122]);
    }

    #[test]
    fn range_from_heights_and_flags() {
        let r = HeightRange::resolve(None, None, [-0.07, 0.1, 0.03]).unwrap();
        assert_eq!((r.min, r.max), (-0.07, 0.1));
        assert_eq!(r.fraction(-0.07), 0.0);
        assert_eq!(r.fraction(0.1), 1.0);
        assert_eq!(r.fraction(5.0), 1.0);
        let flat = HeightRange::resolve(None, None, [0.2, 0.2]).unwrap();
        assert!((flat.min - 0.15).abs() < 1e-6 && (flat.max - 0.25).abs() < 1e-6);
        let none = HeightRange::resolve(None, None, []).unwrap();
        assert!((none.min + 0.12).abs() < 1e-6);
        let fixed = HeightRange::resolve(Some(-0.5), Some(0.5), [0.0]).unwrap();
        assert_eq!((fixed.min, fixed.max), (-0.5, 0.5));
        assert!(HeightRange::resolve(Some(0.5), None, [0.0, 0.1]).unwrap_err().contains("--vmin 0.5"));
        assert!(HeightRange::resolve(Some(1.0), Some(1.0), [0.0]).unwrap_err().contains("below --vmax"));
    }

    #[test]
    fn tick_labels_read_exactly_at_the_ends() {
        let r = HeightRange { min: -0.07, max: 0.2 };
        let labels = |r: HeightRange| r.ticks().into_iter().map(|t| t.1).collect::<Vec<_>>();
        assert_eq!(labels(r), ["-0.07", "0.00", "0.05", "0.10", "0.15", "0.20"]);
        let fine = HeightRange { min: 0.0, max: 0.1 };
        assert_eq!(labels(fine), ["0.00", "0.02", "0.04", "0.06", "0.08", "0.10"]);
        // 0.0 is within 3/4 of a step (0.02) of the end -0.0012: dropped,
        // and the end itself reads "0.00", not "-0.00".
        let small = HeightRange { min: -0.0012, max: 0.06 };
        assert_eq!(labels(small), ["0.00", "0.02", "0.04", "0.06"]);
        let quarter = HeightRange { min: 0.0, max: 0.15 };
        assert_eq!(labels(quarter), ["0.000", "0.025", "0.050", "0.075", "0.100", "0.125", "0.150"]);
        // 0.05 is 0.03 (0.6 step) below the end 0.08: dropped, so the top
        // two labels do not crowd.
        let pallet = HeightRange { min: -0.22, max: 0.08 };
        assert_eq!(labels(pallet), ["-0.22", "-0.15", "-0.10", "-0.05", "0.00", "0.08"]);
    }
}
