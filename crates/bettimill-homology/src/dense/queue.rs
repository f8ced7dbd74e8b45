//! The reduction's first-in, first-out queue of cells.

use std::collections::VecDeque;

/// Cells in first-in, first-out order, in blocks recycled as they empty: the queue's
/// memory follows its length. A cell pushed with [`CellQueue::push`] takes 5 bytes (a
/// 32-bit place and a code); a run of cells pushed with [`CellQueue::push_scanned`] in
/// increasing order of place, as a scan of the owners finds the free faces, takes one byte
/// a cell (the step from the one before and the code), five where the step is 15 or more.
/// On a random 4D image the free faces are about one cell per voxel, the largest part of
/// the pairs' peak at five bytes a cell. Past
/// [`CellQueue::NEAR_FROM`] full blocks, the cells of `push` (the candidates a removal
/// makes) are kept as runs too, their steps either way in 0 to 4 bytes ([`Kind::Near`]):
/// the steps from one candidate to the next are spread (a quarter under 8 places, a
/// quarter under 128, a quarter under 32,768), about 2.7 bytes a cell against 5. A
/// `VecDeque<u64>` would take 16 bytes per cell (8 bytes, doubled capacity, and every page
/// touched as the ring turns).
pub(super) struct CellQueue {
    /// Full blocks, oldest first.
    pub(super) full: VecDeque<Block>,
    /// The block being filled.
    pub(super) tail: Block,
    /// The next cell to pop (a byte offset in a run): in the front full block, or in
    /// `tail` when there is none.
    pub(super) head: usize,
    /// In a run at the front: the place of the cell popped last (0 at its start).
    pub(super) read_place: u32,
    /// In a run at the tail: the place of the cell pushed last (0 at its start).
    pub(super) write_place: u32,
    /// The cells a plain tail holds, 0 for a run (so that [`CellQueue::push`] tests one
    /// length for both a full tail and a run).
    pub(super) plain_room: usize,
    /// An emptied block, kept for the next one needed.
    pub(super) spare: Option<Block>,
}

/// A block of [`CellQueue`], in an anonymous mapping of its own, so that an emptied block
/// goes back to the system (small heap blocks stay with the allocator after the pairs, and
/// the lists of the cells left would be allocated beside them, raising the peak by an
/// amount that varies from run to run).
/// Plain: `len` cells, their places (four bytes each) from the start, their codes (a byte
/// each) after [`CellQueue::BLOCK`] places. A run: `len` bytes of steps and codes
/// ([`Block::push_run`] for a scan's, [`Block::push_near`] for candidates).
pub(super) struct Block {
    pub(super) map: memmap2::MmapMut,
    pub(super) len: usize,
    pub(super) kind: Kind,
}

/// How a [`Block`] holds its cells.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Kind {
    /// Four bytes of place and one of code a cell.
    Plain,
    /// A run of a scan ([`Block::push_run`]).
    Scan,
    /// A run of candidates ([`Block::push_near`]).
    Near,
}

impl Block {
    /// Bytes a block holds.
    pub(super) const BYTES: usize = 5 * CellQueue::BLOCK;
    /// The step that stands for a step of four bytes after it.
    pub(super) const FAR: u8 = 15;

    pub(super) fn new() -> Block {
        let map = memmap2::MmapMut::map_anon(Block::BYTES)
            .unwrap_or_else(|error| panic!("no memory for the reduction's queue: {error}"));
        Block {
            map,
            len: 0,
            kind: Kind::Plain,
        }
    }

    #[inline(always)]
    pub(super) fn push(&mut self, place: u32, code: u8) {
        let at = self.len;
        self.map[4 * at..4 * at + 4].copy_from_slice(&place.to_ne_bytes());
        self.map[4 * CellQueue::BLOCK + at] = code;
        self.len += 1;
    }

    #[inline(always)]
    pub(super) fn get(&self, at: usize) -> (u32, u8) {
        let place = self.map[4 * at..4 * at + 4]
            .try_into()
            .map(u32::from_ne_bytes)
            .expect("four bytes");
        (place, self.map[4 * CellQueue::BLOCK + at])
    }

    /// Appends to a run a cell `step` places after the one before (wrapping), with code
    /// `code` (below 16): one byte, the step times 16 plus the code, when the step is
    /// below [`Block::FAR`]; else [`Block::FAR`] times 16 plus the code, then the step's
    /// four bytes. The caller leaves room for five bytes.
    #[inline]
    pub(super) fn push_run(&mut self, step: u32, code: u8) {
        let at = self.len;
        if step < Block::FAR as u32 {
            self.map[at] = (step as u8) << 4 | code;
            self.len += 1;
        } else {
            self.map[at] = Block::FAR << 4 | code;
            self.map[at + 1..at + 5].copy_from_slice(&step.to_ne_bytes());
            self.len += 5;
        }
    }

    /// Appends to a run of candidates a cell `step` places after the one before (wrapping,
    /// as a signed step), with code `code` (below 32): a byte of the code and of how many
    /// bytes the step takes, zigzag-coded (0 to 4, least significant first), then those
    /// bytes. The caller leaves room for five bytes.
    #[inline]
    pub(super) fn push_near(&mut self, step: u32, code: u8) {
        let at = self.len;
        let step = step as i32;
        let zigzag = (step << 1 ^ step >> 31) as u32;
        let bytes = (32 - zigzag.leading_zeros()).div_ceil(8) as usize;
        self.map[at] = code | (bytes as u8) << 5;
        self.map[at + 1..at + 5].copy_from_slice(&zigzag.to_le_bytes());
        self.len += 1 + bytes;
    }

    /// The step, the code and the bytes of the candidates' cell at byte `at`.
    #[inline(always)]
    pub(super) fn get_near(&self, at: usize) -> (u32, u8, usize) {
        let byte = self.map[at];
        let bytes = (byte >> 5) as usize;
        let word = self.map[at + 1..at + 5]
            .try_into()
            .map(u32::from_le_bytes)
            .expect("four bytes");
        let zigzag = (word as u64 & ((1u64 << (8 * bytes)) - 1)) as u32;
        let step = (zigzag >> 1) as i32 ^ -((zigzag & 1) as i32);
        (step as u32, byte & 31, 1 + bytes)
    }

    /// The step, the code and the bytes of the run's cell at byte `at`.
    #[inline(always)]
    pub(super) fn get_run(&self, at: usize) -> (u32, u8, usize) {
        let byte = self.map[at];
        let code = byte & 15;
        if byte >> 4 != Block::FAR {
            return ((byte >> 4) as u32, code, 1);
        }
        let step = self.map[at + 1..at + 5]
            .try_into()
            .map(u32::from_ne_bytes)
            .expect("four bytes");
        (step, code, 5)
    }
}

impl Default for CellQueue {
    fn default() -> CellQueue {
        CellQueue {
            full: VecDeque::new(),
            tail: Block::new(),
            head: 0,
            read_place: 0,
            write_place: 0,
            plain_room: CellQueue::BLOCK,
            spare: None,
        }
    }
}

impl CellQueue {
    pub(super) const BLOCK: usize = 1 << 16;

    /// Full blocks from which a queue keeps its candidates as runs ([`Kind::Near`]),
    /// until it runs empty: a smooth image's queue never holds that many.
    pub(super) const NEAR_FROM: usize = 8;

    #[inline]
    pub(super) fn push(&mut self, owner: usize, code: u32) {
        if self.tail.len < self.plain_room {
            self.tail.push(owner as u32, code as u8);
        } else {
            self.push_other(owner, code);
        }
    }

    /// [`CellQueue::push`] when the tail is full or not plain.
    #[cold]
    #[inline(never)]
    pub(super) fn push_other(&mut self, owner: usize, code: u32) {
        let place = owner as u32;
        if self.tail.kind == Kind::Near && self.tail.len + 5 <= Block::BYTES {
            self.tail
                .push_near(place.wrapping_sub(self.write_place), code as u8);
            self.write_place = place;
            return;
        }
        let kind = if self.tail.kind == Kind::Near || self.full.len() >= Self::NEAR_FROM {
            Kind::Near
        } else {
            Kind::Plain
        };
        self.start_block(kind);
        self.push(owner, code);
    }

    /// [`CellQueue::push`] for cells found in increasing order of place (any order is
    /// right, that one is compact): `code` is below 16 (not [`COREDUCIBLE`](super::reduce::COREDUCIBLE)).
    #[inline]
    pub(super) fn push_scanned(&mut self, owner: usize, code: u32) {
        debug_assert!(code < 16);
        if self.tail.kind != Kind::Scan || self.tail.len + 5 > Block::BYTES {
            self.start_block(Kind::Scan);
        }
        let place = owner as u32;
        self.tail
            .push_run(place.wrapping_sub(self.write_place), code as u8);
        self.write_place = place;
    }

    /// Pushes the cells of `other`, in its order.
    pub(super) fn append(&mut self, mut other: CellQueue) {
        while let Some((owner, code)) = other.pop() {
            self.push(owner, code);
        }
    }

    /// Files the tail block, unless it is empty, and starts another of kind `kind`.
    #[cold]
    pub(super) fn start_block(&mut self, kind: Kind) {
        if self.tail.len > 0 {
            let block = self.spare.take().unwrap_or_else(Block::new);
            let full = std::mem::replace(&mut self.tail, block);
            self.full.push_back(full);
        }
        self.tail.kind = kind;
        self.plain_room = match kind {
            Kind::Plain => Self::BLOCK,
            Kind::Scan | Kind::Near => 0,
        };
        self.write_place = 0;
    }

    /// [`CellQueue::pop`] from a run of candidates at the front (not empty there). Out of
    /// line, as is [`CellQueue::push_other`]: a smooth image's queue never holds such a
    /// run, and both in the reduction's loop would make it larger for every image.
    #[inline(never)]
    pub(super) fn pop_near(&mut self) -> (usize, u32) {
        let block = self.full.front().unwrap_or(&self.tail);
        let (step, code, bytes) = block.get_near(self.head);
        self.head += bytes;
        self.read_place = self.read_place.wrapping_add(step);
        (self.read_place as usize, code as u32)
    }

    // Always inlined: the reduction's loop is large enough that the compiler would not
    // inline it, and a call per cell costs more than the code it saves.
    #[inline(always)]
    pub(super) fn pop(&mut self) -> Option<(usize, u32)> {
        loop {
            let block = self.full.front().unwrap_or(&self.tail);
            if self.head < block.len {
                let (step, code, bytes) = match block.kind {
                    Kind::Plain => {
                        let (place, code) = block.get(self.head);
                        self.head += 1;
                        return Some((place as usize, code as u32));
                    }
                    Kind::Scan => block.get_run(self.head),
                    Kind::Near => return Some(self.pop_near()),
                };
                self.head += bytes;
                self.read_place = self.read_place.wrapping_add(step);
                return Some((self.read_place as usize, code as u32));
            }
            self.head = 0;
            self.read_place = 0;
            match self.full.pop_front() {
                // A used-up full block is kept for reuse; the tail comes next.
                Some(mut block) => {
                    block.len = 0;
                    self.spare = Some(block);
                }
                // The tail is used up too: the queue is empty, and the tail fills again
                // from its start.
                None => {
                    self.tail.len = 0;
                    self.write_place = 0;
                    if self.tail.kind == Kind::Near {
                        self.start_block(Kind::Plain);
                    }
                    return None;
                }
            }
        }
    }
}
