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

pub use bettimill_format::{ClassTable, StratumClass, TopologyClass};
use bettimill_grid::{Dim, Mode};
use bettimill_manifest::{ClassKind, ClassSpec, Manifest, ManifestError};
use bettimill_shapes::Family;
/// The thinnest tube of a stratum's constructions ([`Stratum::tube_floor`]).
pub use bettimill_shapes::TubeFloor;
use bettimill_types::{Deformation, Solid};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

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

/// A contiguous range of samples written as one tar file.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ShardPlan {
    /// Shard number, from 0, over the whole dataset.
    pub index: u64,
    /// The split the shard belongs to.
    pub split: String,
    /// File stem, e.g. `demo-3d-000000`.
    pub name: String,
    /// Index of the shard's first sample.
    pub first_sample: u64,
    /// Number of samples.
    pub samples: u64,
}

/// Everything a worker needs to make one sample.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SampleTask {
    /// Global sample index.
    pub index: u64,
    /// WebDataset key (no dots).
    pub key: String,
    /// Index into [`Plan::strata`].
    pub stratum: usize,
    /// The sample's 32-byte seed.
    pub seed: [u8; 32],
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
    /// Upper bound of one sample's bytes in a shard, uncompressed.
    pub sample_bytes: u64,
}

/// Array size (bytes of voxels) from which `compression = "auto"` compresses; see
/// [`bettimill_manifest::CompressionSetting::Auto`].
pub use bettimill_manifest::AUTO_COMPRESSION_THRESHOLD;

/// Upper bound of one sample's bytes in a shard, uncompressed: tar headers and padding of
/// every member, the arrays (with downscaled copies) and a generous label.
fn sample_bytes_estimate(manifest: &Manifest) -> u64 {
    let member = bettimill_shard::ustar::member_bytes;
    let voxels = |side: u32| (side as u64).pow(manifest.dimension.get() as u32);
    let arrays: u64 = std::iter::once(manifest.side)
        .chain(manifest.resolutions.iter().copied())
        .map(|side| member(128 + voxels(side)))
        .sum();
    arrays + member(8192) + member(16)
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

/// The construction a class entry names, with every key written checked.
fn resolve_class(manifest: &Manifest, class: &ClassSpec) -> Result<Family, ManifestError> {
    let table = match &class.kind {
        ClassKind::Betti(betti) => {
            return Ok(Family::Betti {
                betti: betti.clone(),
            })
        }
        ClassKind::Family(table) => table,
    };
    let refuse = |reason: String| {
        manifest.class_error(class.entry, format!("class {}: {reason}", class.entry))
    };
    let family = <Family as serde::Deserialize>::deserialize(toml::Value::Table(table.clone()))
        .map_err(|err| refuse(err.to_string()))?;
    // serde ignores extra keys next to a unit variant (`{ family = "ball", radius = 3 }`);
    // a misspelt or unsupported parameter must never be silently dropped, so every key
    // written must survive a round trip.
    let known = toml::Value::try_from(&family)
        .ok()
        .and_then(|v| v.as_table().cloned())
        .unwrap_or_default();
    if let Some(extra) = table.keys().find(|k| !known.contains_key(*k)) {
        return Err(refuse(format!(
            "unknown field `{extra}` for family {}",
            family.label()
        )));
    }
    Ok(family)
}

/// The manifest's canonical JSON: every field, defaults filled in, fixed key order, the
/// classes as resolved constructions. Comments, whitespace and the order of keys in the
/// file do not change it.
pub fn canonical_json(manifest: &Manifest, classes: &[Family]) -> String {
    let head = manifest.json_without_classes();
    let head = head
        .strip_suffix("[]}")
        .expect("`classes` is the manifest's last serialised field");
    let classes = serde_json::to_string(classes).expect("families always serialise");
    format!("{head}{classes}}}")
}

/// blake3 of [`canonical_json`], as 64 hex digits. Identifies the dataset.
pub fn manifest_hash(manifest: &Manifest, classes: &[Family]) -> String {
    blake3::hash(canonical_json(manifest, classes).as_bytes())
        .to_hex()
        .to_string()
}

/// Width of the zero-padded sample number in keys: at least 6 digits.
fn key_width(samples: u64) -> usize {
    samples.saturating_sub(1).to_string().len().max(6)
}

/// Derives a 32-byte seed in the named domain from `parts`.
pub fn derive_seed(domain: &str, parts: &[&[u8]]) -> [u8; 32] {
    let mut hasher = blake3::Hasher::new_derive_key(domain);
    for part in parts {
        hasher.update(part);
    }
    *hasher.finalize().as_bytes()
}

/// The RNG for regeneration attempt `attempt` of a sample.
pub fn attempt_rng(sample_seed: &[u8; 32], attempt: u32) -> ChaCha8Rng {
    ChaCha8Rng::from_seed(derive_seed(
        "bettimill attempt seed v1",
        &[sample_seed, &attempt.to_le_bytes()],
    ))
}

impl Plan {
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

    /// Number of shards over all splits.
    pub fn shard_count(&self) -> u64 {
        self.splits
            .iter()
            .map(|(_, size)| size.div_ceil(self.shard_size))
            .sum()
    }

    /// Shard `index` (from 0, over the whole dataset). Panics if `index >= shard_count()`:
    /// callers take indexes from [`Plan::shards`] or check them first.
    pub fn shard(&self, index: u64) -> ShardPlan {
        let mut first_shard = 0;
        let mut split_start = 0;
        for (split, size) in &self.splits {
            let count = size.div_ceil(self.shard_size);
            if index < first_shard + count {
                let k = index - first_shard;
                let first_sample = split_start + k * self.shard_size;
                return ShardPlan {
                    index,
                    split: split.clone(),
                    name: format!("{}{k:06}", self.shard_prefix(split)),
                    first_sample,
                    samples: self.shard_size.min(split_start + size - first_sample),
                };
            }
            first_shard += count;
            split_start += size;
        }
        panic!(
            "shard {index} asked of a plan with {} shards",
            self.shard_count()
        )
    }

    /// Every shard, in order, computed one at a time.
    pub fn shards(&self) -> impl ExactSizeIterator<Item = ShardPlan> + '_ {
        (0..self.shard_count() as usize).map(|i| self.shard(i as u64))
    }

    /// The shards of one split, in order.
    pub fn split_shards<'a>(&'a self, split: &'a str) -> impl Iterator<Item = ShardPlan> + 'a {
        let mut first_shard = 0;
        let mut range = 0..0;
        for (name, size) in &self.splits {
            let count = size.div_ceil(self.shard_size);
            if name == split {
                range = first_shard..first_shard + count;
            }
            first_shard += count;
        }
        range.map(|i| self.shard(i))
    }

    /// The shard whose file stem is `name`, if the plan has one.
    pub fn shard_named(&self, name: &str) -> Option<ShardPlan> {
        let mut first_shard = 0;
        for (split, size) in &self.splits {
            let count = size.div_ceil(self.shard_size);
            if let Some(k) = name
                .strip_prefix(&self.shard_prefix(split))
                .and_then(|k| k.parse::<u64>().ok())
            {
                if k < count && format!("{}{k:06}", self.shard_prefix(split)) == name {
                    return Some(self.shard(first_shard + k));
                }
            }
            first_shard += count;
        }
        None
    }

    /// The stem of every shard of a split up to its number (`NAME-`, or `NAME-SPLIT-` with
    /// named splits); split names hold no `-`, so no split's prefix starts another's.
    pub fn shard_prefix(&self, split: &str) -> String {
        match self.named_splits {
            true => format!("{}-{split}-", self.name),
            false => format!("{}-", self.name),
        }
    }

    /// How many samples of each stratum a shard holds (indexed like [`Plan::strata`]),
    /// computed from the dealing rule without drawing any seed.
    pub fn shard_counts(&self, shard: &ShardPlan) -> Vec<u64> {
        self.range_counts(shard.first_sample, shard.first_sample + shard.samples)
    }

    /// Samples of each stratum among the samples `first..end`.
    fn range_counts(&self, first: u64, end: u64) -> Vec<u64> {
        let n_strata = self.strata.len() as i128;
        let (first, end) = (first as i128, end as i128);
        let mut counts = vec![0u64; self.strata.len()];
        for (position, &stratum) in self.deal_order.iter().enumerate() {
            // Dealt positions p in [first, end) with p mod S == position.
            let q = position as i128;
            let upto = |x: i128| (x - q).div_euclid(n_strata);
            counts[stratum] = (upto(end - 1) - upto(first - 1)) as u64;
        }
        counts
    }

    /// Samples of each stratum over the whole dataset.
    pub fn total_counts(&self) -> Vec<u64> {
        self.range_counts(0, self.samples)
    }

    /// The tasks of one shard, in the order they are written.
    pub fn shard_tasks(&self, shard: &ShardPlan) -> Vec<SampleTask> {
        let positions = self.shard_positions(shard);
        (0..shard.samples)
            .map(|offset| self.task_in(shard, &positions, offset))
            .collect()
    }

    /// The task of sample `index` (from 0, over the whole dataset), the same as its entry in
    /// [`Plan::shard_tasks`] of its shard; `None` past the last sample. Costs one shuffle of
    /// its shard's positions, not the other samples' seeds.
    pub fn task(&self, index: u64) -> Option<SampleTask> {
        if index >= self.samples {
            return None;
        }
        let mut first_shard = 0;
        let mut split_start = 0;
        for (_, size) in &self.splits {
            if index < split_start + size {
                let shard = self.shard(first_shard + (index - split_start) / self.shard_size);
                let positions = self.shard_positions(&shard);
                return Some(self.task_in(&shard, &positions, index - shard.first_sample));
            }
            first_shard += size.div_ceil(self.shard_size);
            split_start += size;
        }
        None
    }

    /// The shard's dealt positions in the order its samples are written.
    fn shard_positions(&self, shard: &ShardPlan) -> Vec<u64> {
        let mut positions: Vec<u64> = (0..shard.samples).collect();
        let mut rng = ChaCha8Rng::from_seed(derive_seed(
            "bettimill shard shuffle v1",
            &[self.manifest_hash.as_bytes(), &shard.index.to_le_bytes()],
        ));
        positions.shuffle(&mut rng);
        positions
    }

    /// The task written at `offset` in `shard`, given its [`Plan::shard_positions`].
    fn task_in(&self, shard: &ShardPlan, positions: &[u64], offset: u64) -> SampleTask {
        let width = key_width(self.samples);
        let index = shard.first_sample + offset;
        let dealt_index = shard.first_sample + positions[offset as usize];
        let stratum = self.deal_order[(dealt_index % self.strata.len() as u64) as usize];
        SampleTask {
            index,
            key: format!("s{index:0width$}"),
            stratum,
            seed: derive_seed(
                "bettimill sample seed v1",
                &[self.manifest_hash.as_bytes(), &index.to_le_bytes()],
            ),
        }
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

/// The class object of a stratum's family: [`class_with_copies`] undone.
fn one_copy(family: &Family, copies: u32) -> Family {
    match family {
        Family::Scene { objects } if copies > 1 => {
            let per_copy = objects.len() / copies as usize;
            match &objects[..per_copy] {
                [one] => one.clone(),
                several => Family::Scene {
                    objects: several.to_vec(),
                },
            }
        }
        other => other.clone(),
    }
}

/// Expands the strata axes, dropping (and listing) combinations that cannot be built. A
/// class that no combination can build is refused with every distinct reason.
fn strata(
    manifest: &Manifest,
    classes: &[Family],
) -> Result<(Vec<Stratum>, Vec<Infeasible>), PlanError> {
    let components = manifest.components.clone().unwrap_or_else(|| vec![1]);
    let bins: Vec<Option<(u64, u64)>> = {
        let bins = manifest.hypervolume_voxel_bins();
        if bins.is_empty() {
            vec![None]
        } else {
            bins.into_iter().map(Some).collect()
        }
    };
    let side = manifest.side as usize;
    let mut strata = Vec::new();
    let mut infeasible = Vec::new();
    for (manifest_class, (class, spec)) in classes.iter().zip(&manifest.classes).enumerate() {
        let before = strata.len();
        let mut reasons: Vec<String> = Vec::new();
        for mode in manifest.mode.to_vec() {
            for &copies in &components {
                let family = class_with_copies(class, copies);
                // Whether a combination can be built does not depend on the bin.
                let dim = manifest.dimension;
                // Thick enough for the copies where that fits, else the usual floor
                // (the copies then record honestly whether they kept the topology).
                let floor = tube_floor_for(manifest, mode);
                let (tube_floor, fits) = match family.check_fits_with(dim, side, mode, floor) {
                    Err(_) if floor != TubeFloor::USUAL => {
                        (TubeFloor::USUAL, family.check_fits(dim, side, mode))
                    }
                    fits => (floor, fits),
                };
                let checked = family
                    .expected_label(dim, mode)
                    .and_then(|label| fits.map(|_| label))
                    .map_err(|err| err.to_string());
                for &bin in &bins {
                    let mut label = format!("{}/{}", class.label(), mode_name(mode));
                    if manifest.components.is_some() {
                        label.push_str(&format!("/x{copies}"));
                    }
                    if let Some((lo, hi)) = bin {
                        label.push_str(&format!("/hv{lo}-{hi}"));
                    }
                    match &checked {
                        Ok((betti, rational)) => strata.push(Stratum {
                            index: strata.len(),
                            manifest_class,
                            label,
                            family: family.clone(),
                            mode,
                            components: copies,
                            hypervolume: bin,
                            betti: betti.clone(),
                            betti_rational: rational.clone(),
                            knot_type: family.knot_type(dim, mode),
                            tube_floor,
                        }),
                        Err(reason) => {
                            if !reasons.contains(reason) {
                                reasons.push(reason.clone());
                            }
                            infeasible.push(Infeasible {
                                label,
                                reason: reason.clone(),
                            });
                        }
                    }
                }
            }
        }
        if strata.len() == before {
            // Every reason, so that a class refused in two modes for two different reasons
            // (too big here, impossible there) says both.
            return Err(manifest
                .class_error(
                    spec.entry,
                    format!(
                        "class {} ({}): {}",
                        manifest_class + 1,
                        class.label(),
                        reasons.join("; ")
                    ),
                )
                .into());
        }
    }
    Ok((strata, infeasible))
}

/// The foreground counts a stratum's samples can reach ([`reach::reach`]).
pub fn stratum_reach(manifest: &Manifest, stratum: &Stratum) -> reach::Reach {
    let dim = manifest.dimension;
    let d = dim.get();
    let tunnel = match stratum.family {
        Family::Tunnel { intervals, .. } => Some(intervals),
        _ => None,
    };
    // The phase's Betti numbers: the objects' in embed mode; in carve mode the cavities',
    // which duality gives from the solid's (each cavity encloses a void of the solid, and
    // the solid's last number counts them); a tunnel encloses none.
    let b = &stratum.betti;
    let phase_betti = match stratum.mode {
        Mode::Embed => b.clone(),
        Mode::Carve if tunnel.is_some() => vec![1],
        Mode::Carve => (0..d)
            .map(|k| match k {
                0 => b[d - 1],
                k if k == d - 1 => b[0].saturating_sub(1),
                k => b[d - 1 - k],
            })
            .collect(),
    };
    reach::reach(&reach::Stratum {
        dim: d,
        side: manifest.side,
        mode: stratum.mode,
        solid: manifest.solid.unwrap_or_default(),
        phase_betti,
        tunnel,
        smallest_radius: stratum
            .family
            .smallest_object_radius(dim, stratum.mode, TubeFloor::USUAL),
    })
}

/// Refuses a manifest with a binned stratum that no sample can bring into its bin: every
/// attempt of every shard holding it would fail, so nothing would be built.
fn check_reach(manifest: &Manifest, strata: &[Stratum]) -> Result<(), PlanError> {
    let voxels = manifest.voxels() as f64;
    let share = |count: u64| count as f64 / voxels;
    let mut refusals: Vec<String> = Vec::new();
    for stratum in strata {
        let Some((lo, hi)) = stratum.hypervolume else {
            continue;
        };
        let r = stratum_reach(manifest, stratum);
        let why = if hi < r.lowest {
            format!(
                "its samples keep at least {} foreground voxels ({:.4} of the image): {}",
                r.lowest,
                share(r.lowest),
                r.lowest_why
            )
        } else if lo > r.highest {
            format!(
                "its samples have at most {} foreground voxels ({:.4} of the image): {}",
                r.highest,
                share(r.highest),
                r.highest_why
            )
        } else {
            continue;
        };
        refusals.push(format!(
            "stratum {} cannot reach its bin of {lo}-{hi} foreground voxels \
             ({:.4}-{:.4} of the image): {why}",
            stratum.label,
            share(lo),
            share(hi + 1)
        ));
    }
    if refusals.is_empty() {
        return Ok(());
    }
    let shown = 3;
    let mut reason = refusals[..refusals.len().min(shown)].join("; ");
    if refusals.len() > shown {
        reason.push_str(&format!(
            "; and {} more unreachable strata",
            refusals.len() - shown
        ));
    }
    Err(manifest.error("bins", reason).into())
}

/// The tube floor a manifest's constructions in `mode` aim for: carve mode with
/// downscaled copies pools them by max pooling ([`bettimill_format::Pooling`]), which fills a
/// cavity thinner than a few blocks, so its cavities are at least
/// [`TubeFloor::for_copies`] of the largest copy's pooling factor. Embed mode (objects grow
/// under max pooling; what closes is background between them) and manifests without
/// copies keep [`TubeFloor::USUAL`].
pub fn tube_floor_for(manifest: &Manifest, mode: Mode) -> TubeFloor {
    match manifest.resolutions.iter().max() {
        Some(&largest) if mode == Mode::Carve => {
            TubeFloor::for_copies(manifest.dimension, (manifest.side / largest) as usize)
        }
        _ => TubeFloor::USUAL,
    }
}

/// The manifest spelling of a mode.
pub fn mode_name(mode: Mode) -> &'static str {
    mode.name()
}

#[cfg(test)]
mod tests;
