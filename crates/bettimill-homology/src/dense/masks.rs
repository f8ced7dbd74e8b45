//! The masks' memory: an anonymous mapping, in huge pages where the system gives them.

use std::sync::atomic::AtomicU16;
use zerocopy::FromBytes;

/// The masks' memory: an anonymous mapping of two bytes per place, rounded up to whole
/// 2 MiB pages and one more for the alignment, zeroed by the kernel (pages no cell touches
/// are never written) and asked for as transparent huge pages on Linux. Fresh memory
/// costs a page fault per page touched, and in 4 KiB pages those faults are most of the
/// inserts' time; a huge page costs one fault per 2 MiB.
pub(super) struct Masks {
    pub(super) map: memmap2::MmapMut,
    /// Where the masks start in `map`: its first 2 MiB boundary, so that they lie in whole
    /// huge pages of the mapping.
    pub(super) start: usize,
    /// Their bytes: two per place.
    pub(super) len: usize,
}

impl Masks {
    /// A huge page.
    pub(super) const HUGE: usize = 2 << 20;

    pub(super) fn zeroed(places: usize) -> Masks {
        let len = 2 * places.max(1);
        // Room for whole huge pages after the first boundary: with only `len` there, the
        // huge page holding the masks' end could stick out of the mapping and be faulted
        // in 4 KiB pages.
        let map = memmap2::MmapMut::map_anon(len.next_multiple_of(Masks::HUGE) + Masks::HUGE)
            .unwrap_or_else(|error| panic!("no memory for the complex's masks: {error}"));
        // Only a hint: without huge pages the mapping works the same.
        #[cfg(target_os = "linux")]
        let _ = map.advise(memmap2::Advice::HugePage);
        let at = map.as_ptr() as usize;
        let start = at.next_multiple_of(Masks::HUGE) - at;
        Masks { map, start, len }
    }

    pub(super) fn bytes(&mut self) -> &mut [u8] {
        &mut self.map[self.start..self.start + self.len]
    }

    /// The masks, for threads to share: relaxed loads and stores of atomics are plain
    /// moves, and the parts of a split reduction never touch the same place (see
    /// [`DenseComplex::betti_with`](super::DenseComplex::betti_with)).
    pub(super) fn shared(&mut self) -> &[AtomicU16] {
        <[AtomicU16]>::mut_from_bytes(self.bytes()).expect("an aligned, even length")
    }

    /// The masks, for one writer.
    #[inline]
    pub(super) fn get_mut(&mut self) -> &mut [u16] {
        <[u16]>::mut_from_bytes(self.bytes()).expect("an aligned, even length")
    }
}
