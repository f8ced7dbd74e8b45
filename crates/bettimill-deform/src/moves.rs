//! Hypervolume-preserving moves (the paper's pixel-moving deformation, in any dimension),
//! of the phase that carries the topology (see `phase.rs`).
//!
//! One move takes a boundary voxel `x` of the phase (in the phase, with a face neighbour
//! outside it) and a voxel `z` outside the phase within Chebyshev distance `max_distance`
//! of it, both in the phase's box, with `noise(z) > noise(x)`, and flips both. It is applied only when `x` is simple in
//! the image and then `z` is simple in the image without `x`; the order matters when the
//! two are close, since deleting `x` changes `z`'s neighbourhood. Both flips are simple, so
//! topology is unchanged, and the foreground count is unchanged by construction.
//!
//! Choosing `x`: a tournament of [`TOURNAMENT`] random boundary voxels, lowest noise wins,
//! so the process prefers low-noise voxels without always hammering the single lowest one.
//! Choosing `z`: the highest-noise candidate that passes the test, among voxels outside the
//! phase with a face neighbour in it. Every move strictly
//! raises the sum of the noise over the foreground, so the process cannot cycle; when no
//! move is possible any more it stops early and the report says how many were applied.
//!
//! A source that fails (not simple, or no target) is marked stuck and leaves the draw
//! until a voxel within Chebyshev distance `max_distance + 1` of it changes: its own test
//! and those of all its possible targets only read voxels that close. Without this, a
//! tournament keeps picking the low-noise voxels on the downhill side of an object, whose
//! background neighbours all have lower noise, and most attempts are wasted.

use crate::apart::{self, Apart};
use crate::field::NoiseCache;
use crate::phase::{chebyshev_ball, BitSet, Layout, Phase};
use crate::DeformReport;
use bettimill_grid::neighbourhood::{face_offsets, flat_offsets};
use bettimill_grid::BinaryImage;
use bettimill_homology::simple::{SimpleCache, SimpleTester};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rustc_hash::FxHashMap;

/// Random boundary voxels drawn per move; the lowest-noise one is the source.
pub(crate) const TOURNAMENT: usize = 4;

/// The rand_chacha stream of the source draws (stream 0 of the same seed shuffles the
/// noise permutation, so the two never share random numbers).
const MOVES_STREAM: u64 = 1;

/// Give up after this many attempts per requested move (plus a constant), so a deformation
/// that has run out of possible moves ends instead of spinning.
const ATTEMPTS_PER_MOVE: u64 = 64;

/// A uniform index in `0..n`, drawn as a u64 so that the stream of random numbers is the
/// same on 32- and 64-bit machines (rand samples usize ranges at pointer width).
pub(crate) fn index_below(rng: &mut ChaCha8Rng, n: usize) -> usize {
    rng.gen_range(0..n as u64) as usize
}

/// The phase's boundary voxels, as a list that supports uniform random draws plus a slot
/// map for O(1) insertion and removal (a map, not a table over the image: the boundary is
/// a small part of a large image; it is only looked up, so its order reaches nothing, and
/// its keys are voxel indices, so rustc-hash's multiply hashes them).
struct BoundarySet {
    list: Vec<usize>,
    // Position in `list`.
    slot: FxHashMap<usize, usize>,
}

impl BoundarySet {
    fn insert(&mut self, v: usize) {
        if let std::collections::hash_map::Entry::Vacant(e) = self.slot.entry(v) {
            e.insert(self.list.len());
            self.list.push(v);
        }
    }

    fn remove(&mut self, v: usize) {
        if let Some(pos) = self.slot.remove(&v) {
            let last = *self
                .list
                .last()
                .expect("the map says the list is non-empty");
            self.list.swap_remove(pos);
            if last != v {
                self.slot.insert(last, pos);
            }
        }
    }
}

struct Geometry {
    layout: Layout,
    value: u8,
    faces: Vec<isize>,
}

impl Geometry {
    fn is_boundary(&self, image: &BinaryImage, v: usize) -> bool {
        let data = image.data();
        data[v] == self.value
            && self.layout.in_box(v)
            && self
                .faces
                .iter()
                .any(|&f| data[(v as isize + f) as usize] != self.value)
    }
}

pub(crate) fn run(
    image: &mut BinaryImage,
    mut noise: NoiseCache,
    phase: &mut Phase,
    mut apart: Option<&mut Apart>,
    steps: u32,
    max_distance: u32,
    seed: u64,
) -> DeformReport {
    let dim = image.dim();
    let d = dim.get();
    let tester = SimpleTester::new(dim);
    // Sources and targets are in the box, which keeps off the outermost layer, so their
    // configurations are read straight from the voxel bytes; the answers are memoised
    // (a pure function of the configuration: it changes no result, only its cost).
    let mut memo = SimpleCache::new(crate::morphology::MEMO_BITS);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(MOVES_STREAM);
    let mut shape = [1usize; 4];
    shape[..d].copy_from_slice(image.shape());
    let geometry = Geometry {
        layout: Layout::new(image, phase),
        value: phase.value,
        faces: flat_offsets(image, &face_offsets(dim)),
    };
    let (inside, outside) = (phase.value, phase.other());
    if steps == 0 || geometry.layout.is_empty() {
        return DeformReport {
            applied: 0,
            rejected: 0,
            iterations: 0,
            foreground_before: 0,
            foreground_after: 0,
        };
    }

    // Target offsets: the Chebyshev ball of radius m without its centre, in lexicographic
    // order (the order only breaks exact noise ties, but it must be fixed).
    let m = max_distance as i64;
    let strides = image.strides().to_vec();
    let ball = chebyshev_ball(image, m);

    // Voxels whose state can change whether a source succeeds: the Chebyshev ball of
    // radius m + 1 around a flipped voxel, centre included (m + 1 + the gap when components
    // are kept apart: a target's separation test reads that far), scanned as rows along
    // the last axis (offsets of the leading axes here; the row spans -reach ..= reach on
    // the last).
    let reach = m + 1 + apart.as_deref().map_or(0, Apart::gap);
    let reach_side = 2 * reach + 1;
    let mut refresh_rows: Vec<([i64; 4], isize)> = Vec::new();
    for k in 0..reach_side.pow(d as u32 - 1) {
        let mut off = [0i64; 4];
        let mut rest = k;
        for axis in (0..d - 1).rev() {
            off[axis] = rest % reach_side - reach;
            rest /= reach_side;
        }
        // In units of rows: every leading stride is a multiple of the row length.
        let rows = (0..d - 1)
            .map(|a| off[a] as isize * (strides[a] / shape[d - 1]) as isize)
            .sum();
        refresh_rows.push((off, rows));
    }
    let mut stuck = BitSet::new(image.len());
    let mut n_stuck = 0usize;
    // Stuck voxels per row along the last axis: a small array that is cheap to consult,
    // where reading `stuck` itself over a 4D ball costs a cache miss per row.
    let row_len = shape[d - 1];
    let mut stuck_in_row = vec![0u32; image.len() / row_len];

    let mut boundary = BoundarySet {
        list: Vec::new(),
        slot: FxHashMap::default(),
    };
    for v in geometry.layout.frontier(image, inside) {
        boundary.insert(v);
    }

    let max_attempts = steps as u64 * ATTEMPTS_PER_MOVE + 1024;
    let (mut applied, mut rejected, mut attempts) = (0u64, 0u64, 0u64);
    let mut candidates: Vec<(f32, usize)> = Vec::with_capacity(ball.len());
    while applied < steps as u64 && attempts < max_attempts && !boundary.list.is_empty() {
        attempts += 1;
        let mut source = boundary.list[index_below(&mut rng, boundary.list.len())];
        let mut source_noise = noise.get(source);
        for _ in 1..TOURNAMENT {
            let v = boundary.list[index_below(&mut rng, boundary.list.len())];
            let n = noise.get(v);
            if n < source_noise || (n == source_noise && v < source) {
                source = v;
                source_noise = n;
            }
        }
        if !memo.is_simple(
            &tester,
            tester.configuration_in(image.data(), &strides, source),
        ) {
            rejected += 1;
            stuck.insert(source);
            n_stuck += 1;
            stuck_in_row[source / row_len] += 1;
            boundary.remove(source);
            continue;
        }
        image.data_mut()[source] = outside;
        let source_label = apart.as_deref_mut().map_or(0, |a| a.leave(source));

        let c = image.coords(source);
        let (lo, hi) = (geometry.layout.lo, geometry.layout.hi);
        // Far enough from every face of the box, the whole ball is inside it.
        let deep =
            (0..d).all(|a| c[a] as i64 - m >= lo[a] as i64 && c[a] as i64 + m <= hi[a] as i64);
        candidates.clear();
        for (off, flat) in &ball {
            let in_box = deep
                || (0..d).all(|a| {
                    let x = c[a] as i64 + off[a];
                    x >= lo[a] as i64 && x <= hi[a] as i64
                });
            if !in_box {
                continue;
            }
            let z = (source as isize + flat) as usize;
            // Targets must touch the phase through a face: a voxel attached only by an
            // edge or corner is often simple, but moving voxels there grows one-voxel
            // diagonal hairs instead of bulges.
            let data = image.data();
            if data[z] == outside
                && geometry
                    .faces
                    .iter()
                    .any(|&f| data[(z as isize + f) as usize] == inside)
            {
                let n = noise.get(z);
                if n > source_noise {
                    candidates.push((n, z));
                }
            }
        }
        candidates.sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let target = candidates.iter().find_map(|&(_, z)| {
            if memo.is_simple(&tester, tester.configuration_in(image.data(), &strides, z)) {
                apart::joins(apart.as_deref(), phase, image, z).map(|label| (z, label))
            } else {
                None
            }
        });
        match target {
            Some((z, label)) => {
                image.data_mut()[z] = inside;
                phase.joined(geometry.layout.coords(z));
                if let Some(apart) = apart.as_deref_mut() {
                    apart.join(z, label);
                }
                applied += 1;
                for centre in [source, z] {
                    // Un-stick the stuck voxels this move may have freed.
                    let cc = image.coords(centre);
                    let last = d - 1;
                    let lo = (cc[last] as i64 - reach).max(0) as usize;
                    let hi = (cc[last] as i64 + reach).min(shape[last] as i64 - 1) as usize;
                    let centre_row = centre / row_len;
                    for (off, rows) in &refresh_rows {
                        if n_stuck == 0 {
                            break;
                        }
                        let inside = (0..last).all(|a| {
                            let x = cc[a] as i64 + off[a];
                            x >= 0 && x < shape[a] as i64
                        });
                        if !inside {
                            continue;
                        }
                        let row_id = (centre_row as isize + rows) as usize;
                        if stuck_in_row[row_id] == 0 {
                            continue;
                        }
                        let row = row_id * row_len;
                        for v in row + lo..=row + hi {
                            if stuck.remove(v) {
                                n_stuck -= 1;
                                stuck_in_row[row_id] -= 1;
                                if geometry.is_boundary(image, v) {
                                    boundary.insert(v);
                                }
                            }
                        }
                    }
                    // Being on the boundary only changes at the flipped voxel and its
                    // face-neighbours (which are inside the image: the centre is interior).
                    for v in std::iter::once(centre).chain(
                        geometry
                            .faces
                            .iter()
                            .map(|&f| (centre as isize + f) as usize),
                    ) {
                        if geometry.is_boundary(image, v) {
                            boundary.insert(v);
                        } else {
                            boundary.remove(v);
                        }
                    }
                }
            }
            None => {
                image.data_mut()[source] = inside;
                if let Some(apart) = apart.as_deref_mut() {
                    apart.join(source, source_label);
                }
                rejected += 1;
                stuck.insert(source);
                n_stuck += 1;
                stuck_in_row[source / row_len] += 1;
                boundary.remove(source);
            }
        }
    }
    DeformReport {
        applied,
        rejected,
        iterations: attempts,
        // The foreground counts are the caller's (`deform_phase_counted`).
        foreground_before: 0,
        foreground_after: 0,
    }
}
