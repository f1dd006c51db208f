//! Text from the public-domain 8x8 bitmap font of `font8x8` (its
//! `BASIC_LEGACY` ASCII table), drawn at an integer scale so every pixel of
//! a glyph becomes a crisp `scale` x `scale` block.
//!
//! Glyph rows run top to bottom; in each row byte, bit `k` (least
//! significant first) is the pixel in column `k`. Text is set
//! proportionally: each glyph advances by its inked width plus one blank
//! column (a space by 4 columns), so "e=0.123" fits under a narrow DEM where
//! a monospaced 8-column advance would not. Characters outside ASCII are
//! drawn as `?`.

use font8x8::legacy::BASIC_LEGACY;

use super::canvas::{Canvas, Rgb};

/// Glyph cell height in font pixels (before scaling).
pub const GLYPH_HEIGHT: u32 = 8;

/// Advance of a space, in font pixels.
const SPACE_ADVANCE: u32 = 4;

/// The 8 row bytes of `c` (`?` for anything outside ASCII).
pub fn glyph(c: char) -> [u8; 8] {
    let i = if c.is_ascii() { c as usize } else { '?' as usize };
    BASIC_LEGACY[i]
}

/// First and last inked column of a glyph, or None for a blank one.
fn ink_columns(g: &[u8; 8]) -> Option<(u32, u32)> {
    let all = g.iter().fold(0u8, |a, &r| a | r);
    (all != 0).then(|| (all.trailing_zeros(), 7 - all.leading_zeros()))
}

/// Horizontal advance of `c` in font pixels: inked width + 1 blank column.
pub fn advance(c: char) -> u32 {
    match ink_columns(&glyph(c)) {
        Some((lo, hi)) => hi - lo + 2,
        None => SPACE_ADVANCE,
    }
}

/// Width in pixels of `s` at `scale` (without the trailing blank column).
pub fn text_width(s: &str, scale: u32) -> u32 {
    let w: u32 = s.chars().map(advance).sum();
    w.saturating_sub(1) * scale
}

/// Height in pixels of a line of text at `scale`.
pub fn text_height(scale: u32) -> u32 {
    GLYPH_HEIGHT * scale
}

/// Draw `s` with its top left corner at `(x, y)`.
pub fn draw_text(canvas: &mut Canvas, x: i64, y: i64, s: &str, scale: u32, color: Rgb) {
    draw(canvas, s, scale, |dx, dy| (x + dx, y + dy), color);
}

/// Draw `s` turned 90 degrees counter-clockwise (reading bottom to top, as a
/// y-axis label), with the start of the text at the bottom: the text's
/// baseline-left corner lands at `(x, y)` and it extends up from there and
/// right by one line height.
pub fn draw_text_up(canvas: &mut Canvas, x: i64, y: i64, s: &str, scale: u32, color: Rgb) {
    // Text pixel (dx along the text, dy down the line) -> screen (x + dy, y - dx).
    draw(canvas, s, scale, |dx, dy| (x + dy, y - 1 - dx), color);
}

/// Draw `s` centred horizontally on `cx`, top at `y`.
pub fn draw_text_centered(canvas: &mut Canvas, cx: i64, y: i64, s: &str, scale: u32, color: Rgb) {
    let w = text_width(s, scale) as i64;
    draw_text(canvas, cx - w / 2, y, s, scale, color);
}

/// Shared glyph walker: `place` maps a pixel offset in unrotated text
/// coordinates to the screen.
fn draw(canvas: &mut Canvas, s: &str, scale: u32, place: impl Fn(i64, i64) -> (i64, i64), color: Rgb) {
    let sc = scale as i64;
    let mut pen = 0i64;
    for c in s.chars() {
        let g = glyph(c);
        let Some((lo, hi)) = ink_columns(&g) else {
            pen += SPACE_ADVANCE as i64 * sc;
            continue;
        };
        for (row, bits) in g.iter().enumerate() {
            for col in lo..=hi {
                if bits >> col & 1 == 1 {
                    let gx = pen + (col - lo) as i64 * sc;
                    let gy = row as i64 * sc;
                    for k in 0..sc * sc {
                        let (px, py) = place(gx + k % sc, gy + k / sc);
                        canvas.set(px, py, color);
                    }
                }
            }
        }
        pen += (hi - lo + 2) as i64 * sc;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::canvas::{BLACK, WHITE};

    /// Inked pixels of a canvas as a set of (x, y).
    fn inked(c: &Canvas) -> Vec<(u32, u32)> {
        let mut v = Vec::new();
        for y in 0..c.height() {
            for x in 0..c.width() {
                if c.get(x, y) == BLACK {
                    v.push((x, y));
                }
            }
        }
        v
    }

    #[test]
    fn one_glyph_sets_exactly_its_pixels_at_scale_2() {
        // '1' in BASIC_LEGACY: rows 0C 0E 0C 0C 0C 0C 3F 00. Ink spans
        // columns 0..=5, so after trimming, bit k lands at column k.
        let g = glyph('1');
        assert_eq!(g, [0x0C, 0x0E, 0x0C, 0x0C, 0x0C, 0x0C, 0x3F, 0x00]);
        let mut c = Canvas::new(20, 20, WHITE);
        draw_text(&mut c, 3, 2, "1", 2, BLACK);
        let mut want = Vec::new();
        for (row, bits) in g.iter().enumerate() {
            for col in 0..8 {
                if bits >> col & 1 == 1 {
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        want.push((3 + 2 * col + dx, 2 + 2 * row as u32 + dy));
                    }
                }
            }
        }
        want.sort_by_key(|&(x, y)| (y, x));
        assert_eq!(inked(&c), want);
        // The flag of the 1 is at the top left: (col 1, row 1) is inked,
        // (col 4, row 1) is not.
        assert_eq!(c.get(3 + 2, 2 + 2), BLACK);
        assert_eq!(c.get(3 + 8, 2 + 2), WHITE);
    }

    #[test]
    fn proportional_widths() {
        assert_eq!(advance('1'), 7);
        assert_eq!(advance('.'), 3);
        assert_eq!(advance(' '), 4);
        assert_eq!(text_width("1.1", 2), (7 + 3 + 7 - 1) * 2);
        assert_eq!(text_width("", 2), 0);
        assert_eq!(glyph('é'), glyph('?'));
    }

    #[test]
    fn rotated_text_reads_bottom_to_top() {
        let mut flat = Canvas::new(30, 30, WHITE);
        let mut up = Canvas::new(30, 30, WHITE);
        draw_text(&mut flat, 0, 0, "L-", 1, BLACK);
        draw_text_up(&mut up, 0, 30, "L-", 1, BLACK);
        // Every inked (x, y) of the flat text appears at (y, 29 - x).
        let mut turned: Vec<(u32, u32)> = inked(&flat).into_iter().map(|(x, y)| (y, 29 - x)).collect();
        turned.sort_by_key(|&(x, y)| (y, x));
        assert_eq!(inked(&up), turned);
    }
}
