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
//! the whole image) deletes about 99% of a blob; later sweeps only revisit the survivors
//! whose neighbourhood changed since their last test. The first sweep slides the 3^d block
//! along the last axis, reading one new column per voxel instead of the whole block.
//! The 4D test has no table, so its answers are memoised in a small direct-mapped cache
//! (a pure function memoised: it cannot change a result).

use crate::simple::SimpleTester;
use bettimill_grid::neighbourhood::flat_offsets;
use bettimill_grid::BinaryImage;

/// Direct-mapped memo of the simple-point test, keyed by `SimpleTester::memo_key` (in 4D
/// the attachment set, at most 80 face bits) with bit 126 marking the slot used and bit 127
/// the answer.
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

    /// Whether the voxel with configuration `config` is simple; memoised on the tester's
    /// memo key (a pure function of the configuration).
    #[inline]
    fn is_simple(&mut self, tester: &SimpleTester, config: u128) -> bool {
        let config = tester.memo_key(config);
        let folded = (config as u64) ^ ((config >> 64) as u64).wrapping_mul(0xD6E8_FEB8_6659_FD93);
        let slot = (folded.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> self.shift) as usize;
        let entry = self.entries[slot];
        if entry & !Self::ANSWER == config | Self::USED {
            return entry & Self::ANSWER != 0;
        }
        let answer = tester.is_simple_key(config);
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
    range: std::ops::Range<usize>,
    global_offset: usize,
    survivors: &mut Vec<usize>,
    phase: Phase,
) {
    let mut cache = SimpleCache::new(16);
    let window = Window::new(strides);
    // `block` is the 3^d block of voxel `previous`, kept current: between two voxels the
    // only write is the deletion of the voxel itself, whose centre bit is cleared.
    let mut block = 0u128;
    let mut previous = usize::MAX;
    let neighbours = window.all_bits & !window.centre_bit;
    // The block of a voxel whose earlier neighbours (in raster order) are all gone and
    // later ones all present: its attachment set is a closed half of the voxel's boundary,
    // a ball, so it is simple. A third of a blob's voxels look like this in the first
    // sweep; they skip the configuration and the memo.
    let half = window.all_bits & !(window.centre_bit - 1);
    for i in range {
        // Skips the other phase, and locked voxels (bit 2), which are never flipped.
        if data[i] & 5 != 1 {
            continue;
        }
        block = if previous.wrapping_add(1) == i {
            window.advance(data, block, i)
        } else {
            window.block(data, i)
        };
        previous = i;
        // A voxel whose face neighbours are all foreground is never simple (the background
        // part of its neighbourhood is empty); that check is much cheaper than the test.
        if phase == Phase::Foreground && block == half {
            data[i] = 0;
            block &= !window.centre_bit;
            continue;
        }
        let (exposed, config) = match phase {
            Phase::Foreground => (
                block & window.face_bits != window.face_bits,
                tester.configuration_of_block(block),
            ),
            // Adding a background voxel to the object needs an object voxel among its
            // neighbours; the object's configuration is the complement.
            Phase::Background => (
                block & neighbours != neighbours,
                tester.configuration_of_block(!block & neighbours),
            ),
        };
        if exposed && cache.is_simple(tester, config) {
            data[i] = 0;
            block &= !window.centre_bit;
        } else {
            survivors.push(i + global_offset);
        }
    }
}

/// The 3^d block of a voxel as 3^(d-1) rows of three bits along the last axis (bit 3r + c,
/// rows in lexicographic order of the other axes, c = 0, 1, 2 for offsets -1, 0, +1), read
/// whole or slid by one voxel along the last axis (one new column of 3^(d-1) bytes instead
/// of the whole block).
struct Window {
    /// Flat offset of each row's middle voxel.
    rows: Vec<isize>,
    /// Bits 0 and 1 of every row.
    low_two: u128,
    /// The bits of the 2d face neighbours.
    face_bits: u128,
    centre_bit: u128,
    /// Every bit of the 3^d block.
    all_bits: u128,
}

impl Window {
    fn new(strides: &[usize]) -> Window {
        let d = strides.len();
        let mut rows = vec![0isize];
        for &stride in &strides[..d - 1] {
            rows = rows
                .iter()
                .flat_map(|&o| [-1isize, 0, 1].map(|t| o + t * stride as isize))
                .collect();
        }
        let n_rows = rows.len();
        let middle_row = n_rows / 2;
        let low_two = (0..n_rows).fold(0u128, |m, r| m | 0b011 << (3 * r));
        let centre_bit = 1u128 << (3 * middle_row + 1);
        let mut face_bits = (centre_bit >> 1) | (centre_bit << 1);
        // Along axis a < d - 1 the rows one step away are 3^(d-2-a) rows apart.
        for axis in 0..d - 1 {
            let apart = 3usize.pow((d - 2 - axis) as u32);
            face_bits |= 1u128 << (3 * (middle_row - apart) + 1);
            face_bits |= 1u128 << (3 * (middle_row + apart) + 1);
        }
        let all_bits = (1u128 << (3 * n_rows)) - 1;
        Window {
            rows,
            low_two,
            face_bits,
            centre_bit,
            all_bits,
        }
    }

    /// The column at flat index `at` (the rows' voxels shifted by `at`), at bits 3r.
    #[inline]
    fn column(&self, data: &[u8], at: usize) -> u128 {
        let mut bits = 0u128;
        for (r, &o) in self.rows.iter().enumerate() {
            bits |= ((data[(at as isize + o) as usize] & 1) as u128) << (3 * r);
        }
        bits
    }

    #[inline]
    fn block(&self, data: &[u8], i: usize) -> u128 {
        self.column(data, i - 1) | self.column(data, i) << 1 | self.column(data, i + 1) << 2
    }

    /// The block of voxel i from the (current) block of voxel i - 1.
    #[inline]
    fn advance(&self, data: &[u8], block: u128, i: usize) -> u128 {
        ((block >> 1) & self.low_two) | self.column(data, i + 1) << 2
    }
}

/// Which phase [`thin`] shrinks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Phase {
    /// Delete simple voxels of value 1 (the object).
    Foreground,
    /// The image holds the complement of an object (1 = background of the object) and
    /// simple voxels of value 1 are given to the object: the object grows and its
    /// background shrinks, with the topology of both unchanged (a voxel is simple for a
    /// set exactly when it is simple for the complement). Voxels with bit 2 set (value
    /// 5) are locked: part of the phase, never flipped.
    Background,
}

/// Flips simple voxels of value 1 of `image` (deletes them from the object, or gives them
/// to the object: see [`Phase`]) until none is simple, and returns the survivors' indices
/// in increasing order (locked voxels are not listed). Every voxel that may be flipped
/// must have all its neighbours inside the image: in the foreground phase the border must
/// be background, in the background phase locked.
///
/// The first sweep, which does almost all the work, runs on two threads: the image is cut
/// across its first axis into slabs A (planes below k) and B (planes from k + 2 on) with
/// planes k and k + 1 left alone. A voxel of A and a voxel of B are at least three planes
/// apart, so neither ever reads what the other writes: the outcome is exactly that of
/// sweeping A and then B sequentially, whatever the thread timing. The seam planes are
/// swept with the survivors afterwards.
pub(crate) fn thin(image: &mut BinaryImage, tester: &SimpleTester, phase: Phase) -> Vec<usize> {
    debug_assert!(match phase {
        Phase::Foreground => image.border_is_background(),
        Phase::Background => border_is_locked(image),
    });
    let steps = flat_offsets(image, tester.offsets());
    // The neighbours whose membership decides whether a flip can be simple at all: the
    // face neighbours (a foreground voxel with none in the background is never simple),
    // or every neighbour (a background voxel needs an object voxel next to it).
    let exposure_steps: Vec<isize> = match phase {
        Phase::Foreground => steps
            .iter()
            .zip(tester.offsets())
            .filter(|(_, off)| off.iter().map(|o| o.abs()).sum::<i8>() == 1)
            .map(|(&s, _)| s)
            .collect(),
        Phase::Background => steps.clone(),
    };
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
                    0..k * plane,
                    0,
                    &mut survivors_a,
                    phase,
                )
            },
            || {
                let n_b = slab_b.len();
                sweep(
                    tester,
                    slab_b,
                    &strides,
                    plane..n_b,
                    (k + 1) * plane,
                    &mut survivors_b,
                    phase,
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
            0..len,
            0,
            &mut remaining,
            phase,
        );
    }
    // Later sweeps: a voxel can only have become simple if a neighbour was flipped since
    // its last test, so each flip flags its neighbours of the same phase (bit 1 of their
    // byte, which configurations and the exposure check ignore) and a sweep after the
    // first retests only flagged voxels, clearing the flag as it does. Skipping a voxel
    // never flips anything, so it cannot affect correctness, and when a sweep flips
    // nothing no flag is left: no survivor is simple, as with full sweeps.
    let n_neighbours = steps.len();
    let mut cache = SimpleCache::new(16);
    let mut every = true;
    loop {
        let before = remaining.len();
        let data = image.data_mut();
        remaining.retain(|&i| {
            if !every && data[i] & 2 == 0 {
                return true;
            }
            data[i] &= !2;
            let exposed = exposure_steps
                .iter()
                .any(|&s| data[(i as isize + s) as usize] & 1 == 0);
            if !exposed {
                return true;
            }
            let mut config = tester.configuration_in(data, &strides, i);
            if phase == Phase::Background {
                config = !config & ((1u128 << n_neighbours) - 1);
            }
            if cache.is_simple(tester, config) {
                data[i] = 0;
                for &s in &steps {
                    let j = (i as isize + s) as usize;
                    if data[j] & 1 != 0 {
                        data[j] |= 2;
                    }
                }
                false
            } else {
                true
            }
        });
        every = false;
        if remaining.len() == before {
            break;
        }
    }
    let data = image.data_mut();
    for &i in &remaining {
        data[i] = 1;
    }
    // Flags set on locked voxels are cleared too.
    if phase == Phase::Background {
        for v in data.iter_mut() {
            *v &= !2;
        }
    }
    remaining
}

/// Whether every voxel of the outer layer is locked (value 5).
fn border_is_locked(image: &BinaryImage) -> bool {
    let d = image.dim().get();
    let shape = image.shape().to_vec();
    (0..image.len()).all(|index| {
        let c = image.coords(index);
        let on_border = (0..d).any(|a| c[a] == 0 || c[a] + 1 == shape[a]);
        !on_border || image.data()[index] == 5
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use bettimill_grid::neighbourhood::is_interior;
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
            let survivors = thin(&mut ball, &tester, Phase::Foreground);
            assert_eq!(survivors.len(), 1, "{d}D ball");
            assert_eq!(ball.count_foreground(), 1);
            let survivors = thin(&mut ring, &tester, Phase::Foreground);
            // A loop cannot shrink to a point, but it does get thinner.
            assert!(
                survivors.len() >= 4 && survivors.len() < n_ring,
                "{d}D ring"
            );
            assert_eq!(survivors.len() as u64, ring.count_foreground());
        }
    }

    /// The first sweep's shortcut: a voxel whose earlier neighbours are gone and later ones
    /// present is simple, in every dimension (checked with the full test and the oracle).
    #[test]
    fn the_half_block_is_simple() {
        for dim in Dim::ALL {
            let tester = SimpleTester::new(dim);
            let n = tester.offsets().len();
            let later = ((1u128 << n) - 1) & !((1u128 << (n / 2)) - 1);
            assert!(tester.is_simple_configuration(later), "{dim:?}");
            assert!(tester.is_simple_by_collapse(later), "{dim:?}");
            let image = BinaryImage::zeros(&vec![5; dim.get()]).unwrap();
            let window = Window::new(image.strides());
            let half = window.all_bits & !(window.centre_bit - 1);
            assert_eq!(tester.configuration_of_block(half), later, "{dim:?}");
        }
    }

    /// The sliding window sees exactly what a fresh read sees, so a sweep deletes exactly
    /// the voxels that a sweep reading every configuration afresh deletes.
    #[test]
    fn sliding_window_sweep_matches_fresh_reads() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        for dim in Dim::ALL {
            let d = dim.get();
            let tester = SimpleTester::new(dim);
            for trial in 0..30 {
                let side = [9, 7, 6][d - 2];
                let shape: Vec<usize> = (0..d).map(|a| side + a % 2).collect();
                let mut image = BinaryImage::zeros(&shape).unwrap();
                let density: f64 = rng.gen_range(0.2..0.95);
                for index in 0..image.len() {
                    if is_interior(&image, index, 1) {
                        image.data_mut()[index] = rng.gen_bool(density) as u8;
                    }
                }
                let mut fresh = image.clone();
                for i in 0..fresh.len() {
                    if fresh.data()[i] == 1
                        && tester.is_simple_configuration(tester.configuration_unchecked(&fresh, i))
                    {
                        fresh.data_mut()[i] = 0;
                    }
                }
                let strides = image.strides().to_vec();
                let len = image.len();
                let mut survivors = Vec::new();
                sweep(
                    &tester,
                    image.data_mut(),
                    &strides,
                    0..len,
                    0,
                    &mut survivors,
                    Phase::Foreground,
                );
                assert_eq!(image.data(), fresh.data(), "{d}D trial {trial}");
                let expected: Vec<usize> = (0..len).filter(|&i| fresh.data()[i] == 1).collect();
                assert_eq!(survivors, expected);
            }
        }
    }
}
