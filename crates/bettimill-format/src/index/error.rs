//! Why an `index.json` cannot be read: the file, its JSON, or what it says.

use super::{INDEX_FORMAT, INDEX_FORMAT_VERSION, MAX_INDEX_FILES, MAX_INDEX_SPLITS};
use crate::dir::SHARDS_DIR;
use std::path::PathBuf;

/// Why an index could not be read.
#[derive(Debug, thiserror::Error)]
pub enum IndexError {
    /// The file could not be opened or read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The index file.
        path: PathBuf,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// The file is not JSON.
    #[error("{path}: invalid JSON: {source}")]
    Json {
        /// The index file.
        path: PathBuf,
        /// The parser's reason, with line and column.
        source: serde_json::Error,
    },
    /// The file is JSON but not a valid bettimill index.
    #[error("{path}: not a valid bettimill index: {reason}")]
    Format {
        /// The index file.
        path: PathBuf,
        /// What is wrong.
        reason: IndexRefusal,
    },
}

/// What makes parsed JSON not a valid bettimill index.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum IndexRefusal {
    /// Another `format` name.
    #[error("format is {found:?}, expected {INDEX_FORMAT:?}")]
    OtherFormat {
        /// The name found.
        found: String,
    },
    /// Format version 1, which listed every member.
    #[error("format_version 1 (written by bettimill {tool}, listing every member) is not read by this bettimill, which reads version {INDEX_FORMAT_VERSION} (shards only; member hashes are in records/NAME.json); rewrite the index with `bettimill finalize DIR`, or use bettimill {tool}")]
    Version1 {
        /// The tool version that wrote it.
        tool: String,
    },
    /// Format version 2, without the directory's other files.
    #[error("format_version 2 (written by bettimill {tool}, without the list of the directory's other files) is not read by this bettimill, which reads version {INDEX_FORMAT_VERSION}; rewrite the index with `bettimill finalize DIR` (shards and records are unchanged), or use bettimill {tool}")]
    Version2 {
        /// The tool version that wrote it.
        tool: String,
    },
    /// A format version this bettimill does not know.
    #[error("format_version {version} is not supported (this bettimill reads version {INDEX_FORMAT_VERSION}); use the bettimill version that wrote it ({tool})")]
    UnknownVersion {
        /// The version found.
        version: u32,
        /// The tool version that wrote it.
        tool: String,
    },
    /// A required field is missing.
    #[error("{field} is missing")]
    Missing {
        /// The field.
        field: &'static str,
    },
    /// `files` lists more entries than any build writes.
    #[error("files lists {count} entries, at most {MAX_INDEX_FILES} are allowed")]
    TooManyFiles {
        /// Entries listed.
        count: usize,
    },
    /// A `files` entry that is not a plain file name of the directory.
    #[error("file name {name:?} is not a plain file name of the dataset directory")]
    BadFileName {
        /// The name.
        name: String,
    },
    /// `files` out of order, or a name listed twice.
    #[error("files are not sorted by name, or {name:?} is listed twice")]
    FilesUnsorted {
        /// The first name out of order.
        name: String,
    },
    /// A shard name outside `shards/`.
    #[error("shard name {name:?} is not under {SHARDS_DIR}/")]
    NotUnderShards {
        /// The name.
        name: String,
    },
    /// A shard name that is not a plain relative path.
    #[error("shard name {name:?} is not a plain relative path under {SHARDS_DIR}/")]
    NotAPlainPath {
        /// The name.
        name: String,
    },
    /// A shard listed twice in a row.
    #[error("shard {name:?} is listed twice")]
    ListedTwice {
        /// The name.
        name: String,
    },
    /// A split's shards out of order.
    #[error("shard {name:?} is listed after {previous:?}: a split's shards are listed in increasing order")]
    OutOfOrder {
        /// The name.
        name: String,
        /// The name before it.
        previous: String,
    },
    /// More splits than a plan allows.
    #[error("shards of more than {MAX_INDEX_SPLITS} splits are listed")]
    TooManySplits,
    /// A split's shards not listed together.
    #[error("shard {name:?} of split {split:?} is listed after another split's: each split's shards are listed together")]
    SplitNotTogether {
        /// The name.
        name: String,
        /// Its split.
        split: String,
    },
    /// The shards do not add up to the header's counts.
    #[error("the index lists {shards} shards of {samples} samples, its header says {header_shards} shards of {header_samples} samples")]
    Counts {
        /// Shards listed.
        shards: u64,
        /// Samples of the shards listed.
        samples: u64,
        /// The header's `shard_count`.
        header_shards: u64,
        /// The header's `samples`.
        header_samples: u64,
    },
}
