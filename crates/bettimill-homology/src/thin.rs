//! Homotopy-preserving thinning by sequential simple-point deletion.
//!
//! Deleting a simple voxel changes no topology, so deleting them one at a time until none is
//! left shrinks the foreground to a thin remnant with the same Betti numbers; a contractible
//! blob ends as a single voxel. The remnant's cubical complex is then small enough for
//! explicit homology. Simple points are not jointly deletable, so the deletion is strictly
//! sequential, driven by a FIFO queue of candidates in a fixed order (peeling layer by
//! layer), which makes the result deterministic.

use crate::simple::SimpleTester;
use bettimill_grid::neighbourhood::flat_offsets;
use bettimill_grid::BinaryImage;
use std::collections::VecDeque;

/// Deletes simple foreground voxels of `image` (which must have a background border) until
/// none is simple. Returns the number of voxels deleted.
#[inline(never)]
pub(crate) fn thin(image: &mut BinaryImage, tester: &SimpleTester) -> u64 {
    let steps = flat_offsets(image, tester.offsets());
    let face_steps: Vec<isize> = steps
        .iter()
        .zip(tester.offsets())
        .filter(|(_, off)| off.iter().map(|o| o.abs()).sum::<i8>() == 1)
        .map(|(&s, _)| s)
        .collect();
    let n = image.len();
    let mut queued = vec![0u64; n.div_ceil(64)];
    let mut queue: VecDeque<usize> = VecDeque::new();
    {
        let data = image.data();
        for i in 0..n {
            // Interior voxels (all face neighbours foreground) are never simple: the
            // background part of their neighbourhood is empty.
            if data[i] == 1
                && face_steps
                    .iter()
                    .any(|&s| data[(i as isize + s) as usize] == 0)
            {
                queued[i / 64] |= 1 << (i % 64);
                queue.push_back(i);
            }
        }
    }
    let mut deleted = 0;
    while let Some(i) = queue.pop_front() {
        queued[i / 64] &= !(1 << (i % 64));
        if image.data()[i] == 0 || !tester.is_simple(image, i) {
            continue;
        }
        image.data_mut()[i] = 0;
        deleted += 1;
        let data = image.data();
        for &s in &steps {
            let j = (i as isize + s) as usize;
            if data[j] == 1 && queued[j / 64] >> (j % 64) & 1 == 0 {
                queued[j / 64] |= 1 << (j % 64);
                queue.push_back(j);
            }
        }
    }
    deleted
}
