//! The slow oracle: Betti numbers from the full boundary matrices of the cubical complex.
//!
//! Every cell of every foreground voxel is listed and the Z/2 ranks of all boundary maps are
//! computed by column reduction, with no collapsing, thinning or duality shortcut. That is
//! far too slow for real samples (the complex has up to 3^d cells per voxel) but it is
//! obviously right, so the tests hold [`crate::topology`] against it on small images.

use crate::complex::{CellComplex, KeyLayout};
use crate::Topology;
use bettimill_grid::BinaryImage;

/// The topology of `image` from the full, uncollapsed cubical complex. Only for small
/// images (a few thousand voxels).
pub fn topology(image: &BinaryImage) -> Topology {
    let d = image.dim().get();
    let complex = CellComplex::of_image(&image.padded(1));
    let mut betti = complex.betti_by_boundaries();
    assert_eq!(
        betti[d], 0,
        "a subcomplex of a box has no top-dimensional homology"
    );
    betti.truncate(d);
    Topology::from_betti(betti)
}

/// The topology of `image` read off the background through Alexander duality, with the
/// background built the other way: voxels as vertices, a cell for every box of 2^k
/// face-adjacent background voxels (CubicalRipser's V-construction). It shares no code path
/// with [`topology`] except the rank computation, which makes it a second, independent
/// oracle. Only for small images.
pub fn topology_by_duality(image: &BinaryImage) -> Topology {
    let padded = image.padded(1);
    let d = image.dim().get();
    let layout = KeyLayout::new(padded.shape());
    let shape = padded.shape();
    let mut cells = Vec::new();
    for index in 0..padded.len() {
        let v = padded.coords(index);
        for subset in 0..(1usize << d) {
            if (0..d).any(|a| subset >> a & 1 == 1 && v[a] + 1 >= shape[a]) {
                continue;
            }
            let all_background = (0..(1usize << d)).filter(|e| e & !subset == 0).all(|e| {
                let mut c = [0usize; 4];
                for a in 0..d {
                    c[a] = v[a] + (e >> a & 1);
                }
                !padded.get(&c[..d])
            });
            if all_background {
                let mut k = [0u64; 4];
                for a in 0..d {
                    k[a] = 2 * v[a] as u64 + (subset >> a & 1) as u64;
                }
                cells.push(layout.key(&k[..d]));
            }
        }
    }
    let background = CellComplex::from_cells(layout, cells).betti_by_boundaries();
    let mut betti = vec![background[d - 1]];
    betti.extend((1..d - 1).map(|k| background[d - 1 - k]));
    betti.push(background[0] - 1);
    Topology::from_betti(betti)
}
