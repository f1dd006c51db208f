//! Line plots of series over any x axis (training curves, sweeps), with
//! "nice" ticks (1, 2 or 5 times a power of ten), an optional log y axis and
//! a legend; several plots stack into one picture with [`stack`].

use super::canvas::{Canvas, Rgb, BLACK, GRID, TEXT, WHITE};
use super::font::{draw_text, draw_text_centered, text_height, text_width};

/// Series colours, distinguishable and in a fixed order.
pub const PALETTE: [Rgb; 6] = [[31, 119, 180], [214, 39, 40], [44, 160, 44], [255, 127, 14], [148, 103, 189], [23, 190, 207]];

/// One series: a name for the legend, a colour and y values over the plot's xs
/// (non-finite values are left out).
pub type Series = (String, Rgb, Vec<f64>);

/// A tick step of about `span / 6`: 1, 2 or 5 times a power of ten.
pub fn nice_step(span: f64) -> f64 {
    let raw = (span / 6.0).max(f64::MIN_POSITIVE);
    let p = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0].into_iter().map(|m| m * p).find(|s| *s >= raw).unwrap_or(10.0 * p)
}

fn label(v: f64, step: f64) -> String {
    let decimals = (-step.log10().floor()).max(0.0) as usize;
    format!("{v:.decimals$}")
}

/// A line plot of `series` over `xs`; with `log_y` the y axis is log10 (values
/// <= 0 are left out).
pub fn line_plot(title: &str, xlabel: &str, xs: &[f64], series: &[Series], log_y: bool) -> Canvas {
    let (w, h) = (900i64, 380i64);
    let (l, r, t, b) = (90i64, 200i64, 40i64, 56i64);
    let mut c = Canvas::new(w as u32, h as u32, WHITE);
    let ty = |v: f64| {
        if log_y {
            if v > 0.0 {
                v.log10()
            } else {
                f64::NAN
            }
        } else {
            v
        }
    };
    let ys: Vec<f64> = series.iter().flat_map(|s| s.2.iter().map(|&v| ty(v))).filter(|v| v.is_finite()).collect();
    let (mut lo, mut hi) = ys.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        (lo, hi) = (0.0, 1.0);
    }
    if hi - lo < 1e-12 {
        (lo, hi) = (lo - 0.5, hi + 0.5);
    }
    let pad = 0.05 * (hi - lo);
    let (lo, hi) = (lo - pad, hi + pad);
    let (x0, x1) = match (xs.first(), xs.last()) {
        (Some(&a), Some(&z)) if z > a => (a, z),
        (Some(&a), _) => (a - 0.5, a + 0.5),
        _ => (0.0, 1.0),
    };
    let px = |x: f64| l + ((x - x0) / (x1 - x0) * (w - l - r) as f64).round() as i64;
    let py = |y: f64| h - b - ((y - lo) / (hi - lo) * (h - t - b) as f64).round() as i64;
    draw_text(&mut c, l, 10, title, 2, TEXT);
    let step = nice_step(hi - lo);
    let mut y = (lo / step).ceil() * step;
    while y <= hi {
        c.hline(l, py(y), w - l - r, GRID);
        let s = if log_y { format!("{:.3}", 10f64.powf(y)) } else { label(y, step) };
        draw_text(&mut c, l - 8 - text_width(&s, 1) as i64, py(y) - 4, &s, 1, TEXT);
        y += step;
    }
    let step = nice_step(x1 - x0);
    let mut x = (x0 / step).ceil() * step;
    while x <= x1 + 1e-9 {
        c.vline(px(x), t, h - t - b, GRID);
        draw_text_centered(&mut c, px(x), h - b + 8, &label(x, step), 1, TEXT);
        x += step;
    }
    c.hline(l, h - b, w - l - r, BLACK);
    c.vline(l, t, h - t - b, BLACK);
    draw_text_centered(&mut c, l + (w - l - r) / 2, h - b + 28, xlabel, 1, TEXT);
    for (k, (name, color, v)) in series.iter().enumerate() {
        let pts: Vec<(i64, i64)> =
            xs.iter().zip(v).map(|(&x, &y)| (x, ty(y))).filter(|(_, y)| y.is_finite()).map(|(x, y)| (px(x), py(y))).collect();
        for p in pts.windows(2) {
            line(&mut c, p[0], p[1], *color, 2);
        }
        // A lone point (a one-epoch run) has no segment: mark it.
        if let [(x, y)] = pts[..] {
            c.fill_rect(x - 3, y - 3, 7, 7, *color);
        }
        let ly = t + 10 + k as i64 * (text_height(2) as i64 + 8);
        c.fill_rect(w - r + 15, ly + 2, 20, 10, *color);
        draw_text(&mut c, w - r + 42, ly, name, 1, TEXT);
    }
    c
}

/// Plots one under the other (widths may differ; the widest sets the width).
pub fn stack(plots: &[Canvas]) -> Canvas {
    let width = plots.iter().map(Canvas::width).max().unwrap_or(1);
    let height = plots.iter().map(Canvas::height).sum::<u32>().max(1);
    let mut out = Canvas::new(width, height, WHITE);
    let mut y0 = 0;
    for p in plots {
        for y in 0..p.height() {
            for x in 0..p.width() {
                out.set(x as i64, (y + y0) as i64, p.get(x, y));
            }
        }
        y0 += p.height();
    }
    out
}

/// A line `width` pixels wide (Bresenham, each point a width x width square).
pub fn line(c: &mut Canvas, (x0, y0): (i64, i64), (x1, y1): (i64, i64), color: Rgb, width: i64) {
    let (dx, dy) = ((x1 - x0).abs(), -(y1 - y0).abs());
    let (sx, sy) = (if x0 < x1 { 1 } else { -1 }, if y0 < y1 { 1 } else { -1 });
    let (mut x, mut y, mut err) = (x0, y0, dx + dy);
    loop {
        c.fill_rect(x - (width - 1) / 2, y - (width - 1) / 2, width, width, color);
        if x == x1 && y == y1 {
            break;
        }
        let e2 = 2 * err;
        if e2 >= dy {
            err += dy;
            x += sx;
        }
        if e2 <= dx {
            err += dx;
            y += sy;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_nice() {
        assert_eq!(nice_step(30.0), 5.0);
        assert_eq!(nice_step(1.0), 0.2);
        assert_eq!(nice_step(0.06), 0.01);
        assert_eq!(label(0.25, 0.05), "0.25");
        assert_eq!(label(20.0, 5.0), "20");
    }

    #[test]
    fn a_plot_draws_its_series_and_stacks() {
        let xs: Vec<f64> = (1..=30).map(f64::from).collect();
        let s = vec![("loss".to_string(), PALETTE[1], xs.iter().map(|x| 1.0 / x).collect())];
        let c = line_plot("t", "epoch", &xs, &s, true);
        let red = (0..c.height()).flat_map(|y| (0..c.width()).map(move |x| (x, y))).filter(|&(x, y)| c.get(x, y) == PALETTE[1]).count();
        assert!(red > 500, "the series is drawn ({red} pixels)");
        let both = stack(&[c.clone(), line_plot("u", "x", &[0.0], &[], false)]);
        assert_eq!((both.width(), both.height()), (900, 760));
    }
}
