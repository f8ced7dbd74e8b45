//! An RGB drawing surface: rectangles, text in the built-in font, greyscale planes.

use crate::font;
use crate::PreviewError;

/// An RGB colour.
pub type Rgb = [u8; 3];

/// The page.
pub const PAGE: Rgb = [255, 255, 255];
/// Text.
pub const INK: Rgb = [24, 24, 32];
/// Secondary text (slice indices, axis labels).
pub const MUTED: Rgb = [110, 112, 124];
/// Background voxels.
pub const EMPTY: Rgb = [232, 234, 240];
/// Foreground voxels.
pub const FOREGROUND: Rgb = [28, 62, 156];
/// Frames around planes.
pub const FRAME: Rgb = [170, 172, 184];
/// Bars of charts.
pub const BAR: Rgb = [222, 110, 40];

/// The largest canvas drawn, in pixels: bigger requests are refused instead of allocating
/// without bound.
pub const MAX_PIXELS: usize = 1 << 26;

/// A rectangular RGB picture, row-major, three bytes per pixel.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Canvas {
    width: usize,
    height: usize,
    pixels: Vec<u8>,
}

/// A 2D array of intensities 0 (background) ..= 255 (foreground), row-major.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Plane {
    /// Number of rows.
    pub rows: usize,
    /// Number of columns.
    pub cols: usize,
    /// `rows * cols` intensities.
    pub values: Vec<u8>,
}

fn mix(a: Rgb, b: Rgb, t: u8) -> Rgb {
    let t = t as u32;
    let channel = |x: u8, y: u8| ((x as u32 * (255 - t) + y as u32 * t + 127) / 255) as u8;
    [
        channel(a[0], b[0]),
        channel(a[1], b[1]),
        channel(a[2], b[2]),
    ]
}

impl Canvas {
    /// A canvas filled with `colour`; refuses empty or oversized canvases.
    pub fn new(width: usize, height: usize, colour: Rgb) -> Result<Canvas, PreviewError> {
        let pixels = width.saturating_mul(height);
        if width == 0 || height == 0 || pixels > MAX_PIXELS {
            return Err(PreviewError::TooLarge { width, height });
        }
        let mut data = Vec::with_capacity(pixels * 3);
        for _ in 0..pixels {
            data.extend_from_slice(&colour);
        }
        Ok(Canvas {
            width,
            height,
            pixels: data,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The colour at (`x`, `y`), or `None` outside the canvas.
    pub fn pixel(&self, x: usize, y: usize) -> Option<Rgb> {
        (x < self.width && y < self.height).then(|| {
            let i = (y * self.width + x) * 3;
            [self.pixels[i], self.pixels[i + 1], self.pixels[i + 2]]
        })
    }

    /// Sets one pixel; pixels outside the canvas are clipped.
    pub fn put(&mut self, x: usize, y: usize, colour: Rgb) {
        if x < self.width && y < self.height {
            let i = (y * self.width + x) * 3;
            self.pixels[i..i + 3].copy_from_slice(&colour);
        }
    }

    /// Fills a rectangle (clipped).
    pub fn fill(&mut self, x: usize, y: usize, width: usize, height: usize, colour: Rgb) {
        for yy in y..(y + height).min(self.height) {
            for xx in x..(x + width).min(self.width) {
                let i = (yy * self.width + xx) * 3;
                self.pixels[i..i + 3].copy_from_slice(&colour);
            }
        }
    }

    /// A one-pixel rectangle outline around the box (`x`, `y`, `width`, `height`).
    pub fn frame(&mut self, x: usize, y: usize, width: usize, height: usize, colour: Rgb) {
        if width == 0 || height == 0 {
            return;
        }
        self.fill(x, y, width, 1, colour);
        self.fill(x, y + height - 1, width, 1, colour);
        self.fill(x, y, 1, height, colour);
        self.fill(x + width - 1, y, 1, height, colour);
    }

    /// Draws `text` with its top-left corner at (`x`, `y`), each font pixel `scale` wide.
    pub fn text(&mut self, x: usize, y: usize, text: &str, scale: usize, colour: Rgb) {
        for (n, c) in text.chars().enumerate() {
            let left = x + n * font::ADVANCE * scale;
            for (row, bits) in font::glyph(c).iter().enumerate() {
                for col in 0..5 {
                    if bits & (0x10 >> col) != 0 {
                        self.fill(left + col * scale, y + row * scale, scale, scale, colour);
                    }
                }
            }
        }
    }

    /// Draws `plane` with its top-left corner at (`x`, `y`), each value a `scale` x `scale`
    /// block (nearest neighbour), coloured between [`EMPTY`] and [`FOREGROUND`].
    pub fn plane(&mut self, x: usize, y: usize, plane: &Plane, scale: usize) {
        for row in 0..plane.rows {
            for col in 0..plane.cols {
                let colour = mix(EMPTY, FOREGROUND, plane.values[row * plane.cols + col]);
                self.fill(x + col * scale, y + row * scale, scale, scale, colour);
            }
        }
    }

    /// Copies `other` with its top-left corner at (`x`, `y`) (clipped).
    pub fn blit(&mut self, x: usize, y: usize, other: &Canvas) {
        for row in 0..other.height {
            for col in 0..other.width {
                let i = (row * other.width + col) * 3;
                let colour = [other.pixels[i], other.pixels[i + 1], other.pixels[i + 2]];
                self.put(x + col, y + row, colour);
            }
        }
    }

    /// The canvas as PNG bytes (see [`crate::png`]).
    pub fn to_png(&self) -> Vec<u8> {
        crate::png::encode_rgb(self.width as u32, self.height as u32, &self.pixels)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_and_planes_land_where_asked() {
        let mut canvas = Canvas::new(40, 20, PAGE).unwrap();
        canvas.text(2, 3, "1", 1, INK);
        // '1' has its top row at column 2 of the glyph only.
        assert_eq!(canvas.pixel(4, 3), Some(INK));
        assert_eq!(canvas.pixel(2, 3), Some(PAGE));
        let plane = Plane {
            rows: 1,
            cols: 2,
            values: vec![0, 255],
        };
        canvas.plane(20, 10, &plane, 3);
        assert_eq!(canvas.pixel(20, 10), Some(EMPTY));
        assert_eq!(canvas.pixel(25, 12), Some(FOREGROUND));
        assert_eq!(canvas.pixel(26, 12), Some(PAGE));
        assert_eq!(canvas.pixel(40, 0), None);
    }

    #[test]
    fn oversized_canvases_are_refused() {
        assert!(Canvas::new(0, 10, PAGE).is_err());
        assert!(Canvas::new(1 << 14, 1 << 14, PAGE).is_err());
    }
}
