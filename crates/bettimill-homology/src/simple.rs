//! The simple-point test: can one voxel be flipped without changing the topology?
//!
//! Both deformations of the paper (hypervolume-preserving moves and topology-preserving
//! dilation) are sequences of simple-point flips, so this test is on the hot path of the
//! generator and has to be exact in 2D, 3D and 4D.
//!
//! The 3^d - 1 neighbours of a voxel x correspond one-to-one to the proper faces of the
//! boundary of x's closed cube: offset delta is the face that fixes coordinate i at +-1/2
//! wherever delta_i != 0. The attachment set A(x) is the part of that boundary covered by
//! the other foreground voxels, i.e. the union of the closures of the faces of the
//! foreground neighbours. x is simple iff A(x) is collapsible, which (see
//! `docs/topology.md`) is decided exactly by three cheap conditions:
//!
//! - T = 1: the foreground neighbours form one (3^d-1)-connected component;
//! - Tbar = 1: the background face-neighbours form one component, two of them (s*e_i and
//!   t*e_j) being joined when the voxel s*e_i + t*e_j is background too;
//! - chi(A) = 1.
//!
//! In 2D and 3D the first two suffice; the Euler test is what makes 4D exact. Faces are
//! stored in the same bit layout as configurations (bit k = the face of neighbour k in
//! [`full_offsets`] order), so A(x) and its Euler characteristic are a few word operations.
//!
//! Answers come from a 256-entry table in 2D, a 2^26-bit (8 MiB) table in 3D shared by the
//! process and filled 64 configurations at a time as they are first asked for (a build or a
//! loader worker meets a small part of the 2^26, so it pays for that part only), and direct
//! evaluation in 4D where a table (2^80 entries) is impossible. [`SimpleCache`] memoises the answers for loops that
//! ask many times (thinning here, the editing loops of `bettimill-deform`): the one memo of
//! the workspace, so every caller keys and hashes it the same way (the thinning's keys,
//! read from its block in column order, are marked apart: `SimpleTester::column_key`).

use bettimill_grid::neighbourhood::{full_offsets, is_interior};
use bettimill_grid::{BinaryImage, Dim};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};

/// A direct-mapped memo of the simple-point test, keyed by what simplicity depends on (in
/// 4D the attachment set, at most 80 face bits; in 2D and 3D the configuration), with bit
/// 126 of a slot marking it used and bit 127 holding the answer.
///
/// It memoises a pure function of the configuration, so it changes no answer, only its
/// cost: in 4D, where the test is evaluated rather than looked up, a hit saves the three
/// conditions. A colliding key overwrites the slot.
#[derive(Clone, Debug)]
pub struct SimpleCache {
    entries: Vec<u128>,
    shift: u32,
}

impl SimpleCache {
    const COLUMN: u128 = 1 << 125;
    const USED: u128 = 1 << 126;
    const ANSWER: u128 = 1 << 127;

    /// An empty memo of `2^bits` slots of 16 bytes (`bits` between 1 and 32).
    pub fn new(bits: u32) -> SimpleCache {
        assert!(
            (1..=32).contains(&bits),
            "a simple-point memo has 2^1 to 2^32 slots, not 2^{bits}"
        );
        SimpleCache {
            entries: vec![0; 1 << bits],
            shift: 64 - bits,
        }
    }

    #[inline]
    fn slot(&self, key: u128) -> usize {
        (mix(key) >> self.shift) as usize
    }

    /// Whether a voxel with configuration `config` (as [`SimpleTester::configuration`]) is
    /// simple for `tester`, memoised on what the answer depends on.
    #[inline]
    pub fn is_simple(&mut self, tester: &SimpleTester, config: u128) -> bool {
        let key = tester.memo_key(config);
        self.memoised(key, || tester.is_simple_key(key))
    }

    /// [`SimpleCache::is_simple`] of a voxel whose block in column order has the key
    /// `column_key` ([`SimpleTester::column_key`]). Such keys are marked by bit 125, so
    /// that they never meet the other keys in a memo that holds both.
    #[inline]
    pub(crate) fn is_simple_by_column_key(
        &mut self,
        tester: &SimpleTester,
        column_key: u128,
    ) -> bool {
        // The miss is out of line: the hit is a few instructions inside the sweep.
        #[cold]
        #[inline(never)]
        fn evaluate(tester: &SimpleTester, column_key: u128) -> bool {
            tester.is_simple_key(tester.face_key(column_key))
        }
        self.memoised(column_key | Self::COLUMN, || evaluate(tester, column_key))
    }

    #[inline(always)]
    fn memoised(&mut self, key: u128, answer: impl FnOnce() -> bool) -> bool {
        let slot = self.slot(key);
        let entry = self.entries[slot];
        if entry & !Self::ANSWER == key | Self::USED {
            return entry & Self::ANSWER != 0;
        }
        let answer = answer();
        self.entries[slot] = key | Self::USED | if answer { Self::ANSWER } else { 0 };
        answer
    }
}

/// A 128-bit key mixed into 64 bits whose high bits pick a memo's slot: the high half
/// folded into the low one, then a Fibonacci multiply.
#[inline]
pub(crate) fn mix(key: u128) -> u64 {
    let folded = (key as u64) ^ ((key >> 64) as u64).wrapping_mul(0xD6E8_FEB8_6659_FD93);
    folded.wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

/// Precomputed tables for one dimension; cloning shares them.
#[derive(Clone, Debug)]
pub struct SimpleTester {
    tables: Arc<Tables>,
}

/// Everything the three-condition test needs, laid out in configuration bit order.
#[derive(Debug)]
struct Tables {
    dim: Dim,
    n_neighbours: usize,
    /// The bits of the neighbours: 2^n_neighbours - 1.
    neighbour_bits: u128,
    /// Bit index of the centre in the 3^d lexicographic block (the bit dropped from it).
    centre: usize,
    offsets: Vec<[i8; 4]>,
    /// `closure[k]`: the faces (as neighbour bits) in the closure of neighbour k's face.
    closure: Vec<u128>,
    /// `closure_low/high[j][b]`: the union of the closures of the neighbours whose
    /// bits are set in byte value b at bits 8j..8j+8 (its bits 0-63 and 64-79), so A(x)
    /// is one lookup per byte. Split so that the 4D tables take 25 KiB and stay in the
    /// first-level cache, where one 128-bit table took 40 KiB and did not.
    closure_low: Vec<[u64; 256]>,
    closure_high: Vec<[u16; 256]>,
    /// `face_low/high[j][b]`: the neighbour bits (configuration order) of the faces whose
    /// bits are set in byte value b at bits 8j..8j+8 of a set of faces in column order,
    /// its centre bit dropped ([`SimpleTester::face_key`]).
    face_low: Vec<[u64; 256]>,
    face_high: Vec<[u16; 256]>,
    /// Per axis, the bits of a block in column order whose offset along it is 0.
    zero_columns: [u128; 4],
    /// `adjacency[k]`: the other neighbours within one step of neighbour k in every axis.
    adjacency: Vec<u128>,
    /// `cofaces[k]`: faces of one dimension more whose closure contains face k.
    cofaces: Vec<u128>,
    even_faces: u128,
    odd_faces: u128,
    // The neighbours below are held as one-bit masks, tested with an AND: a test by a
    // shift of the 128-bit configuration costs more instructions.
    /// The neighbour bit of each face-neighbour (slot s = 2 * axis + (sign > 0)).
    face_neighbours: Vec<u128>,
    /// (slot a, slot b, the neighbour bit of the voxel that joins them).
    face_links: Vec<(u8, u8, u128)>,
    /// The neighbour bit of each vertex face (offsets with no zero), in vertex-slot order.
    vertex_faces: Vec<u128>,
    /// (the neighbour bit of an edge face, its two endpoint vertex slots).
    edge_faces: Vec<(u128, u8, u8)>,
    /// The 2D answers, bit c of the 256-bit table (4 words).
    table_2d: Option<[u64; 4]>,
}

/// The union of the entries of per-byte tables (`low` for bits 0-63 of the result, `high`
/// for bits 64-79) picked by the bytes of `bits`: one lookup per byte, read from its two
/// 64-bit halves (a loop shifting the 128-bit value costs more instructions).
#[inline]
fn by_bytes(low: &[[u64; 256]], high: &[[u16; 256]], bits: u128) -> u128 {
    let (mut result_low, mut result_high) = (0u64, 0u16);
    let words = [bits as u64, (bits >> 64) as u64];
    for (j, (table_low, table_high)) in low.iter().zip(high).enumerate() {
        let byte = (words[j >> 3] >> (8 * (j & 7))) as u8 as usize;
        result_low |= table_low[byte];
        result_high |= table_high[byte];
    }
    (result_high as u128) << 64 | result_low as u128
}

/// The 3D table is 8 MiB and identical for every tester, so one copy serves the process.
static TABLE_3D: OnceLock<LazyTable> = OnceLock::new();

/// The 3D table's 2^26 answers, one bit each, in words of 64 configurations that are
/// evaluated when one of them is first asked for. `filled` has one bit per word. A word
/// is a pure function of its index, so threads that fill the same word at once store the
/// same bits; a reader that sees a word's `filled` bit (acquire) sees its bits (the writer
/// sets the flag with release after storing them).
struct LazyTable {
    words: Vec<AtomicU64>,
    filled: Vec<AtomicU64>,
}

impl LazyTable {
    const WORDS: usize = (1 << 26) / 64;

    fn new() -> LazyTable {
        LazyTable {
            words: (0..Self::WORDS).map(|_| AtomicU64::new(0)).collect(),
            filled: (0..Self::WORDS / 64).map(|_| AtomicU64::new(0)).collect(),
        }
    }

    #[inline]
    fn get(&self, tables: &Tables, config: u128) -> bool {
        let word = (config >> 6) as usize;
        let (slot, flag) = (word >> 6, 1u64 << (word & 63));
        let bits = if self.filled[slot].load(Ordering::Acquire) & flag != 0 {
            self.words[word].load(Ordering::Relaxed)
        } else {
            let mut bits = 0u64;
            for low in 0..64u128 {
                if tables.evaluate(((word as u128) << 6) | low) {
                    bits |= 1 << low;
                }
            }
            self.words[word].store(bits, Ordering::Relaxed);
            self.filled[slot].fetch_or(flag, Ordering::Release);
            bits
        };
        bits >> (config & 63) & 1 == 1
    }
}

impl Tables {
    fn build(dim: Dim) -> Tables {
        let d = dim.get();
        let offsets = full_offsets(dim);
        let n = offsets.len();
        let centre = n / 2;
        let mut closure = vec![0u128; n];
        let mut adjacency = vec![0u128; n];
        let mut cofaces = vec![0u128; n];
        let face_dim = |k: usize| offsets[k][..d].iter().filter(|&&o| o == 0).count();
        for k in 0..n {
            for j in 0..n {
                let (a, b) = (&offsets[k][..d], &offsets[j][..d]);
                // Face j lies in the closure of face k iff it fixes every coordinate k fixes.
                if (0..d).all(|i| a[i] == 0 || a[i] == b[i]) {
                    closure[k] |= 1 << j;
                    if face_dim(j) + 1 == face_dim(k) {
                        cofaces[j] |= 1 << k;
                    }
                }
                if j != k && (0..d).all(|i| (a[i] - b[i]).abs() <= 1) {
                    adjacency[k] |= 1 << j;
                }
            }
        }
        let (mut even_faces, mut odd_faces) = (0u128, 0u128);
        for k in 0..n {
            if face_dim(k) % 2 == 0 {
                even_faces |= 1 << k;
            } else {
                odd_faces |= 1 << k;
            }
        }
        let index_of = |off: [i8; 4]| {
            offsets
                .iter()
                .position(|o| *o == off)
                .expect("every non-zero offset in {-1,0,1}^d is a neighbour")
        };
        let mut face_neighbours = Vec::with_capacity(2 * d);
        for axis in 0..d {
            for sign in [-1i8, 1] {
                let mut off = [0i8; 4];
                off[axis] = sign;
                face_neighbours.push(1u128 << index_of(off));
            }
        }
        let mut face_links = Vec::new();
        for a in 0..2 * d {
            for b in a + 1..2 * d {
                let (axis_a, axis_b) = (a / 2, b / 2);
                if axis_a == axis_b {
                    continue;
                }
                let mut off = [0i8; 4];
                off[axis_a] = if a % 2 == 0 { -1 } else { 1 };
                off[axis_b] = if b % 2 == 0 { -1 } else { 1 };
                face_links.push((a as u8, b as u8, 1u128 << index_of(off)));
            }
        }
        let vertex_faces: Vec<u128> = (0..n)
            .filter(|&k| offsets[k][..d].iter().all(|&o| o != 0))
            .map(|k| 1u128 << k)
            .collect();
        let mut edge_faces = Vec::new();
        for k in 0..n {
            if offsets[k][..d].iter().filter(|&&o| o == 0).count() != 1 {
                continue;
            }
            let ends: Vec<u8> = vertex_faces
                .iter()
                .enumerate()
                .filter(|&(_, &v)| closure[k] & v != 0)
                .map(|(slot, _)| slot as u8)
                .collect();
            assert_eq!(ends.len(), 2, "an edge of a cube has two endpoints");
            edge_faces.push((1u128 << k, ends[0], ends[1]));
        }
        assert!(n <= 80, "face masks have at most 80 bits");
        let closure_bytes: Vec<u128> = (0..n.div_ceil(8) * 256)
            .map(|entry| {
                let (j, byte) = (entry / 256, entry % 256);
                (0..8)
                    .filter(|&b| byte >> b & 1 == 1 && 8 * j + b < n)
                    .fold(0u128, |faces, b| faces | closure[8 * j + b])
            })
            .collect();
        // Bit b of a configuration in column order is bit b of the block in column order
        // below the centre, b + 1 above it; block bit R c + r is position c along the last
        // axis of row r (R rows), the neighbour at raster index 3 r + c.
        let rows = n.div_ceil(3);
        let raster_of = |block_bit: usize| 3 * (block_bit % rows) + block_bit / rows;
        let face_bytes: Vec<u128> = (0..n.div_ceil(8) * 256)
            .map(|entry| {
                let (j, byte) = (entry / 256, entry % 256);
                (0..8)
                    .filter(|&b| byte >> b & 1 == 1 && 8 * j + b < n)
                    .fold(0u128, |faces, b| {
                        let bit = 8 * j + b;
                        let raster = raster_of(if bit < centre { bit } else { bit + 1 });
                        faces | 1 << if raster < centre { raster } else { raster - 1 }
                    })
            })
            .collect();
        // The offset along axis a of the neighbour at raster index i is digit d - 1 - a
        // of i in base 3, minus one.
        let zero_columns = std::array::from_fn(|axis| {
            (0..3 * rows)
                .filter(|&bit| {
                    axis < d && raster_of(bit) / 3usize.pow((d - 1 - axis) as u32) % 3 == 1
                })
                .fold(0u128, |mask, bit| mask | 1 << bit)
        });
        let low_words = |bytes: &[u128]| -> Vec<[u64; 256]> {
            bytes
                .chunks_exact(256)
                .map(|byte| std::array::from_fn(|b| byte[b] as u64))
                .collect()
        };
        let high_words = |bytes: &[u128]| -> Vec<[u16; 256]> {
            bytes
                .chunks_exact(256)
                .map(|byte| std::array::from_fn(|b| (byte[b] >> 64) as u16))
                .collect()
        };
        let mut tables = Tables {
            dim,
            n_neighbours: n,
            neighbour_bits: (1u128 << n) - 1,
            centre,
            offsets,
            closure,
            closure_low: low_words(&closure_bytes),
            closure_high: high_words(&closure_bytes),
            face_low: low_words(&face_bytes),
            face_high: high_words(&face_bytes),
            zero_columns,
            adjacency,
            cofaces,
            even_faces,
            odd_faces,
            face_neighbours,
            face_links,
            vertex_faces,
            edge_faces,
            table_2d: None,
        };
        if dim == Dim::Two {
            let mut table = [0u64; 4];
            for config in 0..256u128 {
                if tables.evaluate(config) {
                    table[(config >> 6) as usize] |= 1 << (config & 63);
                }
            }
            tables.table_2d = Some(table);
        }
        tables
    }

    /// The attachment set A(x) as a face mask: byte-wise lookups of the closures.
    #[inline]
    fn attachment(&self, config: u128) -> u128 {
        by_bytes(&self.closure_low, &self.closure_high, config)
    }

    /// [`Tables::attachment`] by the definition, one closure per foreground neighbour (the
    /// slow oracle uses it, so it does not depend on the byte tables).
    fn attachment_by_neighbours(&self, config: u128) -> u128 {
        let mut faces = 0u128;
        let mut rest = config;
        while rest != 0 {
            let k = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            faces |= self.closure[k];
        }
        faces
    }

    #[inline]
    fn background_faces_connected(&self, config: u128) -> bool {
        let mut background = 0u8;
        for (slot, &bit) in self.face_neighbours.iter().enumerate() {
            if config & bit == 0 {
                background |= 1 << slot;
            }
        }
        if background == 0 {
            return false;
        }
        let mut links = [0u8; 8];
        for &(a, b, joint) in &self.face_links {
            if config & joint == 0 {
                links[a as usize] |= 1 << b;
                links[b as usize] |= 1 << a;
            }
        }
        let mut component = background & background.wrapping_neg();
        loop {
            let mut grown = component;
            let mut rest = component;
            while rest != 0 {
                let slot = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                grown |= links[slot] & background;
            }
            if grown == component {
                return component == background;
            }
            component = grown;
        }
    }

    #[inline]
    fn foreground_connected(&self, config: u128) -> bool {
        if config == 0 {
            return false;
        }
        let mut component = config & config.wrapping_neg();
        let mut frontier = component;
        while frontier != 0 {
            let mut grown = 0u128;
            let mut rest = frontier;
            while rest != 0 {
                let k = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                grown |= self.adjacency[k];
            }
            frontier = grown & config & !component;
            component |= frontier;
        }
        component == config
    }

    /// T = 1 read off the attachment set instead of the neighbours: two neighbours are
    /// adjacent exactly when their faces of x's cube meet, so the neighbour components are
    /// the components of A(x), and A(x) is connected iff its vertices are connected by its
    /// edges. That is a 2^d-vertex graph (16 in 4D) instead of an 80-vertex one.
    #[inline]
    fn attachment_connected(&self, faces: u128) -> bool {
        let mut vertices = 0u16;
        for (slot, &bit) in self.vertex_faces.iter().enumerate() {
            vertices |= ((faces & bit != 0) as u16) << slot;
        }
        if vertices == 0 {
            return false;
        }
        let mut links = [0u16; 16];
        for &(bit, a, b) in &self.edge_faces {
            if faces & bit != 0 {
                links[a as usize] |= 1 << b;
                links[b as usize] |= 1 << a;
            }
        }
        let mut component = vertices & vertices.wrapping_neg();
        let mut frontier = component;
        while frontier != 0 {
            let mut grown = 0u16;
            let mut rest = frontier;
            while rest != 0 {
                grown |= links[rest.trailing_zeros() as usize];
                rest &= rest - 1;
            }
            frontier = grown & !component;
            component |= frontier;
        }
        component == vertices
    }

    /// The three-condition test, cheapest condition first. In 2D and 3D (where it only
    /// fills the tables) T is counted on the neighbours themselves; in 4D, where every call
    /// counts, on the attachment set that the Euler test needs anyway.
    /// The 4D test from the attachment set alone (see `SimpleTester::is_simple_key`).
    #[inline]
    fn evaluate_attachment(&self, faces: u128) -> bool {
        // The Euler characteristic first: two counts, and it is what rejects most often
        // (far more often than the background condition).
        let chi = (faces & self.even_faces).count_ones() as i32
            - (faces & self.odd_faces).count_ones() as i32;
        chi == 1 && self.background_faces_connected(faces) && self.attachment_connected(faces)
    }

    #[inline]
    fn evaluate(&self, config: u128) -> bool {
        if self.dim == Dim::Four {
            return self.evaluate_attachment(self.attachment(config));
        }
        self.background_faces_connected(config) && self.foreground_connected(config)
    }

    /// The slow oracle: greedily collapse A(x) through free faces and report whether one
    /// vertex remains.
    fn collapses_to_a_point(&self, config: u128) -> bool {
        let mut faces = self.attachment_by_neighbours(config);
        'collapse: loop {
            let mut rest = faces;
            while rest != 0 {
                let k = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                let cofaces = self.cofaces[k] & faces;
                // By the diamond property the unique coface of a free face is maximal, so
                // removing the pair keeps A a closed complex.
                if cofaces.count_ones() == 1 {
                    faces &= !(1u128 << k) & !cofaces;
                    continue 'collapse;
                }
            }
            break;
        }
        faces.count_ones() == 1
    }
}

fn table_3d() -> &'static LazyTable {
    TABLE_3D.get_or_init(LazyTable::new)
}

/// [`SimpleTester::configuration_in`] of a 4D voxel whose block, read as 27 unaligned
/// 4-byte rows, lies in `data` (`None` for a voxel so near the end of `data` that the last
/// row's fourth byte is past it). One range check for the whole block, one load and one
/// multiply a row, and the rows' three bits packed with constant shifts into 64-bit halves
/// (shifting a u128 by a running amount costs several instructions a row).
#[inline]
fn configuration_4d(data: &[u8], strides: &[usize], index: usize) -> Option<u128> {
    // Strides that fit in 32 bits (any image the crate can hold in memory) keep every
    // row's offset far from overflowing, so each row needs one range comparison.
    let stride = |a: usize| u32::try_from(strides[a]).ok().map(|s| s as usize);
    let [s0, s1, s2] = [stride(0)?, stride(1)?, stride(2)?];
    let start = index.checked_sub(s0 + s1 + s2 + 1)?;
    let block = data.get(start..start + 2 * (s0 + s1 + s2) + 4)?;
    // With bytes a, b, c (each 0 or 1) at bits 0, 8 and 16, multiplying by
    // 2^14 + 2^7 + 1 lands them on bits 14, 15 and 16 with no other product term touching
    // those bits.
    let row = |p: usize| -> u64 {
        let word = u32::from_le_bytes(block[p..p + 4].try_into().expect("four bytes"));
        u64::from((word & 0x0001_0101).wrapping_mul(0x4081) >> 14 & 7)
    };
    // Nine bits per plane of three rows (a, b).
    let plane = |base: usize| row(base) | row(base + s2) << 3 | row(base + 2 * s2) << 6;
    let mut planes = [0u64; 9];
    for a in 0..3 {
        for b in 0..3 {
            planes[3 * a + b] = plane(a * s0 + b * s1);
        }
    }
    let block = pack_planes(&planes);
    // Without the centre, bit 40 (3^4 / 2), as a constant.
    Some((block & ((1u128 << 40) - 1)) | ((block >> 41) << 40))
}

impl SimpleTester {
    /// The tables for `dim`: built on the process's first call for that dimension (a pure
    /// function of the dimension), shared by the later ones (every sample a build verifies
    /// or deforms asks for them again). The 3D bitset fills as it is asked.
    pub fn new(dim: Dim) -> SimpleTester {
        static TESTERS: [OnceLock<SimpleTester>; 3] = [const { OnceLock::new() }; 3];
        TESTERS[dim.get() - 2]
            .get_or_init(|| SimpleTester {
                tables: Arc::new(Tables::build(dim)),
            })
            .clone()
    }

    /// The dimension this tester answers for.
    pub fn dim(&self) -> Dim {
        self.tables.dim
    }

    /// Bitmask of the 3^d-1 neighbours of voxel `index` (bit k = neighbour k in
    /// [`full_offsets`] order) that are foreground.
    ///
    /// Panics if `index` is not at least one voxel away from every face of the image, or if
    /// the image's dimension differs from the tester's: both are caller bugs, because every
    /// editing loop keeps a padding layer that is never touched.
    pub fn configuration(&self, image: &BinaryImage, index: usize) -> u128 {
        let tables = &*self.tables;
        assert_eq!(
            image.dim(),
            tables.dim,
            "a {}D simple-point tester was given a {}D image",
            tables.dim,
            image.dim()
        );
        assert!(
            index < image.len() && is_interior(image, index, 1),
            "voxel {index} of an image of shape {:?} is on or outside the border; the \
             simple-point test needs all 3^d-1 neighbours inside the image",
            image.shape()
        );
        self.configuration_unchecked(image, index)
    }

    /// [`SimpleTester::configuration`] without the border check (a caller that keeps a
    /// padding layer knows it holds); a voxel on the border reads wrong neighbours or
    /// panics on an out-of-range index.
    #[inline]
    pub(crate) fn configuration_unchecked(&self, image: &BinaryImage, index: usize) -> u128 {
        self.configuration_in(image.data(), image.strides(), index)
    }

    /// What the simple-point test of a voxel depends on, read from its whole 3^d block in
    /// column order (bit R c + r is row r of the R = 3^(d-1) rows along the last axis, in
    /// lexicographic order, at position c = 0, 1, 2 for offsets -1, 0, +1), which the
    /// thinning sweep slides one column at a time. In 4D it is the attachment set A(x)
    /// laid out like the block: a face is in A(x) when it is the face of a foreground
    /// neighbour with some of its zero offsets made -1 or +1 (its closure), so A(x) is the
    /// foreground neighbours spread, one axis at a time, from offset 0 to both sides: a few
    /// shifts, no table. In 2D and 3D it is the block without its centre.
    /// [`SimpleTester::face_key`] turns it into [`SimpleTester::memo_key`]'s layout.
    #[inline]
    pub(crate) fn column_key(&self, block: u128) -> u128 {
        let tables = &*self.tables;
        // The centre's bit is R + (R - 1) / 2 = 3^d / 2, as in raster order: 40 in 4D, a
        // constant (a 128-bit shift by a variable costs several instructions).
        if tables.dim != Dim::Four {
            return block & !(1u128 << tables.centre);
        }
        debug_assert_eq!(tables.centre, 40);
        let faces = block & !(1u128 << 40);
        // The axes' steps in column order: rows 9, 3, 1 apart for axes 0-2, columns 27
        // apart for axis 3 (constants: a 128-bit shift by a variable costs several
        // instructions).
        let zero = &tables.zero_columns;
        let spread = |faces: u128, zero: u128, step: u32| {
            let middle = faces & zero;
            faces | middle << step | middle >> step
        };
        let faces = spread(faces, zero[0], 9);
        let faces = spread(faces, zero[1], 3);
        let faces = spread(faces, zero[2], 1);
        spread(faces, zero[3], 27)
    }

    /// [`SimpleTester::memo_key`] of the voxel whose [`SimpleTester::column_key`] is
    /// `column_key`: the same set in configuration order.
    pub(crate) fn face_key(&self, column_key: u128) -> u128 {
        fn without<const CENTRE: u32>(block: u128) -> u128 {
            (block & ((1u128 << CENTRE) - 1)) | ((block >> (CENTRE + 1)) << CENTRE)
        }
        let tables = &*self.tables;
        debug_assert_eq!(tables.centre, 3usize.pow(tables.dim.get() as u32) / 2);
        let faces = match tables.dim {
            Dim::Two => without::<4>(column_key),
            Dim::Three => without::<13>(column_key),
            Dim::Four => without::<40>(column_key),
        };
        by_bytes(&tables.face_low, &tables.face_high, faces)
    }

    /// The configuration of voxel `index` of C-order voxel bytes `data` laid out with
    /// `strides` (which may be a slab of a larger image: only the strides matter), as
    /// [`SimpleTester::configuration`] gives it for an image, without its checks: for the
    /// hot loops that keep a never-edited padding layer and so only ask about voxels at
    /// least one voxel inside every face. A voxel on the border reads wrong neighbours or
    /// panics on an out-of-range index; `data` must be laid out for this tester's
    /// dimension.
    #[inline]
    pub fn configuration_in(&self, data: &[u8], strides: &[usize], index: usize) -> u128 {
        if self.tables.dim == Dim::Four {
            if let Some(config) = configuration_4d(data, strides, index) {
                return config;
            }
        }
        let start = index - strides.iter().sum::<usize>();
        let row = |p: usize| -> u128 {
            // One unaligned 4-byte load instead of three byte loads: with bytes a, b, c
            // (each 0 or 1) at bits 0, 8 and 16, multiplying by 2^14 + 2^7 + 1 lands them on
            // bits 14, 15 and 16 with no other product term touching those bits.
            match data.get(p..p + 4) {
                Some(bytes) => {
                    let word = u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]);
                    ((word & 0x0001_0101).wrapping_mul(0x4081) >> 14 & 7) as u128
                }
                None => data[p] as u128 | (data[p + 1] as u128) << 1 | (data[p + 2] as u128) << 2,
            }
        };
        // Walk the 3^d block in lexicographic order, one contiguous row of three bytes
        // along the last axis at a time; explicit loops per dimension keep divisions out.
        let mut block = 0u128;
        let mut shift = 0;
        match self.tables.dim {
            Dim::Two => {
                for a in 0..3 {
                    block |= row(start + a * strides[0]) << shift;
                    shift += 3;
                }
            }
            Dim::Three => {
                for a in 0..3 {
                    for b in 0..3 {
                        block |= row(start + a * strides[0] + b * strides[1]) << shift;
                        shift += 3;
                    }
                }
            }
            Dim::Four => {
                // Nine bits per plane of three rows (a, b), packed with constant shifts
                // into 64-bit halves: shifting a u128 by a running amount costs several
                // instructions a row.
                let mut planes = [0u64; 9];
                for a in 0..3 {
                    for b in 0..3 {
                        let base = start + a * strides[0] + b * strides[1];
                        planes[3 * a + b] = row(base) as u64
                            | (row(base + strides[2]) as u64) << 3
                            | (row(base + 2 * strides[2]) as u64) << 6;
                    }
                }
                let block = pack_planes(&planes);
                // The centre, bit 40 (3^4 / 2), as a constant.
                debug_assert_eq!(self.tables.centre, 40);
                return (block & ((1u128 << 40) - 1)) | ((block >> 41) << 40);
            }
        }
        let centre = self.tables.centre;
        (block & ((1u128 << centre) - 1)) | ((block >> (centre + 1)) << centre)
    }

    /// Whether a voxel with this neighbourhood configuration is simple (deleting it if it is
    /// foreground, or adding it if background, changes no topology). The centre voxel's own
    /// value does not matter. Bits beyond the 3^d-1 neighbours are ignored.
    #[inline]
    pub fn is_simple_configuration(&self, config: u128) -> bool {
        let tables = &*self.tables;
        let config = config & tables.neighbour_bits;
        match tables.dim {
            Dim::Two => {
                let table = tables
                    .table_2d
                    .as_ref()
                    .expect("2D tables carry their table");
                table[(config >> 6) as usize] >> (config & 63) & 1 == 1
            }
            Dim::Three => table_3d().get(tables, config),
            Dim::Four => tables.evaluate(config),
        }
    }

    /// What simplicity depends on, as a memo key: in 4D the attachment set A(x) (as a face
    /// mask), which many configurations share (a foreground face neighbour hides 26 of
    /// them); in 2D and 3D the configuration itself (their tables need no memo).
    #[inline]
    pub(crate) fn memo_key(&self, config: u128) -> u128 {
        let tables = &*self.tables;
        let config = config & tables.neighbour_bits;
        match tables.dim {
            Dim::Four => tables.attachment(config),
            _ => config,
        }
    }

    /// [`SimpleTester::is_simple_configuration`] from a [`SimpleTester::memo_key`]. In 4D
    /// all three conditions are read off A(x): a face neighbour is in A exactly when it is
    /// foreground, and the voxel joining two background face neighbours exactly when it is
    /// foreground, so the background condition gives the same answer on A as on the
    /// configuration.
    #[inline]
    pub(crate) fn is_simple_key(&self, key: u128) -> bool {
        let tables = &*self.tables;
        match tables.dim {
            Dim::Four => tables.evaluate_attachment(key),
            _ => self.is_simple_configuration(key),
        }
    }

    /// [`SimpleTester::configuration`] followed by [`SimpleTester::is_simple_configuration`].
    #[inline]
    pub fn is_simple(&self, image: &BinaryImage, index: usize) -> bool {
        self.is_simple_configuration(self.configuration(image, index))
    }

    /// The attachment set A(x) of a configuration: the boundary faces of the voxel that
    /// it shares with its foreground neighbours, as a mask indexed like the neighbours.
    #[inline]
    pub(crate) fn attachment_of(&self, config: u128) -> u128 {
        let tables = &*self.tables;
        tables.attachment(config & tables.neighbour_bits)
    }

    /// For each boundary face k of a voxel (indexed like the neighbours), the faces one
    /// dimension up whose closure contains it, with bit `offsets().len()` standing for the
    /// voxel itself (the coface of its (d-1)-faces).
    pub(crate) fn cofaces_with_cell(&self) -> Vec<u128> {
        let tables = &*self.tables;
        let d = tables.dim.get();
        let cell = 1u128 << tables.n_neighbours;
        (0..tables.n_neighbours)
            .map(|k| {
                let nonzero = tables.offsets[k][..d].iter().filter(|&&o| o != 0).count();
                tables.cofaces[k] | if nonzero == 1 { cell } else { 0 }
            })
            .collect()
    }

    /// The offsets of the neighbours, in configuration bit order.
    pub fn offsets(&self) -> &[[i8; 4]] {
        &self.tables.offsets
    }

    /// Evaluates the three-condition test directly, bypassing any lookup table.
    #[cfg(test)]
    fn evaluate(&self, config: u128) -> bool {
        self.tables.evaluate(config)
    }

    /// The slow oracle: greedily collapses the attachment set A(x) through free faces and
    /// answers whether a single vertex remains. Same answers as
    /// [`SimpleTester::is_simple_configuration`] (the tests check it), tens of times slower;
    /// meant for other crates' tests.
    pub fn is_simple_by_collapse(&self, config: u128) -> bool {
        let config = config & self.tables.neighbour_bits;
        self.tables.collapses_to_a_point(config)
    }
}

/// The 81 bits of a 4D 3x3x3x3 block from its nine 3x3 planes (9 bits each, in order):
/// seven planes fill the low 63 bits of a u64, the last two the next 18.
#[inline]
fn pack_planes(planes: &[u64; 9]) -> u128 {
    let low = planes[0]
        | planes[1] << 9
        | planes[2] << 18
        | planes[3] << 27
        | planes[4] << 36
        | planes[5] << 45
        | planes[6] << 54;
    let high = planes[7] | planes[8] << 9;
    low as u128 | (high as u128) << 63
}

#[cfg(test)]
mod tests;
