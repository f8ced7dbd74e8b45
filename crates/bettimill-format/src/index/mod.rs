//! The dataset index (`index.json`), shard records, and the wids shard index.
//!
//! # `index.json`
//!
//! A JSON object with keys in this order: `format` (always `"bettimill-index"`),
//! `format_version` ([`INDEX_FORMAT_VERSION`]), `tool_version`, `manifest_hash`,
//! `plan_hash`, `shard_count`, `samples`, `shards`, `files`. `files` ([`IndexFile`]) lists
//! every other file of the directory the build wrote (manifest, identity, class table,
//! dataset card, wids indexes) with its size and blake3, sorted by name, so that
//! [`crate::verify()`] covers every byte a build writes; it comes after `shards` so that the
//! wids indexes, written while the shards are listed, can be in it. Each entry of `shards`
//! ([`IndexShard`]) holds `name` (path relative to the dataset directory, always under
//! `shards/`), `split`, `samples`, `bytes`, `blake3` (hex of the whole tar), `first_key`,
//! `last_key` and `record_blake3` (hex of the shard's completion record file, which holds
//! the per-member records: `name`, `offset` of its first data byte in the tar, `bytes`,
//! `blake3` of its data). So the index grows with shards, not with members.
//! Written pretty-printed with two-space indentation and a trailing newline, keys in
//! declaration order, so equal indexes are equal bytes; [`IndexWriter`] writes it one shard
//! at a time and [`read_index`] reads it one shard at a time, so neither holds the list.
//!
//! Format version 1 (bettimill 0.1.0) listed every member in the index
//! instead (about 590 bytes per sample); version 2 had no `files`. Both are refused with a
//! message saying so (`bettimill finalize DIR` rewrites the index from the records).
//!
//! Invariants checked while reading (an index breaking them is refused, because
//! [`crate::verify()`] and readers join shard names onto the dataset directory): the format
//! name and version match, shard names are unique, relative, under `shards/` and free of
//! `..`, `shard_count` and `samples` add up, and `files` names at most [`MAX_INDEX_FILES`]
//! distinct plain file names of the directory itself (not `index.json`).

mod build;
mod error;
mod stream;
#[cfg(test)]
mod tests;
mod wids;

pub use build::{build_shard, count_samples, write_shard};
pub use error::{IndexError, IndexRefusal};
pub use stream::{read_index, read_index_from, IndexWriter, MAX_INDEX_SPLITS};
pub use wids::{wids_index, WidsWriter};

use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::path::Path;

/// Value of [`IndexHeader::format`].
pub const INDEX_FORMAT: &str = "bettimill-index";
/// Value of [`IndexHeader::format_version`] written by this version.
pub const INDEX_FORMAT_VERSION: u32 = 3;
/// Most entries `files` may hold (a dataset has a few files besides its shards and records:
/// one wids index per split).
pub const MAX_INDEX_FILES: usize = 4096;

/// A file of the dataset directory other than shards and records, as `index.json` lists it.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct IndexFile {
    /// File name, relative to the dataset directory (no directory part).
    pub name: String,
    /// Its size.
    pub bytes: u64,
    /// BLAKE3 of the whole file, lowercase hex.
    pub blake3: String,
}

/// Where one member's data sits in its shard, and its hash.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct MemberRecord {
    /// Name inside the tar.
    pub name: String,
    /// Offset of the member's first data byte in the tar (its header is 512 bytes before).
    pub offset: u64,
    /// Length of the member's data.
    pub bytes: u64,
    /// BLAKE3 of the member's data, lowercase hex.
    pub blake3: String,
}

/// One shard file of the dataset, with every member: the record a shard's completion record
/// holds, and what [`crate::verify()`] checks a tar against.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct ShardRecord {
    /// Path relative to the dataset directory, such as `shards/train-000000.tar`.
    pub name: String,
    /// The split the shard belongs to (`train`, `val`, ...).
    pub split: String,
    /// Number of samples (runs of members sharing a key).
    pub samples: u64,
    /// Size of the tar file.
    pub bytes: u64,
    /// BLAKE3 of the whole tar file, lowercase hex.
    pub blake3: String,
    /// Key of the first sample.
    pub first_key: String,
    /// Key of the last sample.
    pub last_key: String,
    /// Every member, in tar order.
    pub members: Vec<MemberRecord>,
}

impl ShardRecord {
    /// The shard's entry in `index.json`, given the blake3 of its record file.
    pub fn index_entry(&self, record_blake3: impl Into<String>) -> IndexShard {
        IndexShard {
            name: self.name.clone(),
            split: self.split.clone(),
            samples: self.samples,
            bytes: self.bytes,
            blake3: self.blake3.clone(),
            first_key: self.first_key.clone(),
            last_key: self.last_key.clone(),
            record_blake3: record_blake3.into(),
        }
    }

    /// How this record disagrees with an index entry (everything but `record_blake3`).
    pub fn disagreement(&self, entry: &IndexShard) -> Option<String> {
        let mine = self.index_entry(entry.record_blake3.clone());
        (mine != *entry).then(|| {
            format!(
                "the index says {} samples, {} bytes, blake3 {}, keys {}..{} in split {}; its record says {} samples, {} bytes, blake3 {}, keys {}..{} in split {}",
                entry.samples, entry.bytes, entry.blake3, entry.first_key, entry.last_key, entry.split,
                self.samples, self.bytes, self.blake3, self.first_key, self.last_key, self.split,
            )
        })
    }
}

/// One shard in `index.json`: its file and the hash of its record (members are in the
/// record, not here).
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct IndexShard {
    /// Path relative to the dataset directory, such as `shards/train-000000.tar`.
    pub name: String,
    /// The split the shard belongs to.
    pub split: String,
    /// Number of samples.
    pub samples: u64,
    /// Size of the tar file.
    pub bytes: u64,
    /// BLAKE3 of the whole tar file, lowercase hex.
    pub blake3: String,
    /// Key of the first sample.
    pub first_key: String,
    /// Key of the last sample.
    pub last_key: String,
    /// BLAKE3 of the shard's completion record file (which lists every member), lowercase hex.
    pub record_blake3: String,
}

/// Everything in `index.json` before the list of shards.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
pub struct IndexHeader {
    /// Always [`INDEX_FORMAT`].
    pub format: String,
    /// [`INDEX_FORMAT_VERSION`] when written by this version.
    pub format_version: u32,
    /// Version of the bettimill that wrote the dataset.
    pub tool_version: String,
    /// Hash of the manifest the dataset was built from.
    pub manifest_hash: String,
    /// Hash of the build plan.
    pub plan_hash: String,
    /// Number of shards listed.
    pub shard_count: u64,
    /// Samples in all shards.
    pub samples: u64,
    /// Every other file of the directory, sorted by name (written after `shards`).
    #[serde(skip)]
    pub files: Vec<IndexFile>,
}

impl IndexHeader {
    /// A header of the current format.
    pub fn new(
        tool_version: impl Into<String>,
        manifest_hash: impl Into<String>,
        plan_hash: impl Into<String>,
        shard_count: u64,
        samples: u64,
    ) -> IndexHeader {
        IndexHeader {
            format: INDEX_FORMAT.to_string(),
            format_version: INDEX_FORMAT_VERSION,
            tool_version: tool_version.into(),
            manifest_hash: manifest_hash.into(),
            plan_hash: plan_hash.into(),
            shard_count,
            samples,
            files: Vec::new(),
        }
    }

    /// The header listing `files` (sorted here by name).
    pub fn with_files(mut self, mut files: Vec<IndexFile>) -> IndexHeader {
        files.sort_by(|a, b| a.name.cmp(&b.name));
        self.files = files;
        self
    }
}

/// The contents of `index.json`, held in memory: for tests and small datasets. Large ones
/// are written with [`IndexWriter`] and read with [`read_index`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Index {
    /// Everything but the shards.
    pub header: IndexHeader,
    /// Every shard, in the order the build wrote them.
    pub shards: Vec<IndexShard>,
}

impl Index {
    /// An index of the current format with the given shards.
    pub fn new(
        tool_version: impl Into<String>,
        manifest_hash: impl Into<String>,
        plan_hash: impl Into<String>,
        shards: Vec<IndexShard>,
    ) -> Index {
        let samples = shards.iter().map(|s| s.samples).sum();
        Index {
            header: IndexHeader::new(
                tool_version,
                manifest_hash,
                plan_hash,
                shards.len() as u64,
                samples,
            ),
            shards,
        }
    }

    /// Reads and validates an index file (see the module documentation for the checks).
    pub fn read(path: &Path) -> Result<Index, IndexError> {
        let mut shards = Vec::new();
        let header = read_index(path, &mut |_, shard| shards.push(shard))?;
        Ok(Index { header, shards })
    }

    /// Parses and validates index bytes; `path` is only used in error messages.
    pub fn from_json_bytes(bytes: &[u8], path: &Path) -> Result<Index, IndexError> {
        let mut shards = Vec::new();
        let header = read_index_from(bytes, path, &mut |_, shard| shards.push(shard))?;
        Ok(Index { header, shards })
    }

    /// Pretty JSON with keys in declaration order and a trailing newline (what
    /// [`IndexWriter`] writes for the same shards).
    pub fn to_json_bytes(&self) -> Vec<u8> {
        let mut writer =
            IndexWriter::new(Vec::new(), &self.header).expect("writing to memory cannot fail");
        for shard in &self.shards {
            writer.push(shard).expect("writing to memory cannot fail");
        }
        writer.finish().expect("writing to memory cannot fail")
    }

    /// The shards of one split, in index order.
    pub fn split_shards(&self, split: &str) -> Vec<IndexShard> {
        self.shards
            .iter()
            .filter(|s| s.split == split)
            .cloned()
            .collect()
    }

    /// The distinct split names, sorted.
    pub fn splits(&self) -> Vec<String> {
        let set: BTreeSet<&str> = self.shards.iter().map(|s| s.split.as_str()).collect();
        set.into_iter().map(str::to_string).collect()
    }
}
