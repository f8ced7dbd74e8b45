//! The phase a deformation acts on, and the bookkeeping every method shares: the region
//! it may edit, the frontier, and a bitset over the image.
//!
//! A sample's topology is carried by one phase: the objects (foreground) in embed mode,
//! the cavities (background inside the solid) in carve mode. Deformations grow, shrink and
//! move that phase and nothing else. Every edit is a simple-point flip, and simplicity is
//! a property of the flip, not of which side is called the phase: a flip that is simple
//! for the foreground keeps the Betti numbers of the image and, by duality, of its
//! complement. So one set of algorithms serves both modes; a [`Phase`] says which value
//! is "inside" and which box of voxels may change.
//!
//! The box is what keeps a carve-mode solid's outer boundary as built: it lies inside the
//! solid, at least one voxel in from every face, so a voxel of value 0 in the box is a
//! cavity voxel and a foreground voxel outside it is never touched.

use bettimill_grid::BinaryImage;

/// The phase to deform: voxels of `value` within the inclusive box `lo ..= hi`.
///
/// A phase also learns where its voxels are (its extent: a box holding them), so that the
/// frontier scans of the deformations read that part of the box, not all of it: the first
/// deformation finds it in the image, and each keeps it as it changes that image. A phase
/// belongs to one image from its first deformation on; an image changed otherwise needs a
/// new phase.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Phase {
    /// 1 for the objects of embed mode, 0 for the cavities of carve mode.
    pub value: u8,
    /// The box's lowest coordinate on each axis (only the first `d` are used).
    pub lo: [usize; 4],
    /// The box's highest coordinate on each axis, inclusive.
    pub hi: [usize; 4],
    /// `None` until a deformation looks for it.
    extent: Option<Extent>,
    /// The narrowest gap growth may leave between parts of the phase that do not touch
    /// (see [`crate::clearance`]); 0 and 1 leave growth unrestricted.
    clearance: u32,
}

/// A box that holds every voxel of value `value` within the box `lo ..= hi` grown by one
/// layer (the voxels a frontier of that box reads), or `None` when there is none. It is
/// only ever a superset: a voxel leaving the phase leaves it as it is. It speaks for the
/// value and box it was found for: a phase whose public fields are changed afterwards
/// (tests narrow the box or swap the value) looks for it again.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Extent {
    value: u8,
    lo: [usize; 4],
    hi: [usize; 4],
    found: Option<([usize; 4], [usize; 4])>,
}

impl Extent {
    /// The bounding box of the voxels of `value` in the box `lo ..= hi` grown by one
    /// layer (clipped to the image).
    fn find(image: &BinaryImage, value: u8, lo: [usize; 4], hi: [usize; 4]) -> Extent {
        let d = image.dim().get();
        let shape = image.shape();
        let mut region_lo = [0usize; 4];
        let mut region_hi = [0usize; 4];
        let mut empty = false;
        for a in 0..d {
            region_lo[a] = lo[a].saturating_sub(1);
            region_hi[a] = (hi[a] + 1).min(shape[a] - 1);
            empty |= lo[a] > hi[a];
        }
        let found = if empty {
            None
        } else {
            image.value_box(value, &region_lo, &region_hi)
        };
        Extent {
            value,
            lo,
            hi,
            found,
        }
    }
}

impl Phase {
    /// The foreground, anywhere but the image's outermost layer (embed mode; what
    /// [`crate::deform`] acts on).
    pub fn foreground(image: &BinaryImage) -> Phase {
        let d = image.dim().get();
        let mut hi = [0usize; 4];
        for (h, &n) in hi.iter_mut().zip(image.shape()).take(d) {
            *h = n.saturating_sub(2);
        }
        Phase {
            value: 1,
            lo: [1; 4],
            hi,
            extent: None,
            clearance: 0,
        }
    }

    /// The cavities of a carved solid, editable within `lo ..= hi` (which the caller keeps
    /// inside the solid, away from its outer faces).
    pub fn cavities(image: &BinaryImage, lo: &[usize], hi: &[usize]) -> Phase {
        let mut box_lo = [1usize; 4];
        let mut box_hi = [0usize; 4];
        for a in 0..image.dim().get() {
            box_lo[a] = lo[a].max(1);
            box_hi[a] = hi[a].min(image.shape()[a].saturating_sub(2));
        }
        Phase {
            value: 0,
            lo: box_lo,
            hi: box_hi,
            extent: None,
            clearance: 0,
        }
    }

    /// The extent this phase's value and box have in `image`, unless it is known: what a
    /// deformation does before its first scan. A scan of the box grown by one layer; from
    /// then on the deformations keep it.
    pub(crate) fn find_extent(&mut self, image: &BinaryImage) {
        if self.extent_known().is_none() {
            self.extent = Some(Extent::find(image, self.value, self.lo, self.hi));
        }
    }

    /// The extent, when it is known for this value and box.
    fn extent_known(&self) -> Option<&Extent> {
        self.extent
            .as_ref()
            .filter(|e| (e.value, e.lo, e.hi) == (self.value, self.lo, self.hi))
    }

    /// Records that the voxel at `coords` joined the phase (a flip into its value), so
    /// that the extent still holds every voxel of the phase.
    #[inline]
    pub(crate) fn joined(&mut self, coords: [usize; 4]) {
        let Some(extent) = self.extent.as_mut() else {
            return;
        };
        extent.found = Some(match extent.found {
            None => (coords, coords),
            Some((mut lo, mut hi)) => {
                for a in 0..4 {
                    lo[a] = lo[a].min(coords[a]);
                    hi[a] = hi[a].max(coords[a]);
                }
                (lo, hi)
            }
        });
    }

    /// The part of the box a frontier can lie in: the extent grown by one layer, within
    /// the box (`lo ..= hi` as given, before [`Layout`] keeps it off the outermost
    /// layer); `None` when the frontier is empty. The whole box when the extent is not
    /// known.
    fn frontier_box(&self, d: usize) -> Option<([usize; 4], [usize; 4])> {
        let Some(extent) = self.extent_known() else {
            return Some((self.lo, self.hi));
        };
        let (found_lo, found_hi) = extent.found?;
        let mut lo = self.lo;
        let mut hi = self.hi;
        for a in 0..d {
            lo[a] = lo[a].max(found_lo[a].saturating_sub(1));
            hi[a] = hi[a].min(found_hi[a] + 1);
        }
        Some((lo, hi))
    }

    /// The flat indices of the phase's voxels (value [`Phase::value`] inside the box), in
    /// increasing order: what a comparison of two states of one phase (an overlap, a
    /// changed-voxel count) walks.
    pub fn voxels(&self, image: &BinaryImage) -> Vec<usize> {
        let layout = Layout::new(image, self);
        let data = image.data();
        let mut out = Vec::new();
        if layout.is_empty() {
            return out;
        }
        let d = layout.d;
        let mut at = layout.lo;
        loop {
            // One row along the last axis at a time.
            let start = layout.index(&at);
            let len = layout.hi[d - 1] - layout.lo[d - 1] + 1;
            out.extend((start..start + len).filter(|&i| data[i] == self.value));
            // The next row: odometer over the first d - 1 axes.
            let mut a = d - 1;
            loop {
                if a == 0 {
                    return out;
                }
                a -= 1;
                if at[a] < layout.hi[a] {
                    at[a] += 1;
                    break;
                }
                at[a] = layout.lo[a];
            }
        }
    }

    /// The value a voxel of the other phase has.
    pub(crate) fn other(&self) -> u8 {
        1 - self.value
    }

    /// This phase, growing from now on only where it leaves gaps of at least `clearance`
    /// voxels between parts of itself that do not touch: a voxel joins only if, along
    /// each direction from a neighbour inside it through the voxel to a neighbour outside,
    /// the next `clearance - 1` voxels are outside too.
    pub fn with_clearance(mut self, clearance: u32) -> Phase {
        self.clearance = clearance;
        self
    }

    /// The narrowest gap growth may leave (0 and 1: unrestricted).
    pub fn clearance(&self) -> u32 {
        self.clearance
    }

    /// A copy of `image` with this phase dilated `steps` times: every voxel within
    /// Chebyshev distance `steps` of a phase voxel (of this value, inside the box) takes
    /// the phase's value. Dilation is not a deformation: it closes the phase's narrowest
    /// holes and gaps, and whether the copy keeps the Betti numbers tells how wide they
    /// are. The box is a cube, so the dilation runs one axis at a time.
    pub fn dilated(&self, image: &BinaryImage, steps: usize) -> BinaryImage {
        let layout = Layout::new(image, self);
        let (shape, strides) = (image.shape(), image.strides());
        let mut mask: Vec<bool> = (0..image.len())
            .map(|v| image.data()[v] == self.value && layout.in_box(v))
            .collect();
        let mut before = vec![false; mask.len()];
        for a in 0..image.dim().get() {
            let (n, stride) = (shape[a], strides[a]);
            before.copy_from_slice(&mask);
            for (v, out) in mask.iter_mut().enumerate() {
                let x = (v / stride) % n;
                let base = v - x * stride;
                let (lo, hi) = (x.saturating_sub(steps), (x + steps).min(n - 1));
                *out = (lo..=hi).any(|y| before[base + y * stride]);
            }
        }
        let mut out = image.clone();
        for (voxel, &inside) in out.data_mut().iter_mut().zip(&mask) {
            if inside {
                *voxel = self.value;
            }
        }
        out
    }
}

/// Flat-index geometry of an image and a phase's box.
#[derive(Clone, Copy)]
pub(crate) struct Layout {
    pub(crate) d: usize,
    pub(crate) strides: [usize; 4],
    pub(crate) lo: [usize; 4],
    pub(crate) hi: [usize; 4],
    /// The part of the box the frontier lies in (see [`Phase::frontier_box`]), `None`
    /// when it is empty.
    scan: Option<([usize; 4], [usize; 4])>,
}

impl Layout {
    pub(crate) fn new(image: &BinaryImage, phase: &Phase) -> Layout {
        let d = image.dim().get();
        let mut shape = [1usize; 4];
        let mut strides = [0usize; 4];
        shape[..d].copy_from_slice(image.shape());
        strides[..d].copy_from_slice(image.strides());
        let mut lo = [0usize; 4];
        let mut hi = [0usize; 4];
        for a in 0..d {
            // Never the outermost layer: the simple-point test reads all 3^d neighbours.
            lo[a] = phase.lo[a].max(1);
            hi[a] = phase.hi[a].min(shape[a].saturating_sub(2));
        }
        let scan = phase.frontier_box(d).map(|(scan_lo, scan_hi)| {
            let within_lo = std::array::from_fn(|a| if a < d { scan_lo[a].max(lo[a]) } else { 0 });
            let within_hi = std::array::from_fn(|a| if a < d { scan_hi[a].min(hi[a]) } else { 0 });
            (within_lo, within_hi)
        });
        Layout {
            d,
            strides,
            lo,
            hi,
            scan,
        }
    }

    /// Whether the box holds no voxel.
    pub(crate) fn is_empty(&self) -> bool {
        (0..self.d).any(|a| self.lo[a] > self.hi[a])
    }

    #[inline]
    pub(crate) fn coords(&self, mut index: usize) -> [usize; 4] {
        let mut out = [0usize; 4];
        for (coordinate, &stride) in out.iter_mut().zip(&self.strides[..self.d]) {
            *coordinate = index / stride;
            index %= stride;
        }
        out
    }

    #[inline]
    pub(crate) fn index(&self, coords: &[usize; 4]) -> usize {
        (0..self.d).map(|a| coords[a] * self.strides[a]).sum()
    }

    /// Whether coordinates (possibly out of the image) are in the box.
    #[inline]
    pub(crate) fn in_box_signed(&self, coords: &[i64; 4]) -> bool {
        (0..self.d).all(|a| coords[a] >= self.lo[a] as i64 && coords[a] <= self.hi[a] as i64)
    }

    #[inline]
    pub(crate) fn in_box(&self, index: usize) -> bool {
        let c = self.coords(index);
        (0..self.d).all(|a| c[a] >= self.lo[a] && c[a] <= self.hi[a])
    }

    /// Calls `f` with every face neighbour of `v` that is in the box.
    #[inline]
    #[allow(clippy::needless_range_loop)] // Four arrays indexed by the same axis.
    pub(crate) fn for_each_face_neighbour_in_box(&self, v: usize, mut f: impl FnMut(usize)) {
        let c = self.coords(v);
        for a in 0..self.d {
            let s = self.strides[a];
            if c[a] > self.lo[a] && c[a] - 1 <= self.hi[a] {
                f(v - s);
            }
            if c[a] < self.hi[a] && c[a] + 1 >= self.lo[a] {
                f(v + s);
            }
        }
    }

    /// Calls `f` with every voxel of the box, in increasing flat order, a row of the last
    /// axis at a time.
    pub(crate) fn for_each_row(&self, mut f: impl FnMut(usize, usize)) {
        if self.is_empty() {
            return;
        }
        let d = self.d;
        let mut c = self.lo;
        loop {
            let start: usize =
                (0..d - 1).map(|a| c[a] * self.strides[a]).sum::<usize>() + self.lo[d - 1];
            f(start, start + (self.hi[d - 1] - self.lo[d - 1]));
            let mut axis = d - 1;
            loop {
                if axis == 0 {
                    return;
                }
                axis -= 1;
                if c[axis] < self.hi[axis] {
                    c[axis] += 1;
                    break;
                }
                c[axis] = self.lo[axis];
            }
        }
    }

    /// The voxels of the box whose value is `flip_from` and that have a face neighbour of
    /// the other value: what growing (`flip_from` = the other phase) or shrinking
    /// (`flip_from` = the phase) would flip next. In increasing flat order.
    ///
    /// Only the part of the box next to the phase's extent is scanned: a voxel that the
    /// phase grows into has a face neighbour in the phase (in the box grown by one layer,
    /// so in the extent), and one it shrinks from is in the phase; both lie within the
    /// extent grown by one layer. The voxels found, and their order, are those of a scan of
    /// the whole box (debug builds compare the two).
    pub(crate) fn frontier(&self, image: &BinaryImage, flip_from: u8) -> Vec<usize> {
        let Some((lo, hi)) = self.scan else {
            debug_assert_eq!(
                self.frontier_of_box(image, flip_from),
                Vec::<usize>::new(),
                "the phase has no voxel near its box"
            );
            return Vec::new();
        };
        let found = Layout { lo, hi, ..*self }.frontier_of_box(image, flip_from);
        debug_assert_eq!(
            found,
            self.frontier_of_box(image, flip_from),
            "the extent holds every voxel of the phase"
        );
        found
    }

    /// [`Layout::frontier`] by a scan of the whole box.
    ///
    /// The rows along the last axis that the box's voxels can touch (the box's rows and
    /// their face neighbours) are packed first, one bit a voxel set where it holds the
    /// other value, eight voxels a multiply. A row's frontier is then a few word
    /// operations: its own bits shifted by one (the neighbours along the row) or'ed with
    /// the face-neighbouring rows' bits, kept where the voxel itself holds `flip_from`.
    fn frontier_of_box(&self, image: &BinaryImage, flip_from: u8) -> Vec<usize> {
        let mut out = Vec::new();
        if self.is_empty() {
            return out;
        }
        let d = self.d;
        let row_len = image.shape()[d - 1];
        let other = PackedRows::of(image, self, 1 - flip_from);
        let (bits, words) = (&other.bits, other.words);
        // The leading axes' steps in the packed words. An axis the image lacks steps 0,
        // which reads the row itself: its bits are where the voxels hold the other value,
        // and those are dropped below, so it adds nothing.
        let steps = other.steps;
        if words == 1 {
            // Rows of up to 64 voxels, the sides people train on: one word a row, and the
            // rows of the box visited a line of them at a time along the last leading axis.
            let span = span_mask(0, self.lo[d - 1], self.hi[d - 1]);
            let line = d - 2;
            let mut c = self.lo;
            loop {
                c[line] = self.lo[line];
                let start = other.at(&c);
                let first_voxel = (0..=line).map(|a| c[a] * self.strides[a]).sum::<usize>();
                for k in 0..=self.hi[line] - self.lo[line] {
                    let at = start + k * steps[line];
                    let own = bits[at];
                    let touching = own << 1
                        | own >> 1
                        | bits[at - steps[0]]
                        | bits[at + steps[0]]
                        | bits[at - steps[1]]
                        | bits[at + steps[1]]
                        | bits[at - steps[2]]
                        | bits[at + steps[2]];
                    let base = first_voxel + k * self.strides[line];
                    push_bits(&mut out, base, touching & !own & span);
                }
                // The next line: odometer over the axes before it.
                let mut axis = line;
                loop {
                    if axis == 0 {
                        return out;
                    }
                    axis -= 1;
                    if c[axis] < self.hi[axis] {
                        c[axis] += 1;
                        break;
                    }
                    c[axis] = self.lo[axis];
                }
            }
        }
        self.for_each_row(|first, last| {
            let row = first / row_len;
            let base = row * row_len;
            let (lo_bit, hi_bit) = (first - base, last - base);
            let at = row * words;
            for w in lo_bit / 64..=hi_bit / 64 {
                let own = bits[at + w];
                // The neighbours along the row, across word ends; the box keeps off the
                // row's ends, so every voxel of it has both.
                let before = if w > 0 { bits[at + w - 1] >> 63 } else { 0 };
                let after = if w + 1 < words {
                    bits[at + w + 1] << 63
                } else {
                    0
                };
                let mut touching = own << 1 | before | own >> 1 | after;
                for &s in &steps {
                    touching |= bits[at + w - s] | bits[at + w + s];
                }
                push_bits(
                    &mut out,
                    base + w * 64,
                    touching & !own & span_mask(w, lo_bit, hi_bit),
                );
            }
        });
        out
    }

    /// Which of the 3^d parity subfields `v` is in.
    #[inline]
    pub(crate) fn subfield(&self, v: usize) -> usize {
        let c = self.coords(v);
        (0..self.d).fold(0, |acc, a| acc * 3 + c[a] % 3)
    }
}

/// The Chebyshev ball of `radius` around a voxel, without its centre, as coordinate and
/// flat offsets in lexicographic order (a fixed order: callers that break ties by position
/// depend on it).
pub(crate) fn chebyshev_ball(image: &BinaryImage, radius: i64) -> Vec<([i64; 4], isize)> {
    let d = image.dim().get();
    let side = 2 * radius + 1;
    let strides = image.strides();
    let mut ball = Vec::new();
    for k in 0..side.pow(d as u32) {
        let mut off = [0i64; 4];
        let mut rest = k;
        for axis in (0..d).rev() {
            off[axis] = rest % side - radius;
            rest /= side;
        }
        if off.iter().all(|&o| o == 0) {
            continue;
        }
        let flat = (0..d).map(|a| off[a] as isize * strides[a] as isize).sum();
        ball.push((off, flat));
    }
    ball
}

/// The lowest bit of every byte of a u64.
const LOW_BYTES: u64 = 0x0101_0101_0101_0101;

/// The bits `w * 64 ..` of a row that lie in `lo_bit ..= hi_bit`.
#[inline]
fn span_mask(w: usize, lo_bit: usize, hi_bit: usize) -> u64 {
    let start = w * 64;
    let from = lo_bit.saturating_sub(start);
    let to = (hi_bit - start).min(63);
    (u64::MAX >> (63 - to)) & (u64::MAX << from)
}

/// Bytes that are 0 or 1 at bits 0, 8, .., 56 of a u64, gathered by one multiply onto bits
/// 56 ..= 63 (byte k onto bit 56 + k): no two product terms share a bit, so none carries.
const GATHER: u64 = 0x0102_0408_1020_4080;

/// Appends `base + i` for every set bit `i` of `found`, lowest first.
#[inline]
fn push_bits(out: &mut Vec<usize>, base: usize, mut found: u64) {
    while found != 0 {
        out.push(base + found.trailing_zeros() as usize);
        found &= found - 1;
    }
}

/// Rows along the last axis packed one bit a voxel (bit `i` of a row's words: voxel `i`
/// holds the value asked for), for the rows a box's frontier reads: the box's rows and
/// their face neighbours.
struct PackedRows {
    bits: Vec<u64>,
    words: usize,
    /// The words between one row and the next along each leading axis.
    steps: [usize; 3],
    /// The leading coordinates of the row `bits` starts at.
    origin: [usize; 4],
}

impl PackedRows {
    /// The first word of the row at leading coordinates `c`.
    #[inline]
    fn at(&self, c: &[usize; 4]) -> usize {
        (0..3)
            .map(|a| (c[a] - self.origin[a]) * self.steps[a])
            .sum()
    }

    fn of(image: &BinaryImage, layout: &Layout, value: u8) -> PackedRows {
        let data = image.data();
        let d = layout.d;
        let row_len = image.shape()[d - 1];
        let words = row_len.div_ceil(64);
        // A byte of `word ^ flip` is 1 exactly where the voxel holds `value`.
        let flip = u64::from(1 - value) * LOW_BYTES;
        let gather = |chunk: &[u8]| {
            let word = u64::from_le_bytes(chunk.try_into().expect("eight bytes"));
            ((word ^ flip) & LOW_BYTES).wrapping_mul(GATHER) >> 56
        };
        // The box grown by one layer on the leading axes (it keeps off the outermost
        // layer, so the grown box is in the image).
        let mut rows = *layout;
        for a in 0..d - 1 {
            rows.lo[a] -= 1;
            rows.hi[a] += 1;
        }
        if words == 1 {
            // Short rows: only the grown box's rows are packed, in its own C order, so the
            // work follows the box, not the image. The rows of a line along the last
            // leading axis follow each other in memory: they are packed as one run of bits
            // (long loops, eight voxels a multiply), then each row's bits cut out.
            let line = d - 2;
            let mut steps = [0usize; 3];
            let mut step = 1;
            for a in (0..d - 1).rev() {
                steps[a] = step;
                step *= rows.hi[a] - rows.lo[a] + 1;
            }
            let line_rows = rows.hi[line] - rows.lo[line] + 1;
            let mask = u64::MAX >> (64 - row_len);
            let mut bits = Vec::with_capacity(step);
            let mut run: Vec<u64> = Vec::with_capacity((line_rows * row_len).div_ceil(64) + 1);
            let mut c = rows.lo;
            loop {
                let first = (0..=line).map(|a| c[a] * layout.strides[a]).sum::<usize>();
                let voxels = &data[first..first + line_rows * row_len];
                let mut blocks = voxels.chunks_exact(64);
                run.clear();
                run.extend(blocks.by_ref().map(|block| {
                    let mut packed = 0u64;
                    for (k, chunk) in block.chunks_exact(8).enumerate() {
                        packed |= gather(chunk) << (8 * k);
                    }
                    packed
                }));
                let mut tail = 0u64;
                for (i, &v) in blocks.remainder().iter().enumerate() {
                    tail |= u64::from(v == value) << i;
                }
                run.extend([tail, 0]);
                bits.extend((0..line_rows).map(|r| {
                    let at = r * row_len;
                    let pair = u128::from(run[at / 64]) | u128::from(run[at / 64 + 1]) << 64;
                    (pair >> (at % 64)) as u64 & mask
                }));
                // The next line: odometer over the axes before it.
                let mut axis = line;
                loop {
                    if axis == 0 {
                        let mut origin = [0usize; 4];
                        origin[..d - 1].copy_from_slice(&rows.lo[..d - 1]);
                        return PackedRows {
                            bits,
                            words,
                            steps,
                            origin,
                        };
                    }
                    axis -= 1;
                    if c[axis] < rows.hi[axis] {
                        c[axis] += 1;
                        break;
                    }
                    c[axis] = rows.lo[axis];
                }
            }
        }
        let mut bits = vec![0u64; data.len() / row_len * words];
        rows.for_each_row(|first, _| {
            let row = first / row_len;
            let voxels = &data[row * row_len..(row + 1) * row_len];
            for (w, out) in bits[row * words..(row + 1) * words].iter_mut().enumerate() {
                let part = &voxels[w * 64..voxels.len().min(w * 64 + 64)];
                let mut chunks = part.chunks_exact(8);
                let mut packed = 0u64;
                let mut shift = 0;
                for chunk in chunks.by_ref() {
                    packed |= gather(chunk) << shift;
                    shift += 8;
                }
                for &v in chunks.remainder() {
                    packed |= u64::from(v == value) << shift;
                    shift += 1;
                }
                *out = packed;
            }
        });
        let mut steps = [0usize; 3];
        for (step, &stride) in steps.iter_mut().zip(&layout.strides[..d - 1]) {
            *step = stride / row_len * words;
        }
        PackedRows {
            bits,
            words,
            steps,
            origin: [0; 4],
        }
    }
}

/// A fixed-size set of flat indices: one bit a voxel.
pub(crate) struct BitSet {
    words: Vec<u64>,
}

impl BitSet {
    pub(crate) fn new(len: usize) -> BitSet {
        BitSet {
            words: vec![0; len.div_ceil(64)],
        }
    }

    /// Inserts `i`; true if it was not there.
    #[inline]
    pub(crate) fn insert(&mut self, i: usize) -> bool {
        let (w, bit) = (i / 64, 1u64 << (i % 64));
        let fresh = self.words[w] & bit == 0;
        self.words[w] |= bit;
        fresh
    }

    /// Removes `i`; true if it was there.
    #[inline]
    pub(crate) fn remove(&mut self, i: usize) -> bool {
        let (w, bit) = (i / 64, 1u64 << (i % 64));
        let was = self.words[w] & bit != 0;
        self.words[w] &= !bit;
        was
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dilated_cavity_grows_by_a_layer_and_the_outside_does_not() {
        // A 9 x 9 solid with the outer layer empty and a one-voxel cavity at its centre.
        let mut image = BinaryImage::zeros(&[9, 9]).unwrap();
        for y in 1..8 {
            for x in 1..8 {
                image.set(&[y, x], true);
            }
        }
        image.set(&[4, 4], false);
        let phase = Phase::cavities(&image, &[2, 2], &[6, 6]);
        let once = phase.dilated(&image, 1);
        let empty = |im: &BinaryImage| im.len() as u64 - im.count_foreground();
        // The outer layer (32 voxels) stays as it is; the cavity becomes 3 x 3.
        assert_eq!(empty(&once), 32 + 9);
        assert!(!once.get(&[3, 3]) && once.get(&[2, 2]) && once.get(&[1, 4]));
        assert_eq!(empty(&phase.dilated(&image, 2)), 32 + 25);
        // The objects of embed mode: the solid grows into the outer layer.
        let objects = Phase::foreground(&image).dilated(&image, 1);
        assert_eq!(objects.count_foreground(), 81);
    }

    #[test]
    fn box_rows_visit_exactly_the_box() {
        for shape in [vec![7usize, 6], vec![5, 6, 7], vec![6, 5, 7, 6]] {
            let image = BinaryImage::zeros(&shape).unwrap();
            let d = shape.len();
            let mut phase = Phase::foreground(&image);
            phase.lo[..d].fill(2);
            phase.hi[d - 1] = 3;
            let layout = Layout::new(&image, &phase);
            let mut seen = Vec::new();
            layout.for_each_row(|a, b| seen.extend(a..=b));
            let expected: Vec<usize> = (0..image.len())
                .filter(|&v| {
                    let c = image.coords(v);
                    (0..d).all(|a| c[a] >= phase.lo[a] && c[a] <= phase.hi[a])
                })
                .collect();
            assert_eq!(seen, expected, "{shape:?}");
            assert!(expected.iter().all(|&v| layout.in_box(v)));
        }
    }

    #[test]
    fn the_frontier_is_what_the_definition_names() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for shape in [
            vec![5usize, 7],
            vec![9, 21],
            vec![6, 5, 13],
            vec![7, 8, 34],
            vec![5, 6, 4, 11],
            vec![6, 5, 7, 19],
            vec![12, 11, 14],
            vec![9, 8, 10, 12],
            vec![5, 6, 70],
            vec![4, 5, 4, 131],
        ] {
            // Voxels of the phase everywhere, or only in a corner (the rest of the image
            // the other value), for a phase of either value; rows of one word and of
            // several.
            for (density, value, corner) in [
                (2u64, 1u8, false),
                (5, 1, false),
                (17, 1, false),
                (5, 0, false),
                (2, 1, true),
                (5, 0, true),
                (17, 1, true),
                (3, 0, true),
            ] {
                let mut image = BinaryImage::zeros(&shape).unwrap();
                let d = shape.len();
                for v in 0..image.len() {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    let c = image.coords(v);
                    let near = !corner || (0..d).all(|a| (1..=shape[a] / 2).contains(&c[a]));
                    image.data_mut()[v] = if near {
                        state.is_multiple_of(density) as u8
                    } else {
                        1 - value
                    };
                }
                let mut phase = Phase::foreground(&image);
                phase.value = value;
                phase.lo[d - 1] = 2;
                phase.hi[0] = shape[0] - 3;
                let layout = Layout::new(&image, &phase);
                let data = image.data();
                for flip_from in [0u8, 1] {
                    let want: Vec<usize> = (0..image.len())
                        .filter(|&v| {
                            layout.in_box(v)
                                && data[v] == flip_from
                                && (0..d).any(|a| {
                                    let s = image.strides()[a];
                                    data[v - s] != flip_from || data[v + s] != flip_from
                                })
                        })
                        .collect();
                    assert_eq!(
                        layout.frontier(&image, flip_from),
                        want,
                        "{shape:?} 1/{density} value {value} corner {corner} from {flip_from}"
                    );
                    // The same box with its extent found: only the part near the phase is
                    // scanned, and the frontier is the same.
                    let mut found = phase;
                    found.find_extent(&image);
                    assert_eq!(
                        Layout::new(&image, &found).frontier(&image, flip_from),
                        want,
                        "{shape:?} 1/{density} value {value} corner {corner} from {flip_from}"
                    );
                }
            }
        }
    }

    #[test]
    fn face_neighbours_in_the_box_are_those_the_definition_names() {
        let image = BinaryImage::zeros(&[6, 7, 5, 6]).unwrap();
        let mut phase = Phase::foreground(&image);
        phase.lo[1] = 2;
        phase.hi[3] = 3;
        let layout = Layout::new(&image, &phase);
        for v in 0..image.len() {
            if !layout.in_box(v) {
                continue;
            }
            let mut got = Vec::new();
            layout.for_each_face_neighbour_in_box(v, |u| got.push(u));
            got.sort_unstable();
            let c = image.coords(v);
            let mut want = Vec::new();
            for a in 0..4 {
                for delta in [-1i64, 1] {
                    let mut n = [0i64; 4];
                    for k in 0..4 {
                        n[k] = c[k] as i64;
                    }
                    n[a] += delta;
                    if layout.in_box_signed(&n) {
                        want.push(layout.index(&n.map(|x| x as usize)));
                    }
                }
            }
            want.sort_unstable();
            assert_eq!(got, want, "voxel {v}");
        }
    }
}
