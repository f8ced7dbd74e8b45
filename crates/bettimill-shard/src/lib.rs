//! The storage layer of bettimill: deterministic WebDataset tar shards, the dataset
//! index, and verification.
//!
//! A dataset directory looks like this:
//!
//! ```text
//! DIR/index.json                 the Index: every shard, its size and hash, its record's hash
//! DIR/shards/NAME-000000.tar     USTAR shards written by tar_bytes / build_shard
//! DIR/*shardindex*.json          optional wids-shard-index-v1 files, one per split
//! ```
//!
//! - [`ustar`]: the byte layout of a shard and a safe reader for untrusted tars.
//! - [`mod@compress`]: deterministic per-member gzip and zstd (`KEY.npy.gz`, `KEY.npy.zst`).
//! - [`index`]: shard and member records, `index.json`, the wids index.
//! - [`mod@verify`]: re-checks a directory against its index and localises damage.
//! - [`atomic`]: crash-safe file replacement used for every file the build writes.
//!
//! Architecture invariant: the same members always give the same bytes; nothing here
//! reads the clock, the environment, the user name or the file system order.

pub mod atomic;
pub mod compress;
mod error;
pub mod index;
pub mod ustar;
pub mod verify;

pub use atomic::{write_atomic, AtomicFile};
pub use compress::{compress, decoder, decompress, sniff, Compression};
pub use error::ShardError;
pub use index::{
    blake3_hex, build_shard, count_samples, read_index, read_index_from, wids_index, Index,
    IndexFile, IndexHeader, IndexShard, IndexWriter, MemberRecord, ShardRecord, WidsWriter,
    INDEX_FORMAT, INDEX_FORMAT_VERSION, MAX_INDEX_FILES, MAX_INDEX_SPLITS,
};
pub use ustar::{
    read_tar, read_tar_with_limit, split_key, tar_bytes, tar_entries, Member, TarEntry, TarStream,
};
pub use verify::{
    file_matches, verify, verify_with_progress, Problem, RecordSource, Region, VerifyReport,
};
