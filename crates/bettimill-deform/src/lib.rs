//! Topology-preserving deformations of binary images.
//!
//! This crate implements the deformations of the paper's "roadmap towards 4D
//! deformations" for 2D, 3D and 4D images, on top of the exact simple-point test of
//! `bettimill-homology`, and the growth along random paths that other topology data
//! generators use. Every method acts on a [`Phase`]: the part of the image that carries
//! its topology (the objects in embed mode, the cavities in carve mode), inside a box
//! that keeps the rest (a carved solid's outer boundary) as built.
//!
//! - [`Method::Moves`], volume-preserving moves: a boundary voxel of the phase at low
//!   noise is moved to a voxel outside it at higher noise within `max_distance`, only when
//!   both flips are simple. The phase bulges where the noise is high and narrows where it
//!   is low; its voxel count never changes.
//! - [`Method::Dilate`] and [`Method::Erode`], modified morphology: growth (shrinking) of
//!   the phase by the unit ball, where a voxel flips only when it is simple, and only the
//!   `growth_probability` fraction of the frontier with the highest (lowest) noise takes part
//!   in each iteration, so high-noise regions grow and low-noise regions do not ("lumpy"
//!   results). This is the simple-point generalisation of the paper's 2D hit-or-miss
//!   thickening and thinning: every flip a hit-or-miss structuring element may make
//!   without changing topology is a simple-point flip, and the simple-point test covers 3D
//!   and 4D without enumerating structuring elements.
//! - [`Method::Tentacles`] and [`Method::Walk`]: thick paths grown from the phase's
//!   surface along persistent or plain random walks (`walkers.rs`).
//! - [`Method::Pinch`]: necks, erosion confined to slabs across the phase (`pinch.rs`).
//! - [`target_hypervolume_phase`] brings the foreground count into `[lo, hi]` by the same
//!   noise-guided growth or shrinking of the phase.
//! - [`draw_settings`] turns a manifest's step, whose settings may be ranges, into one
//!   sample's settings.
//!
//! The objects to deform come from the shape library, `bettimill-shapes` (a
//! dev-dependency here: the tests, examples and benchmarks deform its scenes).
//!
//! Invariants shared by everything here:
//! - Topology is never changed: every flip is a simple-point flip applied to the image as
//!   it is at that moment, so the Betti numbers before and after are identical.
//! - Only voxels in the phase's box change, and the box never includes the outermost
//!   layer (the simple-point test needs every neighbour of a voxel to exist).
//! - Work and memory follow the phase's frontier, not the image: after one scan of the
//!   part of the box next to the phase (its extent, which a [`Phase`] keeps as the steps
//!   grow it), nothing visits or allocates per voxel of the image but bitsets (one bit a
//!   voxel) and, for a phase of two or more components, their labels ([`Apart`], a byte a
//!   voxel).
//! - Components of the phase that start a gap apart (at least [`APART`] background voxels,
//!   as placement leaves them) keep it when the caller passes an [`Apart`] made for that
//!   gap: growth never presses two objects or two cavities against each other.
//! - Results depend only on the input image, the settings and the seed: the randomness is
//!   `ChaCha8Rng`, the noise is `bettimill-noise`, and the only parallel step (simple-point
//!   decisions within one 3^d parity subfield, whose voxels are 3 apart and so cannot
//!   influence each other's test) gives the same answers on any number of threads.

mod apart;
mod clearance;
mod field;
pub mod hitmiss;
mod morphology;
mod moves;
mod phase;
mod pinch;
mod walkers;

use bettimill_grid::BinaryImage;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

pub use apart::{Apart, APART};
pub use bettimill_types::deform::{
    DeformSettings, DeformStep, Deformation, Method, Spread, DEFAULT_COUNT,
    DEFAULT_GROWTH_PROBABILITY, DEFAULT_MAX_DISTANCE, DEFAULT_NOISE_FREQUENCY, DEFAULT_OCTAVES,
    MAX_DISTANCE,
};
pub use morphology::{DEFAULT_TARGET_FREQUENCY, DEFAULT_TARGET_OCTAVES};
pub use phase::Phase;

/// The foreground count after `flipped` voxels of the other value became `to`: a flip
/// changes the count by one, so no pass over the image is needed. Debug builds check it
/// against a count.
fn foreground_after(image: &BinaryImage, before: u64, flipped: u64, to: u8) -> u64 {
    let after = if to == 1 {
        before + flipped
    } else {
        before - flipped
    };
    debug_assert_eq!(after, image.count_foreground(), "the flips were counted");
    after
}

/// What a deformation did (`Default`: nothing yet, counts to be filled in).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct DeformReport {
    /// Moves applied ([`Method::Moves`]) or voxels flipped (dilation, erosion, targeting).
    pub applied: u64,
    /// Candidates turned down: non-simple voxels, and for moves sources without a target.
    pub rejected: u64,
    /// Moves: attempts made. Morphology: iterations run.
    pub iterations: u64,
    /// Foreground voxels before.
    pub foreground_before: u64,
    /// Foreground voxels after.
    pub foreground_after: u64,
}

/// Why a deformation could not run. The image is unchanged whenever one is returned.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum DeformError {
    /// A setting is out of range.
    #[error("invalid deformation setting `{field}`: {reason}")]
    InvalidSetting {
        /// The field of [`DeformSettings`] (or argument) at fault.
        field: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// The noise could not be set up.
    #[error(transparent)]
    Noise(#[from] bettimill_noise::NoiseError),
    /// `lo > hi` in [`target_hypervolume`].
    #[error("hypervolume range [{lo}, {hi}] is empty")]
    EmptyRange {
        /// Requested lower bound.
        lo: u64,
        /// Requested upper bound.
        hi: u64,
    },
    /// Topology-preserving growth or shrinking stalled before reaching the range.
    #[error(
        "cannot bring the hypervolume from {start} into [{lo}, {hi}] without changing \
         topology: every frontier voxel is non-simple at {reached} foreground voxels"
    )]
    HypervolumeUnreachable {
        /// Foreground voxels at the start.
        start: u64,
        /// Requested lower bound.
        lo: u64,
        /// Requested upper bound.
        hi: u64,
        /// Where growth or shrinking stalled.
        reached: u64,
    },
}

/// Deforms the foreground of `image` in place without changing its topology (the
/// objects of embed mode; [`deform_phase`] with [`Phase::foreground`]).
///
/// Deterministic: the same image, settings and seed give the same result on any machine
/// and any number of threads. Returns an error (leaving the image untouched) only for
/// invalid settings.
pub fn deform(
    image: &mut BinaryImage,
    settings: &DeformSettings,
    seed: u64,
) -> Result<DeformReport, DeformError> {
    let mut phase = Phase::foreground(image);
    let mut apart = Apart::new(image, &phase);
    deform_phase(image, settings, &mut phase, apart.as_mut(), seed)
}

/// Deforms `phase` of `image` in place without changing its topology: grows, shrinks,
/// moves or extends the voxels of the phase's value inside its box, and nothing else.
///
/// With `apart` (made by [`Apart::new`] or [`Apart::keeping`] from the image before its
/// first step and passed to every step and to the targeting), the phase's components keep
/// its gap between them as they grow.
///
/// `phase` is made from `image` and passed to every step; each step records in it where
/// the phase grew (see [`Phase`]).
///
/// Deterministic: the same image, settings, phase and seed give the same result on any
/// machine and any number of threads. Returns an error (leaving the image untouched) only
/// for invalid settings.
pub fn deform_phase(
    image: &mut BinaryImage,
    settings: &DeformSettings,
    phase: &mut Phase,
    apart: Option<&mut Apart>,
    seed: u64,
) -> Result<DeformReport, DeformError> {
    let foreground = image.count_foreground();
    deform_phase_counted(image, settings, phase, apart, seed, foreground)
}

/// [`deform_phase`] for a caller that knows the image's foreground count `foreground`
/// (the count it built, or the previous step's [`DeformReport::foreground_after`]): a
/// sequence of steps then counts once, not once a step. The count must be right; debug
/// builds check it.
pub fn deform_phase_counted(
    image: &mut BinaryImage,
    settings: &DeformSettings,
    phase: &mut Phase,
    apart: Option<&mut Apart>,
    seed: u64,
    foreground: u64,
) -> Result<DeformReport, DeformError> {
    debug_assert_eq!(
        foreground,
        image.count_foreground(),
        "the count is the image's"
    );
    settings
        .validate()
        .map_err(|err| DeformError::InvalidSetting {
            field: err.field,
            reason: err.reason,
        })?;
    phase.find_extent(image);
    let mut report = match settings.method {
        Method::Moves => {
            let noise =
                field::NoiseCache::new(image, seed, settings.noise_frequency, settings.octaves)?;
            moves::run(
                image,
                noise,
                phase,
                apart,
                settings.steps,
                settings.max_distance,
                seed,
            )
        }
        Method::Dilate | Method::Erode => morphology::run(
            image,
            &mut morphology::Morphology {
                phase,
                grow: settings.method == Method::Dilate,
                steps: settings.steps,
                growth_probability: settings.growth_probability,
                noise_frequency: settings.noise_frequency,
                octaves: settings.octaves,
                seed,
                slab: None,
            },
            apart,
        )?,
        Method::Pinch => pinch::run(image, phase, apart, settings, seed)?,
        Method::Tentacles | Method::Walk => walkers::run(
            image,
            phase,
            apart,
            settings.count,
            settings.steps,
            settings.method == Method::Tentacles,
            seed,
        ),
    };
    // The runners count flips; the foreground count follows from them (a move flips one
    // voxel each way, the other methods flip voxels into the value they grow).
    let to = match settings.method {
        Method::Moves => None,
        Method::Dilate | Method::Tentacles | Method::Walk => Some(phase.value),
        Method::Erode | Method::Pinch => Some(phase.other()),
    };
    report.foreground_before = foreground;
    report.foreground_after = match to {
        Some(to) => foreground_after(image, foreground, report.applied, to),
        None => foreground_after(image, foreground, 0, 1),
    };
    Ok(report)
}

/// How far from the phase one step with `settings` can change a voxel: every voxel it
/// flips lies within this Chebyshev distance of the phase as it was before the step. A
/// sequence of steps reaches at most the sum of its steps' reaches, so a carved solid's
/// voxels farther than that from every cavity are never touched.
///
/// Per method: an iteration of dilation adds one layer of the frontier (distance 1); an
/// erosion or a neck only removes phase voxels (0); a move's target has a face neighbour in the
/// phase (1 per move); a tentacle or walker starts on the frontier and paints a ball of
/// radius 1 around each of its unit-distance steps (`steps + 2`).
pub fn reach(settings: &DeformSettings) -> u64 {
    let steps = u64::from(settings.steps);
    match settings.method {
        Method::Dilate | Method::Moves => steps,
        Method::Erode | Method::Pinch => 0,
        Method::Tentacles | Method::Walk => {
            if settings.count == 0 {
                0
            } else {
                steps + 2
            }
        }
    }
}

/// The settings one sample applies for `step`: each range drawn uniformly from `seed`
/// (integers inclusive; reals rounded to six decimals, so a label records them exactly).
pub fn draw_settings(step: &DeformStep, seed: u64) -> DeformSettings {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut int = |spread: &Spread<u32>| match *spread {
        Spread::One(v) => v,
        Spread::Range([lo, hi]) => (lo as u64 + rng.gen_range(0..=(hi - lo) as u64)) as u32,
    };
    let steps = int(&step.steps);
    let count = int(&step.count);
    let mut real = |spread: &Spread<f64>| match *spread {
        Spread::One(v) => v,
        Spread::Range([lo, hi]) => {
            let u = (rng.gen::<u64>() >> 11) as f64 / (1u64 << 53) as f64;
            (libm::round((lo + (hi - lo) * u) * 1e6) / 1e6).clamp(lo, hi)
        }
    };
    let noise_frequency = real(&step.noise_frequency);
    let growth_probability = real(&step.growth_probability);
    DeformSettings {
        method: step.method,
        steps,
        noise_frequency,
        octaves: step.octaves,
        max_distance: step.max_distance,
        growth_probability,
        count,
    }
}

/// Brings the foreground count into `[lo, hi]` by topology-preserving growth (if below)
/// or shrinking (if above) of the foreground ([`target_hypervolume_phase`] with
/// [`Phase::foreground`]).
pub fn target_hypervolume(
    image: &mut BinaryImage,
    lo: u64,
    hi: u64,
    seed: u64,
) -> Result<DeformReport, DeformError> {
    let mut phase = Phase::foreground(image);
    let goal = morphology::nearest_end(image.count_foreground(), lo, hi);
    let mut apart = Apart::new(image, &phase);
    morphology::target(image, lo, hi, goal, &mut phase, apart.as_mut(), seed)
}

/// Brings the foreground count into `[lo, hi]` by topology-preserving growth or
/// shrinking of `phase` (the cavities of carve mode shrink to raise the count and grow to
/// lower it), flipping frontier voxels of the phase's box one at a time in order of noise
/// (highest first when the phase grows, lowest first when it shrinks; noise of
/// [`DEFAULT_TARGET_FREQUENCY`] and [`DEFAULT_TARGET_OCTAVES`] seeded by `seed`). A count
/// outside the range moves to `goal` (clamped into the range) and stops there, or earlier
/// inside the range if the phase runs out of simple frontier voxels; a count inside the
/// range stays. A goal drawn per sample spreads a bin's samples over the bin, where
/// stopping at the first count inside would pile them on its ends.
///
/// With `apart`, growth keeps the phase's components apart as [`deform_phase`] does.
///
/// Fails, leaving the image (and `apart`) unchanged, when `lo > hi` or when no simple
/// frontier voxel is left before the range is reached (an empty phase cannot grow; a closed
/// curve cannot shrink).
pub fn target_hypervolume_phase(
    image: &mut BinaryImage,
    lo: u64,
    hi: u64,
    goal: u64,
    phase: &mut Phase,
    apart: Option<&mut Apart>,
    seed: u64,
) -> Result<DeformReport, DeformError> {
    morphology::target(image, lo, hi, goal, phase, apart, seed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drawn_settings_stay_in_their_ranges_and_vary_with_the_seed() {
        let step = DeformStep {
            steps: Spread::Range([2, 9]),
            noise_frequency: Spread::Range([0.05, 0.2]),
            growth_probability: Spread::Range([0.3, 0.6]),
            count: Spread::Range([1, 4]),
            ..DeformStep::new(Method::Tentacles, 0)
        };
        let drawn: Vec<DeformSettings> = (0..64).map(|seed| draw_settings(&step, seed)).collect();
        for s in &drawn {
            assert!((2..=9).contains(&s.steps), "{s:?}");
            assert!((0.05..=0.2).contains(&s.noise_frequency), "{s:?}");
            assert!((0.3..=0.6).contains(&s.growth_probability), "{s:?}");
            assert!((1..=4).contains(&s.count), "{s:?}");
            assert_eq!(s.validate(), Ok(()));
        }
        let steps: std::collections::BTreeSet<u32> = drawn.iter().map(|s| s.steps).collect();
        assert_eq!(
            steps.len(),
            8,
            "every value of the range is drawn: {steps:?}"
        );
        assert_eq!(draw_settings(&step, 7), draw_settings(&step, 7));
        // One value draws itself.
        let fixed = DeformStep::new(Method::Dilate, 3);
        assert_eq!(
            draw_settings(&fixed, 11),
            DeformSettings::new(Method::Dilate, 3)
        );
    }

    #[test]
    fn a_phase_kept_by_its_steps_finds_the_frontier_a_fresh_one_finds() {
        use crate::phase::Layout;
        // Two balls in a 4D image (embed) and a cavity in a solid (carve); every method
        // and the targeting grow the phase somewhere, and the extent it records must hold
        // all of it: the frontiers are those of a phase found afresh.
        let side = 20;
        let mut objects = BinaryImage::zeros(&[side; 4]).unwrap();
        let mut solid = BinaryImage::zeros(&[side; 4]).unwrap();
        for v in 0..objects.len() {
            let c = objects.coords(v);
            let dist = |centre: i64| c.iter().map(|&x| (x as i64 - centre).pow(2)).sum::<i64>();
            objects.data_mut()[v] = (dist(6) <= 9 || dist(13) <= 4) as u8;
            let inside = c.iter().all(|&x| (2..side - 2).contains(&x));
            solid.data_mut()[v] = (inside && dist(9) > 9) as u8;
        }
        let fresh = |image: &BinaryImage, phase: &Phase| {
            if phase.value == 1 {
                Phase::foreground(image)
            } else {
                Phase::cavities(image, &phase.lo, &phase.hi)
            }
        };
        let check = |image: &BinaryImage, phase: &Phase, what: &str| {
            for flip_from in [0, 1] {
                assert_eq!(
                    Layout::new(image, phase).frontier(image, flip_from),
                    Layout::new(image, &fresh(image, phase)).frontier(image, flip_from),
                    "{what}: value {} from {flip_from}",
                    phase.value
                );
            }
        };
        let cases = [
            (objects.clone(), Phase::foreground(&objects)),
            (
                solid.clone(),
                Phase::cavities(&solid, &[3; 4], &[side - 4; 4]),
            ),
        ];
        for (mut image, mut phase) in cases {
            let methods = [
                Method::Dilate,
                Method::Tentacles,
                Method::Moves,
                Method::Erode,
            ];
            for (i, method) in methods.into_iter().enumerate() {
                let steps = if method == Method::Moves { 200 } else { 3 };
                let settings = DeformSettings {
                    growth_probability: 0.5,
                    count: 3,
                    ..DeformSettings::new(method, steps)
                };
                deform_phase(&mut image, &settings, &mut phase, None, i as u64).unwrap();
                check(&image, &phase, &format!("{method:?}"));
            }
            // The phase grows by 40 voxels: the foreground rises for objects, falls for
            // cavities.
            let goal = if phase.value == 1 {
                image.count_foreground() + 40
            } else {
                image.count_foreground() - 40
            };
            target_hypervolume_phase(&mut image, goal, goal, goal, &mut phase, None, 3).unwrap();
            check(&image, &phase, "targeting");
        }
    }

    /// A 3D U: two arms joined by a base, six voxels apart; the narrowest background run
    /// between the arms (along x, over the rows above the base) after `grow`.
    fn gap_after(grow: impl Fn(&mut BinaryImage, &mut Phase)) -> usize {
        let side = 24;
        let mut image = BinaryImage::zeros(&[side; 3]).unwrap();
        for v in 0..image.len() {
            let [x, y, z, _] = image.coords(v);
            let arm = (4..8).contains(&x) || (14..18).contains(&x);
            let base = (4..18).contains(&x) && (4..8).contains(&y);
            image.data_mut()[v] =
                ((arm || base) && (4..20).contains(&y) && (6..18).contains(&z)) as u8;
        }
        let mut phase = Phase::foreground(&image);
        grow(&mut image, &mut phase);
        let mut narrowest = side;
        for y in 9..20 {
            for z in 7..17 {
                let run = (8..14).filter(|&x| !image.get(&[x, y, z])).count();
                narrowest = narrowest.min(run);
            }
        }
        narrowest
    }

    #[test]
    fn growth_with_a_clearance_leaves_gaps_open_that_plain_growth_fills() {
        let dilate = |clearance: u32| {
            gap_after(|image, phase| {
                *phase = phase.with_clearance(clearance);
                deform_phase(
                    image,
                    &DeformSettings::new(Method::Dilate, 8),
                    phase,
                    None,
                    3,
                )
                .unwrap();
            })
        };
        // Filling a U's gap keeps it a ball, so plain growth closes it.
        assert_eq!(dilate(0), 0);
        assert_eq!(dilate(1), 0);
        let kept = dilate(4);
        assert!((2..=6).contains(&kept), "gap {kept}");
        let target = |clearance: u32| {
            gap_after(|image, phase| {
                *phase = phase.with_clearance(clearance);
                let goal = image.count_foreground() + 3500;
                target_hypervolume_phase(image, goal, goal, goal, phase, None, 5)
                    .unwrap_or_else(|e| panic!("clearance {clearance}: {e}"));
                assert_eq!(image.count_foreground(), goal);
            })
        };
        let filled = target(0);
        assert!(filled <= 1, "gap {filled}");
        let kept = target(4);
        assert!((2..=6).contains(&kept), "gap {kept}");
    }

    #[test]
    fn the_leaf_crate_and_the_noise_agree_on_the_octave_limit() {
        assert_eq!(bettimill_types::MAX_OCTAVES, bettimill_noise::MAX_OCTAVES);
    }
}
