//! The one check that a shard's tar matches its completion record.
//!
//! Because the tar bytes are deterministic, a record determines every byte of its shard but
//! member data: each header follows from the member's name and size, padding and the
//! end-of-archive marker are zeros, and each member's data has a blake3 in the record. So
//! the check first asks whether the record describes the layout bettimill writes (sample
//! count and first/last keys from the member names, the tar's size, each member's offset,
//! names that make a header), then streams the file once through a fixed buffer, header by
//! header and member by member, never past the record's size, hashing the whole as it goes.
//!
//! [`crate::verify`] collects every problem, to say where a shard is damaged; resume,
//! status and finalize ([`crate::DatasetDir::check_tar`]) stop at the first, since one
//! makes the shard incomplete. Both read the same [`Problem`]s.

use crate::index::{count_samples, MemberRecord, ShardRecord};
use crate::verify::{Problem, Region};
use bettimill_shard::ustar::{self, BLOCK};
use std::io::Read;
use std::path::{Path, PathBuf};

/// Why a tar does not match its record ([`crate::DatasetDir::check_tar`]).
#[derive(Debug, thiserror::Error)]
pub enum TarMismatch {
    /// The record is another shard's.
    #[error("{record}: it names the shard {named}, not {expected}")]
    OtherShard {
        /// The record file.
        record: PathBuf,
        /// The shard it names.
        named: String,
        /// The shard it is the record of.
        expected: String,
    },
    /// The tar is not a regular file, or cannot be looked at.
    #[error(transparent)]
    Unreadable(#[from] Box<crate::FormatError>),
    /// The tar has another size.
    #[error("{path} has {found} bytes, its record says {expected}")]
    Size {
        /// The tar.
        path: PathBuf,
        /// Its size.
        found: u64,
        /// The record's size.
        expected: u64,
    },
    /// The tar could not be read through.
    #[error("{path}: {source}")]
    Io {
        /// The tar.
        path: PathBuf,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// The first thing that differs.
    #[error("{0}")]
    Differs(Problem),
}

/// [`crate::DatasetDir::check_tar`] for a tar at `path`: its size, then (with
/// [`crate::TarCheck::Full`]) the one streamed check of the record and the tar, stopping at the
/// first problem. So a record is checked whole, not only its shard hash: a damaged member
/// hash or offset makes the shard incomplete.
pub fn check_tar_file(
    path: &Path,
    record: &ShardRecord,
    check: crate::TarCheck,
) -> Result<(), TarMismatch> {
    let size = crate::dir::regular_file_len(path).map_err(Box::new)?;
    if size != record.bytes {
        return Err(TarMismatch::Size {
            path: path.to_path_buf(),
            found: size,
            expected: record.bytes,
        });
    }
    if check == crate::TarCheck::Size {
        return Ok(());
    }
    let mut problems = Vec::new();
    if record_problems(record, &mut problems) && problems.is_empty() {
        std::fs::File::open(path)
            .and_then(|mut file| {
                file_problems(record, &mut file, size, Depth::First, &mut problems)
            })
            .map_err(|source| TarMismatch::Io {
                path: path.to_path_buf(),
                source,
            })?;
    }
    match problems.into_iter().next() {
        Some(problem) => Err(TarMismatch::Differs(problem)),
        None => Ok(()),
    }
}

/// How far a check goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Depth {
    /// Stop at the first problem: one makes the shard incomplete.
    First,
    /// Find every problem, to localise the damage.
    All,
}

/// Adds the problems `record` has on its own, without looking at the file, to `problems`.
/// Returns whether its layout is the one bettimill writes (the tar's size and each member's
/// offset from the member sizes, every name one a header can hold), so that the file can be
/// checked part by part against it.
pub(crate) fn record_problems(record: &ShardRecord, problems: &mut Vec<Problem>) -> bool {
    let shard = &record.name;
    let inconsistent = |reason: String| Problem::RecordInconsistent {
        shard: shard.clone(),
        reason,
    };
    let found = count_samples(record.members.iter().map(|m| m.name.as_str()));
    if found != record.samples {
        problems.push(Problem::SampleCount {
            shard: shard.clone(),
            expected: record.samples,
            found,
        });
    }
    let key = |member: Option<&MemberRecord>| {
        member.map_or(String::new(), |m| {
            ustar::split_key(&m.name).map_or(m.name.clone(), |(key, _)| key.to_string())
        })
    };
    let (first, last) = (key(record.members.first()), key(record.members.last()));
    if first != record.first_key || last != record.last_key {
        problems.push(inconsistent(format!(
            "its record says samples from {} to {}, its members from {first} to {last}",
            record.first_key, record.last_key
        )));
    }
    let mut consistent = true;
    let layout_len = ustar::tar_len(record.members.iter().map(|m| m.bytes));
    if layout_len != record.bytes {
        problems.push(inconsistent(format!(
            "its record lists members that take {layout_len} bytes, but says the tar has {}",
            record.bytes
        )));
        consistent = false;
    }
    let mut position = 0u64;
    for member in &record.members {
        let name = &member.name;
        if member.offset != position + BLOCK {
            problems.push(inconsistent(format!(
                "its record puts member {name} at byte {}, the layout at {}",
                member.offset,
                position + BLOCK
            )));
            consistent = false;
        }
        if let Err(err) = ustar::header_block(name, member.bytes) {
            problems.push(inconsistent(format!(
                "its record lists member {name}: {err}"
            )));
            consistent = false;
        }
        position += ustar::member_bytes(member.bytes);
    }
    consistent
}

/// Compares the tar read from `file` (from its start; `len` bytes on disk) with the layout
/// of `record`, which [`record_problems`] found consistent, adding what differs to
/// `problems`: a cut by the member and part it falls in, a corrupt header by its first wrong
/// byte, corrupt data by its member, a non-zero padding byte, trailing bytes, and a whole
/// hash that differs though every part checks out. Reads each byte once through a fixed
/// buffer and nothing past the record's size; returns the bytes read.
pub(crate) fn file_problems(
    record: &ShardRecord,
    file: &mut dyn Read,
    len: u64,
    depth: Depth,
    problems: &mut Vec<Problem>,
) -> std::io::Result<u64> {
    let shard = &record.name;
    let before = problems.len();
    let stop = |problems: &Vec<Problem>| depth == Depth::First && problems.len() > before;
    let mut stream = Stream {
        file,
        buffer: vec![0u8; 1 << 16],
        read_bytes: 0,
        whole: blake3::Hasher::new(),
    };
    let truncated = |member: Option<&str>, region| Problem::Truncated {
        shard: shard.clone(),
        expected_bytes: record.bytes,
        found_bytes: len,
        member: member.map(str::to_string),
        region,
    };
    for member in &record.members {
        let name = &member.name;
        let header_offset = member.offset - BLOCK;
        if header_offset + BLOCK > len {
            problems.push(truncated(Some(name), Region::Header));
            return Ok(stream.read_bytes);
        }
        let expected = match ustar::header_block(name, member.bytes) {
            Ok(expected) => expected,
            Err(err) => {
                problems.push(Problem::RecordInconsistent {
                    shard: shard.clone(),
                    reason: format!("its record lists member {name}: {err}"),
                });
                return Ok(stream.read_bytes);
            }
        };
        let mut found = Vec::with_capacity(BLOCK as usize);
        stream.read(BLOCK, &mut |_, b| found.extend_from_slice(b))?;
        if let Some(i) = expected.iter().zip(&found).position(|(a, b)| a != b) {
            problems.push(Problem::HeaderCorrupt {
                shard: shard.clone(),
                member: name.clone(),
                header_offset,
                offset: header_offset + i as u64,
            });
            if stop(problems) {
                return Ok(stream.read_bytes);
            }
        }
        let data_end = member.offset + member.bytes;
        if data_end > len {
            problems.push(truncated(Some(name), Region::Data));
            return Ok(stream.read_bytes);
        }
        let mut hasher = blake3::Hasher::new();
        stream.read(member.bytes, &mut |_, b| {
            hasher.update(b);
        })?;
        let found_blake3 = hasher.finalize().to_hex().to_string();
        if found_blake3 != member.blake3 {
            problems.push(Problem::DataCorrupt {
                shard: shard.clone(),
                member: name.clone(),
                offset: member.offset,
                bytes: member.bytes,
                expected_blake3: member.blake3.clone(),
                found_blake3,
            });
            if stop(problems) {
                return Ok(stream.read_bytes);
            }
        }
        let padded_end = data_end.div_ceil(BLOCK) * BLOCK;
        if padded_end > len {
            problems.push(truncated(Some(name), Region::Padding));
            return Ok(stream.read_bytes);
        }
        if let Some(offset) = stream.first_non_zero(padded_end - data_end)? {
            problems.push(Problem::NonZeroPadding {
                shard: shard.clone(),
                member: Some(name.clone()),
                offset,
            });
            if stop(problems) {
                return Ok(stream.read_bytes);
            }
        }
    }
    if len < record.bytes {
        problems.push(truncated(None, Region::EndMarker));
        if stop(problems) {
            return Ok(stream.read_bytes);
        }
    }
    let marker_end = record.bytes.min(len);
    if let Some(offset) = stream.first_non_zero(marker_end.saturating_sub(stream.read_bytes))? {
        problems.push(Problem::NonZeroPadding {
            shard: shard.clone(),
            member: None,
            offset,
        });
    }
    if len > record.bytes {
        problems.push(Problem::TrailingBytes {
            shard: shard.clone(),
            expected_bytes: record.bytes,
            found_bytes: len,
        });
    }
    if problems.len() == before {
        let found_blake3 = stream.whole.finalize().to_hex().to_string();
        if found_blake3 != record.blake3 {
            problems.push(Problem::HashMismatch {
                shard: shard.clone(),
                expected_blake3: record.blake3.clone(),
                found_blake3,
            });
        }
    }
    Ok(stream.read_bytes)
}

/// A shard file read from its start through one fixed buffer, hashed whole as it goes.
struct Stream<'a> {
    file: &'a mut dyn Read,
    buffer: Vec<u8>,
    /// Bytes read so far: the offset of the next one.
    read_bytes: u64,
    whole: blake3::Hasher,
}

impl Stream<'_> {
    /// Reads the next `len` bytes, calling `each` with them in order, with their offsets.
    fn read(&mut self, len: u64, each: &mut dyn FnMut(u64, &[u8])) -> std::io::Result<()> {
        let mut left = len;
        while left > 0 {
            let take = left.min(self.buffer.len() as u64) as usize;
            self.file.read_exact(&mut self.buffer[..take])?;
            self.whole.update(&self.buffer[..take]);
            each(self.read_bytes, &self.buffer[..take]);
            self.read_bytes += take as u64;
            left -= take as u64;
        }
        Ok(())
    }

    /// Reads the next `len` bytes; the offset of the first non-zero one.
    fn first_non_zero(&mut self, len: u64) -> std::io::Result<Option<u64>> {
        let mut found = None;
        self.read(len, &mut |at, bytes| {
            if found.is_none() {
                found = bytes.iter().position(|&b| b != 0).map(|i| at + i as u64);
            }
        })?;
        Ok(found)
    }
}
