//! Shards and dealing: shards computed on demand from the split table, and the balanced,
//! shuffled dealing of strata to samples (never stored: any shard or task is computed in
//! constant time from the plan).

use crate::{derive_seed, Plan};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

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

/// Width of the zero-padded sample number in keys: at least 6 digits.
pub(crate) fn key_width(samples: u64) -> usize {
    samples.saturating_sub(1).to_string().len().max(6)
}

impl Plan {
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
    pub(crate) fn range_counts(&self, first: u64, end: u64) -> Vec<u64> {
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
    pub(crate) fn shard_positions(&self, shard: &ShardPlan) -> Vec<u64> {
        let mut positions: Vec<u64> = (0..shard.samples).collect();
        let mut rng = ChaCha8Rng::from_seed(derive_seed(
            "bettimill shard shuffle v1",
            &[self.manifest_hash.as_bytes(), &shard.index.to_le_bytes()],
        ));
        positions.shuffle(&mut rng);
        positions
    }

    /// The task written at `offset` in `shard`, given its [`Plan::shard_positions`].
    pub(crate) fn task_in(&self, shard: &ShardPlan, positions: &[u64], offset: u64) -> SampleTask {
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
