//! Explicit cubical complexes in Khalimsky coordinates and their Z/2 homology.
//!
//! A cell of the cubical grid of an image is named by its Khalimsky coordinates: one number
//! per axis, odd where the cell spans a unit interval and even where it sits at a grid
//! plane, so voxel u is the cell (2u_0+1, ..., 2u_{d-1}+1) and its dimension is the number
//! of odd coordinates. Cells are packed into one `u64` key, 64/d bits per coordinate with
//! the first axis most significant, so that a complex is a sorted `Vec<u64>` in
//! lexicographic order and coordinates, parities and neighbours are shifts and masks rather
//! than divisions (which made collapsing several times slower). 16 bits per axis in 4D
//! limit an axis to 32766 voxels, far beyond any 4D image that fits in memory.
//!
//! Homology is computed in two steps. Elementary collapses (remove a face that has exactly
//! one coface, together with that coface) shrink the complex without changing its homotopy
//! type; a per-cell table of the neighbouring cells along each axis, built by linear merges
//! of the sorted keys, makes them cheap. The survivors then go through sparse Z/2 column
//! reductions and b_k = n_k - rank d_k - rank d_{k+1}. The fast path ([`CellComplex::betti`])
//! reduces coboundaries with clearing, the way Ripser does, and gets the vertex-to-edge step
//! from a union-find; [`crate::reference`] reduces the plain boundary matrices of the whole,
//! uncollapsed complex ([`CellComplex::betti_by_boundaries`]), so the two check each other.

use bettimill_grid::BinaryImage;

/// The layout of Khalimsky keys for one padded image shape.
#[derive(Clone, Debug)]
pub(crate) struct KeyLayout {
    d: usize,
    /// Khalimsky extent per axis: 2n+1 for an axis of n voxels.
    extent: [u64; 4],
    /// 1 << (bits * (d - 1 - axis)): one step along an axis.
    stride: [u64; 4],
    bits: u32,
    /// The lowest bit of every coordinate field: key & odd_bits says which are odd.
    odd_bits: u64,
}

impl KeyLayout {
    pub(crate) fn new(shape: &[usize]) -> KeyLayout {
        let d = shape.len();
        let bits = 64 / d as u32;
        let mut extent = [1u64; 4];
        let mut stride = [0u64; 4];
        let mut odd_bits = 0;
        for axis in 0..d {
            extent[axis] = 2 * shape[axis] as u64 + 1;
            assert!(
                extent[axis] < 1 << bits,
                "axis {axis} of {} voxels is too long for {bits}-bit cell coordinates",
                shape[axis]
            );
            stride[axis] = 1 << (bits * (d - 1 - axis) as u32);
            odd_bits |= stride[axis];
        }
        KeyLayout {
            d,
            extent,
            stride,
            bits,
            odd_bits,
        }
    }

    #[inline]
    fn coordinate(&self, key: u64, axis: usize) -> u64 {
        (key >> (self.bits * (self.d - 1 - axis) as u32)) & ((1 << self.bits) - 1)
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
            if key & self.stride[axis] != 0 {
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

    /// The number of cells.
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.cells.len()
    }

    /// For every cell, the positions of the cells one step away along each axis, slot
    /// 2 * axis for -1 and 2 * axis + 1 for +1 (`NONE` when absent). Along an axis where the
    /// cell's coordinate is odd these are its facets, along an even one its cofacets. Each
    /// slot is filled by one linear merge of the sorted keys with themselves shifted by a
    /// step, so building the table is sequential memory traffic instead of a random lookup
    /// per neighbour.
    fn neighbour_table(&self) -> Vec<[u32; 8]> {
        let n = self.cells.len();
        assert!(n < NONE as usize, "too many cells for u32 positions");
        let mut table = vec![[NONE; 8]; n];
        for axis in 0..self.layout.d {
            let step = self.layout.stride[axis];
            // A step below 0 in one field borrows from the next and lands on a field value
            // of all ones, which no cell has, so such targets are simply not found.
            for (slot, shift) in [(2 * axis, step.wrapping_neg()), (2 * axis + 1, step)] {
                let mut q = 0;
                for (&key, row) in self.cells.iter().zip(table.iter_mut()) {
                    // Keys below `step` would wrap around to the top and break the
                    // increasing order of targets the merge relies on.
                    if shift != step && key < step {
                        continue;
                    }
                    let target = key.wrapping_add(shift);
                    while q < n && self.cells[q] < target {
                        q += 1;
                    }
                    if q < n && self.cells[q] == target {
                        row[slot] = q as u32;
                    }
                }
            }
        }
        table
    }

    /// Removes free pairs until none is left. The result has the same homotopy type.
    pub(crate) fn collapse(&mut self) {
        let n = self.cells.len();
        let table = self.neighbour_table();
        let d = self.layout.d;
        let odd = |p: usize, axis: usize| self.cells[p] & self.layout.stride[axis] != 0;
        let mut alive = vec![true; n];
        let mut coface_count: Vec<u8> = (0..n)
            .map(|p| {
                (0..d)
                    .filter(|&axis| !odd(p, axis))
                    .map(|axis| {
                        (table[p][2 * axis] != NONE) as u8 + (table[p][2 * axis + 1] != NONE) as u8
                    })
                    .sum()
            })
            .collect();
        // A FIFO over positions in key order keeps the collapse deterministic.
        let mut queue: std::collections::VecDeque<usize> =
            (0..n).filter(|&i| coface_count[i] == 1).collect();
        while let Some(i) = queue.pop_front() {
            if !alive[i] || coface_count[i] != 1 {
                continue;
            }
            let Some(j) = (0..d)
                .filter(|&axis| !odd(i, axis))
                .flat_map(|axis| [table[i][2 * axis], table[i][2 * axis + 1]])
                .filter(|&q| q != NONE && alive[q as usize])
                .map(|q| q as usize)
                .next()
            else {
                continue;
            };
            alive[i] = false;
            alive[j] = false;
            // Faces of i lose coface i; faces of j other than i lose coface j.
            for (removed, skip) in [(i, usize::MAX), (j, i)] {
                for axis in 0..d {
                    if !odd(removed, axis) {
                        continue;
                    }
                    for q in [table[removed][2 * axis], table[removed][2 * axis + 1]] {
                        let p = q as usize;
                        if q == NONE || p == skip || !alive[p] {
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

    /// The position of each cell within its own dimension's list (cells of each dimension
    /// keep key order), indexed by global position.
    fn rank_within_dimension(&self) -> Vec<u32> {
        let mut next = vec![0u32; self.layout.d + 1];
        self.cells
            .iter()
            .map(|&c| {
                let k = self.layout.dimension(c);
                next[k] += 1;
                next[k] - 1
            })
            .collect()
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

    /// Betti numbers b_0..b_d over Z/2, computed like Ripser: reduce the coboundary
    /// matrices from low to high dimension and skip ("clear") every k-cell that was a pivot
    /// of the previous one, since its column is known to reduce to zero. The cleared
    /// columns are the ones with heavy fill-in, so this is much faster than
    /// [`CellComplex::betti_by_boundaries`] on complexes with many cycles.
    pub(crate) fn betti(&self) -> Vec<u64> {
        let d = self.layout.d;
        let by_dim = self.cells_by_dimension();
        // rank[k] = rank of the boundary map from k-cells to (k-1)-cells, which equals the
        // rank of the coboundary map from (k-1)-cells to k-cells.
        let mut rank = vec![0u64; d + 2];
        let index = PositionIndex::new(&self.cells);
        let within = self.rank_within_dimension();
        let mut cofacets = Vec::with_capacity(8);
        if d == 0 || by_dim[0].is_empty() {
            return by_dim.iter().map(|cells| cells.len() as u64).collect();
        }
        // The vertex coboundaries fill in badly under column reduction, but their pivots
        // have a closed form: edge e is a pivot of the coboundary from vertices to edges
        // iff it joins two components of the graph of the edges after it (the rank of an
        // incidence matrix is vertices minus components). So that step is a union-find
        // over the edges in decreasing order.
        let mut parent: Vec<u32> = (0..by_dim[0].len() as u32).collect();
        let mut facets = Vec::with_capacity(8);
        let mut edge_pivots = vec![false; by_dim.get(1).map_or(0, |e| e.len())];
        for (e, &edge) in by_dim[1].iter().enumerate().rev() {
            self.layout.facets(edge, &mut facets);
            let ends: Vec<u32> = facets
                .iter()
                .map(|&v| within[index.get(v).expect("a complex is closed under faces")])
                .collect();
            let (a, b) = (find(&mut parent, ends[0]), find(&mut parent, ends[1]));
            if a != b {
                parent[a.max(b) as usize] = a.min(b);
                edge_pivots[e] = true;
                rank[1] += 1;
            }
        }
        let mut cleared = edge_pivots;
        for k in 1..d {
            let n_rows = by_dim[k + 1].len();
            let columns: Vec<Vec<u32>> = by_dim[k]
                .iter()
                .zip(&cleared)
                .map(|(&c, &skip)| {
                    if skip {
                        return Vec::new();
                    }
                    self.layout.cofacets(c, &mut cofacets);
                    let mut column: Vec<u32> = cofacets
                        .iter()
                        .filter_map(|&f| index.get(f).map(|p| within[p]))
                        .collect();
                    column.sort_unstable();
                    column
                })
                .collect();
            let (r, pivots) = z2_rank(columns, n_rows);
            rank[k + 1] = r;
            cleared = vec![false; n_rows];
            for p in pivots {
                cleared[p as usize] = true;
            }
        }
        (0..=d)
            .map(|k| by_dim[k].len() as u64 - rank[k] - rank[k + 1])
            .collect()
    }
}

/// Union-find root with path halving.
fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        parent[x as usize] = parent[parent[x as usize] as usize];
        x = parent[x as usize];
    }
    x
}

/// "No such cell" in a neighbour table.
const NONE: u32 = u32::MAX;

/// Key-to-position lookup for a sorted cell list: open addressing with a multiplicative
/// hash, about one cache miss per lookup where a binary search takes twenty. Only looked
/// up, never iterated, so nothing about it can reach an output.
struct PositionIndex {
    keys: Vec<u64>,
    positions: Vec<u32>,
    shift: u32,
}

impl PositionIndex {
    const EMPTY: u64 = u64::MAX;

    fn new(cells: &[u64]) -> PositionIndex {
        assert!(
            cells.len() < u32::MAX as usize,
            "too many cells for u32 positions"
        );
        let bits = (2 * cells.len())
            .max(16)
            .next_power_of_two()
            .trailing_zeros();
        let size = 1usize << bits;
        let mut index = PositionIndex {
            keys: vec![Self::EMPTY; size],
            positions: vec![0; size],
            shift: 64 - bits,
        };
        for (p, &key) in cells.iter().enumerate() {
            let mut slot = index.slot(key);
            while index.keys[slot] != Self::EMPTY {
                slot = (slot + 1) & (size - 1);
            }
            index.keys[slot] = key;
            index.positions[slot] = p as u32;
        }
        index
    }

    #[inline]
    fn slot(&self, key: u64) -> usize {
        (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> self.shift) as usize
    }

    #[inline]
    fn get(&self, key: u64) -> Option<usize> {
        let mask = self.keys.len() - 1;
        let mut slot = self.slot(key);
        loop {
            let k = self.keys[slot];
            if k == key {
                return Some(self.positions[slot] as usize);
            }
            if k == Self::EMPTY {
                return None;
            }
            slot = (slot + 1) & mask;
        }
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
        let n_before = complex.len();
        complex.collapse();
        assert!(
            complex.cells.len() < n_before / 4,
            "{} of {n_before} cells left",
            complex.cells.len()
        );
        assert_eq!(complex.betti(), before);
        assert_eq!(complex.betti_by_boundaries(), before);
        assert_eq!(before, vec![1, 1, 0, 0]);
    }
}
