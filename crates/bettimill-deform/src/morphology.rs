//! Modified morphology: topology-preserving, noise-modulated growth and shrinking of a
//! phase, and hypervolume targeting built from the same flips.
//!
//! One iteration of growth takes the frontier (voxels of the other phase in the box with a
//! face neighbour in the phase, i.e. what a unit-ball dilation of the phase would add),
//! keeps the `growth_probability` fraction of it with the highest noise, and flips each
//! kept voxel that is simple in the image as it is at that moment. Shrinking is the mirror
//! image (phase voxels with a face neighbour outside it, lowest noise first). Because the
//! noise is fixed, the same regions keep growing from one iteration to the next, which
//! gives the paper's lumpy thick-and-thin results; with probability 1 this is plain
//! topology-preserving dilation (thickening) or erosion (thinning).
//!
//! Only the frontier is ever visited: it is found by one scan of the part of the box next
//! to the phase (see [`Phase`]), then kept up to date from the flips (a voxel joins it
//! when a face neighbour flips, and leaves it when it flips itself), so an iteration costs
//! what its frontier costs, not what the image does. The noise of a candidate is computed once, when it is first ranked (in parallel:
//! each value depends only on its coordinates), and kept with it for as long as it stays
//! on the frontier; it is never stored for the whole image.
//!
//! Order of the flips within an iteration: the kept voxels are split into the 3^d parity
//! subfields (coordinates modulo 3), visited in an order shuffled per iteration by the
//! seed. Two voxels of one subfield are at least 3 apart in some coordinate, so neither is
//! in the other's 3^d block and flipping one cannot change the other's simple-point test:
//! the decisions of a subfield are made in parallel against the same image and then
//! applied, with the same outcome as applying them one by one, on any number of threads.

use crate::apart::{self, Apart};
use crate::phase::{BitSet, Layout, Phase};
use crate::{DeformError, DeformReport};
use bettimill_grid::BinaryImage;
use bettimill_homology::simple::{SimpleCache, SimpleTester};
use bettimill_noise::{Fractal, FractalMemo};
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

/// The f32 noise mapped to a u32 whose unsigned order is `f32::total_cmp`'s, reversed when
/// `highest_first`, so that sorting by it ranks the candidates.
#[inline]
fn rank_key(noise: f64, highest_first: bool) -> u32 {
    let bits = (noise as f32).to_bits();
    let ordered = if bits >> 31 == 1 {
        !bits
    } else {
        bits | 1 << 31
    };
    if highest_first {
        !ordered
    } else {
        ordered
    }
}

/// Keyed candidates in rank order: by noise, highest first when the keys say so, ties to
/// the lower index (a total order, so the result does not depend on the input order or
/// the thread count).
fn rank_by_key(mut keyed: Vec<(u32, usize)>) -> Vec<(u32, usize)> {
    keyed.par_sort_unstable();
    keyed
}

/// The candidates with their rank keys ([`rank_key`] of their noise), computed in
/// parallel: each value depends only on its voxel's coordinates. A frontier comes in C
/// order, so neighbours along the last axis follow each other; each part of the split
/// keeps a memo of the point before ([`FractalMemo`]), which changes no value.
fn keyed_by_noise(
    candidates: &[usize],
    fractal: &Fractal,
    layout: &Layout,
    highest_first: bool,
) -> Vec<(u32, usize)> {
    candidates
        .par_iter()
        .map_init(FractalMemo::default, |memo, &v| {
            let noise = fractal.sample_memo(layout.coords(v), memo);
            (rank_key(noise, highest_first), v)
        })
        .collect()
}

/// The `keep` keyed candidates that come first in [`rank_by_noise`]'s order, in no
/// particular order. An iteration of growth or shrinking needs only which voxels are kept:
/// they are split into subfields whose decisions are independent of their order, and the
/// next frontier is the same set whatever order it is collected in (the next ranking is a
/// total order). So a selection, linear in the frontier, replaces the sort.
fn best_by_key(keyed: &[(u32, usize)], keep: usize) -> Vec<usize> {
    let mut keyed = keyed.to_vec();
    if keep < keyed.len() {
        keyed.select_nth_unstable(keep);
        keyed.truncate(keep);
    }
    keyed.into_iter().map(|(_, v)| v).collect()
}

/// What one growth or shrinking run needs besides the image.
pub(crate) struct Morphology<'a> {
    pub(crate) phase: &'a mut Phase,
    /// True to grow the phase, false to shrink it.
    pub(crate) grow: bool,
    pub(crate) steps: u32,
    pub(crate) growth_probability: f64,
    pub(crate) noise_frequency: f64,
    pub(crate) octaves: u32,
    pub(crate) seed: u64,
    /// Only voxels in this slab take part (a neck of [`crate::Method::Pinch`]).
    pub(crate) slab: Option<Slab>,
}

/// The voxels whose centres lie within `half` of the hyperplane `normal . x = offset`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Slab {
    /// A unit vector (its first `d` coordinates).
    pub(crate) normal: [f64; 4],
    pub(crate) offset: f64,
    pub(crate) half: f64,
}

impl Slab {
    /// The signed depth of a voxel's centre along the normal.
    pub(crate) fn depth(normal: &[f64; 4], c: [usize; 4]) -> f64 {
        normal.iter().zip(c).map(|(n, x)| n * x as f64).sum()
    }

    pub(crate) fn holds(&self, c: [usize; 4]) -> bool {
        (Slab::depth(&self.normal, c) - self.offset).abs() <= self.half
    }
}

pub(crate) fn run(
    image: &mut BinaryImage,
    job: &mut Morphology,
    mut apart: Option<&mut Apart>,
) -> Result<DeformReport, DeformError> {
    let dim = image.dim();
    // The foreground counts are the caller's (`deform_phase_counted`), from the flips.
    let mut report = DeformReport::default();
    let layout = Layout::new(image, job.phase);
    if job.steps == 0 || layout.is_empty() {
        return Ok(report);
    }
    let fractal = Fractal::new(dim, job.seed, job.noise_frequency, job.octaves)?;
    let tester = SimpleTester::new(dim);
    let strides = image.strides().to_vec();
    let mut memo = SimpleCache::new(MEMO_BITS);
    let parallel = rayon::current_num_threads() > 1;
    let mut rng = ChaCha8Rng::seed_from_u64(job.seed);
    rng.set_stream(MORPHOLOGY_STREAM);
    let n_subfields = 3usize.pow(dim.get() as u32);
    let flip_from = if job.grow {
        job.phase.other()
    } else {
        job.phase.value
    };
    let flip_to = 1 - flip_from;
    let mut buckets: Vec<Vec<usize>> = vec![Vec::new(); n_subfields];
    // The candidates with their rank keys: a candidate that does not flip stays one, and
    // its key, a function of its coordinates, is carried to the next iteration rather
    // than computed again. Without ranking (every candidate kept) the keys are 0.
    let ranked = job.growth_probability < 1.0;
    let with_keys = |voxels: &[usize]| -> Vec<(u32, usize)> {
        if ranked {
            keyed_by_noise(voxels, &fractal, &layout, job.grow)
        } else {
            voxels.iter().map(|&v| (0, v)).collect()
        }
    };
    // Voxels that joined the frontier and have no key yet: keyed when an iteration needs
    // them, so the frontier after the last iteration costs no noise.
    let in_slab = |v: usize| job.slab.is_none_or(|slab| slab.holds(layout.coords(v)));
    let mut joined = layout.frontier(image, flip_from);
    joined.retain(|&v| in_slab(v));
    let mut queued = BitSet::new(image.len());
    for &v in &joined {
        queued.insert(v);
    }
    let mut candidates: Vec<(u32, usize)> = Vec::new();
    for _ in 0..job.steps {
        candidates.extend(with_keys(&joined));
        if candidates.is_empty() {
            break;
        }
        let kept: Vec<usize> = if ranked {
            let keep = libm::ceil(job.growth_probability * candidates.len() as f64) as usize;
            let keep = keep.clamp(1, candidates.len());
            best_by_key(&candidates, keep)
        } else {
            candidates.iter().map(|&(_, v)| v).collect()
        };
        for bucket in buckets.iter_mut() {
            bucket.clear();
        }
        for &v in &kept {
            buckets[layout.subfield(v)].push(v);
        }
        let mut order: Vec<usize> = (0..n_subfields).collect();
        order.shuffle(&mut rng);
        report.iterations += 1;
        let mut flipped = 0u64;
        for &class in &order {
            let members = &buckets[class];
            // Candidates are in the box, which keeps off the outermost layer: their
            // configurations are read straight from the voxel bytes. On one thread the
            // answers are memoised (a pure function of the configuration, so the same
            // answers either way).
            let frozen = image.data();
            let simple: Vec<bool> = if members.len() >= PARALLEL_SUBFIELD && parallel {
                members
                    .par_iter()
                    .map(|&v| {
                        tester.is_simple_configuration(tester.configuration_in(frozen, &strides, v))
                    })
                    .collect()
            } else {
                members
                    .iter()
                    .map(|&v| memo.is_simple(&tester, tester.configuration_in(frozen, &strides, v)))
                    .collect()
            };
            // A simple voxel flips unless growth would bring it too near another
            // component; that test reads the image as the subfield's earlier members
            // left it (a gap wider than the subfields' spacing of 3 reaches voxels they
            // flip), so no two flips of one subfield together narrow a gap.
            for (&v, ok) in members.iter().zip(simple) {
                let label = if !ok {
                    None
                } else if job.grow {
                    apart::joins(apart.as_deref(), job.phase, image, v)
                } else {
                    Some(0)
                };
                if let Some(label) = label {
                    image.data_mut()[v] = flip_to;
                    flipped += 1;
                    if job.grow {
                        job.phase.joined(layout.coords(v));
                    }
                    if let Some(apart) = apart.as_deref_mut() {
                        if job.grow {
                            apart.join(v, label);
                        } else {
                            apart.leave(v);
                        }
                    }
                } else {
                    report.rejected += 1;
                }
            }
        }
        report.applied += flipped;
        // The image is unchanged by an iteration that flips nothing, and so is the
        // frontier: every further iteration would flip nothing too.
        if flipped == 0 {
            break;
        }
        // The next frontier: the candidates that did not flip (their neighbour across the
        // frontier is still there: growth and shrinking are monotone), and the face
        // neighbours of flipped voxels that are still on the flipping side.
        let data = image.data();
        let next: Vec<(u32, usize)> = candidates
            .iter()
            .copied()
            .filter(|&(_, v)| data[v] == flip_from)
            .collect();
        joined.clear();
        for &v in &kept {
            if data[v] == flip_to {
                layout.for_each_face_neighbour_in_box(v, |u| {
                    if data[u] == flip_from && in_slab(u) && queued.insert(u) {
                        joined.push(u);
                    }
                });
            }
        }
        candidates = next;
    }
    Ok(report)
}

/// The nearest end of `[lo, hi]` to `count`: where targeting that only has to reach the
/// range stops.
pub(crate) fn nearest_end(count: u64, lo: u64, hi: u64) -> u64 {
    if count < lo {
        lo
    } else {
        hi.min(count)
    }
}

pub(crate) fn target(
    image: &mut BinaryImage,
    lo: u64,
    hi: u64,
    goal: u64,
    phase: &mut Phase,
    mut apart: Option<&mut Apart>,
    seed: u64,
) -> Result<DeformReport, DeformError> {
    if lo > hi {
        return Err(DeformError::EmptyRange { lo, hi });
    }
    let goal = goal.clamp(lo, hi);
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
    phase.find_extent(image);
    // The foreground grows by flipping background voxels, whichever side the phase is.
    let grow_foreground = start < lo;
    let (inside, flip_to) = if grow_foreground {
        (0u8, 1u8)
    } else {
        (1u8, 0u8)
    };
    // Growing the phase ranks the highest noise first, shrinking it the lowest.
    let grows_phase = flip_to == phase.value;
    let fractal = Fractal::new(
        image.dim(),
        seed,
        DEFAULT_TARGET_FREQUENCY,
        DEFAULT_TARGET_OCTAVES,
    )?;
    let tester = SimpleTester::new(image.dim());
    let layout = Layout::new(image, phase);
    // The configuration is read straight from the voxel bytes (only voxels in the box,
    // which keeps off the outermost layer, are ever candidates) and the answers are
    // memoised: both are pure functions of the image, so they change no result, only its
    // cost.
    let strides = image.strides().to_vec();
    let mut memo = SimpleCache::new(MEMO_BITS);
    // Voxels flipped so far (to undo them on failure) and voxels already queued for the
    // next iteration (to queue each once).
    let mut flipped_list: Vec<usize> = Vec::new();
    let mut undo_labels: Vec<u8> = Vec::new();
    let mut queued = BitSet::new(image.len());
    let mut count = start;
    // The candidates with their rank keys; a candidate rejected in one iteration carries
    // its key (a function of its coordinates) to the next.
    let mut candidates = if layout.is_empty() {
        Vec::new()
    } else {
        keyed_by_noise(
            &layout.frontier(image, inside),
            &fractal,
            &layout,
            grows_phase,
        )
    };
    loop {
        for &(_, v) in &candidates {
            queued.remove(v);
        }
        let order = rank_by_key(candidates);
        report.iterations += 1;
        let mut flipped = 0u64;
        // The next frontier: voxels that join it (keys still to compute) and rejected
        // candidates (keys known).
        let mut next = Vec::new();
        let mut carried = Vec::new();
        // One at a time, in noise order, so the count stops exactly on the goal.
        for (k, &(key, v)) in order.iter().enumerate() {
            if count == goal {
                break;
            }
            if k % LOOKAHEAD == 0 {
                // Touch the next block of candidates' neighbourhoods together, so their
                // cache misses overlap; the decisions below read the image afresh.
                let data = image.data();
                let ahead = &order[(k + LOOKAHEAD).min(order.len())..];
                let mut sink = 0u128;
                for &(_, u) in ahead.iter().take(LOOKAHEAD) {
                    sink ^= tester.configuration_in(data, &strides, u);
                }
                std::hint::black_box(sink);
            }
            let simple =
                memo.is_simple(&tester, tester.configuration_in(image.data(), &strides, v));
            let label = if !simple {
                None
            } else if grows_phase {
                apart::joins(apart.as_deref(), phase, image, v)
            } else {
                Some(0)
            };
            let data = image.data_mut();
            if let Some(label) = label {
                data[v] = flip_to;
                flipped_list.push(v);
                if grows_phase {
                    phase.joined(layout.coords(v));
                }
                if let Some(apart) = apart.as_deref_mut() {
                    // What undoing the flip restores: no label for a voxel that joined,
                    // its label for one that left.
                    undo_labels.push(if grows_phase {
                        apart.join(v, label);
                        0
                    } else {
                        apart.leave(v)
                    });
                }
                count = if grow_foreground {
                    count + 1
                } else {
                    count - 1
                };
                flipped += 1;
                // Its face neighbours in the box still on the inside join the frontier.
                layout.for_each_face_neighbour_in_box(v, |u| {
                    if data[u] == inside && queued.insert(u) {
                        next.push(u);
                    }
                });
            } else {
                report.rejected += 1;
                // A simple voxel that the separation alone refuses (no clearance in play)
                // while the phase grows stays refused: no voxel leaves the phase here, so
                // the other component it comes too near is still there, and its own
                // component is still beside it. It stays queued, so it is never tried
                // again; the flips are those of trying it every iteration.
                let settled = simple
                    && grows_phase
                    && phase.clearance() < 2
                    && apart.as_deref().is_some_and(|a| a.own(image, v) != 0);
                // Still on the inside with a face neighbour outside: still frontier.
                if queued.insert(v) && !settled {
                    carried.push((key, v));
                }
            }
        }
        report.applied += flipped;
        if count == goal {
            report.foreground_after = count;
            return Ok(report);
        }
        if flipped == 0 && (lo..=hi).contains(&count) {
            // The frontier ran out of simple voxels short of the goal but inside the
            // range: the range is what the caller needs.
            report.foreground_after = count;
            return Ok(report);
        }
        if flipped == 0 {
            let data = image.data_mut();
            for &v in &flipped_list {
                data[v] = inside;
            }
            if let Some(apart) = apart.as_deref_mut() {
                for (&v, &label) in flipped_list.iter().zip(&undo_labels) {
                    apart.join(v, label);
                }
            }
            return Err(DeformError::HypervolumeUnreachable {
                start,
                lo,
                hi,
                reached: count,
            });
        }
        // A voxel queued before it was flipped later in the same iteration is no longer
        // on the inside; the frontier of the next iteration is exactly the voxels of the
        // box on the inside with a face neighbour outside, as a full scan would find.
        let data = image.data();
        next.retain(|&u| data[u] == inside);
        candidates = keyed_by_noise(&next, &fractal, &layout, grows_phase);
        candidates.extend(carried);
    }
}

/// How many candidates ahead the targeting loop touches memory for.
const LOOKAHEAD: usize = 16;

/// log2 of the targeting loop's simple-point memo slots.
pub(crate) const MEMO_BITS: u32 = 12;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::NoiseCache;
    use rand::{Rng, SeedableRng};

    /// The voxels of the phase's box of value `inside` with a face neighbour of the other
    /// value, by a plain scan of the whole image.
    fn scan_frontier(image: &BinaryImage, phase: &Phase, inside: u8) -> Vec<usize> {
        let d = image.dim().get();
        let faces = bettimill_grid::neighbourhood::flat_offsets(
            image,
            &bettimill_grid::neighbourhood::face_offsets(image.dim()),
        );
        let data = image.data();
        (0..image.len())
            .filter(|&v| {
                let c = image.coords(v);
                (0..d).all(|a| c[a] >= phase.lo[a].max(1) && c[a] <= phase.hi[a])
                    && data[v] == inside
                    && faces
                        .iter()
                        .any(|&f| data[(v as isize + f) as usize] == 1 - inside)
            })
            .collect()
    }

    /// Sorts by noise, highest first when `highest_first`, ties to the lower index.
    fn sort_by_noise(candidates: &mut Vec<usize>, noise: &mut NoiseCache, highest_first: bool) {
        let mut keyed: Vec<(f32, usize)> = candidates.iter().map(|&v| (noise.get(v), v)).collect();
        keyed.sort_by(|a, b| {
            let by_noise = if highest_first {
                b.0.total_cmp(&a.0)
            } else {
                a.0.total_cmp(&b.0)
            };
            by_noise.then(a.1.cmp(&b.1))
        });
        *candidates = keyed.into_iter().map(|(_, v)| v).collect();
    }

    /// The targeting loop as first written: a full frontier scan per iteration, the noise
    /// from a whole-image cache, the plain simple-point test, one flip at a time. The fast
    /// loop must give the same bytes and the same report.
    fn target_reference(
        image: &mut BinaryImage,
        lo: u64,
        hi: u64,
        goal: u64,
        phase: &Phase,
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
        let inside = if grow { 0 } else { 1 };
        let highest_first = 1 - inside == phase.value;
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
            let mut candidates = scan_frontier(image, phase, inside);
            sort_by_noise(&mut candidates, &mut noise, highest_first);
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
            if flipped == 0 && (lo..=hi).contains(&count) {
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

    /// Growth or shrinking as the definition reads: a full frontier scan per iteration,
    /// the kept share by noise, then every kept voxel of each subfield decided against the
    /// image as the subfield found it.
    fn run_reference(image: &mut BinaryImage, job: &Morphology) -> u64 {
        let dim = image.dim();
        let tester = SimpleTester::new(dim);
        let mut noise = NoiseCache::new(image, job.seed, job.noise_frequency, job.octaves).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(job.seed);
        rng.set_stream(MORPHOLOGY_STREAM);
        let n_subfields = 3usize.pow(dim.get() as u32);
        let inside = if job.grow {
            1 - job.phase.value
        } else {
            job.phase.value
        };
        let mut applied = 0;
        for _ in 0..job.steps {
            let mut candidates = scan_frontier(image, job.phase, inside);
            if candidates.is_empty() {
                break;
            }
            if job.growth_probability < 1.0 {
                sort_by_noise(&mut candidates, &mut noise, job.grow);
                let keep = libm::ceil(job.growth_probability * candidates.len() as f64) as usize;
                candidates.truncate(keep.max(1));
            }
            let mut order: Vec<usize> = (0..n_subfields).collect();
            order.shuffle(&mut rng);
            let mut flipped = 0;
            for class in order {
                let members: Vec<usize> = candidates
                    .iter()
                    .copied()
                    .filter(|&v| {
                        let c = image.coords(v);
                        (0..dim.get()).fold(0, |acc, a| acc * 3 + c[a] % 3) == class
                    })
                    .collect();
                let decisions: Vec<bool> = members
                    .iter()
                    .map(|&v| tester.is_simple(image, v))
                    .collect();
                for (v, ok) in members.into_iter().zip(decisions) {
                    if ok {
                        image.data_mut()[v] = 1 - inside;
                        flipped += 1;
                    }
                }
            }
            applied += flipped;
            if flipped == 0 {
                break;
            }
        }
        applied
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

    /// A solid cube (one background layer) with a few random box cavities, and the phase
    /// of its cavities two voxels in from the solid's faces.
    fn carved(shape: &[usize], rng: &mut ChaCha8Rng) -> (BinaryImage, Phase) {
        let mut image = blobs(shape, rng);
        let d = shape.len();
        for v in 0..image.len() {
            let c = image.coords(v);
            let border = (0..d).any(|a| c[a] == 0 || c[a] + 1 == shape[a]);
            let cavity = image.data()[v] == 1 && (0..d).all(|a| c[a] >= 3 && c[a] + 4 <= shape[a]);
            image.data_mut()[v] = (!border && !cavity) as u8;
        }
        let lo = vec![2usize; d];
        let hi: Vec<usize> = shape.iter().map(|&n| n - 3).collect();
        let phase = Phase::cavities(&image, &lo, &hi);
        (image, phase)
    }

    fn pools() -> Vec<rayon::ThreadPool> {
        [1, 2, 4]
            .iter()
            .map(|&n| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .unwrap()
            })
            .collect()
    }

    /// Even rounds deform the objects of random blobs, odd rounds the cavities of a cube.
    fn case(shape: &[usize], round: u64, rng: &mut ChaCha8Rng) -> (BinaryImage, Phase) {
        if round.is_multiple_of(2) {
            let image = blobs(shape, rng);
            let phase = Phase::foreground(&image);
            (image, phase)
        } else {
            carved(shape, rng)
        }
    }

    const SHAPES: [&[usize]; 4] = [
        &[40, 36],
        &[18, 20, 16],
        &[10, 11, 9, 12],
        &[14, 14, 14, 14],
    ];

    #[test]
    fn targeting_matches_the_reference_loop_on_any_thread_count() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let pools = pools();
        for shape in SHAPES {
            for round in 0..8u64 {
                let (image, phase) = case(shape, round, &mut rng);
                let start = image.count_foreground();
                let len = image.len() as u64;
                // Wide ranges with a goal inside, and narrow ones reached at their end.
                let (lo, hi, goal) = match round % 4 {
                    0 => (start / 4, start / 2, start / 3),
                    1 => (start / 3, start / 3 + 5, start / 3 + 5),
                    2 => ((start + len) / 2, (start + len) / 2 + 3, (start + len) / 2),
                    _ => (start + 3, start * 2 + 9, start + start / 2),
                };
                let mut expected = image.clone();
                let want = target_reference(&mut expected, lo, hi, goal, &phase, round);
                for pool in &pools {
                    let mut found = image.clone();
                    // Each run keeps its own copy of the phase's extent.
                    let mut phase = phase;
                    let got =
                        pool.install(|| target(&mut found, lo, hi, goal, &mut phase, None, round));
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

    #[test]
    fn growth_and_shrinking_match_the_reference_on_any_thread_count() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let pools = pools();
        for shape in SHAPES {
            for round in 0..8u64 {
                let (image, phase) = case(shape, round, &mut rng);
                let mut job_phase = phase;
                let job = Morphology {
                    phase: &mut job_phase,
                    grow: round % 4 < 2,
                    steps: 1 + round as u32 % 3,
                    growth_probability: [1.0, 0.4, 0.7, 0.2][round as usize % 4],
                    noise_frequency: 0.2,
                    octaves: 2,
                    seed: round,
                    slab: None,
                };
                let mut expected = image.clone();
                let applied = run_reference(&mut expected, &job);
                for pool in &pools {
                    let mut found = image.clone();
                    let mut phase = phase;
                    let mut job = Morphology {
                        phase: &mut phase,
                        ..job
                    };
                    let report = pool.install(|| run(&mut found, &mut job, None)).unwrap();
                    assert_eq!(report.applied, applied, "{shape:?} round {round}");
                    assert_eq!(found.data(), expected.data(), "{shape:?} round {round}");
                }
                assert_eq!(
                    bettimill_homology::topology(&expected).betti,
                    bettimill_homology::topology(&image).betti
                );
            }
        }
    }
}
