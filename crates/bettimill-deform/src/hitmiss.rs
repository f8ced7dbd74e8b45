//! The paper's 2D hit-or-miss thickening, made exact for our adjacency model.
//!
//! The paper inscribes random curves and circles and thickens them by applying the
//! hit-or-miss thinning transform to the *inverse* image: thinning the background thickens
//! the foreground. Classic thinning uses the eight rotations of the Golay L structuring
//! element (an edge form and a corner form, four rotations each) and preserves topology for
//! the (8, 4) pair of the set being thinned. Here the set being thinned is the background,
//! which our model connects by 4-adjacency (the foreground by 8), so the classic guarantee
//! does not apply. Every pixel the transform would flip is therefore also tested with the
//! exact simple-point test and flipped only when simple, one at a time in raster order:
//! the structuring elements decide *where* the foreground grows (the look of the paper's
//! figure), the simple-point test guarantees that its Betti numbers never change.
//!
//! 3D and 4D have no such element sets in common use (the paper notes they grow quickly);
//! there the same role is played by the noise-modulated dilation of [`crate::deform`].

use crate::{DeformError, DeformReport};
use bettimill_grid::{BinaryImage, Dim};
use bettimill_homology::simple::SimpleTester;

/// A 3x3 structuring element on the background: `Some(true)` must be background,
/// `Some(false)` must be foreground, `None` is "don't care". Row-major, centre at [1][1].
type Element = [[Option<bool>; 3]; 3];

const B: Option<bool> = Some(true);
const F: Option<bool> = Some(false);
const X: Option<bool> = None;

/// The Golay L element (edge and corner forms) in the background's terms.
const EDGE: Element = [[F, F, F], [X, B, X], [B, B, B]];
const CORNER: Element = [[X, F, F], [B, B, F], [X, B, X]];

fn rotate(e: &Element) -> Element {
    let mut out = [[None; 3]; 3];
    for (r, row) in out.iter_mut().enumerate() {
        for (c, cell) in row.iter_mut().enumerate() {
            *cell = e[2 - c][r];
        }
    }
    out
}

/// The eight elements in the order they are applied.
fn elements() -> Vec<Element> {
    let mut out = Vec::with_capacity(8);
    let (mut edge, mut corner) = (EDGE, CORNER);
    for _ in 0..4 {
        out.push(edge);
        out.push(corner);
        edge = rotate(&edge);
        corner = rotate(&corner);
    }
    out
}

fn matches(image: &BinaryImage, row: usize, col: usize, element: &Element) -> bool {
    element.iter().enumerate().all(|(dr, line)| {
        line.iter().enumerate().all(|(dc, want)| match want {
            None => true,
            Some(background) => {
                let value = image.get(&[row + dr - 1, col + dc - 1]);
                value != *background
            }
        })
    })
}

/// Thickens a 2D image by `iterations` rounds of hit-or-miss thinning of its background,
/// flipping only simple pixels (see the module documentation). The outermost layer of the
/// image is never edited. Deterministic: no randomness at all.
pub fn thicken_2d(image: &mut BinaryImage, iterations: u32) -> Result<DeformReport, DeformError> {
    if image.dim() != Dim::Two {
        return Err(DeformError::InvalidSetting {
            field: "method",
            reason: format!(
                "hit-or-miss thickening is defined for 2D images; this one is {}D \
                 (use dilate for 3D and 4D)",
                image.dim()
            ),
        });
    }
    let tester = SimpleTester::new(Dim::Two);
    let (rows, cols) = (image.shape()[0], image.shape()[1]);
    let before = image.count_foreground();
    let mut report = DeformReport {
        applied: 0,
        rejected: 0,
        iterations: 0,
        foreground_before: before,
        foreground_after: before,
    };
    if rows < 3 || cols < 3 {
        return Ok(report);
    }
    let elements = elements();
    for _ in 0..iterations {
        report.iterations += 1;
        let mut changed = false;
        for element in &elements {
            // Hit-or-miss marks its pixels on the image as it was before this element...
            let mut marked = Vec::new();
            for row in 1..rows - 1 {
                for col in 1..cols - 1 {
                    if !image.get(&[row, col]) && matches(image, row, col, element) {
                        marked.push(image.index(&[row, col]));
                    }
                }
            }
            // ...and each is flipped in raster order only while it is still simple.
            for index in marked {
                if tester.is_simple(image, index) {
                    image.data_mut()[index] = 1;
                    report.applied += 1;
                    changed = true;
                } else {
                    report.rejected += 1;
                }
            }
        }
        if !changed {
            break;
        }
    }
    report.foreground_after = image.count_foreground();
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use bettimill_homology::topology;

    fn curves_and_circles() -> BinaryImage {
        let mut image = BinaryImage::zeros(&[48, 48]).unwrap();
        // A circle, a second circle touching nothing, and an open curve.
        for t in 0..360 {
            let a = (t as f64).to_radians();
            let (s, c) = (libm::sin(a), libm::cos(a));
            image.set(
                &[(14.0 + 7.0 * s) as usize, (14.0 + 7.0 * c) as usize],
                true,
            );
            image.set(
                &[(32.0 + 6.0 * s) as usize, (32.0 + 6.0 * c) as usize],
                true,
            );
        }
        for col in 5..40 {
            image.set(&[42, col], true);
        }
        image
    }

    #[test]
    fn thickening_grows_without_changing_topology() {
        let mut image = curves_and_circles();
        let before = topology(&image);
        let report = thicken_2d(&mut image, 6).unwrap();
        assert_eq!(topology(&image), before);
        assert!(report.applied > 0);
        assert_eq!(
            report.foreground_after,
            report.foreground_before + report.applied
        );
        let mut again = curves_and_circles();
        thicken_2d(&mut again, 6).unwrap();
        assert_eq!(again, image, "deterministic");
    }

    #[test]
    fn the_eight_elements_are_distinct_rotations() {
        let e = elements();
        assert_eq!(e.len(), 8);
        for i in 0..8 {
            for j in 0..i {
                assert_ne!(e[i], e[j]);
            }
        }
        assert_eq!(rotate(&rotate(&rotate(&rotate(&EDGE)))), EDGE);
    }

    #[test]
    fn three_d_is_refused() {
        let mut image = BinaryImage::zeros(&[5, 5, 5]).unwrap();
        assert!(thicken_2d(&mut image, 1).is_err());
    }
}
