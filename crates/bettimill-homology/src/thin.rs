//! Homotopy-preserving thinning by sequential simple-point deletion.
//!
//! Deleting a simple voxel changes no topology, so deleting them one at a time until none is
//! left shrinks the foreground to a thin remnant with the same Betti numbers; a contractible
//! blob ends as a single voxel. The remnant's cubical complex is then small enough for
//! explicit homology.
//!
//! Simple points are not jointly deletable, so deletion is sequential: one raster sweep
//! in index order, each voxel tested against the image as it is at that moment (the
//! sweep splits into two slabs too far apart to interact, swept on two threads towards
//! each other, then the seam between them; see [`thin`]). Raster order is deterministic
//! and needs no queue, and because the voxels before x are already gone when x is
//! visited, the sweep deletes nearly all of a blob. Then only the survivors whose
//! neighbourhood changed since their last test are tested again, from a stack of pending
//! voxels, until none is pending. The sweep slides the 3^d block along the last axis,
//! reading one new column per voxel instead of the whole block, and reads the columns
//! sixteen at a time. The 4D test has no table, so its answers are memoised in a small
//! direct-mapped cache, [`SimpleCache`] (a pure function memoised: it cannot change a
//! result).

use crate::simple::{SimpleCache, SimpleTester};
use bettimill_grid::neighbourhood::flat_offsets;
use bettimill_grid::BinaryImage;

/// One raster sweep over the voxels `range` of the slab `data` (C order, laid out with the
/// full image's strides), deleting simple ones; pushes the foreground survivors, shifted by
/// `global_offset`, to `survivors`.
fn sweep(
    thinner: &Thinner,
    data: &mut [u8],
    range: std::ops::Range<usize>,
    global_offset: usize,
    survivors: &mut Vec<u32>,
    cache: &mut SimpleCache,
) {
    // One copy per dimension's column bits, so that the blocks' 128-bit shifts are by
    // constants (by a variable they cost several instructions each).
    let args = (thinner, data, range, global_offset, survivors, cache);
    match thinner.window.column_bits {
        27 => sweep_with::<27>(args),
        9 => sweep_with::<9>(args),
        _ => sweep_with::<3>(args),
    }
}

/// [`sweep`] with `R` bits a column.
#[inline(always)]
fn sweep_with<const R: u32>(
    (thinner, data, range, global_offset, survivors, cache): (
        &Thinner,
        &mut [u8],
        std::ops::Range<usize>,
        usize,
        &mut Vec<u32>,
        &mut SimpleCache,
    ),
) {
    let (tester, phase, window) = (thinner.tester, thinner.phase, &thinner.window);
    debug_assert_eq!(window.column_bits, R);
    // `block` is the 3^d block of voxel `previous`, kept current: between two voxels the
    // only write is the deletion of the voxel itself, whose centre bit is cleared.
    let mut block = 0u128;
    let mut previous = usize::MAX;
    let mut columns = Columns::default();
    let neighbours = window.all_bits & !window.centre_bit;
    // The block of a voxel whose earlier neighbours (in raster order) are all gone and
    // later ones all present: its attachment set is a closed half of the voxel's boundary,
    // a ball, so it is simple. Many of a blob's voxels look like this in the first sweep,
    // so they skip the memo.
    let half = window.half;
    // (Indices fit in 32 bits: `thin` checks.)
    let offset = global_offset as u32;
    let mut next = range.start;
    while next < range.end {
        let i = next;
        next += 1;
        // Skips the other phase, and locked voxels (bit 2), which are never flipped: eight
        // at a time past the first (half of a blob's voxels are background, in runs).
        if data[i] & 5 != 1 {
            while let Some(bytes) = data.get(next..next + 8).filter(|_| next + 8 <= range.end) {
                let word = u64::from_le_bytes(bytes.try_into().expect("eight bytes"));
                // Bit 0 of byte k: byte k is of the phase (bit 0) and unlocked (bit 2).
                if word & !(word >> 2) & 0x0101_0101_0101_0101 != 0 {
                    break;
                }
                next += 8;
            }
            continue;
        }
        block = if previous.wrapping_add(1) == i {
            block >> R | window.column(data, i + 1, &mut columns) << (2 * R)
        } else {
            window.block_of::<R>(data, i, &mut columns)
        };
        previous = i;
        // A foreground voxel whose block is `half` (above) is simple: it is deleted
        // without the memo or the test.
        if phase == Phase::Foreground && block == half {
            data[i] = 0;
            block &= !window.centre_bit;
            continue;
        }
        let (exposed, key) = match phase {
            Phase::Foreground => (
                block & window.face_bits != window.face_bits,
                tester.column_key(block),
            ),
            // Adding a background voxel to the object needs an object voxel among its
            // neighbours; the object's configuration is the complement.
            Phase::Background => (
                block & neighbours != neighbours,
                tester.column_key(!block & neighbours),
            ),
        };
        if exposed && cache.is_simple_by_column_key(tester, key) {
            data[i] = 0;
            block &= !window.centre_bit;
        } else {
            survivors.push(offset + i as u32);
        }
    }
}

/// The 3^d block of a voxel in column order: three columns of R = 3^(d-1) bits, one per
/// position along the last axis (bit R c + r, rows r in lexicographic order of the other
/// axes, c = 0, 1, 2 for offsets -1, 0, +1), read whole or slid by one voxel along the last
/// axis (one new column of R voxels instead of the whole block, shifted in whole).
///
/// Columns are read sixteen at a time ([`Window::load`]). That is exact because while a
/// sweep crosses one line of the image, no other line changes: the lines around it are
/// either swept already or not yet reached. In the line itself only voxels already visited
/// change, and a column is only read at a voxel whose predecessor was not visited (the
/// block of a visited one is kept current instead). So a column read ahead is the column
/// it would have been read fresh, as long as it stays within its line.
struct Window {
    /// Flat offset of each row's middle voxel.
    rows: Vec<isize>,
    /// R, the bits of a column.
    column_bits: u32,
    /// The number of voxels of a line along the last axis.
    line: usize,
    /// The bits of the 2d face neighbours.
    face_bits: u128,
    centre_bit: u128,
    /// Every bit of the 3^d block.
    all_bits: u128,
    /// The centre and the neighbours after it in raster order.
    half: u128,
}

/// Columns read ahead for flat indices `base..end` (at most sixteen): `bits[j]` is the
/// column at `base + j` (bit r = row r).
#[derive(Default)]
struct Columns {
    base: usize,
    end: usize,
    bits: [u32; 16],
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
        let bit = |c: usize, r: usize| 1u128 << (n_rows * c + r);
        let centre_bit = bit(1, middle_row);
        let mut face_bits = bit(0, middle_row) | bit(2, middle_row);
        // Along axis a < d - 1 the rows one step away are 3^(d-2-a) rows apart.
        for axis in 0..d - 1 {
            let apart = 3usize.pow((d - 2 - axis) as u32);
            face_bits |= bit(1, middle_row - apart) | bit(1, middle_row + apart);
        }
        let all_bits = (1u128 << (3 * n_rows)) - 1;
        // Bit R c + r has raster index 3 r + c; the centre's is 3^d / 2.
        let centre = 3 * n_rows / 2;
        let half = (0..3 * n_rows)
            .filter(|&b| 3 * (b % n_rows) + b / n_rows >= centre)
            .fold(0u128, |m, b| m | 1 << b);
        Window {
            rows,
            column_bits: n_rows as u32,
            line: strides[d - 2],
            face_bits,
            centre_bit,
            all_bits,
            half,
        }
    }

    /// Reads the columns at flat indices p..p + 16, cut at the end of p's line, into
    /// `columns`: each row contributes sixteen bytes (byte j = voxel p + j), transposed
    /// into sixteen columns of a bit per row ([`pack_rows`]), so that a column is one load
    /// where it was R byte extractions each time it was read.
    #[inline(never)]
    fn load(&self, data: &[u8], p: usize, columns: &mut Columns) {
        let first = (p as isize + self.rows[0]) as usize;
        let last = (p as isize + self.rows[self.rows.len() - 1]) as usize;
        columns.bits = match data.get(first..last + 16) {
            // Unrolled for each dimension's row count.
            Some(span) => {
                let offset = p as isize - first as isize;
                match self.rows.len() {
                    3 => pack_rows::<3>(&self.rows, span, offset),
                    9 => pack_rows::<9>(&self.rows, span, offset),
                    _ => pack_rows::<27>(&self.rows, span, offset),
                }
            }
            None => {
                let mut bits = [0u32; 16];
                for (r, &o) in self.rows.iter().enumerate() {
                    let q = (p as isize + o) as usize;
                    let (low, high) = (word_at_end(data, q), word_at_end(data, q + 8));
                    let bytes = (low as u128 | (high as u128) << 64) & ONES;
                    for (j, column) in bits.iter_mut().enumerate() {
                        *column |= ((bytes >> (8 * j)) as u32 & 1) << r;
                    }
                }
                bits
            }
        };
        columns.base = p;
        columns.end = (p + 16).min((p / self.line + 1) * self.line);
    }

    /// The column at flat index `at` (bit r = row r), read ahead into `columns` when it is
    /// not there.
    #[inline(always)]
    fn column(&self, data: &[u8], at: usize, columns: &mut Columns) -> u128 {
        if at.wrapping_sub(columns.base) >= columns.end - columns.base {
            self.load(data, at, columns);
        }
        // Bit r is row r; the bits past the last row are zero.
        columns.bits[(at - columns.base) & 15] as u128
    }

    /// The block of voxel i read afresh (its three columns).
    #[inline]
    fn block(&self, data: &[u8], i: usize, columns: &mut Columns) -> u128 {
        match self.column_bits {
            27 => self.block_of::<27>(data, i, columns),
            9 => self.block_of::<9>(data, i, columns),
            _ => self.block_of::<3>(data, i, columns),
        }
    }

    /// [`Window::block`] with `R` bits a column: its shifts are constants (a 128-bit shift
    /// by a variable costs several instructions).
    #[inline(always)]
    fn block_of<const R: u32>(&self, data: &[u8], i: usize, columns: &mut Columns) -> u128 {
        debug_assert_eq!(self.column_bits, R);
        self.column(data, i - 1, columns)
            | self.column(data, i, columns) << R
            | self.column(data, i + 1, columns) << (2 * R)
    }
}

/// Bit 0 of the sixteen bytes at `offset + rows[r]` of `span`, for each of the R rows,
/// as sixteen columns: bit r of `columns[j]` is row r's byte j. The rows of each group of
/// eight are gathered into sixteen bytes whose byte j holds their bits of column j (last
/// row first: twice the bytes so far plus the next row's bit 0); then the four groups'
/// bytes j are column j's four bytes.
///
/// On x86-64 in SSE2 vectors, part of the baseline target (through `safe_arch`, without
/// unsafe code): three instructions a row and eight unpacks. The portable code below is
/// the fallback elsewhere; the compiler neither unrolls its rows nor keeps a group in one
/// register.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn pack_rows<const R: usize>(rows: &[isize], span: &[u8], offset: isize) -> [u32; 16] {
    use safe_arch::{
        add_i8_m128i, bitand_m128i, load_unaligned_m128i, set_splat_i8_m128i,
        unpack_high_i16_m128i, unpack_high_i8_m128i, unpack_low_i16_m128i, unpack_low_i8_m128i,
        zeroed_m128i,
    };
    let rows: &[isize; R] = rows.try_into().expect("R rows");
    // Every row lies within `span` (it runs from the first row to the last one's end); the
    // bound tells the compiler so, which spares a pair of checks per row.
    let Some(last) = span.len().checked_sub(16) else {
        return [0; 16];
    };
    // One group at a time, eight rows each: a loop short enough for the compiler to
    // unroll, keeping the group in a register (over all R rows it did neither).
    let group = |g: usize| {
        let ones = set_splat_i8_m128i(1);
        let mut bits = zeroed_m128i();
        for r in (8 * g..(8 * g + 8).min(R)).rev() {
            let q = (offset + rows[r]) as usize;
            debug_assert!(q <= last, "row {r} past the span");
            let q = q.min(last);
            let bytes = load_unaligned_m128i(span[q..q + 16].try_into().expect("16 bytes"));
            bits = add_i8_m128i(add_i8_m128i(bits, bits), bitand_m128i(bytes, ones));
        }
        bits
    };
    let groups = [group(0), group(1), group(2), group(3)];
    let [g0, g1, g2, g3] = groups;
    let (low01, high01) = (unpack_low_i8_m128i(g0, g1), unpack_high_i8_m128i(g0, g1));
    let (low23, high23) = (unpack_low_i8_m128i(g2, g3), unpack_high_i8_m128i(g2, g3));
    let quarters: [[u32; 4]; 4] = [
        unpack_low_i16_m128i(low01, low23).into(),
        unpack_high_i16_m128i(low01, low23).into(),
        unpack_low_i16_m128i(high01, high23).into(),
        unpack_high_i16_m128i(high01, high23).into(),
    ];
    std::array::from_fn(|j| quarters[j / 4][j % 4])
}

/// [`pack_rows`] without vectors, for other targets (and tested against the vectors).
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn pack_rows<const R: usize>(rows: &[isize], span: &[u8], offset: isize) -> [u32; 16] {
    pack_rows_portable::<R>(rows, span, offset)
}

/// [`pack_rows`] in plain Rust.
#[cfg(any(test, not(target_arch = "x86_64")))]
#[inline(always)]
fn pack_rows_portable<const R: usize>(rows: &[isize], span: &[u8], offset: isize) -> [u32; 16] {
    let rows: &[isize; R] = rows.try_into().expect("R rows");
    let Some(last) = span.len().checked_sub(16) else {
        return [0; 16];
    };
    let mut groups = [[0u8; 16]; 4];
    for r in (0..R).rev() {
        let q = (offset + rows[r]) as usize;
        debug_assert!(q <= last, "row {r} past the span");
        let q = q.min(last);
        let bytes: &[u8; 16] = span[q..q + 16].try_into().expect("16 bytes");
        for (lane, &byte) in groups[r / 8].iter_mut().zip(bytes) {
            *lane = lane.wrapping_add(*lane).wrapping_add(byte & 1);
        }
    }
    let [g0, g1, g2, g3] = groups;
    std::array::from_fn(|j| u32::from_le_bytes([g0[j], g1[j], g2[j], g3[j]]))
}

/// Bit 0 of each of sixteen bytes.
const ONES: u128 = 0x0101_0101_0101_0101_0101_0101_0101_0101;

/// The eight bytes from flat index `q` as a little-endian word, zero past the end of the
/// data (the last line of a slab: those columns lie beyond the line and are never used).
#[cold]
fn word_at_end(data: &[u8], q: usize) -> u64 {
    (0..8).fold(0, |word, j| {
        word | (data.get(q + j).copied().unwrap_or(0) as u64) << (8 * j)
    })
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
/// The work runs on two threads without depending on their timing: the image is cut across
/// its first axis into slabs A (planes 0..=k) and B (planes from k + 2 on) with the seam
/// plane k + 1 between them, which both read and neither writes during the sweeps (A's
/// last plane reads it from a copy, as B's data holds it). So neither reads what the
/// other writes, and sweeping A and B at once is exactly sweeping A and then B. The seam
/// is swept after both.
///
/// A sweeps forwards and B backwards, towards the seam. A raster sweep leaves more
/// survivors the further it goes (what cannot go, the loops and shells, is pushed ahead of
/// it), and they pile up against whatever it meets last: the image's last plane, or a
/// seam whose far side was swept already. Meeting at the seam, the two piles are one, so
/// the remnant the reduction gets is smaller than with both sweeps forwards.
///
/// The pending voxels after the sweep are cut the same way, but with a seam of two planes
/// (a flip marks its neighbours pending: A's reach plane k at most, B's plane k + 1) at
/// the plane of the middle survivor (what is left to test is not spread like the
/// foreground), and tested in rounds: A's and B's at once, then the seam's, each part
/// handing the voxels it makes pending in another part to that part for the next round.
/// Every flip is a simple-point flip of the image as it is at that moment, so the topology
/// is kept, and the survivors are the same on every run.
pub(crate) fn thin(image: &mut BinaryImage, tester: &SimpleTester, phase: Phase) -> Vec<u32> {
    debug_assert!(match phase {
        Phase::Foreground => image.border_is_background(),
        Phase::Background => border_is_locked(image),
    });
    // Indices are 32-bit: a 4D image's are (its grid is checked first, `dense::check_grid`).
    assert!(
        image.len() <= u32::MAX as usize + 1,
        "at most 2^32 voxels to thin"
    );
    let thinner = Thinner::new(image, tester, phase);
    let planes = image.shape()[0];
    let plane = thinner.strides[0];
    let len = image.len();
    // 2^12 slots (64 KiB) stay in the core's own cache; a larger memo hits more often but
    // its misses in the shared cache cost more than the hits save.
    let (mut cache_a, mut cache_b) = (SimpleCache::new(12), SimpleCache::new(12));
    let (survivors, split) = sweep_slabs(&thinner, image, [&mut cache_a, &mut cache_b]);
    // After the sweep: a voxel can only have become simple if a neighbour was flipped
    // since its last test. Every survivor is pending once; each flip makes its unflipped
    // neighbours of the same phase pending again (bit 1 of their byte, which
    // configurations and the exposure check ignore, marks a pending voxel), and pending
    // voxels are tested last in, first out, so a flip's neighbours are tested next, while
    // they are in the caches. Each part (A, B, the seam) tests only its own voxels and
    // hands the others' to them; a round tests A and B at once, then the seam, and the
    // rounds end when nothing is pending. Skipping a voxel never flips anything, so it
    // cannot affect correctness, and at the end every survivor was last tested after its
    // neighbours' last flip: no survivor is simple, as with full sweeps. (Passes over all
    // survivors would need one pass per voxel of a curve eaten from its tip.)
    // The survivors in index order. The pending rounds cut the image again, at the plane
    // of the middle survivor: what is left to test is not spread like the foreground (it
    // piles up where the sweeps meet, and grows along each sweep), so a cut by planes
    // left one thread testing twice as long as the other.
    // (Four bytes a survivor, each list at its size: on a random image most of the
    // foreground survives the sweep, and the survivors and the pending lists are the
    // peak of the thinning.)
    let split = split.map(|_| {
        let middle = survivors
            .get(survivors.len() / 2)
            .map_or(0, |&i| i as usize / plane);
        middle.clamp(1, planes - 3)
    });
    let data = image.data_mut();
    for &i in &survivors {
        data[i as usize] |= 2;
    }
    // The survivors are in index order: each part's are a run of them, pending last to
    // first.
    let ends = match split {
        Some(k) => [k * plane, (k + 2) * plane]
            .map(|end| survivors.partition_point(|&i| (i as usize) < end)),
        None => [survivors.len(); 2],
    };
    let runs = [0..ends[0], ends[0]..ends[1], ends[1]..survivors.len()];
    let mut pending: [Vec<u32>; 3] = runs.map(|run| survivors[run].iter().rev().copied().collect());
    match split {
        Some(k) => {
            let (seam_start, seam_end) = (k * plane, (k + 2) * plane);
            let [pending_a, pending_seam, pending_b] = &mut pending;
            loop {
                let (slab_a, slab_b) = image.data_mut().split_at_mut((k + 1) * plane);
                let (mut to_seam, from_b) = rayon::join(
                    || {
                        let mut out = Vec::new();
                        thinner.drain(slab_a, 0, pending_a, 0..seam_start, &mut out, &mut cache_a);
                        out
                    },
                    || {
                        let mut out = Vec::new();
                        let offset = (k + 1) * plane;
                        let own = seam_end..len;
                        thinner.drain(slab_b, offset, pending_b, own, &mut out, &mut cache_b);
                        out
                    },
                );
                to_seam.extend(from_b);
                // Pending from before (a flip of its own) or handed over now.
                pending_seam.extend(to_seam.into_iter().rev());
                let mut out = Vec::new();
                let own = seam_start..seam_end;
                thinner.drain(
                    image.data_mut(),
                    0,
                    pending_seam,
                    own,
                    &mut out,
                    &mut cache_a,
                );
                if out.is_empty() {
                    break;
                }
                for &i in out.iter().rev() {
                    if (i as usize) < seam_start {
                        pending_a.push(i);
                    } else {
                        pending_b.push(i);
                    }
                }
            }
        }
        None => {
            let mut out = Vec::new();
            thinner.drain(data, 0, &mut pending[0], 0..len, &mut out, &mut cache_a);
            debug_assert!(out.is_empty());
        }
    }
    let data = image.data();
    let mut remaining = survivors;
    remaining.retain(|&i| data[i as usize] & 1 != 0);
    remaining.shrink_to_fit();
    // Nothing is pending: every flag was cleared when its voxel was tested.
    debug_assert!(data.iter().all(|&v| v & 2 == 0));
    remaining
}

/// The sweep of [`thin`]: slabs A and B at once (B backwards), then the seam plane between
/// them, or one sweep of the whole image if it has fewer than eight planes. Returns the
/// survivors in increasing order, and the plane k that ends slab A if the image was cut.
fn sweep_slabs(
    thinner: &Thinner,
    image: &mut BinaryImage,
    [cache_a, cache_b]: [&mut SimpleCache; 2],
) -> (Vec<u32>, Option<usize>) {
    let planes = image.shape()[0];
    let plane = thinner.strides[0];
    let len = image.len();
    let (mut part_a, mut seam, mut part_b) = (Vec::new(), Vec::new(), Vec::new());
    // Slab A is planes 0..=k of the data, slab B the rest. A sweeps planes 0..=k and B
    // planes k + 2.., as many each, or A one more. B sweeps from its end: see [`thin`].
    let split = (planes >= 8).then_some((planes - 2) / 2);
    match split {
        Some(k) => {
            // Plane k + 1 as it is before the sweeps: A's last plane reads it from this
            // copy (B's data holds it; neither writes it).
            let next = image.data()[(k + 1) * plane..(k + 2) * plane].to_vec();
            let (slab_a, slab_b) = image.data_mut().split_at_mut((k + 1) * plane);
            rayon::join(
                || {
                    let range = 0..k * plane;
                    sweep(thinner, slab_a, range, 0, &mut part_a, cache_a);
                    // Plane k, between plane k - 1 and the copy of plane k + 1.
                    let ends = &mut slab_a[(k - 1) * plane..];
                    let mut tail = [&*ends, &next].concat();
                    let (range, offset) = (plane..2 * plane, (k - 1) * plane);
                    sweep(thinner, &mut tail, range, offset, &mut part_a, cache_a);
                    ends[plane..].copy_from_slice(&tail[plane..2 * plane]);
                },
                || {
                    // Backwards: point-reflected (its bytes reversed, which reverses every
                    // axis and keeps the shape), swept forwards, reflected back.
                    slab_b.reverse();
                    let n = slab_b.len();
                    sweep(thinner, slab_b, 0..n - plane, 0, &mut part_b, cache_b);
                    slab_b.reverse();
                    let last = ((k + 1) * plane + n - 1) as u32;
                    part_b.reverse();
                    for i in &mut part_b {
                        *i = last - *i;
                    }
                },
            );
            let range = (k + 1) * plane..(k + 2) * plane;
            let data = image.data_mut();
            sweep(thinner, data, range, 0, &mut seam, cache_a);
        }
        None => {
            let data = image.data_mut();
            sweep(thinner, data, 0..len, 0, &mut part_a, cache_a);
        }
    }
    // Slab A's list grows in place to take the others': no second copy of it.
    let mut survivors = part_a;
    survivors.reserve_exact(seam.len() + part_b.len());
    survivors.extend_from_slice(&seam);
    survivors.extend_from_slice(&part_b);
    (survivors, split)
}

/// What the sweeps and passes of [`thin`] need besides the data.
struct Thinner<'a> {
    tester: &'a SimpleTester,
    strides: Vec<usize>,
    /// The sliding 3^d block the sweeps read.
    window: Window,
    /// Flat offsets of all neighbours, and of those that decide exposure.
    steps: Vec<isize>,
    exposure_steps: Vec<isize>,
    phase: Phase,
}

impl<'a> Thinner<'a> {
    fn new(image: &BinaryImage, tester: &'a SimpleTester, phase: Phase) -> Thinner<'a> {
        let steps = flat_offsets(image, tester.offsets());
        // The neighbours whose membership decides whether a flip can be simple at all: the
        // face neighbours (a foreground voxel with none in the background is never
        // simple), or every neighbour (a background voxel needs an object voxel next to
        // it).
        let exposure_steps: Vec<isize> = match phase {
            Phase::Foreground => steps
                .iter()
                .zip(tester.offsets())
                .filter(|(_, off)| off.iter().map(|o| o.abs()).sum::<i8>() == 1)
                .map(|(&s, _)| s)
                .collect(),
            Phase::Background => steps.clone(),
        };
        Thinner {
            tester,
            strides: image.strides().to_vec(),
            window: Window::new(image.strides()),
            steps,
            exposure_steps,
            phase,
        }
    }

    /// Tests the pending voxels of `stack` (global indices; `data` holds the image from
    /// global index `offset` on), last in first out, until none is left, flipping the
    /// simple ones. A flip makes its unflipped neighbours of the same phase pending: those
    /// in `own` go on `stack`, the others (another part's) on `out`.
    fn drain(
        &self,
        data: &mut [u8],
        offset: usize,
        stack: &mut Vec<u32>,
        own: std::ops::Range<usize>,
        out: &mut Vec<u32>,
        cache: &mut SimpleCache,
    ) {
        let neighbours = self.window.all_bits & !self.window.centre_bit;
        while let Some(global) = stack.pop() {
            let i = global as usize - offset;
            data[i] &= !2;
            let exposed = self
                .exposure_steps
                .iter()
                .any(|&s| data[(i as isize + s) as usize] & 1 == 0);
            if !exposed {
                continue;
            }
            // Read as the sweep reads a block afresh (the columns read ahead go unused).
            let mut block = self.window.block(data, i, &mut Columns::default());
            if self.phase == Phase::Background {
                block = !block & neighbours;
            }
            if cache.is_simple_by_column_key(self.tester, self.tester.column_key(block)) {
                data[i] = 0;
                for &s in &self.steps {
                    let j = (i as isize + s) as usize;
                    // Of the phase, not locked, not pending yet.
                    if data[j] & 7 == 1 {
                        data[j] |= 2;
                        let g = j + offset;
                        if own.contains(&g) {
                            stack.push(g as u32);
                        } else {
                            out.push(g as u32);
                        }
                    }
                }
            }
        }
    }
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

    /// Both column transpositions give bit r of column j = bit 0 of row r's byte j, on
    /// bytes with the flag bits set too, for each dimension's row count.
    #[test]
    fn rows_pack_into_columns() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(18);
        fn check<const R: usize>(rng: &mut rand_chacha::ChaCha8Rng) {
            // Rows 37 bytes apart, read from byte 5 of each.
            let rows: Vec<isize> = (0..R as isize).map(|r| 37 * r).collect();
            let span: Vec<u8> = (0..37 * R + 16 + 5).map(|_| rng.gen_range(0..8)).collect();
            let expected: [u32; 16] = std::array::from_fn(|j| {
                (0..R).fold(0, |column, r| {
                    column | ((span[5 + 37 * r + j] & 1) as u32) << r
                })
            });
            assert_eq!(pack_rows::<R>(&rows, &span, 5), expected, "{R} rows");
            assert_eq!(
                pack_rows_portable::<R>(&rows, &span, 5),
                expected,
                "{R} rows"
            );
        }
        for _ in 0..50 {
            check::<3>(&mut rng);
            check::<9>(&mut rng);
            check::<27>(&mut rng);
        }
    }

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

    /// An image of `shape` whose voxels inside its border are foreground with probability
    /// `density`.
    fn random_inside(
        shape: &[usize],
        density: f64,
        rng: &mut rand_chacha::ChaCha8Rng,
    ) -> BinaryImage {
        use rand::Rng;
        let mut image = BinaryImage::zeros(shape).unwrap();
        for index in 0..image.len() {
            if is_interior(&image, index, 1) {
                image.data_mut()[index] = rng.gen_bool(density) as u8;
            }
        }
        image
    }

    /// The image's complement with its border locked (value 5), as the background phase
    /// wants it.
    fn complement_locked(image: &mut BinaryImage) {
        for index in 0..image.len() {
            let inner = is_interior(image, index, 1);
            let v = &mut image.data_mut()[index];
            *v = if inner { 1 - *v } else { 5 };
        }
    }

    /// Whether voxel `i` of `image` (of the phase, its configuration read afresh) may be
    /// flipped: simple for the object, which in the background phase is the complement and
    /// needs a voxel next to it.
    fn flips(tester: &SimpleTester, phase: Phase, image: &BinaryImage, i: usize) -> bool {
        let config = tester.configuration_unchecked(image, i);
        match phase {
            Phase::Foreground => tester.is_simple_configuration(config),
            Phase::Background => {
                let object = !config & ((1u128 << tester.offsets().len()) - 1);
                object != 0 && tester.is_simple_configuration(object)
            }
        }
    }

    /// Thinning ends with no simple survivor, whether the image splits into slabs or not
    /// and in both phases: every survivor was tested after its neighbours' last flip.
    #[test]
    fn no_survivor_is_simple() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(33);
        for dim in Dim::ALL {
            let d = dim.get();
            let tester = SimpleTester::new(dim);
            for trial in 0..12 {
                // First sides below and above the split's eight planes.
                let side = [14, 9, 7][d - 2];
                let mut shape = vec![side; d];
                shape[0] = [6, 12, 17][trial % 3];
                let density: f64 = rng.gen_range(0.3..0.9);
                let mut image = random_inside(&shape, density, &mut rng);
                let phase = if trial % 2 == 0 {
                    Phase::Foreground
                } else {
                    complement_locked(&mut image);
                    Phase::Background
                };
                let survivors = thin(&mut image, &tester, phase);
                assert!(image.data().iter().all(|&v| v & 2 == 0));
                let listed: Vec<u32> = (0..image.len() as u32)
                    .filter(|&i| image.data()[i as usize] == 1)
                    .collect();
                assert_eq!(survivors, listed, "{d}D trial {trial}");
                for i in survivors.iter().map(|&i| i as usize) {
                    assert!(
                        !flips(&tester, phase, &image, i),
                        "{d}D trial {trial}: voxel {i} is simple"
                    );
                }
            }
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
            assert_eq!(
                tester.face_key(tester.column_key(window.half)),
                tester.memo_key(later),
                "{dim:?}"
            );
        }
    }

    /// The cut sweep deletes exactly what one thread deletes reading every configuration
    /// afresh in the order [`thin`] documents: slab A forwards (planes 0..=k), slab B
    /// backwards (from the last plane to k + 2), then the seam plane k + 1; in both phases,
    /// for first sides at and above the cut's eight planes, odd and even.
    #[test]
    fn the_cut_sweep_is_the_documented_order_read_afresh() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for dim in Dim::ALL {
            let d = dim.get();
            let tester = SimpleTester::new(dim);
            for trial in 0..12 {
                let side = [12, 8, 6][d - 2];
                let mut shape: Vec<usize> = (0..d).map(|a| side + a % 2).collect();
                shape[0] = [8, 9, 12, 17][trial % 4];
                let density: f64 = rng.gen_range(0.3..0.9);
                let mut image = random_inside(&shape, density, &mut rng);
                let phase = if trial % 3 == 2 {
                    complement_locked(&mut image);
                    Phase::Background
                } else {
                    Phase::Foreground
                };
                let mut fresh = image.clone();
                let plane = image.strides()[0];
                let k = (shape[0] - 2) / 2;
                let order = (0..(k + 1) * plane)
                    .chain(((k + 2) * plane..image.len()).rev())
                    .chain((k + 1) * plane..(k + 2) * plane);
                for i in order {
                    if fresh.data()[i] & 5 != 1 {
                        continue;
                    }
                    if flips(&tester, phase, &fresh, i) {
                        fresh.data_mut()[i] = 0;
                    }
                }
                let thinner = Thinner::new(&image, &tester, phase);
                let (mut a, mut b) = (SimpleCache::new(12), SimpleCache::new(12));
                let (survivors, split) = sweep_slabs(&thinner, &mut image, [&mut a, &mut b]);
                assert_eq!(split, Some(k));
                assert_eq!(image.data(), fresh.data(), "{d}D trial {trial}");
                let expected: Vec<u32> = (0..image.len() as u32)
                    .filter(|&i| fresh.data()[i as usize] & 5 == 1)
                    .collect();
                assert_eq!(survivors, expected, "{d}D trial {trial}");
            }
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
                // Lines shorter and longer than the sixteen columns read at a time.
                let side = [9, 7, 6][d - 2];
                let mut shape: Vec<usize> = (0..d).map(|a| side + a % 2).collect();
                shape[d - 1] = [7, 10, 19, 26][trial % 4];
                let density: f64 = rng.gen_range(0.2..0.95);
                let mut image = random_inside(&shape, density, &mut rng);
                let mut fresh = image.clone();
                for i in 0..fresh.len() {
                    if fresh.data()[i] == 1
                        && tester.is_simple_configuration(tester.configuration_unchecked(&fresh, i))
                    {
                        fresh.data_mut()[i] = 0;
                    }
                }
                let len = image.len();
                let mut survivors = Vec::new();
                let thinner = Thinner::new(&image, &tester, Phase::Foreground);
                let mut cache = SimpleCache::new(12);
                sweep(
                    &thinner,
                    image.data_mut(),
                    0..len,
                    0,
                    &mut survivors,
                    &mut cache,
                );
                assert_eq!(image.data(), fresh.data(), "{d}D trial {trial}");
                let expected: Vec<u32> = (0..len as u32)
                    .filter(|&i| fresh.data()[i as usize] == 1)
                    .collect();
                assert_eq!(survivors, expected);
            }
        }
    }
}
