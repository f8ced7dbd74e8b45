//! Neighbourhood offset tables shared by homology, shapes and deformations.
//!
//! The full neighbourhood of a voxel is the 3^d - 1 offsets in {-1, 0, 1}^d minus the
//! origin, listed in lexicographic order (first axis slowest, -1 before 0 before 1). That
//! order is part of the contract: configuration bitmasks (bit k = neighbour k) built by one
//! crate are read by another, so it never changes.

use crate::{BinaryImage, Dim};

/// The 3^d - 1 offsets of the (3^d-1)-neighbourhood in canonical order, each padded with
/// zeros to four axes.
pub fn full_offsets(dim: Dim) -> Vec<[i8; 4]> {
    let d = dim.get();
    let total = 3usize.pow(d as u32);
    let mut out = Vec::with_capacity(total - 1);
    for k in 0..total {
        let mut off = [0i8; 4];
        let mut rest = k;
        for axis in (0..d).rev() {
            off[axis] = (rest % 3) as i8 - 1;
            rest /= 3;
        }
        if off.iter().any(|&o| o != 0) {
            out.push(off);
        }
    }
    out
}

/// The 2d face-neighbour offsets, ordered axis by axis, -1 before +1.
pub fn face_offsets(dim: Dim) -> Vec<[i8; 4]> {
    let mut out = Vec::with_capacity(2 * dim.get());
    for axis in 0..dim.get() {
        for s in [-1i8, 1] {
            let mut off = [0i8; 4];
            off[axis] = s;
            out.push(off);
        }
    }
    out
}

/// Flat-index displacements of `offsets` in `image` (valid for voxels at least one layer
/// away from the border).
pub fn flat_offsets(image: &BinaryImage, offsets: &[[i8; 4]]) -> Vec<isize> {
    let strides = image.strides();
    offsets
        .iter()
        .map(|off| {
            strides
                .iter()
                .enumerate()
                .map(|(a, &s)| off[a] as isize * s as isize)
                .sum()
        })
        .collect()
}

/// Whether `index` is at least `margin` voxels away from every face of the image.
#[inline]
pub fn is_interior(image: &BinaryImage, index: usize, margin: usize) -> bool {
    let c = image.coords(index);
    image
        .shape()
        .iter()
        .enumerate()
        .all(|(a, &n)| c[a] >= margin && c[a] + margin < n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_match_the_adjacency_names() {
        assert_eq!(full_offsets(Dim::Two).len(), 8);
        assert_eq!(full_offsets(Dim::Three).len(), 26);
        assert_eq!(full_offsets(Dim::Four).len(), 80);
        assert_eq!(face_offsets(Dim::Four).len(), 8);
    }

    #[test]
    fn canonical_order_is_lexicographic() {
        let offs = full_offsets(Dim::Two);
        assert_eq!(offs[0][..2], [-1, -1]);
        assert_eq!(offs[1][..2], [-1, 0]);
        assert_eq!(offs[3][..2], [0, -1]);
        assert_eq!(offs[4][..2], [0, 1]);
        assert_eq!(offs[7][..2], [1, 1]);
    }
}
