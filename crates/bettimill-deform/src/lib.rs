//! Topology-preserving deformations of binary images.
//!
//! This crate implements the two deformations of the paper's "roadmap towards 4D
//! deformations" for 2D, 3D and 4D images, on top of the exact simple-point test of
//! `bettimill-homology`:
//!
//! - [`Method::Moves`], hypervolume-preserving moves: a foreground boundary voxel at low
//!   noise is moved to a background voxel at higher noise within `max_distance`, only when
//!   deleting it is simple and then adding the target (in the image without the source) is
//!   simple. The foreground count never changes.
//! - [`Method::Dilate`] and [`Method::Erode`], modified morphology: dilation (erosion) by the
//!   unit ball, where a voxel is added (removed) only when it is simple, and only the
//!   `growth_probability` fraction of the frontier with the highest (lowest) noise takes part
//!   in each iteration, so high-noise regions grow and low-noise regions do not ("lumpy"
//!   results). This is the simple-point generalisation of the paper's 2D hit-or-miss
//!   thickening and thinning: every flip a hit-or-miss structuring element may make
//!   without changing topology is a simple-point flip, and the simple-point test covers 3D
//!   and 4D without enumerating structuring elements.
//! - [`target_hypervolume`] brings the foreground count into `[lo, hi]` by the same
//!   topology-preserving growth or shrinking.
//!
//! The objects to deform come from the shape library, `bettimill-shapes` (a
//! dev-dependency here: the tests, examples and benchmarks deform its scenes).
//!
//! Invariants shared by everything here:
//! - Topology is never changed: every flip is a simple-point flip applied to the image as
//!   it is at that moment, so the Betti numbers before and after are identical.
//! - The outermost layer of voxels is never edited (the simple-point test needs every
//!   neighbour of a voxel to exist), so a background border stays background.
//! - Results depend only on the input image, the settings and the seed: the randomness is
//!   `ChaCha8Rng`, the noise is `bettimill-noise`, and the only parallel step (simple-point
//!   decisions within one 3^d parity subfield, whose voxels are 3 apart and so cannot
//!   influence each other's test) gives the same answers on any number of threads.

mod field;
pub mod hitmiss;
mod morphology;
mod moves;

use bettimill_grid::BinaryImage;
use serde::{Deserialize, Serialize};

pub use morphology::{DEFAULT_TARGET_FREQUENCY, DEFAULT_TARGET_OCTAVES};

/// The largest `max_distance` accepted; the target search visits (2m+1)^d voxels per move.
pub const MAX_DISTANCE: u32 = 8;

/// Which deformation [`deform`] applies.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Hypervolume-preserving moves; `steps` counts moves applied.
    Moves,
    /// Topology-preserving, noise-modulated dilation; `steps` counts iterations.
    Dilate,
    /// Topology-preserving, noise-modulated erosion; `steps` counts iterations.
    Erode,
}

/// Default [`DeformSettings::noise_frequency`].
pub const DEFAULT_NOISE_FREQUENCY: f64 = 0.08;
/// Default [`DeformSettings::octaves`].
pub const DEFAULT_OCTAVES: u32 = 3;
/// Default [`DeformSettings::max_distance`].
pub const DEFAULT_MAX_DISTANCE: u32 = 1;
/// Default [`DeformSettings::growth_probability`].
pub const DEFAULT_GROWTH_PROBABILITY: f64 = 0.5;

/// Everything that decides a deformation besides the image and the seed.
///
/// This is the one schema of deformation settings: the manifest's `[deform]` table is read
/// straight into it (so its defaults are the manifest's defaults), the `bettimill deform`
/// command fills it from its flags with the same defaults, and [`DeformSettings::validate`]
/// holds the one set of ranges. Its serialised form is the `deform` field of a label.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeformSettings {
    /// The deformation.
    pub method: Method,
    /// Moves to apply ([`Method::Moves`]) or iterations ([`Method::Dilate`],
    /// [`Method::Erode`]).
    pub steps: u32,
    /// Noise frequency in lattice cells per voxel, in (0, 1] (1/16 gives features ~16
    /// voxels wide).
    #[serde(default = "default_noise_frequency")]
    pub noise_frequency: f64,
    /// Octaves of fractal noise (1 ..= [`bettimill_noise::MAX_OCTAVES`]).
    #[serde(default = "default_octaves")]
    pub octaves: u32,
    /// Moves only: the largest Chebyshev distance between a moved voxel's old and new
    /// position (1 ..= [`MAX_DISTANCE`], checked for every method). 1 means a neighbour, as
    /// in the paper.
    #[serde(default = "default_max_distance")]
    pub max_distance: u32,
    /// Dilate and erode only: the fraction (0, 1] of the frontier allowed to flip in each
    /// iteration, the ones at the highest noise for dilation and the lowest for erosion.
    /// 1 is plain topology-preserving dilation (erosion).
    #[serde(default = "default_growth_probability")]
    pub growth_probability: f64,
}

fn default_noise_frequency() -> f64 {
    DEFAULT_NOISE_FREQUENCY
}
fn default_octaves() -> u32 {
    DEFAULT_OCTAVES
}
fn default_max_distance() -> u32 {
    DEFAULT_MAX_DISTANCE
}
fn default_growth_probability() -> f64 {
    DEFAULT_GROWTH_PROBABILITY
}

impl DeformSettings {
    /// `method` for `steps` with every other setting at its default.
    pub fn new(method: Method, steps: u32) -> DeformSettings {
        DeformSettings {
            method,
            steps,
            noise_frequency: DEFAULT_NOISE_FREQUENCY,
            octaves: DEFAULT_OCTAVES,
            max_distance: DEFAULT_MAX_DISTANCE,
            growth_probability: DEFAULT_GROWTH_PROBABILITY,
        }
    }
}

impl Default for DeformSettings {
    /// 600 hypervolume-preserving moves with the default settings.
    fn default() -> Self {
        DeformSettings::new(Method::Moves, 600)
    }
}

/// What a deformation did.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
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

impl DeformSettings {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), DeformError> {
        let bad = |field, reason: String| Err(DeformError::InvalidSetting { field, reason });
        if !(self.noise_frequency > 0.0 && self.noise_frequency <= 1.0) {
            return bad(
                "noise_frequency",
                format!("must be in (0, 1], got {}", self.noise_frequency),
            );
        }
        if self.octaves == 0 || self.octaves > bettimill_noise::MAX_OCTAVES {
            return bad(
                "octaves",
                format!(
                    "must be between 1 and {}, got {}",
                    bettimill_noise::MAX_OCTAVES,
                    self.octaves
                ),
            );
        }
        if !(1..=MAX_DISTANCE).contains(&self.max_distance) {
            return bad(
                "max_distance",
                format!(
                    "must be between 1 and {MAX_DISTANCE}, got {}",
                    self.max_distance
                ),
            );
        }
        if !(self.growth_probability > 0.0 && self.growth_probability <= 1.0) {
            return bad(
                "growth_probability",
                format!("must be in (0, 1], got {}", self.growth_probability),
            );
        }
        Ok(())
    }
}

/// Deforms `image` in place without changing its topology.
///
/// Deterministic: the same image, settings and seed give the same result on any machine
/// and any number of threads. Returns an error (leaving the image untouched) only for
/// invalid settings.
pub fn deform(
    image: &mut BinaryImage,
    settings: &DeformSettings,
    seed: u64,
) -> Result<DeformReport, DeformError> {
    settings.validate()?;
    let noise = field::NoiseCache::new(image, seed, settings.noise_frequency, settings.octaves)?;
    let report = match settings.method {
        Method::Moves => moves::run(image, noise, settings.steps, settings.max_distance, seed),
        Method::Dilate | Method::Erode => morphology::run(
            image,
            noise,
            settings.method == Method::Dilate,
            settings.steps,
            settings.growth_probability,
            seed,
        ),
    };
    Ok(report)
}

/// Brings the foreground count into `[lo, hi]` by topology-preserving growth (if below)
/// or shrinking (if above), flipping frontier voxels one at a time in order of noise
/// (highest first when growing, lowest first when shrinking; noise of
/// [`DEFAULT_TARGET_FREQUENCY`] and [`DEFAULT_TARGET_OCTAVES`] seeded by `seed`). It stops
/// as soon as the count reaches the range, so it lands exactly on `lo` or `hi`.
///
/// Fails, leaving the image unchanged, when `lo > hi` or when no simple frontier voxel is
/// left before the range is reached (an empty image cannot grow; a closed curve cannot
/// shrink).
pub fn target_hypervolume(
    image: &mut BinaryImage,
    lo: u64,
    hi: u64,
    seed: u64,
) -> Result<DeformReport, DeformError> {
    morphology::target(image, lo, hi, seed)
}

/// The flat indices of voxels at least one voxel away from every face, in increasing
/// order: the only voxels a deformation may edit.
pub(crate) fn for_each_interior(image: &BinaryImage, mut f: impl FnMut(usize)) {
    let shape = image.shape();
    let strides = image.strides();
    let d = shape.len();
    if shape.iter().any(|&n| n < 3) {
        return;
    }
    // Odometer over the leading axes, each in 1 ..= n-2.
    let mut coords = [1usize; 4];
    let last = shape[d - 1];
    loop {
        let base: usize = (0..d - 1).map(|a| coords[a] * strides[a]).sum();
        for i in 1..last - 1 {
            f(base + i);
        }
        let mut axis = d - 1;
        loop {
            if axis == 0 {
                return;
            }
            axis -= 1;
            coords[axis] += 1;
            if coords[axis] + 1 < shape[axis] {
                break;
            }
            coords[axis] = 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interior_iteration_visits_exactly_the_interior() {
        for shape in [vec![5usize, 4], vec![3, 6, 4], vec![4, 3, 5, 4], vec![2, 5]] {
            let image = BinaryImage::zeros(&shape).unwrap();
            let mut seen = Vec::new();
            for_each_interior(&image, |i| seen.push(i));
            let expected: Vec<usize> = (0..image.len())
                .filter(|&i| bettimill_grid::neighbourhood::is_interior(&image, i, 1))
                .collect();
            assert_eq!(seen, expected, "{shape:?}");
        }
    }

    #[test]
    fn settings_are_validated() {
        let ok = DeformSettings::default();
        assert_eq!(ok.validate(), Ok(()));
        for broken in [
            DeformSettings {
                noise_frequency: 0.0,
                ..ok.clone()
            },
            DeformSettings {
                octaves: 0,
                ..ok.clone()
            },
            DeformSettings {
                max_distance: 0,
                ..ok.clone()
            },
            DeformSettings {
                max_distance: MAX_DISTANCE + 1,
                ..ok.clone()
            },
            DeformSettings {
                growth_probability: f64::NAN,
                ..ok.clone()
            },
            DeformSettings {
                growth_probability: 1.5,
                ..ok.clone()
            },
            // The manifest once accepted 0 and every build attempt then failed.
            DeformSettings {
                growth_probability: 0.0,
                ..ok.clone()
            },
            DeformSettings {
                noise_frequency: 1.5,
                ..ok.clone()
            },
        ] {
            assert!(
                matches!(broken.validate(), Err(DeformError::InvalidSetting { .. })),
                "{broken:?}"
            );
        }
    }

    #[test]
    fn settings_round_trip_through_json_and_reject_unknown_fields() {
        let s = DeformSettings {
            method: Method::Dilate,
            ..DeformSettings::default()
        };
        let text = serde_json::to_string(&s).unwrap();
        assert!(text.contains("\"dilate\""), "{text}");
        let back: DeformSettings = serde_json::from_str(&text).unwrap();
        assert_eq!(back, s);
        let extra = text.replace('}', ",\"radius\":3}");
        assert!(serde_json::from_str::<DeformSettings>(&extra).is_err());
    }
}
