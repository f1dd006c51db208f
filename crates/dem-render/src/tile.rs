//! One DEM drawn as a tile of coloured cells, the robot marker beside it,
//! and the colour bar that explains the colours.
//!
//! Cell `(row, col)` of the grid covers the `cell` x `cell` pixel square at
//! `(x0 + col * cell, y0 + row * cell)` from the tile's top left `(x0, y0)`:
//! row 0 (0.6 m behind the robot centre C) at the top, row 19 (ending 1.4 m
//! ahead) at the bottom, so the robot sits near the top of the tile facing
//! down; column 0 (the robot's left, y = +0.2 m) is on the left, as
//! `imshow` draws the array. C, the boundary between rows 5 and 6, is
//! `6 * cell` pixels below the tile's top; a small triangle pointing down
//! (the robot's heading) marks it on the left side. Row 20 (attitude) is not
//! drawn.

use super::canvas::{Canvas, BLACK, GRID, TEXT, WHITE};
use super::colormap::HeightRange;
use super::font;
use dem_core::format::{Dem, DemCells, COLS, GRID_ROWS};

/// Grid rows behind C: C is the top edge of this row.
pub const ROWS_BEHIND_C: u32 = 6;

/// How tiles look.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TileStyle {
    /// Edge of one cell in pixels.
    pub cell: u32,
    /// Draw thin grey lines between cells.
    pub cell_lines: bool,
    /// Integer scale of the 8x8 font (2 = 16 pixels high).
    pub text_scale: u32,
}

impl Default for TileStyle {
    /// 16-pixel cells (a DEM is 80 x 320 pixels), no cell lines, text 16
    /// pixels high.
    fn default() -> Self {
        TileStyle { cell: 16, cell_lines: false, text_scale: 2 }
    }
}

impl TileStyle {
    /// Tile width in pixels (5 cells).
    pub fn width(&self) -> u32 {
        COLS as u32 * self.cell
    }

    /// Tile height in pixels (20 cells).
    pub fn height(&self) -> u32 {
        GRID_ROWS as u32 * self.cell
    }

    /// Half width of the robot marker triangle, in pixels.
    pub fn marker_half(&self) -> u32 {
        (self.cell * 2 / 5).max(3)
    }

    /// Pixels the robot marker needs left of a tile (triangle plus gap).
    pub fn marker_room(&self) -> u32 {
        2 * self.marker_half() + 4
    }
}

/// Pixel rectangle `(x, y, w, h)` of grid cell `(row, col)`, relative to
/// the tile's top left corner.
pub fn cell_rect(row: usize, col: usize, cell: u32) -> (u32, u32, u32, u32) {
    (col as u32 * cell, row as u32 * cell, cell, cell)
}

/// Draw `dem` with its top left at `(x0, y0)`: jet over `range` for valid
/// cells, white for missing ones (mask <= 0), optional cell lines, a black
/// frame just outside the tile and the robot marker left of it.
pub fn draw_dem(canvas: &mut Canvas, x0: i64, y0: i64, dem: &Dem, range: &HeightRange, style: &TileStyle) {
    let cell = style.cell;
    for row in 0..GRID_ROWS {
        for col in 0..COLS {
            let color = if dem.is_valid(row, col) { range.color(dem.height(row, col)) } else { WHITE };
            let (x, y, w, h) = cell_rect(row, col, cell);
            canvas.fill_rect(x0 + x as i64, y0 + y as i64, w as i64, h as i64, color);
        }
    }
    let (w, h) = (style.width() as i64, style.height() as i64);
    if style.cell_lines {
        for col in 1..COLS as i64 {
            canvas.vline(x0 + col * cell as i64, y0, h, GRID);
        }
        for row in 1..GRID_ROWS as i64 {
            canvas.hline(x0, y0 + row * cell as i64, w, GRID);
        }
    }
    canvas.frame_around(x0, y0, w, h, BLACK);
    let half = style.marker_half() as i64;
    let c_y = y0 + (ROWS_BEHIND_C * cell) as i64;
    canvas.triangle_down(x0 - 3 - half, c_y - half / 2, half, TEXT);
}

/// Text of the robot marker's legend.
pub const MARKER_LEGEND: &str = "robot";

/// Draw the legend of the robot marker (the triangle and "robot") with its
/// top left at `(x0, y0)`; it is one text line high.
pub fn draw_marker_legend(canvas: &mut Canvas, x0: i64, y0: i64, style: &TileStyle) {
    let half = style.marker_half() as i64;
    let text_h = font::text_height(style.text_scale) as i64;
    canvas.triangle_down(x0 + half, y0 + (text_h - half) / 2, half, TEXT);
    font::draw_text(canvas, x0 + 2 * half + 6, y0, MARKER_LEGEND, style.text_scale, TEXT);
}

/// Tick labels the colour bar will show (exposed so layout can size it).
fn tick_label_width(range: &HeightRange, scale: u32) -> u32 {
    range.ticks().iter().map(|(_, l)| font::text_width(l, scale)).max().unwrap_or(0)
}

/// Width of the colour bar bar itself, in pixels.
const BAR_WIDTH: u32 = 18;
/// Length of a tick mark.
const TICK: u32 = 5;
/// The colour bar's axis label.
pub const BAR_LABEL: &str = "height [m]";

/// Width in pixels that [`draw_colorbar`] uses: bar, ticks, labels and the
/// turned axis label.
pub fn colorbar_width(range: &HeightRange, scale: u32) -> u32 {
    BAR_WIDTH + TICK + 4 + tick_label_width(range, scale) + 10 + font::text_height(scale)
}

/// Draw a vertical colour bar of height `h` with its top left at `(x0, y0)`:
/// `max` at the top, `min` at the bottom, tick labels in metres on the
/// right and the label `height [m]` turned to read bottom to top.
pub fn draw_colorbar(canvas: &mut Canvas, x0: i64, y0: i64, h: u32, range: &HeightRange, scale: u32) {
    let h = h.max(2) as i64;
    // Pixel row y shows the height at its centre; the top row is `max`.
    for y in 0..h {
        let t = 1.0 - y as f64 / (h - 1) as f64;
        let height = range.min as f64 + t * (range.max as f64 - range.min as f64);
        canvas.hline(x0, y0 + y, BAR_WIDTH as i64, range.color(height as f32));
    }
    canvas.frame_around(x0, y0, BAR_WIDTH as i64, h, BLACK);
    let text_h = font::text_height(scale) as i64;
    let label_x = x0 + (BAR_WIDTH + TICK + 4) as i64;
    for (value, label) in range.ticks() {
        let y = y0 + ((1.0 - range.fraction(value)) * (h - 1) as f64).round() as i64;
        canvas.hline(x0 + BAR_WIDTH as i64, y, TICK as i64, BLACK);
        font::draw_text(canvas, label_x, y - text_h / 2 + scale as i64 / 2, &label, scale, TEXT);
    }
    let axis_x = label_x + tick_label_width(range, scale) as i64 + 10;
    let axis_len = font::text_width(BAR_LABEL, scale) as i64;
    font::draw_text_up(canvas, axis_x, y0 + (h + axis_len) / 2, BAR_LABEL, scale, TEXT);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::colormap::jet_rgb;
    use dem_core::format::empty_dem;

    #[test]
    fn cells_map_row_0_to_the_top_and_column_0_to_the_left() {
        assert_eq!(cell_rect(0, 0, 16), (0, 0, 16, 16));
        assert_eq!(cell_rect(19, 4, 16), (64, 304, 16, 16));
        assert_eq!(cell_rect(6, 2, 10), (20, 60, 10, 10));
    }

    #[test]
    fn valid_cells_take_jet_and_missing_cells_stay_white() {
        let style = TileStyle::default();
        let range = HeightRange { min: 0.0, max: 1.0 };
        let mut dem = empty_dem();
        dem.set_valid(0, 0, 1.0);
        dem.set_valid(19, 4, 0.0);
        dem.set_valid(10, 2, 0.5);
        dem[dem_core::format::at(10, 2, 1)] = 0.0; // mask 0 is missing, whatever the height
        let mut c = Canvas::new(200, 400, WHITE);
        draw_dem(&mut c, 40, 20, &dem, &range, &style);
        let centre = |row: usize, col: usize| {
            let (x, y, w, h) = cell_rect(row, col, style.cell);
            c.get(40 + x + w / 2, 20 + y + h / 2)
        };
        assert_eq!(centre(0, 0), jet_rgb(1.0));
        assert_eq!(centre(19, 4), jet_rgb(0.0));
        assert_eq!(centre(10, 2), WHITE);
        assert_eq!(centre(5, 1), WHITE);
        // Frame just outside, marker left of the tile at C (row 6's top edge).
        assert_eq!(c.get(39, 19), BLACK);
        assert_eq!(c.get(40 + 80, 20 + 320), BLACK);
        let c_y = 20 + ROWS_BEHIND_C * style.cell;
        let marker_x = 40 - 3 - style.marker_half();
        assert_eq!(c.get(marker_x, c_y), TEXT);
        assert_eq!(c.get(marker_x, c_y - 3 * style.cell), WHITE);
    }

    #[test]
    fn colorbar_runs_dark_red_at_the_top_to_dark_blue_at_the_bottom() {
        let range = HeightRange { min: -0.07, max: 0.2 };
        let w = colorbar_width(&range, 2);
        let mut c = Canvas::new(w + 20, 340, WHITE);
        draw_colorbar(&mut c, 10, 10, 300, &range, 2);
        assert_eq!(c.get(15, 10), jet_rgb(1.0));
        assert_eq!(c.get(15, 309), jet_rgb(0.0));
        // Some text was drawn right of the bar.
        let inked = (10 + BAR_WIDTH + TICK..w + 10).any(|x| (0..340).any(|y| c.get(x, y) == TEXT));
        assert!(inked);
    }
}
