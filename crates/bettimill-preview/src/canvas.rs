//! An RGB drawing surface: rectangles, text in the bundled font, greyscale planes, and
//! its PNG encoding (through the `png` crate).

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

    /// Draws `text` with the top-left corner of its line at (`x`, `y`), at `size` pixels
    /// (see [`font`]), blended over what is there by the glyphs' coverage.
    pub fn text(&mut self, x: usize, y: usize, text: &str, size: f32, colour: Rgb) {
        font::rasterise(text, size, |gx, gy, coverage| {
            let (px, py) = (x as i64 + gx, y as i64 + gy);
            if px < 0 || py < 0 {
                return;
            }
            let (px, py) = (px as usize, py as usize);
            if let Some(under) = self.pixel(px, py) {
                let t = (coverage.clamp(0.0, 1.0) * 255.0).round() as u8;
                self.put(px, py, mix(under, colour, t));
            }
        });
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

    /// A canvas holding `pixels` (`width * height` RGB triples, row-major), as drawn by
    /// another library; `None` when the sizes disagree or are refused.
    pub fn from_rgb(width: usize, height: usize, pixels: Vec<u8>) -> Option<Canvas> {
        let ok = width > 0
            && height > 0
            && width.saturating_mul(height) <= MAX_PIXELS
            && pixels.len() == width * height * 3;
        ok.then_some(Canvas {
            width,
            height,
            pixels,
        })
    }

    /// The pixels, row-major, three bytes each.
    pub fn rgb(&self) -> &[u8] {
        &self.pixels
    }

    /// The canvas as PNG bytes: 8-bit RGB, no interlace, no time or text chunks, at a
    /// fixed compression level, so equal pictures are equal bytes.
    pub fn to_png(&self) -> Result<Vec<u8>, PreviewError> {
        let mut out = Vec::new();
        let mut encoder = png::Encoder::new(&mut out, self.width as u32, self.height as u32);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_compression(png::Compression::Best);
        let mut writer = encoder.write_header()?;
        writer.write_image_data(&self.pixels)?;
        writer.finish()?;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_and_planes_land_where_asked() {
        let mut canvas = Canvas::new(60, 40, PAGE).unwrap();
        canvas.text(2, 3, "Ab", font::BODY, INK);
        // Ink lands inside the text's box only, and somewhere in it.
        let (w, h) = (
            font::text_width("Ab", font::BODY),
            font::line_height(font::BODY),
        );
        for y in 0..40 {
            for x in 0..60 {
                let inked = canvas.pixel(x, y) != Some(PAGE);
                assert!(!inked || (2..=2 + w).contains(&x) && (3..3 + h).contains(&y));
            }
        }
        assert!((0..60).any(|x| (0..40).any(|y| canvas.pixel(x, y) == Some(INK))));
        let plane = Plane {
            rows: 1,
            cols: 2,
            values: vec![0, 255],
        };
        canvas.plane(30, 30, &plane, 3);
        assert_eq!(canvas.pixel(30, 30), Some(EMPTY));
        assert_eq!(canvas.pixel(35, 32), Some(FOREGROUND));
        assert_eq!(canvas.pixel(36, 32), Some(PAGE));
        assert_eq!(canvas.pixel(60, 0), None);
    }

    #[test]
    fn pixels_survive_a_round_trip_through_png() {
        let mut canvas = Canvas::new(5, 3, PAGE).unwrap();
        canvas.fill(1, 1, 2, 1, BAR);
        canvas.put(4, 2, [1, 2, 3]);
        let bytes = canvas.to_png().unwrap();
        assert_eq!(bytes, canvas.to_png().unwrap());
        let decoder = png::Decoder::new(bytes.as_slice());
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (5, 3));
        assert_eq!(info.color_type, png::ColorType::Rgb);
        assert_eq!(&buf[..info.buffer_size()], canvas.rgb());
        assert!(Canvas::from_rgb(2, 2, vec![0; 11]).is_none());
        assert_eq!(Canvas::from_rgb(5, 3, buf[..45].to_vec()), Some(canvas));
    }

    #[test]
    fn oversized_canvases_are_refused() {
        assert!(Canvas::new(0, 10, PAGE).is_err());
        assert!(Canvas::new(1 << 14, 1 << 14, PAGE).is_err());
    }
}
