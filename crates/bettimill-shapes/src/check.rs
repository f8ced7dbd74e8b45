//! Independent, simple topology checks for the unit tests (no dependency on the homology
//! crate): foreground components with (3^d-1)-adjacency, background components with
//! 2d-adjacency, and the Euler characteristic of the union of closed voxels. Together
//! they pin down all Betti numbers in 2D and 3D and b0, b3 and b1 - b2 in 4D.

use crate::BinaryImage;

fn find(parent: &mut [usize], mut x: usize) -> usize {
    while parent[x] != x {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    x
}

/// Components of voxels with value `value` in the image padded by one layer of
/// background; `full` selects (3^d-1)-adjacency instead of 2d-adjacency.
pub(crate) fn components(image: &BinaryImage, value: u8, full: bool) -> usize {
    let padded = image.padded(1);
    let dim = padded.dim();
    let offsets = if full {
        bettimill_grid::neighbourhood::full_offsets(dim)
    } else {
        bettimill_grid::neighbourhood::face_offsets(dim)
    };
    let flat = bettimill_grid::neighbourhood::flat_offsets(&padded, &offsets);
    let data = padded.data();
    let mut parent: Vec<usize> = (0..data.len()).collect();
    for i in 0..data.len() {
        if data[i] != value {
            continue;
        }
        let c = padded.coords(i);
        let d = dim.get();
        let inner = (0..d).all(|k| c[k] > 0 && c[k] + 1 < padded.shape()[k]);
        for (off, &delta) in offsets.iter().zip(&flat) {
            let j = if inner {
                (i as isize + delta) as usize
            } else {
                let mut coords = [0i64; 4];
                let mut ok = true;
                for k in 0..d {
                    coords[k] = c[k] as i64 + off[k] as i64;
                    if coords[k] < 0 || coords[k] >= padded.shape()[k] as i64 {
                        ok = false;
                    }
                }
                if !ok {
                    continue;
                }
                let u: Vec<usize> = coords[..d].iter().map(|&x| x as usize).collect();
                padded.index(&u)
            };
            if data[j] == value {
                let a = find(&mut parent, i);
                let b = find(&mut parent, j);
                if a != b {
                    parent[a.max(b)] = a.min(b);
                }
            }
        }
    }
    (0..data.len())
        .filter(|&i| data[i] == value && find(&mut parent, i) == i)
        .count()
}

/// Euler characteristic of the union of the closed foreground voxels: mark the closure
/// (3^d cells) of every foreground voxel in the doubled grid, then count cells with sign
/// (-1)^dimension.
pub(crate) fn euler(image: &BinaryImage) -> i64 {
    let d = image.dim().get();
    let shape = image.shape().to_vec();
    // Doubled grid: coordinate 2x+1 is the open interval of voxel x, 2x its lower vertex.
    let doubled: Vec<usize> = shape.iter().map(|&n| 2 * n + 1).collect();
    let mut strides = vec![1usize; d];
    for k in (0..d - 1).rev() {
        strides[k] = strides[k + 1] * doubled[k + 1];
    }
    let total: usize = doubled.iter().product();
    let mut present = vec![false; total];
    let closure = 3usize.pow(d as u32);
    for index in 0..image.len() {
        if image.data()[index] == 0 {
            continue;
        }
        let c = image.coords(index);
        for code in 0..closure {
            let mut rest = code;
            let mut flat = 0;
            for k in 0..d {
                flat += (2 * c[k] + rest % 3) * strides[k];
                rest /= 3;
            }
            present[flat] = true;
        }
    }
    let mut chi = 0i64;
    for (flat, &here) in present.iter().enumerate() {
        if !here {
            continue;
        }
        let mut rest = flat;
        let mut odd = 0;
        for &stride in &strides {
            odd += (rest / stride) % 2;
            rest %= stride;
        }
        chi += if odd % 2 == 0 { 1 } else { -1 };
    }
    chi
}

/// What the simple checks can say about an image's Betti numbers: b0, b_{d-1}, and the
/// Euler characteristic (which fixes the rest in 2D and 3D).
#[derive(Debug, PartialEq, Eq)]
pub(crate) struct Summary {
    pub(crate) b0: u64,
    pub(crate) top: u64,
    pub(crate) euler: i64,
}

pub(crate) fn summary(image: &BinaryImage) -> Summary {
    let b0 = components(image, 1, true) as u64;
    let top = components(image, 0, false) as u64 - 1;
    Summary {
        b0,
        top,
        euler: euler(image),
    }
}

/// The same summary computed from a label.
pub(crate) fn summary_of(betti: &[u64]) -> Summary {
    let euler = betti
        .iter()
        .enumerate()
        .map(|(k, &b)| if k % 2 == 0 { b as i64 } else { -(b as i64) })
        .sum();
    Summary {
        b0: betti[0],
        top: betti[betti.len() - 1],
        euler,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_of_small_images() {
        // A 3x3 ring in 2D: one component, one hole.
        let mut ring = BinaryImage::zeros(&[5, 5]).unwrap();
        for x in 1..4 {
            for y in 1..4 {
                if (x, y) != (2, 2) {
                    ring.set(&[x, y], true);
                }
            }
        }
        assert_eq!(summary(&ring), summary_of(&[1, 1]));
        // Two voxels touching at a corner are one component in this model.
        let mut diagonal = BinaryImage::zeros(&[4, 4, 4]).unwrap();
        diagonal.set(&[1, 1, 1], true);
        diagonal.set(&[2, 2, 2], true);
        assert_eq!(summary(&diagonal), summary_of(&[1, 0, 0]));
        let mut tesseract = BinaryImage::zeros(&[3, 3, 3, 3]).unwrap();
        tesseract.set(&[1, 1, 1, 1], true);
        assert_eq!(summary(&tesseract), summary_of(&[1, 0, 0, 0]));
    }
}
