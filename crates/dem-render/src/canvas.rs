//! An RGB picture in memory, the few shapes the DEM pictures need (filled
//! rectangles, frames, lines, a marker triangle) and PNG encoding.
//!
//! Coordinates are pixels with (0, 0) at the top left, x to the right and y
//! down. Drawing clips silently at the edges, so layout code never has to
//! guard against a shape that touches the border.

use std::io::{self, Write};

/// A colour, 8 bits per channel.
pub type Rgb = [u8; 3];

/// Background and missing cells.
pub const WHITE: Rgb = [255, 255, 255];
/// Frames around DEMs and the colour bar.
pub const BLACK: Rgb = [0, 0, 0];
/// Text: a near-black grey that reads well on white.
pub const TEXT: Rgb = [34, 34, 34];
/// Thin lines between cells and tick marks of secondary importance.
pub const GRID: Rgb = [200, 200, 200];

/// An RGB image, rows top to bottom, 3 bytes per pixel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Canvas {
    width: u32,
    height: u32,
    data: Vec<u8>,
}

impl Canvas {
    /// A `width` x `height` picture filled with `background`.
    pub fn new(width: u32, height: u32, background: Rgb) -> Self {
        let mut data = Vec::with_capacity(width as usize * height as usize * 3);
        for _ in 0..width as usize * height as usize {
            data.extend_from_slice(&background);
        }
        Canvas { width, height, data }
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The raw RGB bytes, rows top to bottom.
    pub fn pixels(&self) -> &[u8] {
        &self.data
    }

    /// Colour at `(x, y)`; panics outside the picture.
    pub fn get(&self, x: u32, y: u32) -> Rgb {
        assert!(x < self.width && y < self.height, "pixel ({x}, {y}) outside {}x{}", self.width, self.height);
        let i = (y as usize * self.width as usize + x as usize) * 3;
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    /// Set one pixel; outside the picture does nothing.
    pub fn set(&mut self, x: i64, y: i64, c: Rgb) {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return;
        }
        let i = (y as usize * self.width as usize + x as usize) * 3;
        self.data[i..i + 3].copy_from_slice(&c);
    }

    /// Fill the rectangle with top left `(x, y)` and size `w` x `h`.
    pub fn fill_rect(&mut self, x: i64, y: i64, w: i64, h: i64, c: Rgb) {
        let (x0, x1) = (x.max(0), (x + w).min(self.width as i64));
        let (y0, y1) = (y.max(0), (y + h).min(self.height as i64));
        if x0 >= x1 {
            return;
        }
        for yy in y0..y1 {
            let row = yy as usize * self.width as usize;
            for px in self.data[(row + x0 as usize) * 3..(row + x1 as usize) * 3].chunks_exact_mut(3) {
                px.copy_from_slice(&c);
            }
        }
    }

    /// A horizontal line of `len` pixels starting at `(x, y)`.
    pub fn hline(&mut self, x: i64, y: i64, len: i64, c: Rgb) {
        self.fill_rect(x, y, len, 1, c);
    }

    /// A vertical line of `len` pixels starting at `(x, y)`.
    pub fn vline(&mut self, x: i64, y: i64, len: i64, c: Rgb) {
        self.fill_rect(x, y, 1, len, c);
    }

    /// A 1-pixel outline just outside the rectangle `(x, y, w, h)`, so the
    /// rectangle's own pixels stay untouched.
    pub fn frame_around(&mut self, x: i64, y: i64, w: i64, h: i64, c: Rgb) {
        self.hline(x - 1, y - 1, w + 2, c);
        self.hline(x - 1, y + h, w + 2, c);
        self.vline(x - 1, y, h, c);
        self.vline(x + w, y, h, c);
    }

    /// A filled triangle pointing down: its top edge is `2 * half + 1` pixels
    /// wide, centred on `cx` at row `top`; each row below is one pixel
    /// narrower on both sides, down to the tip at `(cx, top + half)`.
    pub fn triangle_down(&mut self, cx: i64, top: i64, half: i64, c: Rgb) {
        for k in 0..=half {
            self.hline(cx - (half - k), top + k, 2 * (half - k) + 1, c);
        }
    }

    /// Encode as an 8-bit RGB PNG.
    pub fn write_png(&self, w: impl Write) -> io::Result<()> {
        let mut enc = png::Encoder::new(w, self.width, self.height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        // Flat colour areas: the adaptive filter keeps files small (tens of
        // KB for a page of DEMs) at a cost that is small next to drawing.
        enc.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
        enc.set_compression(png::Compression::Default);
        let mut writer = enc.write_header().map_err(png_to_io)?;
        writer.write_image_data(&self.data).map_err(png_to_io)?;
        writer.finish().map_err(png_to_io)
    }
}

/// Keep an I/O error (a broken pipe must stay recognisable); wrap the rest.
fn png_to_io(e: png::EncodingError) -> io::Error {
    match e {
        png::EncodingError::IoError(e) => e,
        other => io::Error::other(other),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rectangles_clip_at_the_border() {
        let mut c = Canvas::new(4, 3, WHITE);
        c.fill_rect(-2, 1, 4, 10, BLACK);
        assert_eq!(c.get(0, 0), WHITE);
        assert_eq!(c.get(1, 1), BLACK);
        assert_eq!(c.get(1, 2), BLACK);
        assert_eq!(c.get(2, 1), WHITE);
    }

    #[test]
    fn frame_leaves_the_inside_alone() {
        let mut c = Canvas::new(6, 6, WHITE);
        c.frame_around(2, 2, 2, 2, BLACK);
        assert_eq!(c.get(1, 1), BLACK);
        assert_eq!(c.get(4, 4), BLACK);
        assert_eq!(c.get(2, 2), WHITE);
        assert_eq!(c.get(3, 3), WHITE);
    }

    #[test]
    fn triangle_points_down() {
        let mut c = Canvas::new(7, 5, WHITE);
        c.triangle_down(3, 0, 3, BLACK);
        assert!((0..7).all(|x| c.get(x, 0) == BLACK));
        assert_eq!(c.get(3, 3), BLACK);
        assert_eq!(c.get(2, 3), WHITE);
        assert_eq!(c.get(3, 4), WHITE);
    }

    #[test]
    fn png_round_trips() {
        let mut c = Canvas::new(3, 2, WHITE);
        c.set(2, 1, [10, 20, 30]);
        let mut bytes = Vec::new();
        c.write_png(&mut bytes).unwrap();
        let dec = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = dec.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height, info.color_type), (3, 2, png::ColorType::Rgb));
        assert_eq!(&buf[..info.buffer_size()], c.pixels());
    }
}
