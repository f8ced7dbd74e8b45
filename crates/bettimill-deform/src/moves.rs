//! Hypervolume-preserving moves (the paper's pixel-moving deformation, in any dimension).
//!
//! One move takes a foreground boundary voxel `x` (foreground, with a background
//! face-neighbour) and a background voxel `z` within Chebyshev distance `max_distance` of
//! it, with `noise(z) > noise(x)`, and flips both. It is applied only when `x` is simple in
//! the image and then `z` is simple in the image without `x`; the order matters when the
//! two are close, since deleting `x` changes `z`'s neighbourhood. Both flips are simple, so
//! topology is unchanged, and the foreground count is unchanged by construction.
//!
//! Choosing `x`: a tournament of [`TOURNAMENT`] random boundary voxels, lowest noise wins,
//! so the process prefers low-noise voxels without always hammering the single lowest one.
//! Choosing `z`: the highest-noise candidate that passes the test, among background voxels
//! with a foreground face-neighbour. Every move strictly
//! raises the sum of the noise over the foreground, so the process cannot cycle; when no
//! move is possible any more it stops early and the report says how many were applied.
//!
//! A source that fails (not simple, or no target) is marked stuck and leaves the draw
//! until a voxel within Chebyshev distance `max_distance + 1` of it changes: its own test
//! and those of all its possible targets only read voxels that close. Without this, a
//! tournament keeps picking the low-noise voxels on the downhill side of an object, whose
//! background neighbours all have lower noise, and most attempts are wasted.

use crate::field::NoiseCache;
use crate::DeformReport;
use bettimill_grid::neighbourhood::{face_offsets, flat_offsets};
use bettimill_grid::BinaryImage;
use bettimill_homology::simple::SimpleTester;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

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

/// The foreground voxels with a background face-neighbour, as a list that supports
/// uniform random draws plus a slot table for O(1) insertion and removal.
struct BoundarySet {
    list: Vec<usize>,
    // 0 = absent, otherwise position in `list` plus one.
    slot: Vec<u32>,
}

impl BoundarySet {
    fn insert(&mut self, v: usize) {
        if self.slot[v] == 0 {
            self.list.push(v);
            self.slot[v] = self.list.len() as u32;
        }
    }

    fn remove(&mut self, v: usize) {
        let s = self.slot[v];
        if s != 0 {
            let pos = s as usize - 1;
            let last = *self.list.last().expect("slot says the list is non-empty");
            self.list.swap_remove(pos);
            if last != v {
                self.slot[last] = s;
            }
            self.slot[v] = 0;
        }
    }
}

struct Geometry {
    shape: [usize; 4],
    d: usize,
    faces: Vec<isize>,
}

impl Geometry {
    fn interior(&self, image: &BinaryImage, v: usize) -> bool {
        let c = image.coords(v);
        (0..self.d).all(|a| c[a] >= 1 && c[a] + 1 < self.shape[a])
    }

    fn is_boundary(&self, image: &BinaryImage, v: usize) -> bool {
        let data = image.data();
        data[v] == 1
            && self.interior(image, v)
            && self
                .faces
                .iter()
                .any(|&f| data[(v as isize + f) as usize] == 0)
    }
}

pub(crate) fn run(
    image: &mut BinaryImage,
    mut noise: NoiseCache,
    steps: u32,
    max_distance: u32,
    seed: u64,
) -> DeformReport {
    let dim = image.dim();
    let d = dim.get();
    let foreground_before = image.count_foreground();
    let tester = SimpleTester::new(dim);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(MOVES_STREAM);
    let mut shape = [1usize; 4];
    shape[..d].copy_from_slice(image.shape());
    let geometry = Geometry {
        shape,
        d,
        faces: flat_offsets(image, &face_offsets(dim)),
    };

    // Target offsets: the Chebyshev ball of radius m without its centre, in lexicographic
    // order (the order only breaks exact noise ties, but it must be fixed).
    let m = max_distance as i64;
    let side = 2 * m + 1;
    let strides = image.strides().to_vec();
    let mut ball: Vec<([i64; 4], isize)> = Vec::new();
    for k in 0..side.pow(d as u32) {
        let mut off = [0i64; 4];
        let mut rest = k;
        for axis in (0..d).rev() {
            off[axis] = rest % side - m;
            rest /= side;
        }
        if off.iter().all(|&o| o == 0) {
            continue;
        }
        let flat = (0..d).map(|a| off[a] as isize * strides[a] as isize).sum();
        ball.push((off, flat));
    }

    // Voxels whose state can change whether a source succeeds: the Chebyshev ball of
    // radius m + 1 around a flipped voxel, centre included, scanned as rows along the last
    // axis (offsets of the leading axes here; the row spans -(m+1) ..= m+1 on the last).
    let reach = m + 1;
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
    let mut stuck = vec![false; image.len()];
    let mut n_stuck = 0usize;
    // Stuck voxels per row along the last axis: a small array that is cheap to consult,
    // where reading `stuck` itself over a 4D ball costs a cache miss per row.
    let row_len = shape[d - 1];
    let mut stuck_in_row = vec![0u32; image.len() / row_len];

    let mut boundary = BoundarySet {
        list: Vec::new(),
        slot: vec![0; image.len()],
    };
    crate::for_each_interior(image, |v| {
        if geometry.is_boundary(image, v) {
            boundary.insert(v);
        }
    });

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
        if !tester.is_simple(image, source) {
            rejected += 1;
            stuck[source] = true;
            n_stuck += 1;
            stuck_in_row[source / row_len] += 1;
            boundary.remove(source);
            continue;
        }
        image.data_mut()[source] = 0;

        let c = image.coords(source);
        // Far enough from every face, the whole ball is inside the editable region.
        let deep = (0..d).all(|a| c[a] as i64 > m && ((c[a] + 1) as i64 + m) < shape[a] as i64);
        candidates.clear();
        for (off, flat) in &ball {
            let inside = deep
                || (0..d).all(|a| {
                    let x = c[a] as i64 + off[a];
                    x >= 1 && x + 1 < shape[a] as i64
                });
            if !inside {
                continue;
            }
            let z = (source as isize + flat) as usize;
            // Targets must touch the foreground through a face: a voxel attached only by
            // an edge or corner is often simple, but moving voxels there grows one-voxel
            // diagonal hairs instead of bulges.
            let data = image.data();
            if data[z] == 0
                && geometry
                    .faces
                    .iter()
                    .any(|&f| data[(z as isize + f) as usize] == 1)
            {
                let n = noise.get(z);
                if n > source_noise {
                    candidates.push((n, z));
                }
            }
        }
        candidates.sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let target = candidates
            .iter()
            .map(|&(_, z)| z)
            .find(|&z| tester.is_simple(image, z));
        match target {
            Some(z) => {
                image.data_mut()[z] = 1;
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
                        for (v, is_stuck) in stuck
                            .iter_mut()
                            .enumerate()
                            .take(row + hi + 1)
                            .skip(row + lo)
                        {
                            if *is_stuck {
                                *is_stuck = false;
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
                image.data_mut()[source] = 1;
                rejected += 1;
                stuck[source] = true;
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
        foreground_before,
        foreground_after: image.count_foreground(),
    }
}
