//! Homotopy-preserving thinning by sequential simple-point deletion.
//!
//! Deleting a simple voxel changes no topology, so deleting them one at a time until none is
//! left shrinks the foreground to a thin remnant with the same Betti numbers; a contractible
//! blob ends as a single voxel. The remnant's cubical complex is then small enough for
//! explicit homology.
//!
//! Simple points are not jointly deletable, so deletion is sequential: raster sweeps in
//! index order, each voxel tested against the image as it is at that moment, until a sweep
//! deletes nothing (the first sweep splits into two slabs too far apart to interact; see
//! [`thin`]). Raster order is deterministic and needs no queue, and
//! because the voxels before x are already gone when x is visited, the first sweep (over
//! the whole image) deletes about 99% of a blob; later sweeps only revisit the survivors.
//! The 4D test has no table, so its answers are memoised in a small direct-mapped cache
//! (a pure function memoised: it cannot change a result).

use crate::simple::SimpleTester;
use bettimill_grid::neighbourhood::flat_offsets;
use bettimill_grid::BinaryImage;

/// Direct-mapped memo of `is_simple_configuration`. Entries store the configuration (at
/// most 80 bits) with bit 126 marking the slot used and bit 127 the answer.
struct SimpleCache {
    entries: Vec<u128>,
    shift: u32,
}

impl SimpleCache {
    const USED: u128 = 1 << 126;
    const ANSWER: u128 = 1 << 127;

    fn new(bits: u32) -> SimpleCache {
        SimpleCache {
            entries: vec![0; 1 << bits],
            shift: 64 - bits,
        }
    }

    #[inline]
    fn is_simple(&mut self, tester: &SimpleTester, config: u128) -> bool {
        let folded = (config as u64) ^ ((config >> 64) as u64).wrapping_mul(0xD6E8_FEB8_6659_FD93);
        let slot = (folded.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> self.shift) as usize;
        let entry = self.entries[slot];
        if entry & !Self::ANSWER == config | Self::USED {
            return entry & Self::ANSWER != 0;
        }
        let answer = tester.is_simple_configuration(config);
        self.entries[slot] = config | Self::USED | if answer { Self::ANSWER } else { 0 };
        answer
    }
}

/// One raster sweep over the voxels `range` of the slab `data` (C order, `strides` of the
/// full image), deleting simple ones; pushes the foreground survivors, shifted by
/// `global_offset`, to `survivors`.
fn sweep(
    tester: &SimpleTester,
    data: &mut [u8],
    strides: &[usize],
    face_steps: &[isize],
    range: std::ops::Range<usize>,
    global_offset: usize,
    survivors: &mut Vec<usize>,
) {
    let mut cache = SimpleCache::new(16);
    for i in range {
        if data[i] == 0 {
            continue;
        }
        // A voxel whose face neighbours are all foreground is never simple (the background
        // part of its neighbourhood is empty); that check is much cheaper than the test.
        let exposed = face_steps
            .iter()
            .any(|&s| data[(i as isize + s) as usize] == 0);
        if exposed && cache.is_simple(tester, tester.configuration_in(data, strides, i)) {
            data[i] = 0;
        } else {
            survivors.push(i + global_offset);
        }
    }
}

/// Deletes simple foreground voxels of `image` until none is simple and returns the
/// survivors' indices in increasing order. `image` must have a background border, so every
/// foreground voxel has all its neighbours inside.
///
/// The first sweep, which does almost all the work, runs on two threads: the image is cut
/// across its first axis into slabs A (planes below k) and B (planes from k + 2 on) with
/// planes k and k + 1 left alone. A voxel of A and a voxel of B are at least three planes
/// apart, so neither ever reads what the other writes: the outcome is exactly that of
/// sweeping A and then B sequentially, whatever the thread timing. The seam planes are
/// swept with the survivors afterwards.
pub(crate) fn thin(image: &mut BinaryImage, tester: &SimpleTester) -> Vec<usize> {
    debug_assert!(image.border_is_background());
    let face_steps: Vec<isize> = flat_offsets(image, tester.offsets())
        .into_iter()
        .zip(tester.offsets())
        .filter(|(_, off)| off.iter().map(|o| o.abs()).sum::<i8>() == 1)
        .map(|(s, _)| s)
        .collect();
    let strides = image.strides().to_vec();
    let planes = image.shape()[0];
    let plane = strides[0];
    let len = image.len();
    let mut remaining = Vec::new();
    if planes >= 8 {
        let k = planes / 2;
        let (slab_a, slab_b) = image.data_mut().split_at_mut((k + 1) * plane);
        let (mut survivors_a, mut survivors_b) = (Vec::new(), Vec::new());
        rayon::join(
            || {
                sweep(
                    tester,
                    slab_a,
                    &strides,
                    &face_steps,
                    0..k * plane,
                    0,
                    &mut survivors_a,
                )
            },
            || {
                let n_b = slab_b.len();
                sweep(
                    tester,
                    slab_b,
                    &strides,
                    &face_steps,
                    plane..n_b,
                    (k + 1) * plane,
                    &mut survivors_b,
                )
            },
        );
        remaining = survivors_a;
        let data = image.data();
        remaining.extend((k * plane..(k + 2) * plane).filter(|&i| data[i] == 1));
        remaining.extend(survivors_b);
    } else {
        sweep(
            tester,
            image.data_mut(),
            &strides,
            &face_steps,
            0..len,
            0,
            &mut remaining,
        );
    }
    let mut cache = SimpleCache::new(16);
    loop {
        let before = remaining.len();
        remaining.retain(|&i| {
            let data = image.data();
            let exposed = face_steps
                .iter()
                .any(|&s| data[(i as isize + s) as usize] == 0);
            if exposed && cache.is_simple(tester, tester.configuration_unchecked(image, i)) {
                image.data_mut()[i] = 0;
                false
            } else {
                true
            }
        });
        if remaining.len() == before {
            return remaining;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bettimill_grid::Dim;

    #[test]
    fn a_ball_thins_to_one_voxel_and_a_ring_does_not() {
        for dim in Dim::ALL {
            let d = dim.get();
            let mut ball = BinaryImage::cube(dim, 11).unwrap();
            let mut ring = ball.clone();
            for index in 0..ball.len() {
                let c = ball.coords(index);
                let p: Vec<f64> = (0..d).map(|a| c[a] as f64 - 5.0).collect();
                let r2: f64 = p.iter().map(|x| x * x).sum();
                ball.data_mut()[index] = (r2 <= 16.0) as u8;
                let rest: f64 = p[2..].iter().map(|x| x * x).sum();
                let radial = (p[0] * p[0] + p[1] * p[1]).sqrt() - 3.0;
                ring.data_mut()[index] = (radial * radial + rest <= 1.0) as u8;
            }
            let tester = SimpleTester::new(dim);
            let n_ring = ring.count_foreground() as usize;
            let survivors = thin(&mut ball, &tester);
            assert_eq!(survivors.len(), 1, "{d}D ball");
            assert_eq!(ball.count_foreground(), 1);
            let survivors = thin(&mut ring, &tester);
            // A loop cannot shrink to a point, but it does get thinner.
            assert!(
                survivors.len() >= 4 && survivors.len() < n_ring,
                "{d}D ring"
            );
            assert_eq!(survivors.len() as u64, ring.count_foreground());
        }
    }
}
