//! The Euler characteristic of a binary image in one streaming pass over grid vertices.
//!
//! Every cell of the cubical complex is owned by exactly one grid vertex v: the cell that
//! starts at v and extends in the + direction along a subset S of the axes. That cell is in
//! the complex iff one of the voxels containing it is foreground, and those voxels are
//! among the 2^d voxels around v (v - eps, eps in {0,1}^d, with eps_i = 0 for i in S). So
//! the Euler characteristic is a sum over vertices of a table indexed by the 2^d voxels
//! around the vertex (2^16 entries in 4D), and needs no memory beyond the image.

use bettimill_grid::BinaryImage;

/// A one in every byte of a word: eight foreground voxels.
const LOW_BYTES: u64 = 0x0101_0101_0101_0101;

/// chi contribution of a vertex given the foreground mask of its 2^d surrounding voxels
/// (bit e = the voxel v - eps where eps_i is bit i of e).
fn vertex_table(d: usize) -> Vec<i8> {
    let n_configs = 1usize << (1 << d);
    (0..n_configs)
        .map(|config| {
            let mut chi = 0i8;
            for subset in 0..(1usize << d) {
                // Voxels containing cell (v, S) have eps_i = 0 on S.
                let present = (0..(1usize << d)).any(|e| e & subset == 0 && config >> e & 1 == 1);
                if present {
                    chi += if subset.count_ones() % 2 == 0 { 1 } else { -1 };
                }
            }
            chi
        })
        .collect()
}

/// The Euler characteristic of the union of the closed foreground voxels of `image`, which
/// must have a background border (pad it first).
pub(crate) fn euler_characteristic(image: &BinaryImage) -> i64 {
    debug_assert!(image.border_is_background());
    let d = image.dim().get();
    let table = vertex_table(d);
    // Every voxel of a column (one voxel of each of the 2^(d-1) rows) in the image.
    let full = (1usize << (1 << (d - 1))) - 1;
    debug_assert_eq!(table[0], 0);
    debug_assert_eq!(table[full | full << (1 << (d - 1))], 0);
    let shape = image.shape();
    let strides = image.strides();
    let data = image.data();
    let last = d - 1;
    let n_lower = 1usize << last;
    // Vertices v with 1 <= v_i <= n_i - 1 suffice: cells owned by other vertices touch only
    // the background border. A vertex's voxels split into the 2^(d-1) "rows" along the last
    // axis; the column of those rows at one last-axis position is reused by the next vertex.
    let mut total = 0i64;
    let mut lower = [0usize; 3];
    let n_outer: usize = shape[..last].iter().map(|&n| n - 1).product::<usize>();
    let mut row_offsets = vec![0usize; n_lower];
    for (e, slot) in row_offsets.iter_mut().enumerate() {
        *slot = (0..last)
            .filter(|&axis| e >> axis & 1 == 1)
            .map(|axis| strides[axis])
            .sum();
    }
    for outer in 0..n_outer {
        let mut rest = outer;
        for axis in (0..last).rev() {
            lower[axis] = rest % (shape[axis] - 1) + 1;
            rest /= shape[axis] - 1;
        }
        // base = flat index of voxel (v_0, .., v_{d-2}, 0); voxel v - eps subtracts rows.
        let base: usize = (0..last).map(|axis| lower[axis] * strides[axis]).sum();
        let column = |c: usize| -> usize {
            let mut bits = 0usize;
            for (e, &off) in row_offsets.iter().enumerate() {
                bits |= (data[base - off + c] as usize) << e;
            }
            bits
        };
        let mut previous = column(0);
        let mut c = 1;
        while c < shape[last] {
            // A vertex whose 2^d voxels all have one value owns no cell (background) or
            // cells summing to 0 (foreground), so eight columns that repeat a uniform
            // column add nothing: empty space and solid walls go eight voxels a step.
            if (previous == 0 || previous == full) && c + 8 <= shape[last] {
                let want = if previous == 0 { 0 } else { LOW_BYTES };
                let uniform = row_offsets.iter().all(|&off| {
                    let at = base - off + c;
                    u64::from_le_bytes(data[at..at + 8].try_into().expect("eight bytes")) == want
                });
                if uniform {
                    c += 8;
                    continue;
                }
            }
            let current = column(c);
            // eps_last = 0 is voxel coordinate c, eps_last = 1 is c - 1.
            total += table[current | previous << n_lower] as i64;
            previous = current;
            c += 1;
        }
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_single_voxel_and_a_ring_have_the_right_euler_characteristic() {
        for d in 2..=4 {
            let shape = vec![5; d];
            let mut image = BinaryImage::zeros(&shape).unwrap();
            image.set(&vec![2; d], true);
            assert_eq!(euler_characteristic(&image), 1, "{d}D voxel");
        }
        let mut ring = BinaryImage::zeros(&[5, 5]).unwrap();
        for i in 1..4 {
            for j in 1..4 {
                ring.set(&[i, j], !(i == 2 && j == 2));
            }
        }
        assert_eq!(euler_characteristic(&ring), 0);
    }
}
