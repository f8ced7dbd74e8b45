//! The plan: a manifest expanded into strata, shards and per-sample seeds.
//!
//! The plan is a pure function of the manifest, so every machine that reads the same
//! manifest computes the same plan, and a worker can be handed nothing but the manifest text
//! and a shard index. Nothing here depends on worker count, time or file system state.
//!
//! Balance: samples are assigned to strata cyclically in global order (sample j gets
//! stratum `order[j mod S]`), so stratum counts differ by at most one over the whole dataset
//! and over every contiguous shard. Within each shard the positions are then shuffled with a
//! permutation drawn from the shard's own seed, which keeps both balances exact while making
//! neighbouring samples unpredictable.
//!
//! Seeds: `sample_seed = blake3-derive-key("bettimill sample seed v1", manifest_hash ||
//! index_le)` (32 bytes), and regeneration attempt k of that sample uses
//! `blake3-derive-key("bettimill attempt seed v1", sample_seed || k_le)` as a ChaCha8 seed.

use bettimill_grid::Dim;
use bettimill_manifest::Manifest;
use bettimill_shapes::{Family, Mode};
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
    pub class_index: usize,
    /// The construction family.
    pub family: Family,
    /// Object in empty space or cavity in a cube.
    pub mode: Mode,
    /// Analytic Betti numbers over Z/2.
    pub betti: Vec<u64>,
    /// A short human-readable name.
    pub label: String,
}

/// A contiguous range of samples written as one tar file.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ShardPlan {
    /// Shard number, from 0.
    pub index: u64,
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
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// The manifest's canonical hash.
    pub manifest_hash: String,
    /// Number of axes.
    pub dimension: Dim,
    /// Voxels per axis.
    pub side: u32,
    /// Total samples.
    pub samples: u64,
    /// The strata, in manifest order (classes outer, modes inner).
    pub strata: Vec<Stratum>,
    /// The shards, in order.
    pub shards: Vec<ShardPlan>,
    /// The order in which strata are dealt out cyclically.
    pub deal_order: Vec<usize>,
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
    /// Expands a validated manifest.
    pub fn new(manifest: &Manifest) -> Plan {
        let manifest_hash = manifest.canonical_hash();
        let mut strata = Vec::new();
        for (class_index, family) in manifest.classes.iter().enumerate() {
            for mode in manifest.mode.to_vec() {
                let betti = family
                    .expected_betti(manifest.dimension, mode)
                    .expect("a validated manifest has only existing families");
                strata.push(Stratum {
                    index: strata.len(),
                    class_index,
                    label: format!("{}/{}", family.label(), mode_name(mode)),
                    family: family.clone(),
                    mode,
                    betti,
                });
            }
        }
        let mut deal_order: Vec<usize> = (0..strata.len()).collect();
        let mut rng = ChaCha8Rng::from_seed(derive_seed(
            "bettimill deal order v1",
            &[manifest_hash.as_bytes()],
        ));
        deal_order.shuffle(&mut rng);
        let shard_count = manifest.samples.div_ceil(manifest.shard_size);
        let shards = (0..shard_count)
            .map(|index| {
                let first_sample = index * manifest.shard_size;
                ShardPlan {
                    index,
                    name: format!("{}-{index:06}", manifest.name),
                    first_sample,
                    samples: manifest.shard_size.min(manifest.samples - first_sample),
                }
            })
            .collect();
        Plan {
            manifest_hash,
            dimension: manifest.dimension,
            side: manifest.side,
            samples: manifest.samples,
            strata,
            shards,
            deal_order,
        }
    }

    /// blake3 of the plan's canonical JSON (64 hex digits).
    pub fn hash(&self) -> String {
        let json = serde_json::to_string(self).expect("a plan always serialises");
        blake3::hash(json.as_bytes()).to_hex().to_string()
    }

    /// The tasks of one shard, in the order they are written.
    pub fn shard_tasks(&self, shard: &ShardPlan) -> Vec<SampleTask> {
        let mut positions: Vec<u64> = (0..shard.samples).collect();
        let mut rng = ChaCha8Rng::from_seed(derive_seed(
            "bettimill shard shuffle v1",
            &[self.manifest_hash.as_bytes(), &shard.index.to_le_bytes()],
        ));
        positions.shuffle(&mut rng);
        let width = key_width(self.samples);
        positions
            .iter()
            .enumerate()
            .map(|(offset, &dealt)| {
                let index = shard.first_sample + offset as u64;
                let dealt_index = shard.first_sample + dealt;
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
            })
            .collect()
    }
}

/// The manifest spelling of a mode.
pub fn mode_name(mode: Mode) -> &'static str {
    match mode {
        Mode::Embed => "embed",
        Mode::Carve => "carve",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn manifest(samples: u64, shard_size: u64) -> Manifest {
        let text = bettimill_manifest::DEMO_MANIFEST
            .replace("samples = 240", &format!("samples = {samples}"))
            .replace("shard_size = 40", &format!("shard_size = {shard_size}"));
        Manifest::parse(&text, Path::new("t")).unwrap()
    }

    #[test]
    fn plans_are_reproducible() {
        let a = Plan::new(&manifest(100, 7));
        let b = Plan::new(&manifest(100, 7));
        assert_eq!(a.hash(), b.hash());
        assert_eq!(a.shard_tasks(&a.shards[3]), b.shard_tasks(&b.shards[3]));
        assert_ne!(a.hash(), Plan::new(&manifest(101, 7)).hash());
    }

    #[test]
    fn shards_cover_every_sample_once() {
        let plan = Plan::new(&manifest(103, 10));
        assert_eq!(plan.shards.len(), 11);
        let mut all: Vec<u64> = plan
            .shards
            .iter()
            .flat_map(|s| plan.shard_tasks(s))
            .map(|t| t.index)
            .collect();
        all.sort();
        assert_eq!(all, (0..103).collect::<Vec<_>>());
        assert_eq!(plan.shards[10].samples, 3);
    }

    fn counts(plan: &Plan, tasks: &[SampleTask]) -> Vec<u64> {
        let mut c = vec![0u64; plan.strata.len()];
        for t in tasks {
            c[t.stratum] += 1;
        }
        c
    }

    proptest::proptest! {
        #[test]
        fn balance_is_exact_per_dataset_and_per_shard(samples in 1u64..400, shard_size in 1u64..60) {
            let plan = Plan::new(&manifest(samples, shard_size));
            let mut all = Vec::new();
            for shard in &plan.shards {
                let tasks = plan.shard_tasks(shard);
                let c = counts(&plan, &tasks);
                proptest::prop_assert!(c.iter().max().unwrap() - c.iter().min().unwrap() <= 1);
                all.extend(tasks);
            }
            let c = counts(&plan, &all);
            proptest::prop_assert!(c.iter().max().unwrap() - c.iter().min().unwrap() <= 1);
        }
    }
}
