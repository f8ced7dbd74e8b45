//! A cell's rank among the alive cells of one dimension, read off the masks.

use std::sync::atomic::{AtomicU16, Ordering::Relaxed};

/// The rank of a cell among the alive cells of some codes (one dimension's), in increasing
/// order of place and code, read off the masks: the count before every
/// [`Ranks::STRIDE`]-th place is kept (a quarter of a byte a place), the places since are
/// counted when asked.
pub(super) struct Ranks {
    pub(super) codes: u16,
    pub(super) before: Vec<u32>,
}

impl Ranks {
    pub(super) const STRIDE: usize = 16;

    pub(super) fn new(masks: &[AtomicU16], codes: u16) -> Ranks {
        let mut before = Vec::with_capacity(masks.len().div_ceil(Ranks::STRIDE));
        let mut n = 0u32;
        for stride in masks.chunks(Ranks::STRIDE) {
            before.push(n);
            n += Ranks::count(stride, codes);
        }
        Ranks { codes, before }
    }

    /// The cells of `masks` whose codes are in `codes`. Four masks a word: one count of
    /// its ones for four places (x86-64 without `popcnt` counts a word's ones in a dozen
    /// instructions).
    #[inline]
    pub(super) fn count(masks: &[AtomicU16], codes: u16) -> u32 {
        let codes = codes as u64 * 0x0001_0001_0001_0001;
        masks
            .chunks(4)
            .map(|four| {
                let word = four
                    .iter()
                    .rev()
                    .fold(0u64, |word, mask| word << 16 | mask.load(Relaxed) as u64);
                (word & codes).count_ones()
            })
            .sum()
    }

    /// The rank of the alive cell (owner, code), whose code is one of the codes.
    #[inline]
    pub(super) fn rank(&self, masks: &[AtomicU16], owner: usize, code: u32) -> u32 {
        let start = owner - owner % Ranks::STRIDE;
        let earlier = Ranks::count(&masks[start..owner], self.codes);
        let below = masks[owner].load(Relaxed) & self.codes & ((1u16 << code) - 1);
        self.before[owner / Ranks::STRIDE] + earlier + below.count_ones()
    }
}
