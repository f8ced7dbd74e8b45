//! The manifest: a TOML file that declares a whole dataset.
//!
//! A manifest is the user's entire interface to a build, so parsing it is strict: unknown
//! fields, wrong types and impossible values are errors that name the file, the line and the
//! field, never silent defaults. This crate knows the syntax and the ranges of every field;
//! what the classes mean (which constructions exist, whether they fit) is decided once, by
//! the plan (`bettimill_plan::Plan::new`), which also computes the canonical hash that
//! identifies the dataset. Two manifests that differ only in comments, whitespace or key
//! order build identical bytes.
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

use bettimill_grid::{Dim, Mode};
use bettimill_types::MAX_4D_SIDE;
use bettimill_types::{Deformation, Solid, Spread};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The manifest schema version this build of bettimill reads.
pub const SCHEMA_VERSION: u32 = 1;

/// The default manifest built by `bettimill build` with no argument: a small 3D demo.
pub const DEMO_MANIFEST: &str = include_str!("../../../manifests/demo-3d.toml");

/// The manifests of the repository's `manifests/` directory, by name (the file stem), in
/// name order: built in, so that the Python package and the CLI reach them from anywhere.
pub const PRESETS: &[(&str, &str)] = &[
    (
        "4d-mixed-128",
        include_str!("../../../manifests/4d-mixed-128.toml"),
    ),
    ("demo-2d", include_str!("../../../manifests/demo-2d.toml")),
    ("demo-3d", DEMO_MANIFEST),
    ("demo-4d", include_str!("../../../manifests/demo-4d.toml")),
    (
        "paper-figures",
        include_str!("../../../manifests/paper-figures.toml"),
    ),
];

/// The text of the preset manifest `name` (see [`PRESETS`]).
pub fn preset(name: &str) -> Option<&'static str> {
    PRESETS
        .iter()
        .find(|(preset, _)| *preset == name)
        .map(|(_, text)| *text)
}

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
    pub compression: CompressionSetting,
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
    /// Carve mode: the solid the cavities are carved from, the full cube (default) or a
    /// box sized for the hypervolume bin.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solid: Option<Solid>,
    /// The narrowest gap, in voxels, that growth of the topological phase may leave
    /// between two of its parts that do not touch: across a hole, a cavity's wall, or
    /// between components. One value, or a range `[lo, hi]` drawn per sample; 0 or 1 (the
    /// default) leaves growth unrestricted. Gaps narrower at construction stay as built.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clearance: Option<Spread<u32>>,
    /// The narrowest gap, in voxels, that constructions leave between two parts of one
    /// object that must stay apart: across a hole, inside a shell or a 2-sphere, between
    /// the strands of a knot ([`bettimill_types::MIN_INNER_GAP`] to
    /// [`bettimill_types::MAX_INNER_GAP`]; default the minimum). Wider holes survive more
    /// dilations; `clearance` keeps growth from narrowing them again.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inner_gap: Option<f64>,
    /// How many dilations (Chebyshev steps) of the topological phase every sample's Betti
    /// numbers must survive, checked per sample: an attempt whose holes or gaps that many
    /// dilations close is made again (0 to [`MAX_SURVIVED_DILATIONS`]; default none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub survives_dilations: Option<u32>,
    /// Optional topology-preserving deformations applied in order to the phase that
    /// carries each sample's topology (one `[deform]` table or an array of `[[deform]]`
    /// tables; the schema, its defaults and ranges are `bettimill_types::deform`'s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deform: Option<Deformation>,
    /// The label classes, expanded: an integer parameter written `[lo, hi]` or a list of
    /// strings becomes one class per value. The plan's canonical form serialises this field
    /// last, so it must stay the last field.
    #[serde(deserialize_with = "classes::expand")]
    pub classes: Vec<ClassSpec>,
    /// Where the manifest came from, for error messages of later stages; not part of the
    /// dataset's identity.
    #[serde(skip)]
    pub origin: Origin,
}

/// The file a manifest was read from and its text, so that the plan can point at the line
/// of a field it refuses.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Origin {
    /// The manifest path (or `<embedded demo manifest>`).
    pub path: PathBuf,
    /// The manifest text.
    pub text: String,
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
    /// Voxels of one sample: side^dimension.
    pub fn voxels(&self) -> u64 {
        (self.side as u64).pow(self.dimension.get() as u32)
    }

    /// An error about `field` of this manifest, at the line where the field is written.
    pub fn error(&self, field: &str, reason: impl Into<String>) -> ManifestError {
        ManifestError::invalid(&self.origin.source(), field, reason)
    }

    /// An error about the `entry`-th (1-based) `[[classes]]` entry, at its header line.
    pub fn class_error(&self, entry: usize, reason: impl Into<String>) -> ManifestError {
        let line = self
            .origin
            .text
            .lines()
            .enumerate()
            .filter(|(_, l)| l.trim() == "[[classes]]")
            .nth(entry.saturating_sub(1))
            .map_or(0, |(i, _)| i + 1);
        ManifestError::Invalid {
            path: self.origin.path.clone(),
            line,
            field: "classes".to_string(),
            reason: printable(&reason.into()),
        }
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
pub enum CompressionSetting {
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

/// The most dilations a manifest's `survives_dilations` may ask for: as many as a
/// manifest's widest `clearance` keeps a gap open against from both sides.
pub const MAX_SURVIVED_DILATIONS: u32 = 4;

/// Array size (bytes of voxels) from which `compression = "auto"` compresses: 1 MiB, a 4D
/// image of side 32 or a 3D image of side 102.
pub const AUTO_COMPRESSION_THRESHOLD: u64 = 1 << 20;

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
            field: printable(field),
            reason: printable(&reason.into()),
        }
    }
}

/// `text` with control characters (NUL, newlines, escapes) written as escapes, so an error
/// about a hostile key stays one line of visible text.
fn printable(text: &str) -> String {
    if !text.chars().any(char::is_control) {
        return text.to_string();
    }
    text.chars()
        .map(|c| {
            if c.is_control() {
                c.escape_default().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}

/// A number from the manifest as a message shows it: as written for ordinary magnitudes,
/// in exponent form for tiny and huge ones (a subnormal's plain decimal form has hundreds
/// of digits).
pub(crate) fn short_float(x: f64) -> String {
    if x != 0.0 && x.is_finite() && (x.abs() < 1e-6 || x.abs() >= 1e16) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

struct Source<'a> {
    path: &'a Path,
    text: &'a str,
}

impl Origin {
    fn source(&self) -> Source<'_> {
        Source {
            path: &self.path,
            text: &self.text,
        }
    }
}

impl Source<'_> {
    /// The 0-based line of a quoted key with any characters, escapes and dots too
    /// (`"v\u0000al" = 2`, `"v.al" = 2`), that TOML reads as exactly `field`.
    fn quoted_key_line(&self, field: &str) -> Option<usize> {
        self.text.lines().position(|line| {
            let line = line.trim_start();
            (line.starts_with('"') || line.starts_with('\''))
                && line.split_once('=').is_some_and(|(key, _)| {
                    toml::from_str::<toml::Table>(&format!("{} = 0", key.trim()))
                        .is_ok_and(|table| table.len() == 1 && table.contains_key(field))
                })
        })
    }

    /// The 1-based line where `field` is assigned (`field = ...`), or 0 if it is absent.
    /// A field of the i-th entry of an array of tables (`deform[1].steps`) is searched from
    /// that entry's `[[deform]]` header on.
    fn line_of(&self, field: &str) -> usize {
        // A key written quoted (`"v.al" = 2`) is the whole field, not a dotted path whose
        // leaf (`al`) names another line.
        if !field.contains('[') {
            if let Some(at) = self.quoted_key_line(field) {
                return at + 1;
            }
        }
        let leaf = field.rsplit('.').next().unwrap_or(field);
        let skip = field
            .split_once('[')
            .and_then(|(table, rest)| {
                let index: usize = rest.split_once(']')?.0.parse().ok()?;
                let header = format!("[[{table}]]");
                self.text
                    .lines()
                    .enumerate()
                    .filter(|(_, line)| line.trim() == header)
                    .nth(index)
                    .map(|(at, _)| at)
            })
            .unwrap_or(0);
        self.text
            .lines()
            .skip(skip)
            .position(|line| {
                let line = line.trim_start();
                line.strip_prefix(leaf)
                    .map(|rest| rest.trim_start().starts_with('='))
                    .unwrap_or(false)
                    || line == format!("[{leaf}]")
                    || line == format!("[[{leaf}]]")
            })
            .map(|i| skip + i)
            .or_else(|| self.quoted_key_line(field))
            .or_else(|| {
                // A key of an inline table (`splits = { train = 8, "v al" = 2 }`).
                self.text.lines().position(|line| {
                    [format!("\"{field}\""), format!("'{field}'")]
                        .iter()
                        .chain(std::iter::once(&field.to_string()))
                        .any(|key| {
                            line.match_indices(key.as_str()).any(|(at, _)| {
                                let before = line[..at].trim_end();
                                let after = line[at + key.len()..].trim_start();
                                after.starts_with('=')
                                    && (before.is_empty()
                                        || before.ends_with('{')
                                        || before.ends_with(','))
                            })
                        })
                })
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

/// The largest manifest file read: 1 MiB. A manifest is a few kilobytes (the biggest preset
/// is under 4 KiB); anything larger is refused before it is read whole.
pub const MAX_MANIFEST_BYTES: u64 = 1 << 20;

/// Reads a manifest file's text, refusing files over [`MAX_MANIFEST_BYTES`] (`/dev/zero`
/// included) after reading at most one byte more than the limit, and text that is not UTF-8.
/// A named pipe, a socket or a directory is refused by its type before it is opened: opening
/// a pipe that no process writes waits for ever.
pub fn read_text(path: &Path) -> Result<String, ManifestError> {
    use std::io::Read;
    let io = |source| ManifestError::Io {
        path: path.to_path_buf(),
        source,
    };
    let kind = std::fs::metadata(path).map_err(io)?.file_type();
    let refused = if kind.is_dir() {
        Some("a directory")
    } else {
        special_file(&kind)
    };
    if let Some(what) = refused {
        return Err(ManifestError::Invalid {
            path: path.to_path_buf(),
            line: 0,
            field: "(file)".to_string(),
            reason: format!("is {what}, not a regular file; give the manifest's TOML file"),
        });
    }
    let file = std::fs::File::open(path).map_err(io)?;
    let mut bytes = Vec::new();
    file.take(MAX_MANIFEST_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > MAX_MANIFEST_BYTES {
        return Err(too_large(path));
    }
    String::from_utf8(bytes).map_err(|err| ManifestError::Invalid {
        path: path.to_path_buf(),
        line: 0,
        field: "(file)".to_string(),
        reason: format!("is not UTF-8 text ({err})"),
    })
}

/// The refusal of a manifest over [`MAX_MANIFEST_BYTES`], the same for a file and for text
/// given directly (which it never repeats).
fn too_large(path: &Path) -> ManifestError {
    ManifestError::Invalid {
        path: path.to_path_buf(),
        line: 0,
        field: "(file)".to_string(),
        reason: format!(
            "is larger than {MAX_MANIFEST_BYTES} bytes; a manifest is a short TOML file"
        ),
    }
}

/// What a file that reading could block on is (a named pipe or a socket); character
/// devices such as `/dev/zero` are read up to the size limit instead.
#[cfg(unix)]
fn special_file(kind: &std::fs::FileType) -> Option<&'static str> {
    use std::os::unix::fs::FileTypeExt;
    if kind.is_fifo() {
        Some("a named pipe (FIFO)")
    } else if kind.is_socket() {
        Some("a socket")
    } else {
        None
    }
}

#[cfg(not(unix))]
fn special_file(_: &std::fs::FileType) -> Option<&'static str> {
    None
}

impl Manifest {
    /// Reads and validates a manifest file (at most [`MAX_MANIFEST_BYTES`]).
    pub fn from_path(path: &Path) -> Result<Manifest, ManifestError> {
        Manifest::parse(&read_text(path)?, path)
    }

    /// Parses and validates manifest text (at most [`MAX_MANIFEST_BYTES`], as a file); `path`
    /// is only used in error messages.
    pub fn parse(text: &str, path: &Path) -> Result<Manifest, ManifestError> {
        if text.len() as u64 > MAX_MANIFEST_BYTES {
            return Err(too_large(path));
        }
        let source = Source { path, text };
        let mut manifest: Manifest = toml::from_str(text).map_err(|err| {
            let (mut line, mut field) = match err.span() {
                Some(span) => (source.line_at(span.start), source.key_at(span.start)),
                None => (0, String::from("(file)")),
            };
            let mut reason = err.message().trim().to_string();
            if let Some(name) = unknown_field_name(&reason) {
                reason = unknown_field_reason(&name, &reason);
                field = name;
            }
            if let Some(missing) = missing_field_name(&reason) {
                // serde points a missing field at the table that lacks it: the whole file
                // for a top-level field (an empty file included), else the table's header.
                let top_level = err.span().is_none_or(|span| span.start == 0);
                field = if top_level || field.is_empty() {
                    line = 0;
                    missing
                } else {
                    format!("{field}.{missing}")
                };
            }
            let written = err
                .span()
                .and_then(|span| text.get(span))
                .unwrap_or("")
                .trim();
            if reason.starts_with("invalid type: map")
                && written.parse::<toml::value::Datetime>().is_ok()
            {
                // TOML date-times reach serde as a private map; say what was written.
                reason = reason.replacen("invalid type: map", "invalid type: date-time", 1);
            }
            if reason.contains("untagged enum Modes") {
                reason = format!(
                    "{} is not a mode: write \"embed\", \"carve\" or a list of them such as [\"embed\", \"carve\"]",
                    truncate(written, 60)
                );
            }
            ManifestError::Invalid {
                path: path.to_path_buf(),
                line,
                field: truncate(&printable(&field), 80),
                reason: truncate(&printable(&reason), MAX_REASON_CHARS),
            }
        })?;
        manifest.validate(&source)?;
        manifest.origin = Origin {
            path: path.to_path_buf(),
            text: text.to_string(),
        };
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
        // The exact Betti numbers of a larger 4D sample would be
        // `TopologyError::TooLarge` in a worker.
        if self.dimension.get() == 4 && self.side as usize > MAX_4D_SIDE {
            return Err(ManifestError::invalid(
                source,
                "side",
                format!(
                    "{} is over {MAX_4D_SIDE}, the largest 4D side whose exact Betti numbers \
                     bettimill computes (its places are 32-bit)",
                    self.side
                ),
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
            if let Some(twice) = first_repeat(components) {
                return Err(ManifestError::invalid(
                    source,
                    "components",
                    format!(
                        "lists {twice} twice; each count is a stratum of its own, so a repeated \
                         count would be a second identical class sharing the samples"
                    ),
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
                        "bin [{}, {}) must satisfy 0 <= lo < hi <= {limit}",
                        short_float(lo),
                        short_float(hi)
                    ))
                } else if vlo > vhi || vhi == 0 {
                    Some(format!(
                        "bin [{}, {}) holds no whole voxel count at side {} (it spans [{vlo}, {vhi}])",
                        short_float(lo),
                        short_float(hi),
                        self.side
                    ))
                } else if vlo > inner {
                    Some(format!(
                        "bin [{}, {}) needs at least {vlo} foreground voxels, but only {inner} fit inside the border at side {}",
                        short_float(lo),
                        short_float(hi),
                        self.side
                    ))
                } else {
                    None
                };
                if let Some(reason) = reason {
                    return Err(ManifestError::invalid(source, "bins", reason));
                }
            }
            let spans = self.hypervolume_voxel_bins();
            for (i, span) in spans.iter().enumerate() {
                if let Some(j) = spans[..i].iter().position(|earlier| earlier == span) {
                    let ([alo, ahi], [blo, bhi]) = (h.bins[j], h.bins[i]);
                    return Err(ManifestError::invalid(
                        source,
                        "bins",
                        format!(
                            "bins [{}, {}) and [{}, {}) are the same voxel counts [{}, {}] at \
                             side {}; each bin is a stratum of its own, so a repeated bin would \
                             be a second identical class sharing the samples",
                            short_float(alo),
                            short_float(ahi),
                            short_float(blo),
                            short_float(bhi),
                            span.0,
                            span.1,
                            self.side
                        ),
                    ));
                }
            }
        }
        // Each resolution is a member of every sample: a repeated one makes two members of
        // one name, which no shard can hold.
        if let Some(twice) = first_repeat(&self.resolutions) {
            return Err(ManifestError::invalid(
                source,
                "resolutions",
                format!("lists {twice} twice; each resolution is one downscaled copy per sample"),
            ));
        }
        for &r in &self.resolutions {
            if r < 4 || r >= self.side || !self.side.is_multiple_of(r) {
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
        if let Some(clearance) = &self.clearance {
            if let Err(err) = bettimill_types::deform::validate_clearance(clearance) {
                return Err(ManifestError::invalid(source, "clearance", err.reason));
            }
        }
        if let Some(gap) = self.inner_gap {
            use bettimill_types::{MAX_INNER_GAP, MIN_INNER_GAP};
            if !(MIN_INNER_GAP..=MAX_INNER_GAP).contains(&gap) {
                return Err(ManifestError::invalid(
                    source,
                    "inner_gap",
                    format!("is {gap}; it must be from {MIN_INNER_GAP} to {MAX_INNER_GAP} voxels"),
                ));
            }
        }
        if let Some(n) = self.survives_dilations {
            if n > MAX_SURVIVED_DILATIONS {
                return Err(ManifestError::invalid(
                    source,
                    "survives_dilations",
                    format!("is {n}; it must be from 0 to {MAX_SURVIVED_DILATIONS}"),
                ));
            }
        }
        if let Some(deform) = &self.deform {
            if let Err((field, err)) = deform.validate() {
                return Err(ManifestError::invalid(source, &field, err.reason));
            }
        }
        Ok(())
    }

    /// The manifest's JSON form with `classes` left empty: the plan appends the resolved
    /// classes to make the canonical form (`bettimill_plan::canonical_json`).
    pub fn json_without_classes(&self) -> String {
        let mut copy = self.clone();
        copy.classes.clear();
        serde_json::to_string(&copy).expect("a manifest always serialises")
    }
}

/// The first value that `values` holds twice.
fn first_repeat<T: Ord + Copy>(values: &[T]) -> Option<T> {
    let mut seen = std::collections::BTreeSet::new();
    values.iter().copied().find(|&v| !seen.insert(v))
}

/// The longest reason a parse error prints: serde's messages quote what they saw, and a
/// table of 100,000 keys would otherwise make one error line of hundreds of kilobytes.
pub const MAX_REASON_CHARS: usize = 400;

/// `text` cut to `max` characters, saying how much was left out.
fn truncate(text: &str, max: usize) -> String {
    let count = text.chars().count();
    if count <= max {
        return text.to_string();
    }
    let kept: String = text.chars().take(max).collect();
    format!("{kept}... ({} more characters)", count - max)
}

fn missing_field_name(message: &str) -> Option<String> {
    let rest = message.strip_prefix("missing field `")?;
    Some(rest.split('`').next()?.to_string())
}

fn unknown_field_name(message: &str) -> Option<String> {
    let rest = message.strip_prefix("unknown field `")?;
    Some(rest.split('`').next()?.to_string())
}

/// The known name nearest to `name` (fewest single-character edits, the first of a tie),
/// for a message that names the way on.
fn nearest<'a>(name: &str, known: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    known
        .into_iter()
        .min_by_key(|candidate| strsim::levenshtein(name, candidate))
}

/// serde's "unknown field `x`, expected one of `a`, `b`" as "unknown field `x`: did you mean
/// `a`? The known fields are `a`, `b`".
fn unknown_field_reason(name: &str, message: &str) -> String {
    let Some((_, expected)) = message.split_once("expected ") else {
        return message.to_string();
    };
    // serde lists the fields in backquotes: every second piece is one.
    let known: Vec<&str> = expected.split('`').skip(1).step_by(2).collect();
    match nearest(name, known.iter().copied()) {
        Some(best) => format!(
            "unknown field `{name}`: did you mean `{best}`? The known fields are `{}`",
            known.join("`, `")
        ),
        None => message.to_string(),
    }
}

mod classes;
pub use classes::{ClassKind, ClassSpec};
#[cfg(test)]
mod tests;
