//! Public multi-component placement for arbitrary voxel objects, as the paper describes
//! it: dilate what is already in the image by the gap, then put the next object where it
//! meets none of that dilation.
//!
//! [`crate::generate`] places its own analytic objects the same way (see `place.rs`);
//! this module serves callers that already hold an object as voxels, e.g. a deformed
//! object that must be fitted into a sample without touching the others.

use crate::geometry::uniform_int;
use crate::BinaryImage;
use rand_chacha::ChaCha8Rng;

/// The dilation of the foreground by a cube of half-width `radius` (Chebyshev distance
/// <= radius), computed as one running maximum per axis.
pub fn dilate(image: &BinaryImage, radius: usize) -> BinaryImage {
    let mut current = image.clone();
    if radius == 0 {
        return current;
    }
    let shape = image.shape().to_vec();
    let strides = image.strides().to_vec();
    for axis in 0..shape.len() {
        let n = shape[axis];
        let stride = strides[axis];
        let source = current.data().to_vec();
        let data = current.data_mut();
        for start in 0..source.len() {
            // Visit each line along `axis` once, from its first voxel.
            if (start / stride) % n != 0 {
                continue;
            }
            // Distance (in voxels along the line) to the nearest foreground voxel so far,
            // scanning forward and then backward.
            let mut last: Option<usize> = None;
            for k in 0..n {
                if source[start + k * stride] == 1 {
                    last = Some(k);
                }
                if last.is_some_and(|l| k - l <= radius) {
                    data[start + k * stride] = 1;
                }
            }
            let mut next: Option<usize> = None;
            for k in (0..n).rev() {
                if source[start + k * stride] == 1 {
                    next = Some(k);
                }
                if next.is_some_and(|l| l - k <= radius) {
                    data[start + k * stride] = 1;
                }
            }
        }
    }
    current
}

/// A random offset at which `object` (an image no larger than `canvas`, same dimension)
/// can be pasted so that its foreground keeps at least `gap` background voxels to the
/// canvas' foreground and `margin` voxels to the canvas border. Tries `attempts` random
/// offsets; `None` if none worked.
pub fn find_place(
    canvas: &BinaryImage,
    object: &BinaryImage,
    gap: usize,
    margin: usize,
    attempts: usize,
    rng: &mut ChaCha8Rng,
) -> Option<Vec<usize>> {
    if canvas.dim() != object.dim() {
        return None;
    }
    let blocked = dilate(canvas, gap);
    let d = canvas.dim().get();
    let foreground: Vec<[usize; 4]> = (0..object.len())
        .filter(|&i| object.data()[i] == 1)
        .map(|i| object.coords(i))
        .collect();
    if foreground.is_empty() {
        return None;
    }
    let mut low = [0usize; 4];
    let mut high = [0usize; 4];
    for k in 0..d {
        let (lo, hi) = foreground
            .iter()
            .fold((usize::MAX, 0), |(lo, hi), c| (lo.min(c[k]), hi.max(c[k])));
        // The offset o must keep lo + o >= margin and hi + o < side - margin.
        low[k] = margin.saturating_sub(lo);
        let limit = canvas.shape()[k].checked_sub(margin + hi + 1)?;
        if limit < low[k] {
            return None;
        }
        high[k] = limit;
    }
    for _ in 0..attempts {
        let offset: Vec<usize> = (0..d)
            .map(|k| uniform_int(rng, low[k] as u64, high[k] as u64) as usize)
            .collect();
        let free = foreground.iter().all(|c| {
            let target: Vec<usize> = (0..d).map(|k| c[k] + offset[k]).collect();
            !blocked.get(&target)
        });
        if free {
            return Some(offset);
        }
    }
    None
}

/// Sets the foreground of `object`, shifted by `offset`, in `canvas` (voxels that fall
/// outside are ignored).
pub fn paste(canvas: &mut BinaryImage, object: &BinaryImage, offset: &[usize]) {
    let d = canvas.dim().get();
    for i in 0..object.len() {
        if object.data()[i] == 0 {
            continue;
        }
        let c = object.coords(i);
        let target: Vec<i64> = (0..d).map(|k| (c[k] + offset[k]) as i64).collect();
        if canvas.contains(&target) {
            let t: Vec<usize> = target.iter().map(|&x| x as usize).collect();
            canvas.set(&t, true);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn dilation_is_a_chebyshev_ball() {
        let mut image = BinaryImage::zeros(&[9, 9, 9]).unwrap();
        image.set(&[4, 4, 4], true);
        let grown = dilate(&image, 2);
        assert_eq!(grown.count_foreground(), 125);
        assert!(grown.get(&[2, 6, 2]));
        assert!(!grown.get(&[1, 4, 4]));
    }

    #[test]
    fn placed_objects_keep_the_gap() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut canvas = BinaryImage::zeros(&[24, 24]).unwrap();
        let mut blob = BinaryImage::zeros(&[4, 4]).unwrap();
        for c in [[0, 0], [1, 1], [2, 2], [3, 3], [0, 3]] {
            blob.set(&c, true);
        }
        let mut placed = 0;
        while let Some(offset) = find_place(&canvas, &blob, 2, 2, 200, &mut rng) {
            // Before pasting, the new copy must be at Chebyshev distance >= 3 from all
            // foreground already there.
            let near = dilate(&canvas, 2);
            let mut copy = BinaryImage::zeros(&[24, 24]).unwrap();
            paste(&mut copy, &blob, &offset);
            assert!((0..copy.len()).all(|i| copy.data()[i] == 0 || near.data()[i] == 0));
            paste(&mut canvas, &blob, &offset);
            placed += 1;
            assert!(placed < 100);
        }
        assert!(placed >= 4, "only {placed} copies fit");
        assert!(canvas.border_is_background());
    }
}
