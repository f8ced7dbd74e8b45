//! The dataset index (`index.json`), shard records, and the wids shard index.
//!
//! # `index.json`
//!
//! A JSON object with keys in this order: `format` (always `"bettimill-index"`),
//! `format_version` ([`INDEX_FORMAT_VERSION`]), `tool_version`, `manifest_hash`,
//! `plan_hash`, `shards`. Each shard record holds `name` (path relative to the dataset
//! directory, always under `shards/`), `split`, `samples`, `bytes`, `blake3` (hex of the
//! whole tar), `first_key`, `last_key` and `members`; each member record holds `name`,
//! `offset` (of its first data byte in the tar), `bytes` and `blake3` (hex of its data).
//! Written pretty-printed with two-space indentation and a trailing newline, keys in
//! declaration order, so equal indexes are equal bytes.
//!
//! Invariants checked by [`Index::read`] (an index breaking them is refused, because
//! [`crate::verify()`] and readers join shard names onto the dataset directory): the format
//! name and version match, shard names are unique, relative, under `shards/` and free of
//! `..`, and every member record lies where the deterministic layout of
//! [`crate::tar_bytes`] puts it, so the records add up to the shard's size.
//!
//! # wids index
//!
//! [`wids_index`] writes the `wids-shard-index-v1` JSON that `wids.ShardListDataset` opens:
//! `{"__kind__": "wids-shard-index-v1", "wids_version": 1, "name": ..., "shardlist":
//! [{"url": ..., "nsamples": ..., "filesize": ...}]}`. URLs are the shard names relative to
//! the dataset directory, so the index file belongs in that directory.

use crate::ustar::{self, split_key, Member, BLOCK};
use crate::ShardError;
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::path::Path;

/// Value of [`Index::format`].
pub const INDEX_FORMAT: &str = "bettimill-index";
/// Value of [`Index::format_version`] written by this version.
pub const INDEX_FORMAT_VERSION: u32 = 1;

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

/// One shard file of the dataset.
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

/// The contents of `index.json`.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Index {
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
    /// Every shard, in the order the build wrote them.
    pub shards: Vec<ShardRecord>,
}

impl Index {
    /// An index of the current format with the given shards.
    pub fn new(
        tool_version: impl Into<String>,
        manifest_hash: impl Into<String>,
        plan_hash: impl Into<String>,
        shards: Vec<ShardRecord>,
    ) -> Index {
        Index {
            format: INDEX_FORMAT.to_string(),
            format_version: INDEX_FORMAT_VERSION,
            tool_version: tool_version.into(),
            manifest_hash: manifest_hash.into(),
            plan_hash: plan_hash.into(),
            shards,
        }
    }

    /// Reads and validates an index file (see the module documentation for the checks).
    pub fn read(path: &Path) -> Result<Index, ShardError> {
        let bytes = std::fs::read(path).map_err(|e| ShardError::io("cannot read", path, e))?;
        Index::from_json_bytes(&bytes, path)
    }

    /// Parses and validates index bytes; `path` is only used in error messages.
    pub fn from_json_bytes(bytes: &[u8], path: &Path) -> Result<Index, ShardError> {
        let index: Index = serde_json::from_slice(bytes).map_err(|source| ShardError::Json {
            path: path.to_path_buf(),
            source,
        })?;
        index.validate().map_err(|reason| ShardError::IndexFormat {
            path: path.to_path_buf(),
            reason,
        })?;
        Ok(index)
    }

    fn validate(&self) -> Result<(), String> {
        if self.format != INDEX_FORMAT {
            return Err(format!(
                "format is {:?}, expected {INDEX_FORMAT:?}",
                self.format
            ));
        }
        if self.format_version != INDEX_FORMAT_VERSION {
            return Err(format!(
                "format_version {} is not supported (this bettimill reads version {INDEX_FORMAT_VERSION}); use the bettimill version that wrote it ({})",
                self.format_version, self.tool_version
            ));
        }
        let mut seen = BTreeSet::new();
        for shard in &self.shards {
            check_shard_name(&shard.name)?;
            if !seen.insert(shard.name.as_str()) {
                return Err(format!("shard {:?} is listed twice", shard.name));
            }
            let mut expected_offset = BLOCK;
            for member in &shard.members {
                if member.offset != expected_offset {
                    return Err(format!(
                        "shard {:?}: member {:?} is recorded at offset {}, the layout puts it at {expected_offset}",
                        shard.name, member.name, member.offset
                    ));
                }
                expected_offset = member
                    .offset
                    .checked_add(member.bytes.div_ceil(BLOCK) * BLOCK + BLOCK)
                    .ok_or_else(|| format!("shard {:?}: member sizes overflow", shard.name))?;
            }
            let expected_bytes = ustar::tar_len(shard.members.iter().map(|m| m.bytes));
            if shard.bytes != expected_bytes {
                return Err(format!(
                    "shard {:?}: recorded size {} but its members add up to {expected_bytes}",
                    shard.name, shard.bytes
                ));
            }
        }
        Ok(())
    }

    /// Pretty JSON with keys in declaration order and a trailing newline.
    pub fn to_json_bytes(&self) -> Vec<u8> {
        to_pretty_json(self)
    }

    /// The shards of one split, in index order.
    pub fn split_shards(&self, split: &str) -> Vec<ShardRecord> {
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

fn to_pretty_json<T: Serialize>(value: &T) -> Vec<u8> {
    let mut out = serde_json::to_vec_pretty(value)
        .expect("index types serialise infallibly: string keys, no maps with non-string keys");
    out.push(b'\n');
    out
}

fn check_shard_name(name: &str) -> Result<(), String> {
    let Some(rest) = name.strip_prefix("shards/") else {
        return Err(format!("shard name {name:?} is not under shards/"));
    };
    if rest.is_empty()
        || rest
            .split('/')
            .any(|c| c.is_empty() || c == "." || c == "..")
        || name.contains('\\')
        || name.chars().any(char::is_control)
    {
        return Err(format!(
            "shard name {name:?} is not a plain relative path under shards/"
        ));
    }
    Ok(())
}

/// Lowercase hex BLAKE3 of `bytes`.
pub fn blake3_hex(bytes: &[u8]) -> String {
    blake3::hash(bytes).to_hex().to_string()
}

/// Builds one shard: the tar bytes of the samples (members of each sample together, in
/// the given order) and the record describing them.
///
/// Each sample must be non-empty, its members must share one key, their fields must be in
/// strictly increasing order (sorted, no duplicates), and keys must be unique within the
/// shard, so that every WebDataset reader groups the members back into the same samples.
/// `name` must be a relative path under `shards/`.
pub fn build_shard(
    name: &str,
    split: &str,
    samples: &[Vec<Member>],
) -> Result<(Vec<u8>, ShardRecord), ShardError> {
    let bad = |sample: usize, reason: String| ShardError::BadSample {
        shard: name.to_string(),
        sample,
        reason,
    };
    check_shard_name(name).map_err(|reason| ShardError::bad_name(name, reason))?;
    if samples.is_empty() {
        return Err(bad(0, "a shard needs at least one sample".into()));
    }
    let mut keys = BTreeSet::new();
    let mut first_key = String::new();
    let mut last_key = String::new();
    for (position, sample) in samples.iter().enumerate() {
        let Some(first) = sample.first() else {
            return Err(bad(position, "sample has no members".into()));
        };
        ustar::check_member_name(&first.name)?;
        let (key, _) = split_key(&first.name).expect("checked names have a key");
        let mut previous_field: Option<&str> = None;
        for member in sample {
            ustar::check_member_name(&member.name)?;
            let (member_key, field) = split_key(&member.name).expect("checked names have a key");
            if member_key != key {
                return Err(bad(
                    position,
                    format!(
                        "member {:?} has key {member_key:?}, the sample's key is {key:?}",
                        member.name
                    ),
                ));
            }
            if let Some(previous) = previous_field {
                if field <= previous {
                    return Err(bad(
                        position,
                        format!("field {field:?} comes after {previous:?}: fields must be sorted and distinct"),
                    ));
                }
            }
            previous_field = Some(field);
        }
        if !keys.insert(key.to_string()) {
            return Err(bad(
                position,
                format!("key {key:?} appears twice in the shard"),
            ));
        }
        if position == 0 {
            first_key = key.to_string();
        }
        last_key = key.to_string();
    }
    let members: Vec<Member> = samples.iter().flatten().cloned().collect();
    let bytes = ustar::tar_bytes(&members)?;
    let mut offset = BLOCK;
    let member_records = members
        .iter()
        .map(|member| {
            let size = member.data.len() as u64;
            let record = MemberRecord {
                name: member.name.clone(),
                offset,
                bytes: size,
                blake3: blake3_hex(&member.data),
            };
            offset += size.div_ceil(BLOCK) * BLOCK + BLOCK;
            record
        })
        .collect();
    let record = ShardRecord {
        name: name.to_string(),
        split: split.to_string(),
        samples: samples.len() as u64,
        bytes: bytes.len() as u64,
        blake3: blake3_hex(&bytes),
        first_key,
        last_key,
        members: member_records,
    };
    Ok((bytes, record))
}

/// Counts samples the way WebDataset readers do: a new sample starts whenever a
/// member's key differs from the previous member's key.
pub fn count_samples<'a>(member_names: impl IntoIterator<Item = &'a str>) -> u64 {
    let mut count = 0;
    let mut previous: Option<&str> = None;
    for name in member_names {
        let key = split_key(name).map_or(name, |(key, _)| key);
        if previous != Some(key) {
            count += 1;
            previous = Some(key);
        }
    }
    count
}

#[derive(Serialize)]
struct WidsIndex<'a> {
    #[serde(rename = "__kind__")]
    kind: &'static str,
    wids_version: u32,
    name: &'a str,
    shardlist: Vec<WidsShard<'a>>,
}

#[derive(Serialize)]
struct WidsShard<'a> {
    url: &'a str,
    nsamples: u64,
    filesize: u64,
}

/// The `wids-shard-index-v1` JSON (pretty, trailing newline) listing `shards` in order,
/// with URLs relative to the dataset directory. Pass the shards of one split.
pub fn wids_index(name: &str, shards: &[ShardRecord]) -> Vec<u8> {
    to_pretty_json(&WidsIndex {
        kind: "wids-shard-index-v1",
        wids_version: 1,
        name,
        shardlist: shards
            .iter()
            .map(|s| WidsShard {
                url: &s.name,
                nsamples: s.samples,
                filesize: s.bytes,
            })
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(key: &str, fields: &[&str]) -> Vec<Member> {
        fields
            .iter()
            .map(|f| Member::new(format!("{key}.{f}"), format!("{key}:{f}").into_bytes()))
            .collect()
    }

    #[test]
    fn record_matches_the_tar() {
        let samples = vec![
            sample("train/s1", &["cls", "json", "npy"]),
            sample("train/s2", &["cls", "json", "npy"]),
        ];
        let (bytes, record) = build_shard("shards/train-000000.tar", "train", &samples).unwrap();
        assert_eq!(record.samples, 2);
        assert_eq!(record.bytes, bytes.len() as u64);
        assert_eq!(record.first_key, "train/s1");
        assert_eq!(record.last_key, "train/s2");
        assert_eq!(record.blake3, blake3_hex(&bytes));
        let entries = ustar::tar_entries(&bytes, u64::MAX).unwrap();
        assert_eq!(entries.len(), record.members.len());
        for (entry, member) in entries.iter().zip(&record.members) {
            assert_eq!(entry.name, member.name);
            assert_eq!(entry.data_offset(), member.offset);
            assert_eq!(blake3_hex(entry.data), member.blake3);
        }
        assert_eq!(
            count_samples(record.members.iter().map(|m| m.name.as_str())),
            2
        );
    }

    #[test]
    fn badly_grouped_samples_are_refused() {
        let name = "shards/x-000000.tar";
        let check = |samples: Vec<Vec<Member>>| build_shard(name, "train", &samples);
        assert!(check(vec![]).is_err());
        assert!(check(vec![vec![]]).is_err());
        assert!(
            check(vec![sample("a", &["npy", "json"])]).is_err(),
            "unsorted"
        );
        assert!(
            check(vec![sample("a", &["json", "json"])]).is_err(),
            "duplicate"
        );
        let mut mixed = sample("a", &["json"]);
        mixed.extend(sample("b", &["npy"]));
        assert!(check(vec![mixed]).is_err(), "two keys");
        assert!(check(vec![sample("a", &["json"]), sample("a", &["npy"])]).is_err());
        assert!(build_shard("../x.tar", "t", &[sample("a", &["json"])]).is_err());
        assert!(build_shard("x.tar", "t", &[sample("a", &["json"])]).is_err());
        assert!(check(vec![sample("a", &["json"])]).is_ok());
    }

    #[test]
    fn index_round_trips_and_validates() {
        let (_, record) = build_shard(
            "shards/t-000000.tar",
            "train",
            &[sample("a", &["json", "npy"])],
        )
        .unwrap();
        let index = Index::new("0.1.0", "m", "p", vec![record.clone()]);
        let bytes = index.to_json_bytes();
        assert!(bytes.ends_with(b"}\n"));
        let text = String::from_utf8(bytes.clone()).unwrap();
        let format_at = text.find("\"format\"").unwrap();
        let shards_at = text.find("\"shards\"").unwrap();
        assert!(format_at < shards_at, "declaration order");
        let path = Path::new("index.json");
        assert_eq!(Index::from_json_bytes(&bytes, path).unwrap(), index);

        let mut evil = index.clone();
        evil.shards[0].name = "shards/../../etc/passwd".into();
        assert!(Index::from_json_bytes(&evil.to_json_bytes(), path).is_err());
        let mut twice = index.clone();
        twice.shards.push(record.clone());
        assert!(Index::from_json_bytes(&twice.to_json_bytes(), path).is_err());
        let mut lying = index.clone();
        lying.shards[0].bytes += 512;
        assert!(Index::from_json_bytes(&lying.to_json_bytes(), path).is_err());
        let mut moved = index.clone();
        moved.shards[0].members[1].offset += 1;
        assert!(Index::from_json_bytes(&moved.to_json_bytes(), path).is_err());
        let mut future = index;
        future.format_version = 2;
        let err = Index::from_json_bytes(&future.to_json_bytes(), path).unwrap_err();
        assert!(err.to_string().contains("format_version 2"), "{err}");
        assert!(matches!(
            Index::from_json_bytes(b"{", path),
            Err(ShardError::Json { .. })
        ));
    }

    #[test]
    fn wids_index_has_the_documented_shape() {
        let (_, record) =
            build_shard("shards/t-000000.tar", "train", &[sample("a", &["json"])]).unwrap();
        let json: serde_json::Value =
            serde_json::from_slice(&wids_index("train", &[record])).unwrap();
        assert_eq!(json["__kind__"], "wids-shard-index-v1");
        assert_eq!(json["wids_version"], 1);
        assert_eq!(json["shardlist"][0]["url"], "shards/t-000000.tar");
        assert_eq!(json["shardlist"][0]["nsamples"], 1);
    }
}
