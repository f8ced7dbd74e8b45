//! Explicit cubical complexes in Khalimsky coordinates and their Z/2 homology.
//!
//! A cell of the cubical grid of an image is named by its Khalimsky coordinates: one number
//! per axis, odd where the cell spans a unit interval and even where it sits at a grid
//! plane, so voxel u is the cell (2u_0+1, ..., 2u_{d-1}+1) and its dimension is the number
//! of odd coordinates. Cells are packed into one `u64` key so that a complex is a sorted
//! `Vec<u64>`: deterministic, compact, and searchable without hashing.
//!
//! Homology is computed in two steps. Elementary collapses (remove a face that has exactly
//! one coface, together with that coface) shrink the complex without changing its homotopy
//! type; what survives is usually tiny. The survivors then go through a sparse Z/2 column
//! reduction of the boundary matrices, and b_k = n_k - rank d_k - rank d_{k+1}.
//! [`crate::reference`] runs the reduction on the whole, uncollapsed complex, so the two
//! paths check each other.

use bettimill_grid::BinaryImage;

/// The layout of Khalimsky keys for one padded image shape.
#[derive(Clone, Debug)]
pub(crate) struct KeyLayout {
    d: usize,
    /// Khalimsky extent per axis: 2n+1 for an axis of n voxels.
    extent: [u64; 4],
    stride: [u64; 4],
}

impl KeyLayout {
    pub(crate) fn new(shape: &[usize]) -> KeyLayout {
        let d = shape.len();
        let mut extent = [1u64; 4];
        for axis in 0..d {
            extent[axis] = 2 * shape[axis] as u64 + 1;
        }
        let mut stride = [0u64; 4];
        let mut s = 1u64;
        for axis in (0..d).rev() {
            stride[axis] = s;
            s *= extent[axis];
        }
        KeyLayout { d, extent, stride }
    }

    #[inline]
    fn coordinate(&self, key: u64, axis: usize) -> u64 {
        key / self.stride[axis] % self.extent[axis]
    }

    #[inline]
    fn dimension(&self, key: u64) -> usize {
        (0..self.d)
            .filter(|&axis| self.coordinate(key, axis) % 2 == 1)
            .count()
    }

    /// The key of voxel `coords`.
    #[inline]
    pub(crate) fn voxel(&self, coords: &[usize]) -> u64 {
        (0..self.d)
            .map(|axis| (2 * coords[axis] as u64 + 1) * self.stride[axis])
            .sum()
    }

    /// The key of the cell with Khalimsky coordinates `coords`.
    #[inline]
    pub(crate) fn key(&self, coords: &[u64]) -> u64 {
        (0..self.d)
            .map(|axis| coords[axis] * self.stride[axis])
            .sum()
    }

    /// Calls `f` for each of the 3^d cells in the closure of the cell `key` whose
    /// coordinates are all odd (a voxel), the voxel itself included.
    pub(crate) fn for_each_face_of_voxel(&self, key: u64, mut f: impl FnMut(u64)) {
        let n = 3usize.pow(self.d as u32);
        for k in 0..n {
            let mut rest = k;
            let mut cell = key;
            for axis in 0..self.d {
                match rest % 3 {
                    0 => cell -= self.stride[axis],
                    2 => cell += self.stride[axis],
                    _ => {}
                }
                rest /= 3;
            }
            f(cell);
        }
    }

    /// The codimension-one faces of `key` (two per odd coordinate).
    #[inline]
    fn facets(&self, key: u64, out: &mut Vec<u64>) {
        out.clear();
        for axis in 0..self.d {
            if self.coordinate(key, axis) % 2 == 1 {
                out.push(key - self.stride[axis]);
                out.push(key + self.stride[axis]);
            }
        }
    }

    /// The cells having `key` as a codimension-one face, within the grid.
    #[inline]
    fn cofacets(&self, key: u64, out: &mut Vec<u64>) {
        out.clear();
        for axis in 0..self.d {
            let c = self.coordinate(key, axis);
            if c % 2 == 0 {
                if c > 0 {
                    out.push(key - self.stride[axis]);
                }
                if c + 1 < self.extent[axis] {
                    out.push(key + self.stride[axis]);
                }
            }
        }
    }
}

/// A closed set of cells of one grid, sorted by key.
#[derive(Clone, Debug)]
pub(crate) struct CellComplex {
    layout: KeyLayout,
    cells: Vec<u64>,
}

impl CellComplex {
    /// The closed cubical complex of the foreground voxels of `image`.
    pub(crate) fn of_image(image: &BinaryImage) -> CellComplex {
        let layout = KeyLayout::new(image.shape());
        let d = image.dim().get();
        let mut cells = Vec::new();
        for (index, &v) in image.data().iter().enumerate() {
            if v != 0 {
                let c = image.coords(index);
                layout.for_each_face_of_voxel(layout.voxel(&c[..d]), |cell| cells.push(cell));
            }
        }
        CellComplex::from_cells(layout, cells)
    }

    /// Sorts and deduplicates `cells`, which must be closed under taking faces.
    pub(crate) fn from_cells(layout: KeyLayout, mut cells: Vec<u64>) -> CellComplex {
        cells.sort_unstable();
        cells.dedup();
        CellComplex { layout, cells }
    }

    #[inline]
    fn position(&self, key: u64) -> Option<usize> {
        self.cells.binary_search(&key).ok()
    }

    /// Removes free pairs until none is left. The result has the same homotopy type.
    pub(crate) fn collapse(&mut self) {
        let n = self.cells.len();
        let mut alive = vec![true; n];
        let mut scratch = Vec::with_capacity(8);
        let mut coface_count: Vec<u8> = self
            .cells
            .iter()
            .map(|&cell| {
                self.layout.cofacets(cell, &mut scratch);
                scratch
                    .iter()
                    .filter(|&&c| self.position(c).is_some())
                    .count() as u8
            })
            .collect();
        // A FIFO over positions in key order keeps the collapse deterministic.
        let mut queue: std::collections::VecDeque<usize> =
            (0..n).filter(|&i| coface_count[i] == 1).collect();
        let mut faces = Vec::with_capacity(8);
        while let Some(i) = queue.pop_front() {
            if !alive[i] || coface_count[i] != 1 {
                continue;
            }
            self.layout.cofacets(self.cells[i], &mut scratch);
            let Some(j) = scratch
                .iter()
                .filter_map(|&c| self.position(c))
                .find(|&j| alive[j])
            else {
                continue;
            };
            alive[i] = false;
            alive[j] = false;
            // Faces of i lose coface i; faces of j other than i lose coface j.
            for (removed, skip) in [(i, usize::MAX), (j, i)] {
                self.layout.facets(self.cells[removed], &mut faces);
                for &f in &faces {
                    if let Some(p) = self.position(f) {
                        if p == skip || !alive[p] {
                            continue;
                        }
                        coface_count[p] -= 1;
                        if coface_count[p] == 1 {
                            queue.push_back(p);
                        }
                    }
                }
            }
        }
        let mut k = 0;
        self.cells.retain(|_| {
            k += 1;
            alive[k - 1]
        });
    }

    /// Betti numbers b_0..b_{d-1} and b_d (the last is always 0 for a subcomplex of a
    /// box, but the reduction computes it honestly) over Z/2.
    pub(crate) fn betti(&self) -> Vec<u64> {
        let d = self.layout.d;
        let mut by_dim: Vec<Vec<u64>> = vec![Vec::new(); d + 1];
        for &c in &self.cells {
            by_dim[self.layout.dimension(c)].push(c);
        }
        // rank[k] = rank of the boundary map from k-cells to (k-1)-cells.
        let mut rank = vec![0u64; d + 2];
        let mut facets = Vec::with_capacity(8);
        for k in 1..=d {
            let rows = &by_dim[k - 1];
            let columns: Vec<Vec<u32>> = by_dim[k]
                .iter()
                .map(|&c| {
                    self.layout.facets(c, &mut facets);
                    let mut column: Vec<u32> = facets
                        .iter()
                        .map(|f| {
                            rows.binary_search(f)
                                .expect("a complex is closed under faces")
                                as u32
                        })
                        .collect();
                    column.sort_unstable();
                    column
                })
                .collect();
            rank[k] = z2_rank(columns, rows.len());
        }
        (0..=d)
            .map(|k| by_dim[k].len() as u64 - rank[k] - rank[k + 1])
            .collect()
    }
}

/// Rank over Z/2 of a sparse matrix given as sorted row lists per column (standard
/// persistence-style reduction: each column is reduced by the earlier column with the same
/// lowest row until its lowest row is unclaimed or it vanishes).
pub(crate) fn z2_rank(mut columns: Vec<Vec<u32>>, n_rows: usize) -> u64 {
    let mut owner = vec![u32::MAX; n_rows];
    let mut rank = 0;
    let mut merged = Vec::new();
    for j in 0..columns.len() {
        while let Some(&low) = columns[j].last() {
            let o = owner[low as usize];
            if o == u32::MAX {
                owner[low as usize] = j as u32;
                rank += 1;
                break;
            }
            symmetric_difference(&columns[j], &columns[o as usize], &mut merged);
            std::mem::swap(&mut columns[j], &mut merged);
        }
    }
    rank
}

fn symmetric_difference(a: &[u32], b: &[u32], out: &mut Vec<u32>) {
    out.clear();
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => {
                out.push(a[i]);
                i += 1;
            }
            std::cmp::Ordering::Greater => {
                out.push(b[j]);
                j += 1;
            }
            std::cmp::Ordering::Equal => {
                i += 1;
                j += 1;
            }
        }
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rank_of_small_matrices() {
        // Columns {0,1}, {1,2}, {0,2} are dependent over Z/2 (their sum is zero).
        assert_eq!(z2_rank(vec![vec![0, 1], vec![1, 2], vec![0, 2]], 3), 2);
        assert_eq!(z2_rank(vec![vec![0], vec![1], vec![2]], 3), 3);
        assert_eq!(z2_rank(vec![vec![], vec![1]], 3), 1);
    }

    #[test]
    fn collapse_keeps_homology() {
        let mut image = BinaryImage::zeros(&[7, 7, 7]).unwrap();
        // A square ring of voxels in a plane: one loop.
        for i in 1..6 {
            image.set(&[3, 1, i], true);
            image.set(&[3, 5, i], true);
            image.set(&[3, i, 1], true);
            image.set(&[3, i, 5], true);
        }
        let mut complex = CellComplex::of_image(&image);
        let before = complex.betti();
        let n_before = complex.cells.len();
        complex.collapse();
        assert!(
            complex.cells.len() < n_before / 4,
            "{} of {n_before} cells left",
            complex.cells.len()
        );
        assert_eq!(complex.betti(), before);
        assert_eq!(before, vec![1, 1, 0, 0]);
    }
}
