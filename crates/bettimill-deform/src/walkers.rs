//! Growth along random paths: tentacles and random-walk bodies.
//!
//! Both start from voxels just outside the phase (on its frontier) and paint a thick path
//! into the other phase: at every step the walker's voxel and its face neighbours (a ball
//! of radius 1, three voxels across) join the phase, each only when the flip is simple in
//! the image as it is at that moment. A flip that would join two parts of the phase, or
//! close a loop, is not simple and is skipped, so a path that runs into another part of the
//! phase stops there instead of changing the topology.
//!
//! - Tentacles keep a direction: it starts pointing away from the phase and turns a
//!   little at each step (a persistent random walk), which gives long thin protrusions,
//!   the tentacles of the paper's 3D examples.
//! - Walk bodies take unit steps along a random axis each time: the path folds back on
//!   itself into a lumpy, branching outgrowth, like the random-walk "octopus" bodies of
//!   earlier topology data generators.
//!
//! Everything random comes from one ChaCha8 stream of the seed, drawn in a fixed order,
//! and the walkers run one after the other, so the result is the same on any machine and
//! thread count.

use crate::apart::{self, Apart};
use crate::phase::{Layout, Phase};
use crate::DeformReport;
use bettimill_grid::BinaryImage;
use bettimill_homology::simple::SimpleTester;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The rand_chacha stream of the walkers (see `moves::MOVES_STREAM`).
const WALK_STREAM: u64 = 3;

/// How far a tentacle's direction turns per step: the standard deviation of the random
/// vector added to its unit direction.
const TURN: f64 = 0.3;

/// Passes over a step's ball: a voxel whose only link to the phase is another voxel of
/// the same ball becomes simple once that one has flipped.
const PASSES: usize = 2;

/// A uniform draw in (0, 1], from 53 random bits (never 0, so its logarithm is finite).
pub(crate) fn unit_open(rng: &mut ChaCha8Rng) -> f64 {
    ((rng.gen::<u64>() >> 11) as f64 + 1.0) / (1u64 << 53) as f64
}

/// A standard normal draw (Box-Muller, with libm so every machine gives the same bits).
pub(crate) fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let (u1, u2) = (unit_open(rng), unit_open(rng));
    libm::sqrt(-2.0 * libm::log(u1)) * libm::cos(2.0 * std::f64::consts::PI * u2)
}

pub(crate) fn normalise(v: &mut [f64; 4], d: usize) -> bool {
    let norm = libm::sqrt(v[..d].iter().map(|x| x * x).sum::<f64>());
    if norm < 1e-9 {
        return false;
    }
    for x in v[..d].iter_mut() {
        *x /= norm;
    }
    true
}

struct Painter<'a> {
    layout: Layout,
    tester: &'a SimpleTester,
    apart: Option<&'a mut Apart>,
    /// The phase painted, which records where it grew.
    phase: &'a mut Phase,
    value: u8,
    report: DeformReport,
}

impl Painter<'_> {
    /// Adds the ball of radius 1 around `centre` to the phase where the flips are simple;
    /// returns whether `centre` is in the phase afterwards.
    fn paint(&mut self, image: &mut BinaryImage, centre: [i64; 4]) -> bool {
        let d = self.layout.d;
        for _ in 0..PASSES {
            let mut flipped = false;
            // The centre first, then its face neighbours in a fixed order.
            for k in 0..=2 * d {
                let mut c = centre;
                if k > 0 {
                    c[(k - 1) / 2] += if k % 2 == 1 { -1 } else { 1 };
                }
                if !self.layout.in_box_signed(&c) {
                    continue;
                }
                let v = self.layout.index(&c.map(|x| x as usize));
                if image.data()[v] == self.value {
                    continue;
                }
                let label = if self.tester.is_simple(image, v) {
                    apart::joins(self.apart.as_deref(), self.phase, image, v)
                } else {
                    None
                };
                if let Some(label) = label {
                    image.data_mut()[v] = self.value;
                    self.phase.joined(self.layout.coords(v));
                    if let Some(apart) = self.apart.as_deref_mut() {
                        apart.join(v, label);
                    }
                    self.report.applied += 1;
                    flipped = true;
                } else {
                    self.report.rejected += 1;
                }
            }
            if !flipped {
                break;
            }
        }
        let c = centre.map(|x| x.max(0) as usize);
        self.layout.in_box_signed(&centre) && image.data()[self.layout.index(&c)] == self.value
    }
}

/// Grows `count` tentacles (`persistent`) or random-walk bodies of `steps` steps each from
/// the phase's frontier.
pub(crate) fn run(
    image: &mut BinaryImage,
    phase: &mut Phase,
    apart: Option<&mut Apart>,
    count: u32,
    steps: u32,
    persistent: bool,
    seed: u64,
) -> DeformReport {
    let layout = Layout::new(image, phase);
    let (value, other) = (phase.value, phase.other());
    let mut painter = Painter {
        tester: &SimpleTester::new(image.dim()),
        apart,
        value,
        phase,
        // The foreground counts are the caller's (`deform_phase_counted`).
        report: DeformReport::default(),
        layout,
    };
    if steps == 0 || count == 0 || painter.layout.is_empty() {
        return painter.report;
    }
    let d = painter.layout.d;
    let starts = painter.layout.frontier(image, other);
    if starts.is_empty() {
        return painter.report;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(WALK_STREAM);
    for _ in 0..count {
        let start = starts[crate::moves::index_below(&mut rng, starts.len())];
        let coords = painter.layout.coords(start);
        let mut position = [0f64; 4];
        let mut at = [0i64; 4];
        for a in 0..d {
            position[a] = coords[a] as f64;
            at[a] = coords[a] as i64;
        }
        // Away from the phase: minus the sum of the directions to the start's neighbours
        // in the phase, turned by a random vector so that flat faces do not all send
        // their tentacles straight out.
        let mut direction = [0f64; 4];
        for (a, dir) in direction.iter_mut().enumerate().take(d) {
            let s = painter.layout.strides[a];
            let data = image.data();
            if data[start - s] == value {
                *dir += 1.0;
            }
            if data[start + s] == value {
                *dir -= 1.0;
            }
        }
        for x in direction[..d].iter_mut() {
            *x += 0.5 * normal(&mut rng);
        }
        if !normalise(&mut direction, d) {
            direction[0] = 1.0;
        }
        if !painter.paint(image, at) {
            continue;
        }
        for _ in 0..steps {
            painter.report.iterations += 1;
            let mut next = at;
            if persistent {
                for x in direction[..d].iter_mut() {
                    *x += TURN * normal(&mut rng);
                }
                if !normalise(&mut direction, d) {
                    break;
                }
                for a in 0..d {
                    position[a] += direction[a];
                    next[a] = libm::round(position[a]) as i64;
                }
            } else {
                let k = crate::moves::index_below(&mut rng, 2 * d);
                next[k / 2] += if k.is_multiple_of(2) { -1 } else { 1 };
            }
            if !painter.layout.in_box_signed(&next) {
                if persistent {
                    break;
                }
                continue;
            }
            if painter.paint(image, next) {
                at = next;
            } else if persistent {
                // Blocked: the tentacle would touch another part of the phase.
                break;
            }
        }
    }
    painter.report
}
