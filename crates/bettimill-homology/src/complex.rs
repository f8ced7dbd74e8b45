//! Explicit cubical complexes in Khalimsky coordinates and their Z/2 homology.
//!
//! A cell of the cubical grid of an image is named by its Khalimsky coordinates: one number
//! per axis, odd where the cell spans a unit interval and even where it sits at a grid
//! plane, so voxel u is the cell (2u_0+1, ..., 2u_{d-1}+1) and its dimension is the number
//! of odd coordinates. Cells are packed into one `u64` key, 64/d bits per coordinate with
//! the first axis most significant, so that a complex is a sorted `Vec<u64>` in
//! lexicographic order and coordinates, parities and neighbours are shifts and masks rather
//! than divisions, which would dominate collapsing. 16 bits per axis in 4D
//! limit an axis to 32766 voxels, far beyond any 4D image that fits in memory.
//!
//! This is the plain representation the slow oracle ([`crate::reference`]) works on: every
//! cell listed, boundary matrices reduced as they are. The fast path keeps its complexes in
//! `crate::dense` instead, and the tests hold the two against each other.

use bettimill_grid::BinaryImage;

/// The layout of Khalimsky keys for one padded image shape.
#[derive(Clone, Debug)]
pub(crate) struct KeyLayout {
    d: usize,
    /// 1 << (bits * (d - 1 - axis)): one step along an axis.
    stride: [u64; 4],
    /// The lowest bit of every coordinate field: key & odd_bits says which are odd.
    odd_bits: u64,
}

impl KeyLayout {
    pub(crate) fn new(shape: &[usize]) -> KeyLayout {
        let d = shape.len();
        let bits = 64 / d as u32;
        let mut stride = [0u64; 4];
        let mut odd_bits = 0;
        for axis in 0..d {
            let extent = 2 * shape[axis] as u64 + 1;
            assert!(
                extent < 1 << bits,
                "axis {axis} of {} voxels is too long for {bits}-bit cell coordinates",
                shape[axis]
            );
            stride[axis] = 1 << (bits * (d - 1 - axis) as u32);
            odd_bits |= stride[axis];
        }
        KeyLayout {
            d,
            stride,
            odd_bits,
        }
    }

    #[inline]
    fn dimension(&self, key: u64) -> usize {
        (key & self.odd_bits).count_ones() as usize
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

    /// The 3^d key offsets (wrapping) from a voxel's key to the cells of its closure, the
    /// voxel itself included: `key.wrapping_add(delta)` for each delta. Computed once, so
    /// the closure of a voxel is 3^d additions.
    pub(crate) fn voxel_face_deltas(&self) -> Vec<u64> {
        let n = 3usize.pow(self.d as u32);
        (0..n)
            .map(|k| {
                let mut rest = k;
                let mut delta = 0u64;
                for axis in 0..self.d {
                    match rest % 3 {
                        0 => delta = delta.wrapping_sub(self.stride[axis]),
                        2 => delta = delta.wrapping_add(self.stride[axis]),
                        _ => {}
                    }
                    rest /= 3;
                }
                delta
            })
            .collect()
    }

    /// Calls `f` for each of the 3^d cells in the closure of the cell `key` whose
    /// coordinates are all odd (a voxel), the voxel itself included.
    pub(crate) fn for_each_face_of_voxel(&self, key: u64, mut f: impl FnMut(u64)) {
        for delta in self.voxel_face_deltas() {
            f(key.wrapping_add(delta));
        }
    }

    /// The codimension-one faces of `key` (two per odd coordinate).
    #[inline]
    fn facets(&self, key: u64, out: &mut Vec<u64>) {
        out.clear();
        for axis in 0..self.d {
            if key & self.stride[axis] != 0 {
                out.push(key - self.stride[axis]);
                out.push(key + self.stride[axis]);
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

    fn cells_by_dimension(&self) -> Vec<Vec<u64>> {
        let mut by_dim: Vec<Vec<u64>> = vec![Vec::new(); self.layout.d + 1];
        for &c in &self.cells {
            by_dim[self.layout.dimension(c)].push(c);
        }
        by_dim
    }

    /// Betti numbers b_0..b_d over Z/2 by plain reduction of every boundary matrix (b_d is
    /// always 0 for a subcomplex of a box; the reduction computes it honestly). The
    /// straightforward method, kept for [`crate::reference`].
    pub(crate) fn betti_by_boundaries(&self) -> Vec<u64> {
        let d = self.layout.d;
        let by_dim = self.cells_by_dimension();
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
            rank[k] = z2_rank(columns, rows.len()).0;
        }
        (0..=d)
            .map(|k| by_dim[k].len() as u64 - rank[k] - rank[k + 1])
            .collect()
    }
}

/// Rank over Z/2 of a sparse matrix given as sorted row lists per column (standard
/// persistence-style reduction: each column is reduced by the earlier column with the same
/// lowest row until its lowest row is unclaimed or it vanishes). Also returns the pivot
/// rows, which is what clearing needs.
pub(crate) fn z2_rank(mut columns: Vec<Vec<u32>>, n_rows: usize) -> (u64, Vec<u32>) {
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
    let pivots = (0..n_rows as u32)
        .filter(|&row| owner[row as usize] != u32::MAX)
        .collect();
    (rank, pivots)
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
        assert_eq!(z2_rank(vec![vec![0, 1], vec![1, 2], vec![0, 2]], 3).0, 2);
        assert_eq!(z2_rank(vec![vec![0], vec![1], vec![2]], 3).0, 3);
        assert_eq!(z2_rank(vec![vec![], vec![1]], 3), (1, vec![1]));
    }
}
