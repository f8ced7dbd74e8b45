//! The dataset directory: where each file lives, the identity file, completion records,
//! and the one check of a shard against its record. Each concept has its own file:
//!
//! - `layout`: the names of the layout and the paths made of them;
//! - `identity`: `build.json`, binding and creation, a stopped creation's leftovers;
//! - `records`: completion records and timings, one of each per shard;
//! - `shard_state`: one shard against its record (resume, status, finalize) and reading it;
//! - `finished`: the class table, index entries and `verify` of a finished dataset.

mod finished;
mod identity;
mod layout;
mod records;
mod shard_state;

pub(crate) use identity::identity_problems;
pub use identity::{check_build_info, BuildInfo, Unbound};
pub use layout::{
    dataset_containing, BUILD_INFO_FILE, CARD_FILE, CLASSES_FILE, CREATION_FILES, INDEX_FILE,
    LOCK_FILE, MANIFEST_FILE, MAX_CLASS_TABLE_BYTES, RECORDS_DIR, REQUIRED_FILES, SHARDS_DIR,
    TIMINGS_DIR, TIMINGS_SOURCE,
};
pub use records::{CompletionRecord, ShardTiming};
pub use shard_state::{open_tar_file, ShardState, ShardStream, TarCheck};
pub(crate) use shard_state::{regular_file_len, stream_checked};

use crate::FormatError;
use std::path::{Path, PathBuf};

/// A dataset directory. Every path inside one is made here.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DatasetDir {
    root: PathBuf,
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> FormatError + '_ {
    move |source| FormatError::Io {
        path: path.to_path_buf(),
        source,
    }
}

impl DatasetDir {
    /// The dataset directory at `root` (nothing is read).
    pub fn new(root: impl Into<PathBuf>) -> DatasetDir {
        DatasetDir { root: root.into() }
    }

    /// The directory itself.
    pub fn root(&self) -> &Path {
        &self.root
    }
}

#[cfg(test)]
mod tests;
