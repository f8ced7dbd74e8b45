//! One shard judged from the directory, as resume, status and finalize see it: its record
//! and the tar checked against it ([`ShardState`], [`TarCheck`]), and the one way to read a
//! shard's members ([`DatasetDir::open_tar`], bounded by the record).

use super::{io, CompletionRecord, DatasetDir};
use crate::tar_check::{self, TarMismatch};
use crate::{FormatError, ShardRecord};
use bettimill_shard as shard;
use std::path::Path;

/// What the directory says about one shard.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ShardState {
    /// Its record exists and the tar matches it.
    Complete(CompletionRecord),
    /// Neither tar nor record exists.
    Missing,
    /// Something exists but does not make a complete shard; it will be rebuilt.
    Invalid {
        /// What is wrong.
        reason: String,
    },
}

/// How much of a tar [`DatasetDir::check_tar`] compares with its record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TarCheck {
    /// Size only: for shards this process has just written and hashed.
    Size,
    /// Size, then the blake3 of the whole file, streamed through a fixed buffer.
    Full,
}

impl DatasetDir {
    /// Whether the tar of `shard` matches `record`: its size and, with [`TarCheck::Full`],
    /// the record's layout, every member's blake3 and the whole file's, streamed through a
    /// fixed buffer (a shard is never held in memory). The error is the first problem, in
    /// the words `verify` uses: both run the one tar check of this crate.
    pub fn check_tar(
        &self,
        shard: &str,
        record: &ShardRecord,
        check: TarCheck,
    ) -> Result<(), TarMismatch> {
        let relative = DatasetDir::relative_tar_name(shard);
        if record.name != relative {
            return Err(TarMismatch::OtherShard {
                record: self.record_path(shard),
                named: record.name.clone(),
                expected: relative,
            });
        }
        tar_check::check_tar_file(&self.tar_path(shard), record, check)
    }

    /// The state of one shard, judged from the directory alone (size and streamed hash).
    pub fn shard_state(&self, shard: &str) -> ShardState {
        self.shard_state_checked(shard, TarCheck::Full)
    }

    /// [`DatasetDir::shard_state`] with a chosen depth of the tar check.
    pub fn shard_state_checked(&self, shard: &str, check: TarCheck) -> ShardState {
        let record = match self.read_record(shard) {
            Ok(Some(record)) => record,
            Ok(None) => {
                let tar = self.tar_path(shard);
                return if tar.exists() {
                    ShardState::Invalid {
                        reason: format!("{} has no completion record", tar.display()),
                    }
                } else {
                    ShardState::Missing
                };
            }
            Err(err) => {
                return ShardState::Invalid {
                    reason: err.to_string(),
                }
            }
        };
        match self.check_tar(shard, &record.shard, check) {
            Ok(()) => ShardState::Complete(record),
            Err(mismatch) => ShardState::Invalid {
                reason: mismatch.to_string(),
            },
        }
    }

    /// The shard's completion record if the shard on disk matches it (size and hash).
    pub fn completed(&self, shard: &str) -> Option<CompletionRecord> {
        match self.shard_state(shard) {
            ShardState::Complete(record) => Some(record),
            _ => None,
        }
    }

    /// The shard's completion record if the tar on disk has the record's size (no hash).
    pub fn recorded(&self, shard: &str) -> Option<CompletionRecord> {
        match self.shard_state_checked(shard, TarCheck::Size) {
            ShardState::Complete(record) => Some(record),
            _ => None,
        }
    }

    /// Opens the tar of `shard` for reading member after member ([`ShardStream`]), after
    /// checking the file against its completion record: it must be a regular file (not a
    /// device, such as a link to `/dev/zero`) of the record's size, and a member whose tar
    /// header claims more than the record's largest member is refused by that header. So a
    /// reader holds one member at a time, bounded by the record, whatever the file holds.
    /// Without a record (a tar renamed into place whose record was not written yet) the
    /// file's own size bounds the reading and a member may have `max_member_bytes`.
    pub fn open_tar(
        &self,
        shard: &str,
        max_member_bytes: u64,
    ) -> Result<ShardStream<'static>, FormatError> {
        let record = self.read_record(shard)?;
        let path = self.tar_path(shard);
        match record {
            Some(record) => open_tar_file(
                &path,
                Some((&record.shard, &self.record_path(shard))),
                max_member_bytes,
            ),
            None => open_tar_file(&path, None, max_member_bytes),
        }
    }
}

/// A shard opened by [`DatasetDir::open_tar`], [`open_tar_file`] or
/// [`crate::DatasetSource::open_tar`]: its members one at a time through a fixed buffer,
/// reading bounded by the expected size. The reader is a file's or an object's (by ranges).
pub type ShardStream<'a> = shard::TarStream<Box<dyn std::io::Read + Send + 'a>>;

/// The size of the regular file at `path`; an error naming it for anything else (a device
/// such as `/dev/zero`, which reports no size and never ends, a directory, a FIFO). The
/// check is storage's [`shard::regular_len`]; only its error is put in this crate's terms.
pub(crate) fn regular_file_len(path: &Path) -> Result<u64, FormatError> {
    shard::regular_len(path).map_err(|err| match err {
        shard::RegularFileError::Io(err) => io(path)(err),
        err @ shard::RegularFileError::NotRegular => FormatError::Corrupt {
            path: path.to_path_buf(),
            reason: format!("is {err}"),
        },
    })
}

/// Opens a tar file for streaming (see [`DatasetDir::open_tar`]). With `record` (the
/// shard's record and the record file's path, for the message) the file must have the
/// record's size and each member at most the record's largest member and
/// `max_member_bytes`; without, the file's size bounds the reading.
pub fn open_tar_file(
    path: &Path,
    record: Option<(&ShardRecord, &Path)>,
    max_member_bytes: u64,
) -> Result<ShardStream<'static>, FormatError> {
    let size = regular_file_len(path)?;
    let file = std::fs::File::open(path).map_err(io(path))?;
    let reader = std::io::BufReader::with_capacity(1 << 16, file);
    stream_checked(reader, size, path, record, max_member_bytes)
}

/// The one check before a shard is streamed, for a file and an object alike: with
/// `record`, the tar (`size` bytes, named `location`) must have the record's size and each
/// member at most the record's largest and `max_member_bytes`; without, `size` bounds it.
pub(crate) fn stream_checked<'a>(
    reader: impl std::io::Read + Send + 'a,
    size: u64,
    location: &Path,
    record: Option<(&ShardRecord, &Path)>,
    max_member_bytes: u64,
) -> Result<ShardStream<'a>, FormatError> {
    let (expected, limit) = match record {
        Some((record, record_path)) => {
            if size != record.bytes {
                return Err(FormatError::Corrupt {
                    path: location.to_path_buf(),
                    reason: format!(
                        "has {size} bytes, its completion record {} says {}; it was not read (`bettimill verify` says where it differs, `bettimill build` rebuilds it)",
                        record_path.display(),
                        record.bytes
                    ),
                });
            }
            let largest = record.members.iter().map(|m| m.bytes).max().unwrap_or(0);
            (record.bytes, largest.min(max_member_bytes))
        }
        None => (size, max_member_bytes),
    };
    let reader: Box<dyn std::io::Read + Send + 'a> =
        Box::new(std::io::Read::take(reader, expected));
    Ok(shard::TarStream::new(reader, location, limit))
}
