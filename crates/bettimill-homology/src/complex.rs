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
//! The fast path ([`CellComplex::betti_by_reduction`]) shrinks the complex by reduction
//! pairs: free-face collapses (a face with exactly one coface goes with that coface) and
//! coreductions (a cell with exactly one face goes with that face), restarted by removing a
//! vertex when stuck, which the Betti numbers account for exactly (see there). A per-cell
//! table of the neighbouring cells along each axis, built by linear merges of the sorted
//! keys, makes each step a few lookups. The few cells left go through sparse Z/2 column
//! reductions and b_k = n_k - rank d_k - rank d_{k+1}. [`crate::reference`] reduces the plain
//! boundary matrices of the whole, unreduced complex
//! ([`CellComplex::betti_by_boundaries`]), so the two check each other.

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

    /// The (wrapping) key offset of a step of `steps[a]` (each -1, 0 or 1, as u64 two's
    /// complement) along every axis a.
    pub(crate) fn key_offset(&self, steps: &[u64]) -> u64 {
        (0..self.d).fold(0u64, |sum, axis| {
            sum.wrapping_add(steps[axis].wrapping_mul(self.stride[axis]))
        })
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

    /// Betti numbers b_0..b_d over Z/2 by reduction pairs, the fast path of
    /// [`crate::topology`] in 4D.
    ///
    /// The complex is shrunk by removing pairs (a, b), b a facet of a, that are either a
    /// free-face collapse (a is the only alive cofacet of b) or a coreduction (b is the only
    /// alive facet of a). Over Z/2 both preserve the homology of the remaining set of cells
    /// taken with the restricted boundary (an S-complex in the sense of Mrozek and Batko):
    /// the reduced chain complex differs from the old one only by the deleted pair.
    /// Coreductions need a start, so when no pair is left an alive vertex v is removed,
    /// which turns the homology into that of the pair (X, V) with V the removed vertices.
    /// For k >= 2 the long exact sequence of (X, V) gives H_k(X, V) = H_k(X), and in low
    /// degrees dim H_0(X, V) = b_0 - c and dim H_1(X, V) = b_1 + m - c, where m = |V| and c
    /// is the number of components V meets. b_0 comes from a union-find over the edges, so
    /// b_1 follows (each removed vertex either lowers dim H_0 by one or raises dim H_1 by
    /// one). The Euler characteristic (alternating cell count of the whole complex) checks
    /// the bookkeeping; a mismatch panics rather than returning a wrong answer.
    /// The few cells left are reduced explicitly (boundary matrices, top dimension first,
    /// with clearing).
    pub(crate) fn betti_by_reduction(&self) -> Vec<u64> {
        let d = self.layout.d;
        let n = self.cells.len();
        let mut chi = 0i64;
        for &c in &self.cells {
            chi += if self.layout.dimension(c) % 2 == 0 {
                1
            } else {
                -1
            };
        }
        if n == 0 {
            return vec![0; d + 1];
        }
        let table = self.neighbour_table();
        let stride = self.layout.stride;
        let odd = |p: usize, axis: usize| self.cells[p] & stride[axis] != 0;
        // b_0: union-find over vertices joined by edges.
        let mut parent: Vec<u32> = (0..n as u32).collect();
        let mut n_vertices = 0u64;
        let mut merges = 0u64;
        for (&cell, row) in self.cells.iter().zip(&table) {
            match self.layout.dimension(cell) {
                0 => n_vertices += 1,
                1 => {
                    let axis = (0..d)
                        .find(|&a| cell & stride[a] != 0)
                        .expect("an edge has an odd axis");
                    let (u, v) = (row[2 * axis], row[2 * axis + 1]);
                    assert!(u != NONE && v != NONE, "a complex is closed under faces");
                    let (a, b) = (find(&mut parent, u), find(&mut parent, v));
                    if a != b {
                        parent[a.max(b) as usize] = a.min(b);
                        merges += 1;
                    }
                }
                _ => {}
            }
        }
        let b0 = n_vertices - merges;
        drop(parent);
        // One byte per cell: DEAD, or the alive facets (high nibble) and cofacets (low).
        const DEAD: u8 = 0xFF;
        let mut state = vec![0u8; n];
        for (p, slot) in state.iter_mut().enumerate() {
            for axis in 0..d {
                let present =
                    (table[p][2 * axis] != NONE) as u8 + (table[p][2 * axis + 1] != NONE) as u8;
                *slot += if odd(p, axis) { present << 4 } else { present };
            }
        }
        // Removing cell `r` (paired with `partner`, or none) updates the counts of its alive
        // neighbours and queues those that became candidates.
        let remove = |r: usize,
                      partner: usize,
                      state: &mut [u8],
                      stack: &mut std::collections::VecDeque<u32>| {
            state[r] = DEAD;
            for axis in 0..d {
                // Along an odd axis the neighbours are facets of r (they lose a cofacet),
                // along an even one cofacets (they lose a facet).
                let step = if odd(r, axis) { 1 } else { 0x10 };
                for q in [table[r][2 * axis], table[r][2 * axis + 1]] {
                    let p = q as usize;
                    if q == NONE || p == partner || state[p] == DEAD {
                        continue;
                    }
                    state[p] -= step;
                    if state[p] & 0x0F == 1 || state[p] >> 4 == 1 {
                        stack.push_back(q);
                    }
                }
            }
        };
        // The unique alive neighbour of `p` among its facets (want_facet) or cofacets.
        let unique = |p: usize, want_facet: bool, state: &[u8]| -> Option<usize> {
            (0..d)
                .filter(|&axis| odd(p, axis) == want_facet)
                .flat_map(|axis| [table[p][2 * axis], table[p][2 * axis + 1]])
                .filter(|&q| q != NONE && state[q as usize] != DEAD)
                .map(|q| q as usize)
                .next()
        };
        // First in, first out: coreductions then spread from a removed vertex in waves, which
        // leaves far fewer cells stuck than depth-first order does.
        let mut stack: std::collections::VecDeque<u32> = (0..n as u32)
            .filter(|&p| state[p as usize] & 0x0F == 1)
            .collect();
        let mut removed_vertices = 0u64;
        let mut next_vertex = 0usize;
        loop {
            while let Some(q) = stack.pop_front() {
                let p = q as usize;
                let s = state[p];
                if s == DEAD {
                    continue;
                }
                // Free face: p is the facet and its only cofacet goes with it; coreduction:
                // p is the cell and its only facet goes with it.
                let pair = if s & 0x0F == 1 {
                    unique(p, false, &state).map(|a| (a, p))
                } else if s >> 4 == 1 {
                    unique(p, true, &state).map(|b| (p, b))
                } else {
                    None
                };
                let Some((a, b)) = pair else { continue };
                remove(a, b, &mut state, &mut stack);
                remove(b, a, &mut state, &mut stack);
            }
            while next_vertex < n
                && !(state[next_vertex] != DEAD
                    && self.layout.dimension(self.cells[next_vertex]) == 0)
            {
                next_vertex += 1;
            }
            if next_vertex == n {
                break;
            }
            removed_vertices += 1;
            remove(next_vertex, usize::MAX, &mut state, &mut stack);
        }
        let alive: Vec<bool> = state.iter().map(|&s| s != DEAD).collect();
        drop(state);
        // Explicit reduction of what is left, top dimension first; a k-cell that is the
        // lowest row of a reduced (k+1)-column has a boundary column reducing to zero.
        let left: Vec<usize> = (0..n).filter(|&p| alive[p]).collect();
        let mut position = vec![u32::MAX; n];
        let mut n_left = vec![0u64; d + 1];
        let mut by_dim: Vec<Vec<usize>> = vec![Vec::new(); d + 1];
        for &p in &left {
            let k = self.layout.dimension(self.cells[p]);
            position[p] = n_left[k] as u32;
            n_left[k] += 1;
            by_dim[k].push(p);
        }
        let mut rank = vec![0u64; d + 2];
        let mut cleared = vec![false; by_dim[d].len()];
        for k in (1..=d).rev() {
            let columns: Vec<Vec<u32>> = by_dim[k]
                .iter()
                .zip(&cleared)
                .map(|(&p, &skip)| {
                    if skip {
                        return Vec::new();
                    }
                    let mut column: Vec<u32> = (0..d)
                        .filter(|&axis| odd(p, axis))
                        .flat_map(|axis| [table[p][2 * axis], table[p][2 * axis + 1]])
                        .filter(|&q| q != NONE && alive[q as usize])
                        .map(|q| position[q as usize])
                        .collect();
                    column.sort_unstable();
                    column
                })
                .collect();
            let (r, pivots) = z2_rank(columns, by_dim[k - 1].len());
            rank[k] = r;
            cleared = vec![false; by_dim[k - 1].len()];
            for row in pivots {
                cleared[row as usize] = true;
            }
        }
        let relative: Vec<u64> = (0..=d).map(|k| n_left[k] - rank[k] - rank[k + 1]).collect();
        // c = b_0 - dim H_0(X, V); b_1 = dim H_1(X, V) - m + c.
        let met = b0
            .checked_sub(relative[0])
            .expect("H_0(X, V) cannot exceed H_0(X)");
        let b1 = (relative[1] + met)
            .checked_sub(removed_vertices)
            .expect("H_1(X, V) has dimension b_1 + m - c");
        let mut betti = relative;
        betti[0] = b0;
        betti[1] = b1;
        let euler: i64 = betti
            .iter()
            .enumerate()
            .map(|(k, &b)| if k % 2 == 0 { b as i64 } else { -(b as i64) })
            .sum();
        assert_eq!(
            euler, chi,
            "reduction pairs lost homology: Betti numbers {betti:?} disagree with the Euler \
             characteristic {chi}"
        );
        betti
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

    /// A square ring of voxels in a plane of a 3D image: one loop.
    fn ring() -> BinaryImage {
        let mut image = BinaryImage::zeros(&[7, 7, 7]).unwrap();
        for i in 1..6 {
            image.set(&[3, 1, i], true);
            image.set(&[3, 5, i], true);
            image.set(&[3, i, 1], true);
            image.set(&[3, i, 5], true);
        }
        image
    }

    #[test]
    fn reduction_pairs_keep_homology() {
        let complex = CellComplex::of_image(&ring());
        assert!(complex.len() > 100);
        assert_eq!(complex.betti_by_boundaries(), vec![1, 1, 0, 0]);
        assert_eq!(complex.betti_by_reduction(), vec![1, 1, 0, 0]);
        let empty = CellComplex::of_image(&BinaryImage::zeros(&[4, 4, 4, 4]).unwrap());
        assert_eq!(empty.betti_by_reduction(), vec![0; 5]);
    }

    /// Reduction pairs against plain boundary ranks on random complexes of every dimension,
    /// sparse to dense, including several components (so several vertices are removed) and
    /// checkerboards (only corner contacts).
    #[test]
    fn reduction_agrees_with_boundary_ranks_on_random_complexes() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(31);
        for (d, side, n) in [(2, 9, 400), (3, 6, 400), (4, 4, 300), (4, 5, 60)] {
            for trial in 0..n {
                let shape = vec![side + 2; d];
                let mut image = BinaryImage::zeros(&shape).unwrap();
                let density: f64 = rng.gen_range(0.05..0.95);
                let checker = trial % 10 == 0;
                for index in 0..image.len() {
                    let c = image.coords(index);
                    if c[..d].iter().any(|&x| x == 0 || x == side + 1) {
                        continue;
                    }
                    let on = if checker {
                        c[..d].iter().sum::<usize>() % 2 == 0 || rng.gen_bool(0.1)
                    } else {
                        rng.gen_bool(density)
                    };
                    image.data_mut()[index] = on as u8;
                }
                let complex = CellComplex::of_image(&image);
                assert_eq!(
                    complex.betti_by_reduction(),
                    complex.betti_by_boundaries(),
                    "{d}D trial {trial}, density {density:.2}"
                );
            }
        }
    }
}
