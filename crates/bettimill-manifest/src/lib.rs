//! The manifest: a TOML file that declares a whole dataset.
//!
//! A manifest is the user's entire interface to a build, so parsing it is strict: unknown
//! fields, wrong types and impossible values are errors that name the file, the line and the
//! field, never silent defaults. The [`Manifest::canonical_hash`] identifies the dataset:
//! every sample seed is derived from it, so two manifests that differ only in comments,
//! whitespace or key order build identical bytes.
//!
//! Schema version 1 (see `docs/manifest.md` for every field with an example):
//!
//! ```toml
//! schema_version = 1
//! name = "demo-3d"          # shard file prefix: letters, digits, '-' and '_'
//! dimension = 3             # 2, 3 or 4
//! side = 32                 # voxels per axis
//! mode = ["embed", "carve"] # or a single string
//! samples = 240
//! shard_size = 40           # samples per shard
//! seed = 7
//! compression = "none"      # member compression: none, gzip, zstd
//!
//! [[classes]]
//! family = "ball"
//!
//! [[classes]]
//! family = "handle"
//! ```

use bettimill_grid::Dim;
use bettimill_shapes::{Family, Mode};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The manifest schema version this build of bettimill reads.
pub const SCHEMA_VERSION: u32 = 1;

/// The default manifest built by `bettimill build` with no argument: a small 3D demo.
pub const DEMO_MANIFEST: &str = include_str!("../../../manifests/demo-3d.toml");

/// A parsed and validated manifest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Must equal [`SCHEMA_VERSION`].
    pub schema_version: u32,
    /// Dataset name; prefix of every shard file.
    pub name: String,
    /// Number of axes.
    pub dimension: Dim,
    /// Voxels per axis.
    pub side: u32,
    /// Object in empty space, cavity in a solid cube, or both (a strata axis).
    pub mode: Modes,
    /// Total number of samples.
    pub samples: u64,
    /// Samples per shard. Exactly one of `shard_size` and `shard_bytes` is given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard_size: Option<u64>,
    /// Target shard size in bytes; the plan turns it into a fixed number of samples per
    /// shard from the uncompressed size of one sample, so shards never exceed it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard_bytes: Option<u64>,
    /// The dataset seed; with the rest of the manifest it determines every byte.
    pub seed: u64,
    /// Per-member compression inside the tar shards.
    #[serde(default)]
    pub compression: Compression,
    /// Named splits and their sizes; they must add up to `samples`. Default: all `train`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub splits: Option<std::collections::BTreeMap<String, u64>>,
    /// Strata axis: how many copies of the class object a sample holds (its b0 in embed
    /// mode). Default: one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub components: Option<Vec<u32>>,
    /// Strata axis: foreground voxel count bins, reached by topology-preserving growth or
    /// shrinking of every sample.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hypervolume: Option<HypervolumeBins>,
    /// Side lengths of downscaled copies stored with every sample, each with its own
    /// computed Betti numbers (max pooling; each must divide `side`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub resolutions: Vec<u32>,
    /// Optional topology-preserving deformation applied to every sample.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deform: Option<DeformSpec>,
    /// The label classes, expanded: an integer parameter written `[lo, hi]` or a list of
    /// strings becomes one class per value.
    #[serde(deserialize_with = "classes::expand")]
    pub classes: Vec<Family>,
}

/// Hypervolume bins, as written in the `[hypervolume]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HypervolumeBins {
    /// `fraction` (of side^d voxels) or `voxels`.
    #[serde(default)]
    pub unit: HypervolumeUnit,
    /// Half-open bins `[lo, hi)` in that unit.
    pub bins: Vec<[f64; 2]>,
}

/// The unit of hypervolume bins.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum HypervolumeUnit {
    /// A fraction of all voxels of the image.
    #[default]
    Fraction,
    /// A number of voxels.
    Voxels,
}

impl Manifest {
    /// The member compression actually used: `auto` resolved by the array size.
    pub fn member_compression(&self) -> Compression {
        match self.compression {
            Compression::Auto => {
                let voxels = (self.side as u64).pow(self.dimension.get() as u32);
                if voxels >= AUTO_COMPRESSION_THRESHOLD {
                    Compression::Gzip
                } else {
                    Compression::None
                }
            }
            other => other,
        }
    }

    /// Samples per shard, from `shard_size` or derived from `shard_bytes`.
    pub fn samples_per_shard(&self) -> u64 {
        match (self.shard_size, self.shard_bytes) {
            (Some(n), _) => n,
            (None, Some(bytes)) => (bytes / self.sample_bytes_estimate()).max(1),
            (None, None) => unreachable!("validation requires shard_size or shard_bytes"),
        }
    }

    /// Upper bound of one sample's bytes in a shard, uncompressed: tar headers and
    /// padding of every member, the arrays (with downscaled copies) and a generous label.
    pub fn sample_bytes_estimate(&self) -> u64 {
        let pad = |n: u64| 512 + n.div_ceil(512) * 512;
        let voxels = |side: u32| (side as u64).pow(self.dimension.get() as u32);
        let arrays: u64 = std::iter::once(self.side)
            .chain(self.resolutions.iter().copied())
            .map(|side| pad(128 + voxels(side)))
            .sum();
        arrays + pad(8192) + pad(16)
    }

    /// The voxel bounds `[lo, hi]` (inclusive) of each hypervolume bin.
    pub fn hypervolume_voxel_bins(&self) -> Vec<(u64, u64)> {
        let total = (self.side as u64).pow(self.dimension.get() as u32) as f64;
        self.hypervolume
            .as_ref()
            .map(|h| {
                h.bins
                    .iter()
                    .map(|&[lo, hi]| {
                        let (lo, hi) = match h.unit {
                            HypervolumeUnit::Fraction => (lo * total, hi * total),
                            HypervolumeUnit::Voxels => (lo, hi),
                        };
                        // Half-open [lo, hi) in voxels: the integers lo.ceil() ..= hi.ceil()-1.
                        (lo.ceil() as u64, (hi.ceil() as u64).saturating_sub(1))
                    })
                    .collect()
            })
            .unwrap_or_default()
    }

    /// The splits in a fixed order (`train`, `val`, `test`, then others alphabetically).
    pub fn split_sizes(&self) -> Vec<(String, u64)> {
        let Some(splits) = &self.splits else {
            return vec![("train".to_string(), self.samples)];
        };
        let rank = |name: &str| match name {
            "train" => 0,
            "val" | "validation" => 1,
            "test" => 2,
            _ => 3,
        };
        let mut out: Vec<(String, u64)> = splits.iter().map(|(k, &v)| (k.clone(), v)).collect();
        out.sort_by(|a, b| rank(&a.0).cmp(&rank(&b.0)).then(a.0.cmp(&b.0)));
        out
    }
}

/// One mode or a list of them.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Modes {
    /// `mode = "carve"`.
    One(Mode),
    /// `mode = ["embed", "carve"]`.
    Many(Vec<Mode>),
}

impl Modes {
    /// The modes as a list, in the order written.
    pub fn to_vec(&self) -> Vec<Mode> {
        match self {
            Modes::One(m) => vec![*m],
            Modes::Many(v) => v.clone(),
        }
    }
}

/// Per-member compression of the stored arrays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Compression {
    /// The default: plain `.npy` when one array is smaller than
    /// [`AUTO_COMPRESSION_THRESHOLD`] bytes (every client reads it, and tiny members gain
    /// little), `.npy.gz` from that size on (binary images shrink by one to two orders of
    /// magnitude, and webdataset and HF datasets both decode gzip without extra code).
    #[default]
    Auto,
    /// Plain `.npy` members (readable by every client).
    None,
    /// `.npy.gz` members (webdataset decodes them transparently).
    Gzip,
    /// `.npy.zst` members (HF datasets decodes them; webdataset needs a one-line decoder).
    Zstd,
}

/// Array size (bytes of voxels) from which `compression = "auto"` compresses: 1 MiB, a 4D
/// image of side 32 or a 3D image of side 102.
pub const AUTO_COMPRESSION_THRESHOLD: u64 = 1 << 20;

/// Deformation settings as written in the manifest's `[deform]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeformSpec {
    /// `moves` (hypervolume-preserving), `dilate` or `erode` (modified morphology).
    pub method: DeformMethod,
    /// Number of moves, or of morphology iterations.
    pub steps: u32,
    /// Spatial frequency of the Improved Noise field, in cycles per voxel.
    #[serde(default = "default_frequency")]
    pub noise_frequency: f64,
    /// Fractal octaves of the noise.
    #[serde(default = "default_octaves")]
    pub octaves: u32,
    /// How far (in voxels, Chebyshev) a moved voxel may travel.
    #[serde(default = "default_distance")]
    pub max_distance: u32,
    /// Probability that a simple candidate voxel grows during dilation.
    #[serde(default = "default_growth")]
    pub growth_probability: f64,
}

fn default_frequency() -> f64 {
    0.08
}
fn default_octaves() -> u32 {
    3
}
fn default_distance() -> u32 {
    1
}
fn default_growth() -> f64 {
    0.5
}

/// A deformation method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DeformMethod {
    /// Hypervolume-preserving moves of simple boundary voxels.
    Moves,
    /// Noise-modulated topology-preserving dilation.
    Dilate,
    /// Noise-modulated topology-preserving erosion.
    Erode,
}

/// `path:line`, or just `path` when no line is at fault (a missing field).
fn at_line(path: &std::path::Path, line: usize) -> String {
    if line == 0 {
        path.display().to_string()
    } else {
        format!("{}:{line}", path.display())
    }
}

/// Why a manifest was refused. Every variant names the file; parse and value errors also name
/// the line and the field.
#[derive(Debug, thiserror::Error)]
pub enum ManifestError {
    /// The file could not be read.
    #[error("cannot read manifest {path}: {source}")]
    Io {
        /// The manifest path.
        path: PathBuf,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// A field is missing, unknown, mistyped or has an impossible value.
    #[error("{}: field `{field}`: {reason}", at_line(path, *line))]
    Invalid {
        /// The manifest path (or `<embedded demo>`).
        path: PathBuf,
        /// 1-based line of the offending field (0 when the whole file is at fault).
        line: usize,
        /// The field, as written in the file.
        field: String,
        /// What is wrong and what would be accepted.
        reason: String,
    },
}

impl ManifestError {
    fn invalid(source: &Source<'_>, field: &str, reason: impl Into<String>) -> ManifestError {
        ManifestError::Invalid {
            path: source.path.to_path_buf(),
            line: source.line_of(field),
            field: field.to_string(),
            reason: reason.into(),
        }
    }
}

struct Source<'a> {
    path: &'a Path,
    text: &'a str,
}

impl Source<'_> {
    /// The 1-based line where `field` is assigned (`field = ...`), or 0 if it is absent.
    fn line_of(&self, field: &str) -> usize {
        let leaf = field.rsplit('.').next().unwrap_or(field);
        self.text
            .lines()
            .position(|line| {
                let line = line.trim_start();
                line.strip_prefix(leaf)
                    .map(|rest| rest.trim_start().starts_with('='))
                    .unwrap_or(false)
                    || line == format!("[{leaf}]")
                    || line == format!("[[{leaf}]]")
            })
            .map(|i| i + 1)
            .unwrap_or(0)
    }

    fn line_at(&self, offset: usize) -> usize {
        self.text[..offset.min(self.text.len())]
            .bytes()
            .filter(|&b| b == b'\n')
            .count()
            + 1
    }

    /// The key assigned on the line containing `offset`, or the innermost table header above.
    fn key_at(&self, offset: usize) -> String {
        let line_no = self.line_at(offset);
        let line = self.text.lines().nth(line_no - 1).unwrap_or("");
        if let Some((key, _)) = line.split_once('=') {
            let key = key.trim();
            if !key.is_empty() && !key.starts_with('[') {
                return key.to_string();
            }
        }
        let trimmed = line.trim();
        trimmed
            .trim_start_matches('[')
            .trim_end_matches(']')
            .trim()
            .to_string()
    }
}

impl Manifest {
    /// Reads and validates a manifest file.
    pub fn from_path(path: &Path) -> Result<Manifest, ManifestError> {
        let text = std::fs::read_to_string(path).map_err(|source| ManifestError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Manifest::parse(&text, path)
    }

    /// Parses and validates manifest text; `path` is only used in error messages.
    pub fn parse(text: &str, path: &Path) -> Result<Manifest, ManifestError> {
        let source = Source { path, text };
        let manifest: Manifest = toml::from_str(text).map_err(|err| {
            let (line, field) = match err.span() {
                Some(span) => (source.line_at(span.start), source.key_at(span.start)),
                None => (0, String::from("(file)")),
            };
            let field = unknown_field_name(err.message()).unwrap_or(field);
            ManifestError::Invalid {
                path: path.to_path_buf(),
                line,
                field,
                reason: err.message().trim().to_string(),
            }
        })?;
        manifest.validate(&source)?;
        Ok(manifest)
    }

    fn validate(&self, source: &Source<'_>) -> Result<(), ManifestError> {
        if self.schema_version != SCHEMA_VERSION {
            return Err(ManifestError::invalid(
                source,
                "schema_version",
                format!(
                    "this bettimill reads schema version {SCHEMA_VERSION}, the manifest says {}",
                    self.schema_version
                ),
            ));
        }
        if self.name.is_empty()
            || self.name.len() > 64
            || !self
                .name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
        {
            return Err(ManifestError::invalid(
                source,
                "name",
                format!(
                    "{:?} must be 1 to 64 letters, digits, '-' or '_' (it names the shard files)",
                    self.name
                ),
            ));
        }
        if self.side < 8 || self.side > 1024 {
            return Err(ManifestError::invalid(
                source,
                "side",
                format!("{} is outside the supported range 8..=1024", self.side),
            ));
        }
        let voxels = (self.side as u128).pow(self.dimension.get() as u32);
        if voxels > 1 << 32 {
            return Err(ManifestError::invalid(
                source,
                "side",
                format!(
                    "{}^{} = {voxels} voxels per sample is more than the 2^32 supported",
                    self.side, self.dimension
                ),
            ));
        }
        if self.samples == 0 {
            return Err(ManifestError::invalid(
                source,
                "samples",
                "must be at least 1",
            ));
        }
        match (self.shard_size, self.shard_bytes) {
            (Some(0), _) => {
                return Err(ManifestError::invalid(
                    source,
                    "shard_size",
                    "must be at least 1",
                ))
            }
            (Some(_), Some(_)) => {
                return Err(ManifestError::invalid(
                    source,
                    "shard_bytes",
                    "give either shard_size (samples) or shard_bytes, not both",
                ))
            }
            (None, None) => {
                return Err(ManifestError::invalid(
                    source,
                    "shard_size",
                    "missing: give shard_size (samples per shard) or shard_bytes",
                ))
            }
            (None, Some(bytes)) if bytes < self.sample_bytes_estimate() => {
                return Err(ManifestError::invalid(
                    source,
                    "shard_bytes",
                    format!(
                        "{bytes} bytes cannot hold one sample (about {} bytes each)",
                        self.sample_bytes_estimate()
                    ),
                ))
            }
            _ => {}
        }
        if let Some(splits) = &self.splits {
            let mut total: u64 = 0;
            for (name, &size) in splits {
                if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
                    return Err(ManifestError::invalid(
                        source,
                        name,
                        "split names are letters, digits and '_'",
                    ));
                }
                if size == 0 {
                    return Err(ManifestError::invalid(
                        source,
                        name,
                        "a split needs at least 1 sample",
                    ));
                }
                total = total.saturating_add(size);
            }
            if splits.is_empty() || total != self.samples {
                return Err(ManifestError::invalid(
                    source,
                    "splits",
                    format!(
                        "split sizes add up to {total}, but samples = {}",
                        self.samples
                    ),
                ));
            }
        }
        if let Some(components) = &self.components {
            if components.is_empty() || components.iter().any(|&c| c == 0 || c > 16) {
                return Err(ManifestError::invalid(
                    source,
                    "components",
                    "list 1 to 16 copies per sample, e.g. components = [1, 2, 3]",
                ));
            }
        }
        if let Some(h) = &self.hypervolume {
            let total = (self.side as u64).pow(self.dimension.get() as u32);
            if h.bins.is_empty() {
                return Err(ManifestError::invalid(source, "bins", "lists no bin"));
            }
            // The outer layer of the image is never foreground.
            let inner = (self.side as u64 - 2).pow(self.dimension.get() as u32);
            let limit = match h.unit {
                HypervolumeUnit::Fraction => 1.0,
                HypervolumeUnit::Voxels => total as f64,
            };
            for (&[lo, hi], &(vlo, vhi)) in h.bins.iter().zip(&self.hypervolume_voxel_bins()) {
                let reason = if !(lo.is_finite()
                    && hi.is_finite()
                    && 0.0 <= lo
                    && lo < hi
                    && hi <= limit)
                {
                    Some(format!(
                        "bin [{lo}, {hi}) must satisfy 0 <= lo < hi <= {limit}"
                    ))
                } else if vlo > vhi || vhi == 0 {
                    Some(format!(
                        "bin [{lo}, {hi}) holds no whole voxel count at side {} (it spans [{vlo}, {vhi}])",
                        self.side
                    ))
                } else if vlo > inner {
                    Some(format!(
                        "bin [{lo}, {hi}) needs at least {vlo} foreground voxels, but only {inner} fit inside the border at side {}",
                        self.side
                    ))
                } else {
                    None
                };
                if let Some(reason) = reason {
                    return Err(ManifestError::invalid(source, "bins", reason));
                }
            }
        }
        for &r in &self.resolutions {
            if r < 4 || r >= self.side || self.side % r != 0 {
                return Err(ManifestError::invalid(
                    source,
                    "resolutions",
                    format!(
                        "{r} must be at least 4, smaller than side {} and divide it",
                        self.side
                    ),
                ));
            }
        }
        if self.samples > 1_000_000_000 {
            return Err(ManifestError::invalid(
                source,
                "samples",
                "more than 10^9 samples is not supported",
            ));
        }
        let modes = self.mode.to_vec();
        if self.classes.len() > 10_000 {
            return Err(ManifestError::invalid(
                source,
                "classes",
                format!(
                    "expands to {} classes; at most 10000 are supported",
                    self.classes.len()
                ),
            ));
        }
        if modes.is_empty() {
            return Err(ManifestError::invalid(source, "mode", "lists no mode"));
        }
        let mut sorted = modes.clone();
        sorted.sort();
        sorted.dedup();
        if sorted.len() != modes.len() {
            return Err(ManifestError::invalid(source, "mode", "lists a mode twice"));
        }
        if self.classes.is_empty() {
            return Err(ManifestError::invalid(
                source,
                "classes",
                "at least one [[classes]] entry is needed",
            ));
        }
        let copies = self.components.clone().unwrap_or_else(|| vec![1]);
        for (i, class) in self.classes.iter().enumerate() {
            if self.classes[..i].contains(class) {
                return Err(ManifestError::invalid(
                    source,
                    "classes",
                    format!("class {} ({}) is listed twice", i + 1, class.label()),
                ));
            }
            // A class must be buildable in at least one combination of the other axes;
            // combinations that cannot be built are left out of the plan with a reason.
            let mut errors: Vec<String> = Vec::new();
            let mut feasible = false;
            for &mode in &modes {
                for &c in &copies {
                    let family = class_with_copies(class, c);
                    match family
                        .expected_betti(self.dimension, mode)
                        .and_then(|_| family.check_fits(self.dimension, self.side as usize, mode))
                    {
                        Ok(()) => feasible = true,
                        Err(err) => {
                            let err = err.to_string();
                            if !errors.contains(&err) {
                                errors.push(err);
                            }
                        }
                    }
                }
            }
            if !feasible {
                // Every reason, so that a class refused in two modes for two different
                // reasons (too big here, impossible there) says both.
                return Err(ManifestError::invalid(
                    source,
                    "classes",
                    format!("class {} ({}): {}", i + 1, class.label(), errors.join("; ")),
                ));
            }
        }
        if let Some(deform) = &self.deform {
            if !(deform.noise_frequency > 0.0 && deform.noise_frequency <= 1.0) {
                return Err(ManifestError::invalid(
                    source,
                    "deform.noise_frequency",
                    format!("{} must be in (0, 1]", deform.noise_frequency),
                ));
            }
            if !(0.0..=1.0).contains(&deform.growth_probability) {
                return Err(ManifestError::invalid(
                    source,
                    "deform.growth_probability",
                    format!("{} must be in [0, 1]", deform.growth_probability),
                ));
            }
            if deform.octaves == 0 || deform.octaves > 12 {
                return Err(ManifestError::invalid(
                    source,
                    "deform.octaves",
                    format!("{} must be in 1..=12", deform.octaves),
                ));
            }
            if deform.max_distance == 0 || deform.max_distance > 8 {
                return Err(ManifestError::invalid(
                    source,
                    "deform.max_distance",
                    format!("{} must be in 1..=8", deform.max_distance),
                ));
            }
        }
        Ok(())
    }

    /// The canonical JSON form: every field, defaults filled in, fixed key order. Comments,
    /// whitespace and the order of keys in the file do not change it.
    pub fn canonical_json(&self) -> String {
        serde_json::to_string(self).expect("a manifest always serialises")
    }

    /// blake3 of the canonical JSON, as 64 hex digits. Identifies the dataset.
    pub fn canonical_hash(&self) -> String {
        blake3::hash(self.canonical_json().as_bytes())
            .to_hex()
            .to_string()
    }
}

/// The class object repeated `copies` times: itself for one copy, else a scene (the
/// objects of a scene class are repeated).
pub fn class_with_copies(class: &Family, copies: u32) -> Family {
    if copies == 1 {
        return class.clone();
    }
    let one: Vec<Family> = match class {
        Family::Scene { objects } => objects.clone(),
        other => vec![other.clone()],
    };
    Family::Scene {
        objects: (0..copies).flat_map(|_| one.iter().cloned()).collect(),
    }
}

fn unknown_field_name(message: &str) -> Option<String> {
    let rest = message.strip_prefix("unknown field `")?;
    Some(rest.split('`').next()?.to_string())
}

mod classes;
#[cfg(test)]
mod tests;
