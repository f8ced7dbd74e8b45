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
use bettimill_homology::simple::SimpleTester;
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
    let mut noise = NoiseCache::new(
        image,
        seed,
        DEFAULT_TARGET_FREQUENCY,
        DEFAULT_TARGET_OCTAVES,
    )?;
    let tester = SimpleTester::new(image.dim());
    let original = image.clone();
    let mut count = start;
    let flip_to = grow as u8;
    loop {
        let mut candidates = frontier(image, grow);
        sort_by_noise(&mut candidates, &mut noise, grow);
        report.iterations += 1;
        let mut flipped = 0u64;
        // One at a time, in noise order, so the count stops exactly on the goal.
        for v in candidates {
            if count == goal {
                break;
            }
            if tester.is_simple(image, v) {
                image.data_mut()[v] = flip_to;
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
