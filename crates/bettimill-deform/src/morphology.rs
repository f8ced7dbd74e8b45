//! Modified morphology: topology-preserving, noise-modulated dilation and erosion by the
//! unit ball, and hypervolume targeting built from the same flips.
//!
//! One iteration of dilation takes the frontier (interior background voxels with a
//! foreground face-neighbour, i.e. what a unit-ball dilation would add), keeps the
//! `growth_probability` fraction of it with the highest noise, and adds each kept voxel
//! that is simple in the image as it is at that moment. Erosion is the mirror image
//! (foreground voxels with a background face-neighbour, lowest noise first, removed when
//! simple). Because the noise is fixed, the same regions keep growing from one iteration to
//! the next, which gives the paper's lumpy thick-and-thin results; with probability 1 this
//! is plain topology-preserving dilation (thickening) or erosion (thinning).
//!
//! Order of the flips within an iteration: the kept voxels are split into the 3^d parity
//! subfields (coordinates modulo 3), visited in an order shuffled per iteration by the
//! seed. Two voxels of one subfield are at least 3 apart in some coordinate, so neither is
//! in the other's 3^d block and flipping one cannot change the other's simple-point test:
//! the decisions of a subfield are made in parallel against the same image and then
//! applied, with the same outcome as applying them one by one, on any number of threads.

use crate::field::NoiseCache;
use crate::{DeformError, DeformReport};
use bettimill_grid::neighbourhood::{face_offsets, flat_offsets};
use bettimill_grid::BinaryImage;
use bettimill_homology::simple::{SimpleCache, SimpleTester};
use bettimill_noise::Fractal;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Noise frequency used by [`crate::target_hypervolume`].
pub const DEFAULT_TARGET_FREQUENCY: f64 = 1.0 / 16.0;
/// Octaves used by [`crate::target_hypervolume`].
pub const DEFAULT_TARGET_OCTAVES: u32 = 3;

/// The rand_chacha stream of the subfield order (see `moves::MOVES_STREAM`).
const MORPHOLOGY_STREAM: u64 = 2;

/// Subfields at least this large are decided on rayon; smaller ones are not worth the
/// fork. The answers are the same either way.
const PARALLEL_SUBFIELD: usize = 256;

/// Interior voxels a unit-ball dilation would add (`grow`) or erosion would remove.
fn frontier(image: &BinaryImage, grow: bool) -> Vec<usize> {
    let faces = flat_offsets(image, &face_offsets(image.dim()));
    let data = image.data();
    let (inside, outside) = if grow { (0u8, 1u8) } else { (1u8, 0u8) };
    let mut out = Vec::new();
    crate::for_each_interior(image, |v| {
        if data[v] == inside
            && faces
                .iter()
                .any(|&f| data[(v as isize + f) as usize] == outside)
        {
            out.push(v);
        }
    });
    out
}

/// Sorts candidates by noise, highest first when growing and lowest first when shrinking;
/// ties go to the lower index so the order is total.
fn sort_by_noise(candidates: &mut [usize], noise: &mut NoiseCache, grow: bool) {
    let mut keyed: Vec<(f32, usize)> = candidates.iter().map(|&v| (noise.get(v), v)).collect();
    keyed.sort_unstable_by(|a, b| {
        let by_noise = if grow {
            b.0.total_cmp(&a.0)
        } else {
            a.0.total_cmp(&b.0)
        };
        by_noise.then(a.1.cmp(&b.1))
    });
    for (slot, (_, v)) in candidates.iter_mut().zip(keyed) {
        *slot = v;
    }
}

fn subfield(image: &BinaryImage, v: usize) -> usize {
    let c = image.coords(v);
    (0..image.dim().get()).fold(0, |acc, a| acc * 3 + c[a] % 3)
}

pub(crate) fn run(
    image: &mut BinaryImage,
    mut noise: NoiseCache,
    grow: bool,
    steps: u32,
    growth_probability: f64,
    seed: u64,
) -> DeformReport {
    let dim = image.dim();
    let foreground_before = image.count_foreground();
    let tester = SimpleTester::new(dim);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(MORPHOLOGY_STREAM);
    let n_subfields = 3usize.pow(dim.get() as u32);
    let flip_to = grow as u8;
    let (mut applied, mut rejected, mut iterations) = (0u64, 0u64, 0u64);
    let mut buckets: Vec<Vec<usize>> = vec![Vec::new(); n_subfields];
    for _ in 0..steps {
        let mut candidates = frontier(image, grow);
        if candidates.is_empty() {
            break;
        }
        if growth_probability < 1.0 {
            sort_by_noise(&mut candidates, &mut noise, grow);
            let keep = libm::ceil(growth_probability * candidates.len() as f64) as usize;
            candidates.truncate(keep.max(1));
            candidates.sort_unstable();
        }
        for bucket in buckets.iter_mut() {
            bucket.clear();
        }
        for &v in &candidates {
            buckets[subfield(image, v)].push(v);
        }
        let mut order: Vec<usize> = (0..n_subfields).collect();
        order.shuffle(&mut rng);
        iterations += 1;
        let mut flipped = 0u64;
        for &class in &order {
            let members = &buckets[class];
            let frozen: &BinaryImage = image;
            let simple: Vec<bool> = if members.len() >= PARALLEL_SUBFIELD {
                members
                    .par_iter()
                    .map(|&v| tester.is_simple(frozen, v))
                    .collect()
            } else {
                members
                    .iter()
                    .map(|&v| tester.is_simple(frozen, v))
                    .collect()
            };
            let data = image.data_mut();
            for (&v, ok) in members.iter().zip(simple) {
                if ok {
                    data[v] = flip_to;
                    flipped += 1;
                } else {
                    rejected += 1;
                }
            }
        }
        applied += flipped;
        // The image and the noise are unchanged by an iteration that flips nothing, so
        // every further iteration would flip nothing too.
        if flipped == 0 {
            break;
        }
    }
    DeformReport {
        applied,
        rejected,
        iterations,
        foreground_before,
        foreground_after: image.count_foreground(),
    }
}

pub(crate) fn target(
    image: &mut BinaryImage,
    lo: u64,
    hi: u64,
    seed: u64,
) -> Result<DeformReport, DeformError> {
    if lo > hi {
        return Err(DeformError::EmptyRange { lo, hi });
    }
    let start = image.count_foreground();
    let mut report = DeformReport {
        applied: 0,
        rejected: 0,
        iterations: 0,
        foreground_before: start,
        foreground_after: start,
    };
    if (lo..=hi).contains(&start) {
        return Ok(report);
    }
    let grow = start < lo;
    let goal = if grow { lo } else { hi };
    let fractal = Fractal::new(
        image.dim(),
        seed,
        DEFAULT_TARGET_FREQUENCY,
        DEFAULT_TARGET_OCTAVES,
    )?;
    let tester = SimpleTester::new(image.dim());
    // The configuration is read straight from the voxel bytes (only interior voxels are
    // ever candidates) and the answers are memoised: both are pure functions of the
    // image, so they change no result, only its cost.
    let strides = image.strides().to_vec();
    let mut memo = SimpleCache::new(MEMO_BITS);
    let layout = Layout::new(image);
    // Voxels flipped so far (to undo them on failure) and voxels already queued for the
    // next iteration (to queue each once): bitsets, 1/8 byte per voxel each.
    let mut flipped_set = BitSet::new(image.len());
    let mut queued = BitSet::new(image.len());
    let mut count = start;
    let (inside, flip_to) = if grow { (0u8, 1u8) } else { (1u8, 0u8) };
    let mut candidates = frontier(image, grow);
    loop {
        let order = sort_by_target_noise(&candidates, &fractal, &layout, grow);
        report.iterations += 1;
        let mut flipped = 0u64;
        let mut next = Vec::new();
        queued.clear();
        // One at a time, in noise order, so the count stops exactly on the goal.
        for (k, &v) in order.iter().enumerate() {
            if count == goal {
                break;
            }
            if k % LOOKAHEAD == 0 {
                // Touch the next block of candidates' neighbourhoods together, so their
                // cache misses overlap; the decisions below read the image afresh.
                let data = image.data();
                let ahead = &order[(k + LOOKAHEAD).min(order.len())..];
                let mut sink = 0u128;
                for &u in ahead.iter().take(LOOKAHEAD) {
                    sink ^= tester.configuration_in(data, &strides, u);
                }
                std::hint::black_box(sink);
            }
            let data = image.data_mut();
            if memo.is_simple(&tester, tester.configuration_in(data, &strides, v)) {
                data[v] = flip_to;
                flipped_set.insert(v);
                count = if grow { count + 1 } else { count - 1 };
                flipped += 1;
                // Its interior face neighbours still on the inside join the frontier.
                layout.for_each_interior_face_neighbour(v, |u| {
                    if data[u] == inside && queued.insert(u) {
                        next.push(u);
                    }
                });
            } else {
                report.rejected += 1;
                // Still on the inside with a face neighbour outside: still frontier.
                if queued.insert(v) {
                    next.push(v);
                }
            }
        }
        report.applied += flipped;
        if count == goal {
            report.foreground_after = count;
            return Ok(report);
        }
        if flipped == 0 {
            let data = image.data_mut();
            flipped_set.for_each(|v| data[v] = inside);
            return Err(DeformError::HypervolumeUnreachable {
                start,
                lo,
                hi,
                reached: count,
            });
        }
        // A voxel queued before it was flipped later in the same iteration is no longer
        // on the inside; the frontier of the next iteration is exactly the interior voxels
        // on the inside with a face neighbour outside, as a full scan would find.
        let data = image.data();
        next.retain(|&u| data[u] == inside);
        candidates = next;
    }
}

/// How many candidates ahead the targeting loop touches memory for.
const LOOKAHEAD: usize = 16;

/// log2 of the targeting loop's simple-point memo slots.
const MEMO_BITS: u32 = 12;

/// Flat-index geometry of an image for the targeting loop.
struct Layout {
    d: usize,
    shape: [usize; 4],
    strides: [usize; 4],
}

impl Layout {
    fn new(image: &BinaryImage) -> Layout {
        let d = image.dim().get();
        let mut shape = [1usize; 4];
        let mut strides = [0usize; 4];
        shape[..d].copy_from_slice(image.shape());
        strides[..d].copy_from_slice(image.strides());
        Layout { d, shape, strides }
    }

    #[inline]
    fn coords(&self, mut index: usize) -> [usize; 4] {
        let mut out = [0usize; 4];
        for (coordinate, &stride) in out.iter_mut().zip(&self.strides[..self.d]) {
            *coordinate = index / stride;
            index %= stride;
        }
        out
    }

    /// Calls `f` with every face neighbour of `v` that is an interior voxel.
    #[inline]
    fn for_each_interior_face_neighbour(&self, v: usize, mut f: impl FnMut(usize)) {
        let c = self.coords(v);
        for ((&ca, &s), &n) in c.iter().zip(&self.strides).zip(&self.shape).take(self.d) {
            if ca >= 2 {
                f(v - s);
            }
            if ca + 3 <= n {
                f(v + s);
            }
        }
    }
}

/// A fixed-size set of flat indices.
struct BitSet {
    words: Vec<u64>,
}

impl BitSet {
    fn new(len: usize) -> BitSet {
        BitSet {
            words: vec![0; len.div_ceil(64)],
        }
    }

    /// Inserts `i`; true if it was not there.
    #[inline]
    fn insert(&mut self, i: usize) -> bool {
        let (w, bit) = (i / 64, 1u64 << (i % 64));
        let fresh = self.words[w] & bit == 0;
        self.words[w] |= bit;
        fresh
    }

    fn clear(&mut self) {
        self.words.iter_mut().for_each(|w| *w = 0);
    }

    fn for_each(&self, mut f: impl FnMut(usize)) {
        for (w, &word) in self.words.iter().enumerate() {
            let mut rest = word;
            while rest != 0 {
                f(w * 64 + rest.trailing_zeros() as usize);
                rest &= rest - 1;
            }
        }
    }
}

/// The candidates in the targeting order: by noise, highest first when growing and lowest
/// first when shrinking, ties to the lower index (a total order, so the result does not
/// depend on the input order). The noise of each voxel is computed here, in parallel (each
/// value depends only on its coordinate), rather than cached for the whole image.
fn sort_by_target_noise(
    candidates: &[usize],
    fractal: &Fractal,
    layout: &Layout,
    grow: bool,
) -> Vec<usize> {
    // The f32 noise mapped to a u32 whose unsigned order is `f32::total_cmp`'s (reversed
    // when growing), so a pair sorts as one integer.
    let key = |v: usize| -> u32 {
        let noise = fractal.sample(layout.coords(v)) as f32;
        let bits = noise.to_bits();
        let ordered = if bits >> 31 == 1 {
            !bits
        } else {
            bits | 1 << 31
        };
        if grow {
            !ordered
        } else {
            ordered
        }
    };
    if candidates.len() <= u32::MAX as usize && layout_fits_u32(layout) {
        let mut keyed: Vec<u64> = candidates
            .par_iter()
            .map(|&v| (key(v) as u64) << 32 | v as u64)
            .collect();
        keyed.par_sort_unstable();
        keyed
            .into_iter()
            .map(|k| (k & 0xFFFF_FFFF) as usize)
            .collect()
    } else {
        let mut keyed: Vec<(u32, usize)> = candidates.par_iter().map(|&v| (key(v), v)).collect();
        keyed.par_sort_unstable();
        keyed.into_iter().map(|(_, v)| v).collect()
    }
}

/// Whether every flat index of the image fits in 32 bits.
fn layout_fits_u32(layout: &Layout) -> bool {
    layout.shape[..layout.d]
        .iter()
        .try_fold(1u64, |acc, &n| acc.checked_mul(n as u64))
        .is_some_and(|len| len <= 1 << 32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::NoiseCache;
    use rand::{Rng, SeedableRng};

    /// The targeting loop as first written: a full frontier scan per iteration, the noise
    /// from a whole-image cache, the plain simple-point test, one flip at a time. The fast
    /// loop must give the same bytes and the same report.
    fn target_reference(
        image: &mut BinaryImage,
        lo: u64,
        hi: u64,
        seed: u64,
    ) -> Result<DeformReport, DeformError> {
        let start = image.count_foreground();
        let mut report = DeformReport {
            applied: 0,
            rejected: 0,
            iterations: 0,
            foreground_before: start,
            foreground_after: start,
        };
        if (lo..=hi).contains(&start) {
            return Ok(report);
        }
        let grow = start < lo;
        let goal = if grow { lo } else { hi };
        let mut noise = NoiseCache::new(
            image,
            seed,
            DEFAULT_TARGET_FREQUENCY,
            DEFAULT_TARGET_OCTAVES,
        )?;
        let tester = SimpleTester::new(image.dim());
        let original = image.clone();
        let mut count = start;
        loop {
            let mut candidates = frontier(image, grow);
            sort_by_noise(&mut candidates, &mut noise, grow);
            report.iterations += 1;
            let mut flipped = 0u64;
            for v in candidates {
                if count == goal {
                    break;
                }
                if tester.is_simple(image, v) {
                    image.data_mut()[v] = grow as u8;
                    count = if grow { count + 1 } else { count - 1 };
                    flipped += 1;
                } else {
                    report.rejected += 1;
                }
            }
            report.applied += flipped;
            if count == goal {
                report.foreground_after = count;
                return Ok(report);
            }
            if flipped == 0 {
                *image = original;
                return Err(DeformError::HypervolumeUnreachable {
                    start,
                    lo,
                    hi,
                    reached: count,
                });
            }
        }
    }

    /// Random blobs with a background border: a few random boxes.
    fn blobs(shape: &[usize], rng: &mut ChaCha8Rng) -> BinaryImage {
        let mut image = BinaryImage::zeros(shape).unwrap();
        let d = shape.len();
        for _ in 0..rng.gen_range(1..4) {
            let lo: Vec<usize> = shape.iter().map(|&n| rng.gen_range(1..n / 2)).collect();
            let hi: Vec<usize> = shape
                .iter()
                .zip(&lo)
                .map(|(&n, &l)| rng.gen_range(l + 1..n - 1))
                .collect();
            for v in 0..image.len() {
                let c = image.coords(v);
                if (0..d).all(|a| (lo[a]..hi[a]).contains(&c[a])) {
                    image.data_mut()[v] = 1;
                }
            }
        }
        // Sprinkle holes so that some flips are not simple.
        for v in 0..image.len() {
            if image.data()[v] == 1 && rng.gen_bool(0.02) {
                image.data_mut()[v] = 0;
            }
        }
        image
    }

    #[test]
    fn targeting_matches_the_reference_loop_on_any_thread_count() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let pools: Vec<rayon::ThreadPool> = [1, 2, 4]
            .iter()
            .map(|&n| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .unwrap()
            })
            .collect();
        for shape in [
            vec![40usize, 36],
            vec![18, 20, 16],
            vec![10, 11, 9, 12],
            vec![14, 14, 14, 14],
        ] {
            for round in 0..6u64 {
                let image = blobs(&shape, &mut rng);
                let start = image.count_foreground();
                let len = image.len() as u64;
                let (lo, hi) = match round % 3 {
                    0 => (start / 3, start / 3 + 5),
                    1 => ((start + len) / 2, (start + len) / 2 + 3),
                    _ => (len, len),
                };
                let mut expected = image.clone();
                let want = target_reference(&mut expected, lo, hi, round);
                for pool in &pools {
                    let mut found = image.clone();
                    let got = pool.install(|| target(&mut found, lo, hi, round));
                    assert_eq!(got, want, "{shape:?} round {round}");
                    assert_eq!(found.data(), expected.data(), "{shape:?} round {round}");
                    if got.is_ok() {
                        let n = found.count_foreground();
                        assert!((lo..=hi).contains(&n));
                        assert_eq!(
                            bettimill_homology::topology(&found).betti,
                            bettimill_homology::topology(&image).betti
                        );
                    }
                }
            }
        }
    }
}
