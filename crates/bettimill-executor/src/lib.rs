//! Executors: turn a plan into shards on disk, and shards into a dataset.
//!
//! The output directory is the only shared state. Its layout:
//!
//! ```text
//! DIR/manifest.toml          the manifest, byte for byte as given
//! DIR/build.json             tool version, manifest hash, plan hash (written first)
//! DIR/shards/NAME-000000.tar WebDataset shards
//! DIR/records/NAME-000000.json  one completion record per finished shard
//! DIR/index.json             the hash manifest (written last, by finalize)
//! ```
//!
//! Recovery rule: a shard is complete exactly when its record exists and the tar on disk has
//! the record's size and blake3. Every file is written under a temporary name, fsynced and
//! renamed, and the record only after its tar, so a build killed at any moment leaves either
//! a complete shard or nothing visible; re-running regenerates the rest, and because every
//! shard is a pure function of (manifest, shard index) the result is byte-identical to an
//! uninterrupted build.

//!
//! Besides the in-process build ([`Dataset::build_in_process`]) there are two ways to run a
//! plan across processes, both writing shards with [`Dataset::write_shard`] so the bytes
//! are the same whoever writes them:
//!
//! - [`coordinator`]: `bettimill build --workers N` on one machine; worker processes speak
//!   the [`protocol`] on their stdin/stdout; DIR/.lock ([`lock`]) keeps a second build out.
//! - [`remote`]: `--out s3://BUCKET/PREFIX`: shards made here, staged locally only while
//!   they upload, with a lease object as the lock.
//! - [`cluster`]: Slurm array jobs and Kubernetes Indexed Jobs whose tasks run
//!   [`worker::run_task`] on a shared file system, then `bettimill finalize DIR`.

pub mod build;
pub mod cluster;
pub mod coordinator;
mod dataset;
pub mod memory;
/// The directory lock (owned by `bettimill-format`, which takes it to create a directory).
pub use bettimill_format::lock;
pub mod protocol;
pub mod remote;
pub mod worker;

pub use build::{build, BuildFailure, BuildProgress, BuildReport, BuildRequest, Runner};
pub use dataset::{
    BuildError, BuildInfo, BuildSummary, CompletionRecord, Dataset, SampleEvent, ShardOutcome,
    ShardState,
};
pub use lock::{DirLock, Holder, LockError};
