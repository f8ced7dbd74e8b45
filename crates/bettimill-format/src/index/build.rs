//! A shard's tar bytes and the record that describes them.

use super::stream::check_shard_name;
use super::{MemberRecord, ShardRecord};
use bettimill_shard::ustar::{self, split_key, Member, BLOCK};
use bettimill_shard::{blake3_hex, ShardError};
use std::collections::BTreeSet;

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
    let total = ustar::tar_len(samples.iter().flatten().map(|m| m.data.len() as u64));
    let mut bytes = Vec::with_capacity(total as usize);
    let record = write_shard(name, split, samples, &mut bytes, std::path::Path::new(name))?;
    Ok((bytes, record))
}

/// [`build_shard`] streamed: the same tar bytes written to `out` (a file being written
/// under a temporary name, `out_path` in its errors) member by member and hashed on the
/// way, so no copy of the shard is made in memory. Returns the record; the samples are
/// checked before anything is written.
pub fn write_shard(
    name: &str,
    split: &str,
    samples: &[Vec<Member>],
    out: &mut dyn std::io::Write,
    out_path: &std::path::Path,
) -> Result<ShardRecord, ShardError> {
    let (first_key, last_key) = check_samples(name, samples)?;
    let mut hasher = blake3::Hasher::new();
    let mut put = |bytes: &[u8]| {
        hasher.update(bytes);
        out.write_all(bytes)
            .map_err(|err| ShardError::io("cannot write", out_path, err))
    };
    const ZEROS: [u8; 2 * BLOCK as usize] = [0; 2 * BLOCK as usize];
    let mut offset = 0u64;
    let mut member_records = Vec::with_capacity(samples.iter().map(Vec::len).sum());
    for member in samples.iter().flatten() {
        let size = member.data.len() as u64;
        put(&ustar::header_block(&member.name, size)?)?;
        put(&member.data)?;
        let padding = size.div_ceil(BLOCK) * BLOCK - size;
        put(&ZEROS[..padding as usize])?;
        member_records.push(MemberRecord {
            name: member.name.clone(),
            offset: offset + BLOCK,
            bytes: size,
            blake3: blake3_hex(&member.data),
        });
        offset += BLOCK + size + padding;
    }
    put(&ZEROS)?;
    offset += 2 * BLOCK;
    Ok(ShardRecord {
        name: name.to_string(),
        split: split.to_string(),
        samples: samples.len() as u64,
        bytes: offset,
        blake3: hasher.finalize().to_hex().to_string(),
        first_key,
        last_key,
        members: member_records,
    })
}

/// Checks what [`build_shard`] requires of its name and samples; returns the first and
/// last keys.
fn check_samples(name: &str, samples: &[Vec<Member>]) -> Result<(String, String), ShardError> {
    let bad = |sample: usize, reason: String| ShardError::BadSample {
        shard: name.to_string(),
        sample,
        reason,
    };
    check_shard_name(name).map_err(|reason| ShardError::bad_name(name, reason.to_string()))?;
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
    Ok((first_key, last_key))
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
