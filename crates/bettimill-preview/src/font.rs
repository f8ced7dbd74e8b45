//! Text in pictures: DejaVu Sans Mono (bundled in `fonts/`, under the Bitstream Vera
//! licence beside it), rasterised with `ab_glyph`.
//!
//! A monospaced face keeps columns of numbers aligned and makes a line's width a product
//! of its length, which the layouts use to wrap captions. Rasterisation is a pure function
//! of the text, the size and the font bytes, so equal pictures stay equal bytes.

use ab_glyph::{point, Font, FontRef, PxScale, ScaleFont};
use std::sync::OnceLock;

/// The bundled font file.
pub const FONT_BYTES: &[u8] = include_bytes!("../fonts/DejaVuSansMono.ttf");

/// Tile labels and small print, in pixels (the font's em size).
pub const SMALL: f32 = 12.0;
/// Legends and contact-sheet captions.
pub const BODY: f32 = 13.0;
/// The caption of a single-sample picture.
pub const TITLE: f32 = 19.0;

fn font() -> &'static FontRef<'static> {
    static FONT: OnceLock<FontRef<'static>> = OnceLock::new();
    FONT.get_or_init(|| {
        FontRef::try_from_slice(FONT_BYTES).expect("the bundled font is a valid TrueType file")
    })
}

/// The distance from one line's top to the next one's at `size`, in pixels.
pub fn line_height(size: f32) -> usize {
    let scaled = font().as_scaled(PxScale::from(size));
    (scaled.height() + scaled.line_gap()).ceil() as usize + 1
}

/// The advance of one character at `size` (every glyph has the same).
fn advance(size: f32) -> f32 {
    let scaled = font().as_scaled(PxScale::from(size));
    scaled.h_advance(font().glyph_id('0'))
}

/// Width in pixels of `text` drawn at `size`.
pub fn text_width(text: &str, size: f32) -> usize {
    (text.chars().count() as f32 * advance(size)).ceil() as usize
}

/// How many characters fit in `width` pixels at `size` (at least one).
pub fn chars_in(width: usize, size: f32) -> usize {
    ((width as f32 / advance(size)).floor() as usize).max(1)
}

/// Calls `put(x, y, coverage)` for every pixel the glyphs of `text` cover, with the top
/// of the line at `y = 0` and the text starting at `x = 0`; `coverage` is in 0..=1.
/// Characters the font lacks are drawn as its replacement glyph.
pub fn rasterise(text: &str, size: f32, mut put: impl FnMut(i64, i64, f32)) {
    let scale = PxScale::from(size);
    let scaled = font().as_scaled(scale);
    let step = advance(size);
    for (n, c) in text.chars().enumerate() {
        let glyph = font()
            .glyph_id(c)
            .with_scale_and_position(scale, point(n as f32 * step, scaled.ascent()));
        if let Some(outline) = font().outline_glyph(glyph) {
            let bounds = outline.px_bounds();
            outline.draw(|gx, gy, coverage| {
                put(
                    bounds.min.x as i64 + gx as i64,
                    bounds.min.y as i64 + gy as i64,
                    coverage,
                );
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pixels `text` covers, as a set, for comparing glyphs.
    fn covered(text: &str) -> std::collections::BTreeSet<(i64, i64)> {
        let mut set = std::collections::BTreeSet::new();
        rasterise(text, BODY, |x, y, c| {
            if c > 0.5 {
                set.insert((x, y));
            }
        });
        set
    }

    #[test]
    fn lower_and_upper_case_differ_and_widths_are_monospaced() {
        assert_ne!(covered("s000006"), covered("S000006"));
        assert_ne!(covered("a"), covered("A"));
        assert!(!covered("k").is_empty());
        assert_eq!(text_width("", BODY), 0);
        assert_eq!(text_width("iiii", BODY), text_width("WWWW", BODY));
        assert!(text_width("ab", TITLE) > text_width("ab", SMALL));
        assert!(line_height(TITLE) > line_height(SMALL));
        assert_eq!(chars_in(text_width("abcdefghij", BODY), BODY), 10);
        // Every pixel lies within the line's height and the text's width.
        let (w, h) = (text_width("Betti [1, 0, 2]", BODY), line_height(BODY));
        rasterise("Betti [1, 0, 2]", BODY, |x, y, _| {
            assert!(
                x >= 0 && (x as usize) <= w && y >= 0 && (y as usize) < h,
                "{x} {y}"
            );
        });
    }
}
