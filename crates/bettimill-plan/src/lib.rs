//! The plan: a manifest resolved, once, into strata, shards, per-sample seeds and every
//! setting a worker needs.
//!
//! The plan is a pure function of the manifest, so every machine that reads the same
//! manifest computes the same plan, and a worker can be handed nothing but the manifest text
//! and a shard index. Nothing here depends on worker count, time or file system state.
//!
//! This is the only place a manifest is resolved: the classes are turned into
//! constructions and checked for feasibility here (and only here), `compression = "auto"`
//! becomes a member compression, `shard_bytes` becomes a number of samples, and the
//! deformation settings, resolutions and compression are copied into the plan in the types
//! their consumers take, so that nothing downstream reads the manifest again. A manifest
//! that plans is one every sample of which can be attempted; what cannot be known before
//! building (a construction that fails every attempt) is the sample's to report.
//!
//! Balance: samples are assigned to strata cyclically in global order (sample j gets
//! stratum `order[j mod S]`), so stratum counts differ by at most one over the whole dataset
//! and over every contiguous range of samples: every split and every shard. Within each shard the positions are then shuffled with a
//! permutation drawn from the shard's own seed, which keeps both balances exact while making
//! neighbouring samples unpredictable.
//!
//! Seeds: `sample_seed = blake3-derive-key("bettimill sample seed v1", manifest_hash ||
//! index_le)` (32 bytes), and regeneration attempt k of that sample uses
//! `blake3-derive-key("bettimill attempt seed v1", sample_seed || k_le)` as a ChaCha8 seed.

pub mod estimate;
pub mod memory;
pub mod reach;
mod seed;
mod shards;
mod strata;

pub use bettimill_format::{ClassTable, StratumClass, TopologyClass};
use bettimill_grid::{Dim, Mode};
use bettimill_manifest::{Manifest, ManifestError};
use bettimill_shapes::Family;
/// The thinnest tube of a stratum's constructions ([`Stratum::tube_floor`]).
pub use bettimill_shapes::TubeFloor;
use bettimill_types::{Deformation, Solid, Spread};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
pub use seed::{attempt_rng, canonical_json, derive_seed, manifest_hash};
use serde::{Deserialize, Serialize};
pub use shards::{SampleTask, ShardPlan};
use strata::{check_reach, one_copy, reach_in, resolve_class, strata};
pub use strata::{class_with_copies, mode_name, stratum_reach, tube_floor_for};

/// One cell of the balanced design: a label class in a mode.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Stratum {
    /// Position in [`Plan::strata`]; stored as the sample's `cls`.
    pub index: usize,
    /// Index of the class in the manifest's `[[classes]]` list.
    pub manifest_class: usize,
    /// The construction family (a scene of copies when `components` > 1).
    pub family: Family,
    /// Object in empty space or cavity in a cube.
    pub mode: Mode,
    /// Copies of the class object in the sample.
    pub components: u32,
    /// Inclusive foreground voxel bounds the sample is brought into, if binned.
    pub hypervolume: Option<(u64, u64)>,
    /// Analytic Betti numbers over Z/2.
    pub betti: Vec<u64>,
    /// Analytic Betti numbers over Q where they differ from [`Stratum::betti`] (the Klein
    /// bottle), else `None`. Like [`Stratum::knot_type`] it is a function of the family,
    /// dimension and mode, which the plan hash covers, so it is left out of the hash (and
    /// of the serialised plan).
    #[serde(skip)]
    pub betti_rational: Option<Vec<u64>>,
    /// The `knot_type` every sample of the stratum records (`"trefoil"`, `"none"`, ...).
    #[serde(skip)]
    pub knot_type: String,
    /// The thinnest tube of the stratum's constructions: thick enough for max pooling to
    /// the manifest's largest `resolutions` copy in carve mode ([`tube_floor_for`]) where
    /// the combination fits with it, else the usual 2 voxels. A function of the family,
    /// dimension, side, mode and resolutions, which the plan hash covers.
    #[serde(skip)]
    pub tube_floor: TubeFloor,
    /// A short human-readable name.
    pub label: String,
}

/// A combination of the strata axes that cannot be built, and why.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Infeasible {
    /// The combination, named like a stratum label.
    pub label: String,
    /// Why it cannot be built.
    pub reason: String,
}

/// Why a manifest has no usable plan: the message names the file, line and field.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// A field the plan resolves cannot be used: an unknown family or parameter, a class
    /// listed twice, a class that no combination of the strata axes can build, a
    /// `shard_bytes` too small for one sample.
    #[error(transparent)]
    Manifest(#[from] ManifestError),
}

/// The expanded manifest.
///
/// Shards are not stored: a dataset of 10^7 one-sample shards has a plan of a few
/// kilobytes, and [`Plan::shard`] computes any shard from the split table in constant time.
///
/// ```
/// use bettimill_plan::Plan;
/// use std::path::Path;
///
/// let manifest = r#"
/// schema_version = 1
/// name = "rings"
/// dimension = 2
/// side = 32
/// mode = ["embed", "carve"]
/// samples = 240
/// shard_size = 40
/// seed = 20261122
///
/// [[classes]]
/// family = "ball"
///
/// [[classes]]
/// family = "handle"
/// "#;
/// let plan = Plan::parse(manifest, Path::new("rings.toml")).unwrap();
/// // Two classes in two modes: four strata, dealt out so that each has 60 samples.
/// assert_eq!(plan.strata.len(), 4);
/// assert_eq!(plan.total_counts(), [60, 60, 60, 60]);
/// assert_eq!(plan.shard_count(), 6);
/// let shard = plan.shard(5);
/// assert_eq!((shard.first_sample, shard.samples), (200, 40));
/// // A pure function of the manifest: the same text plans the same everywhere.
/// let again = Plan::parse(manifest, Path::new("elsewhere/rings.toml")).unwrap();
/// assert_eq!(plan.hash(), again.hash());
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// The manifest's canonical hash.
    pub manifest_hash: String,
    /// The dataset name: the prefix of every shard file.
    pub name: String,
    /// Number of axes.
    pub dimension: Dim,
    /// Voxels per axis.
    pub side: u32,
    /// Total samples.
    pub samples: u64,
    /// The strata, in manifest order (classes, then modes, components, hypervolume bins).
    pub strata: Vec<Stratum>,
    /// Combinations left out, with reasons.
    pub infeasible: Vec<Infeasible>,
    /// Samples per split, in split order.
    pub splits: Vec<(String, u64)>,
    /// Whether the manifest names its splits (then shard names carry the split).
    pub named_splits: bool,
    /// Samples per shard.
    pub shard_size: u64,
    /// The order in which strata are dealt out cyclically.
    pub deal_order: Vec<usize>,
    /// Member compression of every array (`auto` resolved).
    pub compression: bettimill_shard::Compression,
    /// Side lengths of the downscaled copies stored with every sample.
    pub resolutions: Vec<u32>,
    /// The deformation steps every sample's topological phase gets, drawn per sample.
    pub deform: Option<Deformation>,
    /// Carve mode's solid.
    pub solid: Solid,
    /// The narrowest gap growth of the topological phase may leave, drawn per sample
    /// (`None`: unrestricted).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clearance: Option<Spread<u32>>,
    /// How many dilations of the topological phase every sample's Betti numbers survive,
    /// checked per sample (`None` or 0: not checked).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub survives_dilations: Option<u32>,
    /// Upper bound of one sample's bytes in a shard, uncompressed.
    pub sample_bytes: u64,
}

/// Array size (bytes of voxels) from which `compression = "auto"` compresses; see
/// [`bettimill_manifest::CompressionSetting::Auto`].
pub use bettimill_manifest::AUTO_COMPRESSION_THRESHOLD;

/// Upper bound of one sample's bytes in a shard, uncompressed: tar headers and padding of
/// every member, the arrays (with downscaled copies) and a generous label.
fn sample_bytes_estimate(manifest: &Manifest) -> u64 {
    sample_bound(
        manifest.dimension,
        manifest.side,
        &manifest.resolutions,
        bettimill_shard::Compression::None,
    )
}

/// [`sample_bytes_estimate`] with every member's data grown to the largest `compression`
/// can make of it ([`bettimill_shard::compress::max_compressed_bytes`]).
fn sample_bound(
    dimension: Dim,
    side: u32,
    resolutions: &[u32],
    compression: bettimill_shard::Compression,
) -> u64 {
    let member = |data: u64| {
        bettimill_shard::ustar::member_bytes(bettimill_shard::compress::max_compressed_bytes(
            data,
            compression,
        ))
    };
    let voxels = |side: u32| (side as u64).saturating_pow(dimension.get() as u32);
    let arrays: u64 = std::iter::once(side)
        .chain(resolutions.iter().copied())
        .map(|side| member(128 + voxels(side)))
        .fold(0, u64::saturating_add);
    arrays
        .saturating_add(member(8192))
        .saturating_add(member(16))
}

/// The member compression a manifest asks for, `auto` resolved by the array size.
fn member_compression(manifest: &Manifest) -> bettimill_shard::Compression {
    use bettimill_manifest::CompressionSetting as Written;
    use bettimill_shard::Compression;
    match manifest.compression {
        Written::Auto if manifest.voxels() >= AUTO_COMPRESSION_THRESHOLD => Compression::Gzip,
        Written::Auto | Written::None => Compression::None,
        Written::Gzip => Compression::Gzip,
        Written::Zstd => Compression::Zstd,
    }
}

impl Plan {
    /// The foreground counts the samples of `stratum` (one of [`Plan::strata`]) can reach,
    /// as the plan decided them ([`stratum_reach`]).
    pub fn reach(&self, stratum: &Stratum) -> reach::Reach {
        reach_in(self.dimension, self.side, self.solid, stratum)
    }

    /// Upper bound of the bytes of the largest shard, whatever the samples' voxels: its
    /// members at their largest compressed size, tar headers, padding and the end of the
    /// archive.
    pub fn shard_bytes_bound(&self) -> u64 {
        self.shard_bound(self.largest_shard())
    }

    fn shard_bound(&self, samples: u64) -> u64 {
        let sample = sample_bound(
            self.dimension,
            self.side,
            &self.resolutions,
            self.compression,
        );
        samples
            .saturating_mul(sample)
            .saturating_add(2 * bettimill_shard::ustar::BLOCK)
    }

    /// Refuses a plan for object storage (`--out s3://...`) when a shard could be larger
    /// than an object a streamed upload can name
    /// ([`bettimill_shard::object::MAX_STREAMED_OBJECT_BYTES`], 5 GiB): the error names the
    /// manifest's `shard_size` or `shard_bytes` and the largest value that fits. `manifest`
    /// is the one this plan was made from. A build to a directory has no such limit.
    pub fn check_object_storage(&self, manifest: &Manifest) -> Result<(), PlanError> {
        use bettimill_shard::object::MAX_STREAMED_OBJECT_BYTES as LIMIT;
        let bound = self.shard_bytes_bound();
        if bound <= LIMIT {
            return Ok(());
        }
        // The largest shard_size whose shards stay within the limit.
        let sample = self.shard_bound(1) - self.shard_bound(0);
        let fitting = (LIMIT.saturating_sub(self.shard_bound(0))) / sample.max(1);
        let field = if manifest.shard_size.is_some() {
            "shard_size"
        } else {
            "shard_bytes"
        };
        let largest = if field == "shard_size" {
            format!("shard_size = {fitting}")
        } else {
            format!(
                "shard_bytes = {}",
                fitting.saturating_mul(self.sample_bytes)
            )
        };
        let reason = if fitting == 0 {
            format!(
                "a shard of one sample can reach {bound1} bytes, more than the {LIMIT} bytes \
                 (5 GiB) an object on S3 can have when bettimill writes it create-only (a \
                 server-side copy of one part); lower `side` or `resolutions`, or build to a \
                 directory",
                bound1 = self.shard_bound(1)
            )
        } else {
            format!(
                "shards of {} samples can reach {bound} bytes ({}), more than the {LIMIT} bytes \
                 (5 GiB) an object on S3 can have when bettimill writes it create-only (a \
                 server-side copy of one part); for an s3:// output use at most {largest}",
                self.largest_shard(),
                memory::human_bytes(bound),
            )
        };
        Err(manifest.error(field, reason).into())
    }

    /// Reads, validates and resolves the manifest file at `path`.
    pub fn from_path(path: &std::path::Path) -> Result<Plan, PlanError> {
        Plan::new(&Manifest::from_path(path)?)
    }

    /// Parses, validates and resolves manifest text; `path` is only used in error messages.
    pub fn parse(text: &str, path: &std::path::Path) -> Result<Plan, PlanError> {
        Plan::new(&Manifest::parse(text, path)?)
    }

    /// Resolves a validated manifest.
    pub fn new(manifest: &Manifest) -> Result<Plan, PlanError> {
        let mut classes: Vec<Family> = Vec::with_capacity(manifest.classes.len());
        for class in &manifest.classes {
            let family = resolve_class(manifest, class)?;
            if let Some(first) = classes.iter().position(|c| *c == family) {
                return Err(manifest
                    .class_error(
                        class.entry,
                        format!(
                            "class {} ({}) is listed twice (also class {})",
                            classes.len() + 1,
                            family.label(),
                            first + 1
                        ),
                    )
                    .into());
            }
            classes.push(family);
        }
        let manifest_hash = manifest_hash(manifest, &classes);
        let (strata, infeasible) = strata(manifest, &classes)?;
        check_reach(manifest, &strata)?;
        let mut deal_order: Vec<usize> = (0..strata.len()).collect();
        let mut rng = ChaCha8Rng::from_seed(derive_seed(
            "bettimill deal order v1",
            &[manifest_hash.as_bytes()],
        ));
        deal_order.shuffle(&mut rng);
        let sample_bytes = sample_bytes_estimate(manifest);
        let shard_size = match (manifest.shard_size, manifest.shard_bytes) {
            (Some(n), _) => n,
            (None, Some(bytes)) if bytes < sample_bytes => {
                return Err(manifest
                    .error(
                        "shard_bytes",
                        format!(
                            "{bytes} bytes cannot hold one sample (about {sample_bytes} bytes each)"
                        ),
                    )
                    .into())
            }
            (None, Some(bytes)) => bytes / sample_bytes,
            (None, None) => unreachable!("manifest validation requires shard_size or shard_bytes"),
        };
        let splits = manifest.split_sizes();
        if splits.len() > bettimill_format::MAX_INDEX_SPLITS {
            return Err(manifest
                .error(
                    "splits",
                    format!(
                        "{} splits; a dataset has at most {} (its index would be refused)",
                        splits.len(),
                        bettimill_format::MAX_INDEX_SPLITS
                    ),
                )
                .into());
        }
        Ok(Plan {
            manifest_hash,
            name: manifest.name.clone(),
            dimension: manifest.dimension,
            side: manifest.side,
            samples: manifest.samples,
            strata,
            infeasible,
            splits,
            named_splits: manifest.splits.is_some(),
            shard_size,
            deal_order,
            compression: member_compression(manifest),
            resolutions: manifest.resolutions.clone(),
            deform: manifest.deform.clone(),
            solid: manifest.solid.unwrap_or_default(),
            clearance: manifest.clearance,
            survives_dilations: manifest.survives_dilations,
            sample_bytes,
        })
    }

    /// The class table (`DIR/classes.json`): what every `cls` value means, with a
    /// topology-only class index over the distinct (Betti vector, knot type) pairs.
    pub fn class_table(&self) -> ClassTable {
        let counts = self.total_counts();
        ClassTable::new(
            self.strata
                .iter()
                .zip(counts)
                .map(|(stratum, samples)| StratumClass {
                    cls: stratum.index,
                    name: stratum.label.clone(),
                    family: one_copy(&stratum.family, stratum.components).label(),
                    mode: mode_name(stratum.mode).to_string(),
                    components: stratum.components,
                    hypervolume_bin: stratum.hypervolume,
                    betti: stratum.betti.clone(),
                    knot_type: stratum.knot_type.clone(),
                    topology_class: 0,
                    samples,
                })
                .collect(),
        )
    }

    /// blake3 of the plan's canonical JSON (64 hex digits).
    pub fn hash(&self) -> String {
        let json = serde_json::to_string(self).expect("a plan always serialises");
        blake3::hash(json.as_bytes()).to_hex().to_string()
    }
}

#[cfg(test)]
mod tests;
