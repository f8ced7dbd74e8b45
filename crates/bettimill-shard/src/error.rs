//! The one error type of the storage layer.
//!
//! Every variant carries the facts a user needs to act on it: the path of the file, the
//! member name, the byte offset in the tar, the limit that was exceeded. Problems that
//! `bettimill verify` finds in a dataset are not errors (the run goes on and reports them
//! all); they are `bettimill_format::Problem`s.

use std::path::{Path, PathBuf};

/// Why a shard could not be written, read or checked.
#[derive(Debug, thiserror::Error)]
pub enum ShardError {
    /// A file or directory could not be read, written, synced or renamed.
    #[error("{action} {path}: {source}")]
    Io {
        /// What was being done ("cannot write", "cannot fsync", ...).
        action: &'static str,
        /// The file or directory.
        path: PathBuf,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// A member name breaks the naming rules of [`crate::tar_bytes`].
    #[error("member name {name:?} refused: {reason}")]
    BadName {
        /// The name as given (or as found in the tar).
        name: String,
        /// Which rule it breaks.
        reason: String,
    },
    /// A member is larger than a USTAR header can describe or than the reader's limit.
    #[error("member {name:?} has {bytes} bytes; at most {limit} are allowed")]
    MemberTooLarge {
        /// The member.
        name: String,
        /// Its size.
        bytes: u64,
        /// The largest size allowed.
        limit: u64,
    },
    /// The samples given to `bettimill_format::build_shard` do not form a valid WebDataset shard.
    #[error("shard {shard:?}, sample {sample}: {reason}")]
    BadSample {
        /// The shard being built.
        shard: String,
        /// Position of the sample in the shard, from 0.
        sample: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// Compressing or decompressing a member failed.
    #[error("{codec} {action} failed: {source}")]
    Codec {
        /// `gzip` or `zstd`.
        codec: &'static str,
        /// `compression` or `decompression`.
        action: &'static str,
        /// The codec's reason.
        source: std::io::Error,
    },
    /// Decompressed data would exceed the caller's limit (a decompression bomb or a
    /// corrupt member).
    #[error("{codec} member decompresses to more than {limit} bytes")]
    DecompressedTooLarge {
        /// `gzip` or `zstd`.
        codec: &'static str,
        /// The limit in bytes.
        limit: u64,
    },
    /// A tar archive is malformed at a byte offset.
    #[error("malformed tar at byte {offset}: {reason}")]
    Tar {
        /// Offset of the 512-byte block (or field) that is wrong.
        offset: u64,
        /// What is wrong.
        reason: String,
    },
    /// A tar archive ends before the end-of-archive marker.
    #[error("tar truncated at byte {offset}: {needed} more bytes were expected ({context})")]
    TarTruncated {
        /// Length of the archive.
        offset: u64,
        /// Bytes missing to finish the current block or member.
        needed: u64,
        /// What was being read.
        context: String,
    },
    /// A tar header's checksum does not match its bytes.
    #[error(
        "tar header at byte {offset}: checksum field says {expected}, the header sums to {found}"
    )]
    HeaderChecksum {
        /// Offset of the header block.
        offset: u64,
        /// The stored checksum.
        expected: u64,
        /// The computed checksum.
        found: u64,
    },
    /// The tar holds an entry that is not a regular file (link, device, FIFO, extension
    /// header) and the safe reader refuses it.
    #[error("tar entry {name:?} at byte {offset} has type {typeflag:?} ({kind}); only regular files are accepted")]
    UnsupportedEntry {
        /// The entry's name.
        name: String,
        /// Offset of its header.
        offset: u64,
        /// The raw type flag.
        typeflag: char,
        /// Human name of the type.
        kind: &'static str,
    },
}

impl ShardError {
    /// Wraps an I/O error with the action and path it concerns.
    pub fn io(action: &'static str, path: &Path, source: std::io::Error) -> ShardError {
        ShardError::Io {
            action,
            path: path.to_path_buf(),
            source,
        }
    }

    /// A member name refused for `reason`.
    pub fn bad_name(name: &str, reason: impl Into<String>) -> ShardError {
        ShardError::BadName {
            name: name.to_string(),
            reason: reason.into(),
        }
    }
}
