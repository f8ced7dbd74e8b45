//! Fast simple-point answers for the editing loops: the neighbourhood configuration read
//! straight from the voxel bytes (no per-call border check: callers only pass interior
//! voxels), and in 4D, where the test has no table, a direct-mapped memo of the answers.
//! Both are pure functions of the image, so they change no result, only its cost.

use bettimill_grid::{BinaryImage, Dim};
use bettimill_homology::simple::SimpleTester;

/// Configuration reader and memoised simple-point test for one image layout.
pub(crate) struct FastSimple {
    tester: SimpleTester,
    dim: Dim,
    strides: [usize; 4],
    /// Sum of the strides: the offset from a voxel to the first voxel of its 3^d block.
    corner: usize,
    /// The configuration bit of the centre in lexicographic block order.
    centre: u32,
    entries: Vec<u128>,
    shift: u32,
}

impl FastSimple {
    const USED: u128 = 1 << 126;
    const ANSWER: u128 = 1 << 127;
    /// log2 of the memo slots (4D only): 2^18 slots of 16 bytes, 4 MiB.
    const MEMO_BITS: u32 = 18;

    pub(crate) fn new(image: &BinaryImage, tester: &SimpleTester) -> FastSimple {
        let dim = image.dim();
        let d = dim.get();
        let mut strides = [0usize; 4];
        strides[..d].copy_from_slice(image.strides());
        let bits = if dim == Dim::Four { Self::MEMO_BITS } else { 0 };
        FastSimple {
            tester: tester.clone(),
            dim,
            strides,
            corner: strides[..d].iter().sum(),
            centre: (3u32.pow(d as u32) - 1) / 2,
            entries: if bits > 0 {
                vec![0; 1 << bits]
            } else {
                Vec::new()
            },
            shift: 64 - bits.max(1),
        }
    }

    /// The configuration of interior voxel `index` (bit k = neighbour k in
    /// `full_offsets` order, as `SimpleTester::configuration`).
    #[inline]
    pub(crate) fn configuration(&self, data: &[u8], index: usize) -> u128 {
        let start = index - self.corner;
        let row = |p: usize| -> u128 {
            (data[p] as u128) | (data[p + 1] as u128) << 1 | (data[p + 2] as u128) << 2
        };
        let s = &self.strides;
        let mut block = 0u128;
        let mut shift = 0;
        match self.dim {
            Dim::Two => {
                for a in 0..3 {
                    block |= row(start + a * s[0]) << shift;
                    shift += 3;
                }
            }
            Dim::Three => {
                for a in 0..3 {
                    for b in 0..3 {
                        block |= row(start + a * s[0] + b * s[1]) << shift;
                        shift += 3;
                    }
                }
            }
            Dim::Four => {
                for a in 0..3 {
                    for b in 0..3 {
                        let base = start + a * s[0] + b * s[1];
                        for c in 0..3 {
                            block |= row(base + c * s[2]) << shift;
                            shift += 3;
                        }
                    }
                }
            }
        }
        let centre = self.centre;
        (block & ((1u128 << centre) - 1)) | ((block >> (centre + 1)) << centre)
    }

    /// Reads what [`FastSimple::is_simple`] of `index` will read (its neighbourhood and its
    /// memo slot) and returns a value to feed to `std::hint::black_box`. Called for the
    /// voxels a little ahead of the one being decided, it lets their cache misses overlap
    /// instead of stalling one by one; it changes nothing.
    #[inline]
    pub(crate) fn touch(&self, data: &[u8], index: usize) -> u128 {
        let config = self.configuration(data, index);
        if self.entries.is_empty() {
            return config;
        }
        config ^ self.entries[self.slot(config)]
    }

    #[inline]
    fn slot(&self, config: u128) -> usize {
        let folded = (config as u64) ^ ((config >> 64) as u64).wrapping_mul(0xD6E8_FEB8_6659_FD93);
        (folded.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> self.shift) as usize
    }

    /// Whether interior voxel `index` of `data` is simple.
    #[inline]
    pub(crate) fn is_simple(&mut self, data: &[u8], index: usize) -> bool {
        let config = self.configuration(data, index);
        if self.entries.is_empty() {
            return self.tester.is_simple_configuration(config);
        }
        let slot = self.slot(config);
        let entry = self.entries[slot];
        if entry & !Self::ANSWER == config | Self::USED {
            return entry & Self::ANSWER != 0;
        }
        let answer = self.tester.is_simple_configuration(config);
        self.entries[slot] = config | Self::USED | if answer { Self::ANSWER } else { 0 };
        answer
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn agrees_with_the_tester() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for shape in [vec![9usize, 11], vec![7, 8, 9], vec![6, 7, 5, 8]] {
            let mut image = BinaryImage::zeros(&shape).unwrap();
            for v in image.data_mut() {
                *v = rng.gen_bool(0.6) as u8;
            }
            let tester = SimpleTester::new(image.dim());
            let mut fast = FastSimple::new(&image, &tester);
            crate::for_each_interior(&image, |v| {
                assert_eq!(
                    fast.configuration(image.data(), v),
                    tester.configuration(&image, v),
                    "{shape:?} voxel {v}"
                );
                // Twice: once computed, once from the memo.
                for _ in 0..2 {
                    assert_eq!(
                        fast.is_simple(image.data(), v),
                        tester.is_simple(&image, v),
                        "{shape:?} voxel {v}"
                    );
                }
            });
        }
    }
}
