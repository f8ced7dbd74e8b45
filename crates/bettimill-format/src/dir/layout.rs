//! Where each file of a dataset directory lives: the names of the layout, the paths
//! [`DatasetDir`] makes of them, and the listing of shards and records. No other crate
//! spells these names.

use super::{io, DatasetDir};
use crate::FormatError;
use std::path::{Path, PathBuf};

/// `DIR/manifest.toml`: the manifest, byte for byte as given.
pub const MANIFEST_FILE: &str = "manifest.toml";
/// `DIR/build.json`: the directory's identity ([`super::BuildInfo`]), written first.
pub const BUILD_INFO_FILE: &str = "build.json";
/// `DIR/index.json`: the hash manifest, written last.
pub const INDEX_FILE: &str = "index.json";
/// `DIR/README.md`: the dataset card.
pub const CARD_FILE: &str = "README.md";
/// `DIR/classes.json`: the class table ([`crate::ClassTable`]), written by finalize.
pub const CLASSES_FILE: &str = "classes.json";
/// The files besides shards and records that every finished dataset has; `index.json`
/// lists each (and the wids indexes) in `files`, and `verify` checks them.
pub const REQUIRED_FILES: &[&str] = &[BUILD_INFO_FILE, CARD_FILE, CLASSES_FILE, MANIFEST_FILE];
/// Largest `classes.json` read (a table of a million strata is far smaller).
pub const MAX_CLASS_TABLE_BYTES: u64 = 256 << 20;
/// `DIR/shards/`: the tar shards.
pub const SHARDS_DIR: &str = "shards";
/// `DIR/records/`: one completion record per finished shard.
pub const RECORDS_DIR: &str = "records";
/// `DIR/timings/`: when and how long each shard took to build ([`super::ShardTiming`]). Not part
/// of the dataset's data: no hash covers it and two builds of one manifest differ there.
pub const TIMINGS_DIR: &str = "timings";
/// Where build times come from, as statistics tell their reader: [`TIMINGS_DIR`].
pub const TIMINGS_SOURCE: &str = "timings/ (recorded by the builds)";
/// `DIR/.lock`: the directory lock ([`crate::lock`]), always empty.
pub const LOCK_FILE: &str = ".lock";
/// The files a new directory gets before `build.json`, in the order they are written: a
/// creation that stopped half-way leaves some of them (or their temporaries) and nothing
/// else, and [`DatasetDir::bind`] finishes it.
pub const CREATION_FILES: &[&str] = &[MANIFEST_FILE];

impl DatasetDir {
    /// `DIR/manifest.toml`.
    pub fn manifest_path(&self) -> PathBuf {
        self.root.join(MANIFEST_FILE)
    }

    /// `DIR/build.json`.
    pub fn build_info_path(&self) -> PathBuf {
        self.root.join(BUILD_INFO_FILE)
    }

    /// `DIR/index.json`.
    pub fn index_path(&self) -> PathBuf {
        self.root.join(INDEX_FILE)
    }

    /// `DIR/README.md`.
    pub fn card_path(&self) -> PathBuf {
        self.root.join(CARD_FILE)
    }

    /// `DIR/classes.json`.
    pub fn classes_path(&self) -> PathBuf {
        self.root.join(CLASSES_FILE)
    }

    /// `DIR/shardindex-SPLIT.json`.
    pub fn wids_index_path(&self, split: &str) -> PathBuf {
        self.root.join(format!("shardindex-{split}.json"))
    }

    /// `DIR/shards`.
    pub fn shards_dir(&self) -> PathBuf {
        self.root.join(SHARDS_DIR)
    }

    /// `DIR/records`.
    pub fn records_dir(&self) -> PathBuf {
        self.root.join(RECORDS_DIR)
    }

    /// The name a shard `NAME` has in records and the index: `shards/NAME.tar`.
    pub fn relative_tar_name(shard: &str) -> String {
        format!("{SHARDS_DIR}/{shard}.tar")
    }

    /// `DIR/shards/NAME.tar`.
    pub fn tar_path(&self, shard: &str) -> PathBuf {
        self.shards_dir().join(format!("{shard}.tar"))
    }

    /// `DIR/records/NAME.json`.
    pub fn record_path(&self, shard: &str) -> PathBuf {
        self.records_dir().join(format!("{shard}.json"))
    }

    /// `DIR/timings/NAME.json`.
    pub fn timing_path(&self, shard: &str) -> PathBuf {
        self.root.join(TIMINGS_DIR).join(format!("{shard}.json"))
    }

    /// Whether `DIR/build.json` exists.
    pub fn has_build_info(&self) -> bool {
        self.build_info_path().exists()
    }

    /// Whether `DIR/index.json` exists (the build is finished).
    pub fn is_finalized(&self) -> bool {
        self.index_path().exists()
    }

    /// The shard name (`NAME`) of an index entry or record name (`shards/NAME.tar`).
    pub fn shard_stem(relative: &str) -> &str {
        let name = relative.strip_prefix("shards/").unwrap_or(relative);
        name.strip_suffix(".tar").unwrap_or(name)
    }

    /// The names (`NAME`, without `.json`) of every completion record, sorted.
    pub fn record_names(&self) -> Result<Vec<String>, FormatError> {
        list_stems(&self.records_dir(), "json")
    }

    /// The names (`NAME`, without `.tar`) of every shard file, sorted.
    pub fn shard_names(&self) -> Result<Vec<String>, FormatError> {
        list_stems(&self.shards_dir(), "tar")
    }
}

/// The dataset directory a file written at `path` would land in, if any: `path` (a link
/// followed, as a write would) or one of its parent directories holds `build.json` or the
/// directory lock. Commands that write an output file refuse such a path: every file in a
/// dataset directory is bettimill's.
pub fn dataset_containing(path: &Path) -> Option<PathBuf> {
    let target = match std::fs::canonicalize(path) {
        Ok(target) => target,
        Err(_) => {
            let parent = path
                .parent()
                .filter(|p| !p.as_os_str().is_empty())
                .unwrap_or(Path::new("."));
            std::fs::canonicalize(parent).ok()?.join(path.file_name()?)
        }
    };
    target
        .ancestors()
        .skip(1)
        .find(|dir| dir.join(BUILD_INFO_FILE).is_file() || dir.join(LOCK_FILE).is_file())
        .map(Path::to_path_buf)
}

/// Creates `path` as a directory unless it is one; refuses a symbolic link (or anything
/// else) in its place.
pub(super) fn ensure_real_dir(path: &Path) -> Result<(), FormatError> {
    match std::fs::symlink_metadata(path) {
        Ok(meta) if meta.file_type().is_symlink() => Err(FormatError::Symlinked {
            path: path.to_path_buf(),
        }),
        Ok(meta) if meta.is_dir() => Ok(()),
        Ok(_) => Err(FormatError::Corrupt {
            path: path.to_path_buf(),
            reason: "is not a directory".into(),
        }),
        Err(err) if err.kind() == std::io::ErrorKind::NotFound => match std::fs::create_dir(path) {
            Err(err) if err.kind() != std::io::ErrorKind::AlreadyExists => Err(io(path)(err)),
            _ => ensure_real_dir_exists(path),
        },
        Err(err) => Err(io(path)(err)),
    }
}

fn ensure_real_dir_exists(path: &Path) -> Result<(), FormatError> {
    match std::fs::symlink_metadata(path) {
        Ok(meta) if meta.is_dir() => Ok(()),
        _ => Err(FormatError::Symlinked {
            path: path.to_path_buf(),
        }),
    }
}

fn list_stems(dir: &Path, extension: &str) -> Result<Vec<String>, FormatError> {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(err) if err.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(source) => {
            return Err(FormatError::Io {
                path: dir.to_path_buf(),
                source,
            })
        }
    };
    let mut names = Vec::new();
    for entry in entries {
        let entry = entry.map_err(io(dir))?;
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        if name.starts_with('.') {
            continue;
        }
        if let Some(stem) = name
            .strip_suffix(extension)
            .and_then(|s| s.strip_suffix('.'))
        {
            names.push(stem.to_string());
        }
    }
    names.sort();
    Ok(names)
}
