//! Page layout: DEM tiles in columns, wrapped into bands, with text around
//! them and one colour bar.
//!
//! A [`Figure`] is a list of columns; each column holds one DEM per figure
//! row (one row for a grid of records, one row per file for a comparison),
//! a header (the record index) and an optional caption. Columns wrap into
//! bands of `per_band`; every band repeats the row labels. From top to
//! bottom a band is: header line, the tile rows, the caption line. The
//! colour bar stands right of the first band's first tile row.
//!
//! Column pitch is the tile plus the robot marker's room, widened when a
//! header or caption is wider, so text never overlaps.

use super::canvas::{Canvas, TEXT, WHITE};
use super::colormap::HeightRange;
use super::font;
use super::tile::{self, TileStyle};
use dem_core::format::Dem;

/// One column of a figure.
#[derive(Debug, Clone)]
pub struct Column {
    /// Text above the column (the record index).
    pub header: String,
    /// One DEM per figure row, top to bottom.
    pub dems: Vec<Dem>,
    /// Text under the column (an error, a distance), if any.
    pub caption: Option<String>,
}

/// A whole picture, ready to draw.
#[derive(Debug, Clone)]
pub struct Figure {
    /// Line of text at the top, centred.
    pub title: Option<String>,
    /// Label left of each figure row; empty for none (a plain grid).
    pub row_labels: Vec<String>,
    /// Label left of the caption line (what the numbers are), if any.
    pub caption_label: Option<String>,
    /// The columns, in reading order.
    pub columns: Vec<Column>,
    /// Columns per band before wrapping.
    pub per_band: usize,
    /// Heights the colours span, shared by every tile.
    pub range: HeightRange,
    /// Tile and text sizes.
    pub style: TileStyle,
}

/// Outer margin of the page.
const MARGIN: u32 = 16;
/// Gap between text and what it labels.
const PAD: u32 = 6;
/// Vertical gap between tile rows of a band.
const ROW_GAP: u32 = 14;
/// Vertical gap between bands.
const BAND_GAP: u32 = 22;
/// Horizontal gap between columns (beyond the marker's room).
const COL_GAP: u32 = 10;
/// Least horizontal gap between the texts of neighbouring columns.
const TEXT_GAP: u32 = 22;
/// Gap between the colour bar and the robot marker's legend below it.
const LEGEND_GAP: u32 = 28;

/// Pixel positions of everything on the page, computed once.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Geometry {
    /// Page width.
    pub width: u32,
    /// Page height.
    pub height: u32,
    /// Distance between the left edges of neighbouring columns.
    pub pitch: u32,
    /// Left edge of the first column's slot (tile minus marker room).
    pub columns_x: u32,
    /// Top of the first band's header line.
    pub bands_y: u32,
    /// Height of one band including the gap after it.
    pub band_height: u32,
    /// Bands on the page.
    pub bands: u32,
    /// Columns per band (at most the number of columns).
    pub per_band: usize,
    /// Left edge of the colour bar.
    pub bar_x: u32,
}

impl Figure {
    fn rows(&self) -> usize {
        self.columns.first().map_or(0, |c| c.dems.len())
    }

    fn has_captions(&self) -> bool {
        self.columns.iter().any(|c| c.caption.is_some())
    }

    /// Where everything goes.
    pub fn geometry(&self) -> Geometry {
        let s = &self.style;
        let text_h = font::text_height(s.text_scale);
        let width_of = |t: &str| font::text_width(t, s.text_scale);
        let per_band = self.per_band.clamp(1, self.columns.len().max(1));
        let bands = (self.columns.len() as u32).div_ceil(per_band as u32).max(1);
        let texts = self.columns.iter().flat_map(|c| std::iter::once(&c.header).chain(c.caption.as_ref()));
        let widest_text = texts.map(|t| width_of(t)).max().unwrap_or(0);
        let pitch = (s.marker_room() + s.width() + COL_GAP).max(widest_text + TEXT_GAP);
        let labels = self.row_labels.iter().chain(self.caption_label.as_ref());
        let label_w = labels.map(|l| width_of(l)).max().map_or(0, |w| w + PAD);
        let columns_x = MARGIN + label_w;
        let title_h = if self.title.is_some() { text_h + 3 * PAD } else { 0 };
        let bands_y = MARGIN + title_h;
        let caption_h = if self.has_captions() { PAD + text_h } else { 0 };
        let rows = self.rows().max(1) as u32;
        let band_height = text_h + PAD + rows * s.height() + (rows - 1) * ROW_GAP + caption_h + BAND_GAP;
        let bar_x = columns_x + per_band as u32 * pitch + 2 * PAD;
        let bar_w = tile::colorbar_width(&self.range, s.text_scale);
        let title_w = self.title.as_deref().map_or(0, |t| width_of(t) + 2 * MARGIN);
        let width = (bar_x + bar_w + MARGIN).max(title_w);
        // Below the colour bar (beside the first tile row): the marker legend.
        let legend_bottom = bands_y + text_h + PAD + s.height() + LEGEND_GAP + text_h;
        let height = (bands_y + bands * band_height - BAND_GAP).max(legend_bottom) + MARGIN;
        Geometry { width, height, pitch, columns_x, bands_y, band_height, bands, per_band, bar_x }
    }

    /// Top left pixel of the tile of column `k`, figure row `row`.
    pub fn tile_origin(&self, g: &Geometry, k: usize, row: usize) -> (u32, u32) {
        let s = &self.style;
        let (band, slot) = ((k / g.per_band) as u32, (k % g.per_band) as u32);
        let slot_x = g.columns_x + slot * g.pitch;
        // Centre the tile plus its marker in the slot.
        let x = slot_x + (g.pitch - COL_GAP - s.width() - s.marker_room()) / 2 + s.marker_room();
        let text_h = font::text_height(s.text_scale);
        let y = g.bands_y + band * g.band_height + text_h + PAD + row as u32 * (s.height() + ROW_GAP);
        (x, y)
    }

    /// Draw the picture.
    pub fn draw(&self) -> Canvas {
        let g = self.geometry();
        let s = &self.style;
        let scale = s.text_scale;
        let text_h = font::text_height(scale) as i64;
        let mut canvas = Canvas::new(g.width, g.height, WHITE);
        if let Some(title) = &self.title {
            font::draw_text_centered(&mut canvas, g.width as i64 / 2, MARGIN as i64, title, scale, TEXT);
        }
        let (tw, th) = (s.width() as i64, s.height() as i64);
        for (k, col) in self.columns.iter().enumerate() {
            let (x0, y0) = self.tile_origin(&g, k, 0);
            let (x0, y0) = (x0 as i64, y0 as i64);
            let cx = x0 + tw / 2;
            font::draw_text_centered(&mut canvas, cx, y0 - PAD as i64 - text_h, &col.header, scale, TEXT);
            let mut bottom = y0;
            for (row, dem) in col.dems.iter().enumerate() {
                let y = self.tile_origin(&g, k, row).1 as i64;
                tile::draw_dem(&mut canvas, x0, y, dem, &self.range, s);
                bottom = y + th;
            }
            if let Some(caption) = &col.caption {
                font::draw_text_centered(&mut canvas, cx, bottom + PAD as i64, caption, scale, TEXT);
            }
            if k % g.per_band == 0 {
                self.draw_row_labels(&mut canvas, &g, k, bottom);
            }
        }
        let bar_y = self.tile_origin(&g, 0, 0).1;
        tile::draw_colorbar(&mut canvas, g.bar_x as i64, bar_y as i64, s.height(), &self.range, scale);
        let legend_y = (bar_y + s.height() + LEGEND_GAP) as i64;
        tile::draw_marker_legend(&mut canvas, g.bar_x as i64, legend_y, s);
        canvas
    }

    /// Row labels (and the caption label) left of the band starting at column `k`.
    fn draw_row_labels(&self, canvas: &mut Canvas, g: &Geometry, k: usize, bottom: i64) {
        let s = &self.style;
        let scale = s.text_scale;
        let text_h = font::text_height(scale) as i64;
        let right = (g.columns_x - PAD) as i64;
        for (row, label) in self.row_labels.iter().enumerate() {
            let y = self.tile_origin(g, k, row).1 as i64 + s.height() as i64 / 2 - text_h / 2;
            font::draw_text(canvas, right - font::text_width(label, scale) as i64, y, label, scale, TEXT);
        }
        if let (Some(label), true) = (&self.caption_label, self.has_captions()) {
            let x = right - font::text_width(label, scale) as i64;
            font::draw_text(canvas, x, bottom + PAD as i64, label, scale, TEXT);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::colormap::jet_rgb;
    use dem_core::format::{empty_dem, DemCells};

    fn figure(n: usize, rows: usize, per_band: usize) -> Figure {
        let mut d = empty_dem();
        d.set_valid(0, 0, 1.0);
        d.set_valid(19, 4, 0.0);
        Figure {
            title: Some("t".into()),
            row_labels: if rows > 1 { (0..rows).map(|r| format!("row {r}")).collect() } else { vec![] },
            caption_label: None,
            columns: (0..n).map(|i| Column { header: format!("#{i}"), dems: vec![d; rows], caption: Some("e=0.123".into()) }).collect(),
            per_band,
            range: HeightRange { min: 0.0, max: 1.0 },
            style: TileStyle::default(),
        }
    }

    #[test]
    fn tiles_land_where_geometry_says_and_wrap_into_bands() {
        let f = figure(5, 2, 3);
        let g = f.geometry();
        assert_eq!(g.bands, 2);
        let canvas = f.draw();
        assert_eq!((canvas.width(), canvas.height()), (g.width, g.height));
        for k in 0..5 {
            for row in 0..2 {
                let (x, y) = f.tile_origin(&g, k, row);
                assert_eq!(canvas.get(x + 8, y + 8), jet_rgb(1.0), "column {k} row {row}: cell (0,0)");
                assert_eq!(canvas.get(x + 4 * 16 + 8, y + 19 * 16 + 8), jet_rgb(0.0));
                assert_eq!(canvas.get(x + 40, y + 160), WHITE);
            }
        }
        // Column 3 starts the second band, below the first.
        let (a, b) = (f.tile_origin(&g, 0, 0), f.tile_origin(&g, 3, 0));
        assert_eq!(a.0, b.0);
        assert_eq!(b.1 - a.1, g.band_height);
    }

    #[test]
    fn text_widens_the_pitch_instead_of_overlapping() {
        let mut f = figure(2, 1, 2);
        let narrow = f.geometry().pitch;
        f.columns[1].caption = Some("a rather long caption".into());
        let wide = f.geometry().pitch;
        assert!(wide > narrow && wide >= font::text_width("a rather long caption", 2));
    }
}
