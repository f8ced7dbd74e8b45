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

mod dataset;

pub use dataset::{BuildError, BuildSummary, Dataset, ShardOutcome};
