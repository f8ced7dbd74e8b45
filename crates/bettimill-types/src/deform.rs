//! The deformation schema: what a manifest asks for (`[[deform]]`, a sequence of steps
//! whose settings may be ranges) and what one sample was given (the drawn, concrete
//! [`DeformSettings`] its label records).
//!
//! A manifest writes either one `[deform]` table or an array of `[[deform]]` tables; both
//! read into a [`Deformation`], a sequence applied in order. Every numeric setting of a
//! step is a [`Spread`]: one value, or an inclusive range `[lo, hi]` from which each sample
//! draws its own value from its seed, so that one stratum holds a spread of strengths.
//! [`DeformStep::validate`] holds the one set of ranges, for the manifest and the
//! `bettimill deform` command alike.

use serde::{Deserialize, Serialize};

/// Which topology-preserving deformation a step applies. Every method acts on the phase
/// that carries the topology: the objects in embed mode, the cavities in carve mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Volume-preserving moves of boundary voxels from low to high noise: the phase bulges
    /// where the noise is high and narrows where it is low. `steps` counts moves.
    Moves,
    /// Noise-modulated growth of the phase ("lumpy" dilation). `steps` counts iterations.
    Dilate,
    /// Noise-modulated shrinking of the phase ("lumpy" erosion). `steps` counts iterations.
    Erode,
    /// Thin protrusions grown from the phase's surface along persistent random directions.
    /// `count` tentacles of `steps` voxels each.
    Tentacles,
    /// Random-walk bodies: `count` walkers each take `steps` unit steps from the phase's
    /// surface and add the voxels they cross, giving lumpy, branching outgrowths.
    Walk,
    /// Necks: `count` times, a slab three voxels thick across the phase, at a random
    /// direction and depth, inside which the phase shrinks as in [`Method::Erode`] for
    /// `steps` iterations. One part then looks like two blobs joined by a narrow neck.
    Pinch,
}

impl Method {
    /// The manifest's spelling.
    pub fn name(self) -> &'static str {
        match self {
            Method::Moves => "moves",
            Method::Dilate => "dilate",
            Method::Erode => "erode",
            Method::Tentacles => "tentacles",
            Method::Walk => "walk",
            Method::Pinch => "pinch",
        }
    }
}

/// Default noise frequency (lattice cells per voxel).
pub const DEFAULT_NOISE_FREQUENCY: f64 = 0.08;
/// Default fractal octaves of the noise.
pub const DEFAULT_OCTAVES: u32 = 3;
/// Default largest Chebyshev distance of one move.
pub const DEFAULT_MAX_DISTANCE: u32 = 1;
/// Default share of the frontier that may flip per dilation or erosion iteration.
pub const DEFAULT_GROWTH_PROBABILITY: f64 = 0.5;
/// Default number of tentacles or walkers.
pub const DEFAULT_COUNT: u32 = 4;

/// The largest `max_distance`; the target search of a move visits (2m+1)^d voxels.
pub const MAX_DISTANCE: u32 = 8;
/// The widest clearance a manifest may ask for; a joining voxel reads this far along
/// each of the 3^d - 1 directions.
pub const MAX_CLEARANCE: u32 = 8;

/// Checks a manifest's `clearance`: each value at most [`MAX_CLEARANCE`], a range written
/// `[low, high]`.
pub fn validate_clearance(clearance: &Spread<u32>) -> Result<(), SettingError> {
    check_range(
        "clearance",
        clearance,
        |v| v <= MAX_CLEARANCE,
        &format!("at most {MAX_CLEARANCE}"),
    )
}

/// The most fractal octaves the noise sums.
pub const MAX_OCTAVES: u32 = 24;
/// The most steps (moves, iterations, tentacle or walk length) one step may ask for.
pub const MAX_STEPS: u32 = 10_000_000;
/// The most tentacles or walkers one step may ask for.
pub const MAX_COUNT: u32 = 10_000;

/// One value, or an inclusive range `[lo, hi]` drawn per sample.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Spread<T> {
    /// The same value for every sample.
    One(T),
    /// Each sample draws its own value in `[lo, hi]` (inclusive) from its seed.
    Range([T; 2]),
}

impl<T: Copy + PartialOrd> Spread<T> {
    /// The inclusive bounds (`[v, v]` for one value).
    pub fn bounds(&self) -> (T, T) {
        match *self {
            Spread::One(v) => (v, v),
            Spread::Range([lo, hi]) => (lo, hi),
        }
    }

    /// The largest value a sample can draw.
    pub fn max(&self) -> T {
        self.bounds().1
    }
}

/// How the solid of carve mode is made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Solid {
    /// The full cube (one background layer on every face), as in the paper; the cavities
    /// alone bring the foreground count into its hypervolume bin.
    #[default]
    Cube,
    /// An axis-aligned box sized so that its volume puts the sample in its hypervolume
    /// bin, with small cavities inside.
    Box,
}

/// One step of a manifest's deformation sequence, with settings that may be ranges.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeformStep {
    /// The deformation.
    pub method: Method,
    /// Moves ([`Method::Moves`]), iterations ([`Method::Dilate`], [`Method::Erode`]) or
    /// voxels per tentacle or walker ([`Method::Tentacles`], [`Method::Walk`]), or
    /// iterations per neck ([`Method::Pinch`]); 0 skips the step for that sample.
    pub steps: Spread<u32>,
    /// Noise frequency in lattice cells per voxel, in (0, 1].
    #[serde(default = "default_noise_frequency")]
    pub noise_frequency: Spread<f64>,
    /// Octaves of fractal noise (1 ..= [`MAX_OCTAVES`]).
    #[serde(default = "default_octaves")]
    pub octaves: u32,
    /// Moves only: the largest Chebyshev distance a voxel travels (1 ..= [`MAX_DISTANCE`]).
    #[serde(default = "default_max_distance")]
    pub max_distance: u32,
    /// Dilate, erode and pinch: the share (0, 1] of the frontier that may flip per
    /// iteration, at the highest noise for dilation and the lowest for erosion.
    #[serde(default = "default_growth_probability")]
    pub growth_probability: Spread<f64>,
    /// Tentacles, walk and pinch: how many (1 ..= [`MAX_COUNT`]).
    #[serde(default = "default_count")]
    pub count: Spread<u32>,
}

fn default_noise_frequency() -> Spread<f64> {
    Spread::One(DEFAULT_NOISE_FREQUENCY)
}
fn default_octaves() -> u32 {
    DEFAULT_OCTAVES
}
fn default_max_distance() -> u32 {
    DEFAULT_MAX_DISTANCE
}
fn default_growth_probability() -> Spread<f64> {
    Spread::One(DEFAULT_GROWTH_PROBABILITY)
}
fn default_count() -> Spread<u32> {
    Spread::One(DEFAULT_COUNT)
}

/// A setting out of its range.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("invalid deformation setting `{field}`: {reason}")]
pub struct SettingError {
    /// The field at fault.
    pub field: &'static str,
    /// What is wrong with it.
    pub reason: String,
}

fn check_range<T: Copy + PartialOrd + std::fmt::Display>(
    field: &'static str,
    spread: &Spread<T>,
    ok: impl Fn(T) -> bool,
    wanted: &str,
) -> Result<(), SettingError> {
    let (lo, hi) = spread.bounds();
    for v in [lo, hi] {
        if !ok(v) {
            return Err(SettingError {
                field,
                reason: format!("must be {wanted}, got {v}"),
            });
        }
    }
    if lo > hi {
        return Err(SettingError {
            field,
            reason: format!("the range [{lo}, {hi}] is empty: write it as [low, high]"),
        });
    }
    Ok(())
}

impl DeformStep {
    /// `method` for `steps` with every other setting at its default.
    pub fn new(method: Method, steps: u32) -> DeformStep {
        DeformStep {
            method,
            steps: Spread::One(steps),
            noise_frequency: default_noise_frequency(),
            octaves: DEFAULT_OCTAVES,
            max_distance: DEFAULT_MAX_DISTANCE,
            growth_probability: default_growth_probability(),
            count: default_count(),
        }
    }

    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), SettingError> {
        check_range(
            "steps",
            &self.steps,
            |v| v <= MAX_STEPS,
            &format!("at most {MAX_STEPS}"),
        )?;
        check_range(
            "noise_frequency",
            &self.noise_frequency,
            |v| v > 0.0 && v <= 1.0,
            "in (0, 1]",
        )?;
        check_range(
            "octaves",
            &Spread::One(self.octaves),
            |v| (1..=MAX_OCTAVES).contains(&v),
            &format!("between 1 and {MAX_OCTAVES}"),
        )?;
        check_range(
            "max_distance",
            &Spread::One(self.max_distance),
            |v| (1..=MAX_DISTANCE).contains(&v),
            &format!("between 1 and {MAX_DISTANCE}"),
        )?;
        check_range(
            "growth_probability",
            &self.growth_probability,
            |v| v > 0.0 && v <= 1.0,
            "in (0, 1]",
        )?;
        check_range(
            "count",
            &self.count,
            |v| (1..=MAX_COUNT).contains(&v),
            &format!("between 1 and {MAX_COUNT}"),
        )
    }
}

/// A manifest's deformation: steps applied in order to every sample. Read from one
/// `[deform]` table or an array of `[[deform]]` tables; always written as an array.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(transparent)]
pub struct Deformation(pub Vec<DeformStep>);

impl<'de> Deserialize<'de> for Deformation {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        // A visitor rather than an untagged enum: an untagged enum hides the inner error
        // (an unknown field, a wrong type) behind "did not match any variant".
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = Deformation;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a [deform] table or an array of [[deform]] tables")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<Deformation, A::Error> {
                let mut steps = Vec::new();
                while let Some(step) = seq.next_element::<DeformStep>()? {
                    steps.push(step);
                }
                Ok(Deformation(steps))
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                map: A,
            ) -> Result<Deformation, A::Error> {
                let step =
                    DeformStep::deserialize(serde::de::value::MapAccessDeserializer::new(map))?;
                Ok(Deformation(vec![step]))
            }
        }
        deserializer.deserialize_any(Visitor)
    }
}

impl Deformation {
    /// Checks every step; the error names the step (`deform[1].steps`) when there are
    /// several.
    pub fn validate(&self) -> Result<(), (String, SettingError)> {
        if self.0.is_empty() {
            return Err((
                "deform".to_string(),
                SettingError {
                    field: "method",
                    reason: "the sequence lists no step".to_string(),
                },
            ));
        }
        for (i, step) in self.0.iter().enumerate() {
            step.validate().map_err(|err| {
                let at = if self.0.len() == 1 {
                    format!("deform.{}", err.field)
                } else {
                    format!("deform[{i}].{}", err.field)
                };
                (at, err)
            })?;
        }
        Ok(())
    }
}

/// One step as applied to one sample: every setting drawn. A label's `deform` field lists
/// these, in the order applied.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeformSettings {
    /// The deformation.
    pub method: Method,
    /// Moves, iterations (per neck for pinch), or voxels per tentacle or walker.
    pub steps: u32,
    /// Noise frequency in lattice cells per voxel, in (0, 1].
    pub noise_frequency: f64,
    /// Octaves of fractal noise.
    pub octaves: u32,
    /// Moves: the largest Chebyshev distance a voxel travels.
    pub max_distance: u32,
    /// Dilate, erode and pinch: the share of the frontier that may flip per iteration.
    pub growth_probability: f64,
    /// Tentacles, walk and pinch: how many.
    pub count: u32,
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
            count: DEFAULT_COUNT,
        }
    }
}

impl Default for DeformSettings {
    /// 600 volume-preserving moves with the default settings.
    fn default() -> Self {
        DeformSettings::new(Method::Moves, 600)
    }
}

impl DeformSettings {
    /// The same settings as a step of one value each.
    pub fn as_step(&self) -> DeformStep {
        DeformStep {
            method: self.method,
            steps: Spread::One(self.steps),
            noise_frequency: Spread::One(self.noise_frequency),
            octaves: self.octaves,
            max_distance: self.max_distance,
            growth_probability: Spread::One(self.growth_probability),
            count: Spread::One(self.count),
        }
    }

    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), SettingError> {
        self.as_step().validate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Deserialize)]
    struct Holder {
        deform: Deformation,
    }

    fn parse(text: &str) -> Result<Deformation, String> {
        toml::from_str::<Holder>(text)
            .map(|h| h.deform)
            .map_err(|e| e.to_string())
    }

    #[test]
    fn one_table_and_an_array_of_tables_both_read() {
        let one = parse("[deform]\nmethod = \"dilate\"\nsteps = 3\n").unwrap();
        assert_eq!(one, Deformation(vec![DeformStep::new(Method::Dilate, 3)]));
        let many = parse(
            "[[deform]]\nmethod = \"dilate\"\nsteps = [0, 12]\nnoise_frequency = [0.04, 0.1]\n\
             [[deform]]\nmethod = \"tentacles\"\nsteps = 20\ncount = [1, 3]\n",
        )
        .unwrap();
        assert_eq!(many.0.len(), 2);
        assert_eq!(many.0[0].steps, Spread::Range([0, 12]));
        assert_eq!(many.0[0].noise_frequency, Spread::Range([0.04, 0.1]));
        assert_eq!(many.0[1].count, Spread::Range([1, 3]));
        assert_eq!(many.validate(), Ok(()));
    }

    #[test]
    fn a_misspelt_field_is_named() {
        let err = parse("[deform]\nmethod = \"dilate\"\nstep = 3\n").unwrap_err();
        assert!(err.contains("step"), "{err}");
        let err = parse("[[deform]]\nmethod = \"spin\"\nsteps = 3\n").unwrap_err();
        assert!(err.contains("spin"), "{err}");
    }

    #[test]
    fn ranges_are_validated_and_the_step_is_named() {
        let bad = parse(
            "[[deform]]\nmethod = \"dilate\"\nsteps = 2\n\
             [[deform]]\nmethod = \"erode\"\nsteps = [5, 2]\n",
        )
        .unwrap();
        let (at, err) = bad.validate().unwrap_err();
        assert_eq!(at, "deform[1].steps");
        assert!(err.reason.contains("empty"), "{}", err.reason);
        let bad = parse("[deform]\nmethod = \"dilate\"\nsteps = 2\ngrowth_probability = [0, 1]\n")
            .unwrap();
        assert_eq!(bad.validate().unwrap_err().0, "deform.growth_probability");
        assert!(Deformation(Vec::new()).validate().is_err());
    }

    #[test]
    fn drawn_settings_round_trip_through_json_and_reject_unknown_fields() {
        let s = DeformSettings::new(Method::Walk, 40);
        let text = serde_json::to_string(&s).unwrap();
        assert!(text.contains("\"walk\""), "{text}");
        let back: DeformSettings = serde_json::from_str(&text).unwrap();
        assert_eq!(back, s);
        let extra = text.replace('}', ",\"radius\":3}");
        assert!(serde_json::from_str::<DeformSettings>(&extra).is_err());
    }
}
