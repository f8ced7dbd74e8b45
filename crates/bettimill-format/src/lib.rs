//! The dataset directory of bettimill, owned in one place.
//!
//! Every crate and command that reads or writes a dataset directory goes through this crate;
//! nobody else parses its records or labels. It holds:
//!
//! - [`dir`]: the layout (where each file lives), the identity file [`BuildInfo`] (checked
//!   in full on every open), the completion records ([`CompletionRecord`]), the tar check
//!   of resume, status and finalize ([`DatasetDir::check_tar`]), and the one way to read a
//!   shard's members ([`DatasetDir::open_tar`]: checked against its record before reading,
//!   one member at a time).
//! - [`bucket`]: a dataset under `s3://BUCKET/PREFIX`, the same names as objects, and
//!   [`lease`], its lock: create-only writes, the identity checked as on disk.
//! - [`source`]: a dataset to read, a directory or a bucket ([`DatasetSource`]): the one
//!   place where the reading commands tell the two apart.
//! - `tar_check`: the one streaming "does this tar match its record" check, which
//!   [`DatasetDir::check_tar`] stops at the first problem of and [`verify()`] reports whole.
//! - [`label`]: the label stored as `KEY.json` ([`Label`], [`ResolutionLabel`]).
//! - [`member`]: member names and their compression suffixes.
//! - [`classes`]: the class table stored as `classes.json` ([`ClassTable`]): what every
//!   `KEY.cls` means, and the topology-only class index.
//!
//! ```text
//! DIR/manifest.toml             the manifest, byte for byte as given
//! DIR/build.json                tool version, manifest hash, plan hash (written first)
//! DIR/shards/NAME-000000.tar    WebDataset shards
//! DIR/records/NAME-000000.json  one completion record per finished shard
//! DIR/timings/NAME-000000.json  when and how long it took (not hashed, never identical)
//! DIR/classes.json              the class table (what each KEY.cls means)
//! DIR/index.json                the hash manifest (written last, by finalize): every
//!                               shard, its record, and every other file but timings/
//! DIR/shardindex-SPLIT.json     wids indexes, DIR/README.md the dataset card
//! ```

pub mod bucket;
pub mod classes;
pub mod diff;
pub mod dir;
pub mod index;
pub mod label;
pub mod lease;
pub mod lock;
pub mod member;
pub mod source;
mod tar_check;
pub mod verify;

pub use classes::{ClassTable, StratumClass, TopologyClass, CLASS_TABLE_FORMAT};
pub use dir::{
    check_build_info, dataset_containing, open_tar_file, BuildInfo, CompletionRecord, DatasetDir,
    ShardState, ShardStream, ShardTiming, TarCheck, Unbound, CLASSES_FILE, REQUIRED_FILES,
};
pub use index::{
    build_shard, count_samples, read_index, read_index_from, wids_index, write_shard, Index,
    IndexError, IndexFile, IndexHeader, IndexRefusal, IndexShard, IndexWriter, MemberRecord,
    ShardRecord, WidsWriter, INDEX_FORMAT, INDEX_FORMAT_VERSION, MAX_INDEX_FILES, MAX_INDEX_SPLITS,
};
pub use label::{Label, Pooling, ResolutionLabel};
pub use member::{member_name, MemberName};
pub use source::{DatasetSource, SourceShard};
pub use tar_check::{check_tar_file, TarMismatch};
pub use verify::{
    verify, verify_with_progress, NoRecord, Problem, RecordSource, Region, VerifyReport,
};

use std::path::PathBuf;

/// The bettimill version: written into every label, `build.json` and `index.json`.
pub const TOOL_VERSION: &str = env!("CARGO_PKG_VERSION");

/// Why a dataset directory could not be read or bound.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    /// The output directory holds something else.
    #[error("{dir} is not empty and holds no bettimill dataset; choose an empty or new directory")]
    ForeignDirectory {
        /// The directory.
        dir: PathBuf,
    },
    /// A creation stopped before `build.json` was written, and a reading command was given
    /// the directory.
    #[error("{dir}: its creation stopped before build.json was written (killed, or the disk was full), so nothing was built yet; rerun the same `bettimill build MANIFEST --out {dir}` to resume")]
    Unfinished {
        /// The directory.
        dir: PathBuf,
    },
    /// A creation stopped half-way with another manifest.
    #[error("{dir} holds the start of a dataset of a different manifest (its manifest.toml differs; build.json was never written and nothing was built); use another --out directory, or delete {dir}")]
    UnfinishedOtherManifest {
        /// The directory.
        dir: PathBuf,
    },
    /// The directory holds no dataset at all.
    #[error("{dir} holds no bettimill dataset (no build.json)")]
    NoDataset {
        /// The directory.
        dir: PathBuf,
    },
    /// A command that reads a finished dataset was given something else.
    #[error("{dir} is not a finished bettimill dataset (no index.json): {found}")]
    NotADataset {
        /// The path given.
        dir: PathBuf,
        /// What the path holds instead, and the way on.
        found: String,
    },
    /// A directory inside the dataset is a symbolic link.
    #[error("{path} is a symbolic link; bettimill does not write through links inside a dataset directory (it would write outside it): replace it with a real directory")]
    Symlinked {
        /// The link.
        path: PathBuf,
    },
    /// The directory lock.
    #[error(transparent)]
    Lock(#[from] crate::lock::LockError),
    /// The directory holds a dataset of a different manifest.
    #[error("{dir} holds a dataset built from a different manifest (hash {found}, this manifest is {expected}); use another --out directory")]
    DifferentManifest {
        /// The directory.
        dir: PathBuf,
        /// This manifest's hash.
        expected: String,
        /// The hash recorded in the directory.
        found: String,
    },
    /// The directory was started by another bettimill version.
    #[error("{dir} was built by bettimill {found} (its build.json says so), this is bettimill {expected}; shards of two versions must not mix: use bettimill {found} for this directory, or another --out directory")]
    OtherToolVersion {
        /// The directory.
        dir: PathBuf,
        /// The version recorded in the directory.
        found: String,
        /// This bettimill's version.
        expected: String,
    },
    /// The directory's plan differs from the one this bettimill makes of the manifest.
    #[error("{dir} holds plan {found} (built by bettimill {tool_version}), but this bettimill plans the same manifest as {expected}; use the bettimill that built it, or another --out directory")]
    DifferentPlan {
        /// The directory.
        dir: PathBuf,
        /// The version recorded in the directory.
        tool_version: String,
        /// The plan hash recorded in the directory.
        found: String,
        /// This bettimill's plan hash.
        expected: String,
    },
    /// A file in the directory is not what bettimill wrote.
    #[error("{path}: {reason}")]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// An I/O error.
    #[error("{path}: {source}")]
    Io {
        /// The path involved.
        path: PathBuf,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// Storage failed.
    #[error(transparent)]
    Shard(#[from] bettimill_shard::ShardError),
    /// `index.json` could not be read.
    #[error(transparent)]
    Index(#[from] IndexError),
    /// Object storage failed (`s3://` datasets).
    #[error(transparent)]
    Object(#[from] bettimill_shard::object::ObjectError),
}
