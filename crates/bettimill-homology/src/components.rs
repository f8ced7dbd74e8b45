//! Connected components of the foreground ((3^d-1)-adjacency) and background (2d-adjacency).
//!
//! b_0 is the number of foreground components, and by duality b_{d-1} is the number of
//! background components of the padded image minus one (the outside). Both are counted by
//! flood fill over flat indices on a padded image, so no neighbour ever falls outside it;
//! the visited marks live in a one-byte-per-voxel copy and the work stack holds `u32`
//! indices when they fit, which keeps the memory at a few bytes per voxel.

use bettimill_grid::neighbourhood::{face_offsets, flat_offsets, full_offsets};
use bettimill_grid::BinaryImage;

/// The number of components of voxels with value `value` in `image`, which must have a
/// border of background (pad it first). Foreground uses the full neighbourhood, background
/// the face neighbourhood; border voxels of the background are never left through the
/// image edge because the flood fill checks bounds for them.
pub(crate) fn count_components(image: &BinaryImage, value: u8) -> u64 {
    let offsets = if value == 1 {
        full_offsets(image.dim())
    } else {
        face_offsets(image.dim())
    };
    let steps = flat_offsets(image, &offsets);
    let mut mark: Vec<u8> = image.data().iter().map(|&v| (v == value) as u8).collect();
    let d = image.dim().get();
    let shape = image.shape().to_vec();
    let strides = image.strides().to_vec();
    // Only background components can reach the border; for them every neighbour is
    // bounds-checked per axis.
    let interior = |index: usize| -> bool {
        let mut rest = index;
        for axis in 0..d {
            let c = rest / strides[axis];
            rest %= strides[axis];
            if c == 0 || c + 1 == shape[axis] {
                return false;
            }
        }
        true
    };
    let mut count = 0;
    let mut stack: Vec<usize> = Vec::new();
    for start in 0..mark.len() {
        if mark[start] != 1 {
            continue;
        }
        count += 1;
        mark[start] = 2;
        stack.push(start);
        while let Some(i) = stack.pop() {
            if interior(i) {
                for &s in &steps {
                    let j = (i as isize + s) as usize;
                    if mark[j] == 1 {
                        mark[j] = 2;
                        stack.push(j);
                    }
                }
            } else {
                let c = image.coords(i);
                for off in &offsets {
                    let inside = (0..d).all(|a| {
                        let x = c[a] as i64 + off[a] as i64;
                        x >= 0 && (x as usize) < shape[a]
                    });
                    if inside {
                        let j = (0..d)
                            .map(|a| (c[a] as i64 + off[a] as i64) as usize * strides[a])
                            .sum::<usize>();
                        if mark[j] == 1 {
                            mark[j] = 2;
                            stack.push(j);
                        }
                    }
                }
            }
        }
    }
    count
}

/// The number of components of `voxels` (flat indices into `data` of voxels whose byte is
/// exactly 1, none on the border), two voxels being joined when they are `steps` apart.
/// Cheap next to a flood fill of the whole image when `voxels` is a thin remnant; bit 1 of
/// the bytes marks the voxels reached and is cleared again before returning.
pub(crate) fn count_components_of(data: &mut [u8], voxels: &[u32], steps: &[isize]) -> u64 {
    let mut count = 0;
    // Four bytes a voxel, like `voxels`: on a random image the stack holds a good part of
    // the remnant at once.
    let mut stack: Vec<u32> = Vec::new();
    for &start in voxels {
        if data[start as usize] != 1 {
            continue;
        }
        count += 1;
        data[start as usize] = 3;
        stack.push(start);
        while let Some(v) = stack.pop() {
            for &s in steps {
                let w = (v as isize + s) as usize;
                if data[w] == 1 {
                    data[w] = 3;
                    stack.push(w as u32);
                }
            }
        }
    }
    for &v in voxels {
        data[v as usize] = 1;
    }
    count
}
