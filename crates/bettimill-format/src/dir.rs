//! The dataset directory: where each file lives, the identity file, completion records,
//! and the one check of a shard against its record.

use crate::{FormatError, TOOL_VERSION};
use bettimill_shard::{self as shard, ShardRecord};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// `DIR/manifest.toml`: the manifest, byte for byte as given.
pub const MANIFEST_FILE: &str = "manifest.toml";
/// `DIR/build.json`: the directory's identity ([`BuildInfo`]), written first.
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

/// The identity of a dataset directory, written before anything else.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BuildInfo {
    /// bettimill version that started the build.
    pub tool_version: String,
    /// The manifest's canonical hash.
    pub manifest_hash: String,
    /// The plan's hash.
    pub plan_hash: String,
}

impl BuildInfo {
    /// The identity this bettimill gives a plan.
    pub fn current(manifest_hash: impl Into<String>, plan_hash: impl Into<String>) -> BuildInfo {
        BuildInfo {
            tool_version: TOOL_VERSION.to_string(),
            manifest_hash: manifest_hash.into(),
            plan_hash: plan_hash.into(),
        }
    }
}

/// A shard's completion record (`DIR/records/NAME.json`): its storage record (with every
/// member's offset, size and hash) plus build statistics.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CompletionRecord {
    /// The shard's storage record.
    pub shard: ShardRecord,
    /// Rejected attempts (regenerations) per stratum label, sorted by label.
    pub regenerations: Vec<(String, u64)>,
}

impl CompletionRecord {
    /// The record's file bytes: pretty JSON and a newline.
    pub fn to_json_bytes(&self) -> Vec<u8> {
        let mut json = serde_json::to_vec_pretty(self).expect("records serialise");
        json.push(b'\n');
        json
    }
}

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

    /// Writes `DIR/classes.json` (atomically).
    pub fn write_class_table(&self, table: &crate::ClassTable) -> Result<(), FormatError> {
        Ok(shard::write_atomic(
            &self.classes_path(),
            &table.to_json_bytes(),
        )?)
    }

    /// Reads `DIR/classes.json`, refusing a file over [`MAX_CLASS_TABLE_BYTES`] (streamed,
    /// never read whole first).
    pub fn read_class_table(&self) -> Result<crate::ClassTable, FormatError> {
        use std::io::Read;
        let path = self.classes_path();
        let file = std::fs::File::open(&path).map_err(io(&path))?;
        let mut limited = std::io::BufReader::new(file).take(MAX_CLASS_TABLE_BYTES + 1);
        let table = serde_json::from_reader(&mut limited);
        if limited.limit() == 0 {
            return Err(FormatError::Corrupt {
                path,
                reason: format!("larger than {MAX_CLASS_TABLE_BYTES} bytes"),
            });
        }
        table.map_err(|err| FormatError::Corrupt {
            path,
            reason: format!("not a class table: {err}"),
        })
    }

    /// The entry `index.json` lists for the directory's file `name` (size and a blake3
    /// streamed through a fixed buffer).
    pub fn index_file(&self, name: &str) -> Result<shard::IndexFile, FormatError> {
        let path = self.root.join(name);
        let mut file = std::fs::File::open(&path).map_err(io(&path))?;
        let mut hasher = blake3::Hasher::new();
        let bytes = std::io::copy(&mut file, &mut hasher).map_err(io(&path))?;
        Ok(shard::IndexFile {
            name: name.to_string(),
            bytes,
            blake3: hasher.finalize().to_hex().to_string(),
        })
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

    /// Whether `DIR/build.json` exists.
    pub fn has_build_info(&self) -> bool {
        self.build_info_path().exists()
    }

    /// Whether `DIR/index.json` exists (the build is finished).
    pub fn is_finalized(&self) -> bool {
        self.index_path().exists()
    }

    /// Reads `DIR/build.json`.
    pub fn read_build_info(&self) -> Result<BuildInfo, FormatError> {
        let path = self.build_info_path();
        let bytes = std::fs::read(&path).map_err(io(&path))?;
        serde_json::from_slice(&bytes).map_err(|err| FormatError::Corrupt {
            path: path.clone(),
            reason: format!("not a bettimill build record: {err}"),
        })
    }

    /// Reads the stored manifest text.
    pub fn read_manifest_text(&self) -> Result<String, FormatError> {
        let path = self.manifest_path();
        std::fs::read_to_string(&path).map_err(io(&path))
    }

    /// Binds the directory to `expected`: checks a stored `build.json` against it in full
    /// (manifest hash, then tool version, then plan hash), or, when there is none, creates
    /// the directory (which must be empty or new) with `manifest.toml` and `build.json`.
    /// Creates `shards/` and `records/` in both cases. Writes nothing when refusing.
    pub fn bind(&self, manifest_text: &str, expected: &BuildInfo) -> Result<(), FormatError> {
        let dir = &self.root;
        if self.has_build_info() {
            let found = self.read_build_info()?;
            check_build_info(dir, &found, expected)?;
        } else {
            if dir.exists() {
                let mut entries = std::fs::read_dir(dir).map_err(io(dir))?;
                if entries.next().is_some() {
                    return Err(FormatError::ForeignDirectory {
                        dir: dir.to_path_buf(),
                    });
                }
            }
            std::fs::create_dir_all(dir).map_err(io(dir))?;
            shard::write_atomic(&self.manifest_path(), manifest_text.as_bytes())?;
            let mut bytes = serde_json::to_vec_pretty(expected).expect("build info serialises");
            bytes.push(b'\n');
            shard::write_atomic(&self.build_info_path(), &bytes)?;
        }
        for path in [self.shards_dir(), self.records_dir()] {
            std::fs::create_dir_all(&path).map_err(io(&path))?;
        }
        Ok(())
    }

    /// Reads a shard's completion record; `Ok(None)` when there is none.
    pub fn read_record(&self, shard: &str) -> Result<Option<CompletionRecord>, FormatError> {
        let path = self.record_path(shard);
        let bytes = match std::fs::read(&path) {
            Ok(bytes) => bytes,
            Err(err) if err.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(source) => return Err(FormatError::Io { path, source }),
        };
        serde_json::from_slice(&bytes)
            .map(Some)
            .map_err(|err| FormatError::Corrupt {
                path,
                reason: format!("not a completion record: {err}"),
            })
    }

    /// Reads a shard's completion record with the blake3 of its file (what `index.json`
    /// keeps as `record_blake3`); `Ok(None)` when there is none.
    pub fn read_record_hashed(
        &self,
        shard: &str,
    ) -> Result<Option<(CompletionRecord, String)>, FormatError> {
        let path = self.record_path(shard);
        let bytes = match std::fs::read(&path) {
            Ok(bytes) => bytes,
            Err(err) if err.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(source) => return Err(FormatError::Io { path, source }),
        };
        let record = serde_json::from_slice(&bytes).map_err(|err| FormatError::Corrupt {
            path,
            reason: format!("not a completion record: {err}"),
        })?;
        Ok(Some((record, shard::blake3_hex(&bytes))))
    }

    /// The shard name (`NAME`) of an index entry or record name (`shards/NAME.tar`).
    pub fn shard_stem(relative: &str) -> &str {
        let name = relative.strip_prefix("shards/").unwrap_or(relative);
        name.strip_suffix(".tar").unwrap_or(name)
    }

    /// Checks every shard against `index.json` and the completion records it covers (see
    /// `bettimill_shard::verify`), streaming the index and each shard. `progress` gets
    /// (shards checked, shards in the index).
    pub fn verify(
        &self,
        progress: &mut dyn FnMut(u64, u64),
    ) -> Result<shard::VerifyReport, FormatError> {
        let mut records = |entry: &shard::IndexShard| -> Result<ShardRecord, String> {
            let name = DatasetDir::shard_stem(&entry.name);
            let path = self.record_path(name);
            match self.read_record_hashed(name) {
                Ok(Some((record, hash))) if hash == entry.record_blake3 => Ok(record.shard),
                Ok(Some((_, hash))) => Err(format!(
                    "{} has blake3 {hash}, index.json says {}",
                    path.display(),
                    entry.record_blake3
                )),
                Ok(None) => Err(format!(
                    "{} is missing (it lists the shard's members)",
                    path.display()
                )),
                Err(err) => Err(err.to_string()),
            }
        };
        Ok(shard::verify_with_progress(
            &self.root,
            REQUIRED_FILES,
            &mut records,
            progress,
        )?)
    }

    /// Reads `index.json` through once, if it exists, and says why it cannot be used (such
    /// as an index of an older format version); `Ok` when there is none yet.
    pub fn check_index(&self) -> Result<(), FormatError> {
        if !self.is_finalized() {
            return Ok(());
        }
        shard::read_index(&self.index_path(), &mut |_, _| Ok(()))?;
        Ok(())
    }

    /// Writes a shard's completion record (atomically). Write it only after its tar.
    pub fn write_record(&self, shard: &str, record: &CompletionRecord) -> Result<(), FormatError> {
        Ok(shard::write_atomic(
            &self.record_path(shard),
            &record.to_json_bytes(),
        )?)
    }

    /// Whether the tar of `shard` matches `record`: its size and, with [`TarCheck::Full`],
    /// its blake3, streamed through a fixed buffer (a shard is never held in memory). The
    /// error says what differs. This is the one "does this tar match its record" check:
    /// resume, status, finalize and verify all use it.
    pub fn check_tar(
        &self,
        shard: &str,
        record: &ShardRecord,
        check: TarCheck,
    ) -> Result<(), String> {
        check_tar_file(&self.tar_path(shard), record, check)
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
            Err(reason) => ShardState::Invalid { reason },
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

    /// The names (`NAME`, without `.json`) of every completion record, sorted.
    pub fn record_names(&self) -> Result<Vec<String>, FormatError> {
        list_stems(&self.records_dir(), "json")
    }

    /// The names (`NAME`, without `.tar`) of every shard file, sorted.
    pub fn shard_names(&self) -> Result<Vec<String>, FormatError> {
        list_stems(&self.shards_dir(), "tar")
    }

    /// The build's span from file modification times, in seconds since the Unix epoch:
    /// (`build.json`, the end, finished) where the end is `index.json`, or the newest
    /// completion record while the build is unfinished. `None` when a time cannot be read.
    /// The directory stores no timings (a rebuild must be byte-identical).
    pub fn file_times(&self) -> Option<(f64, f64, bool)> {
        let mtime = |path: &Path| -> Option<f64> {
            let modified = std::fs::metadata(path).ok()?.modified().ok()?;
            Some(
                modified
                    .duration_since(std::time::UNIX_EPOCH)
                    .ok()?
                    .as_secs_f64(),
            )
        };
        let start = mtime(&self.build_info_path())?;
        if self.is_finalized() {
            return Some((start, mtime(&self.index_path())?, true));
        }
        let newest = self
            .record_names()
            .ok()?
            .iter()
            .filter_map(|name| mtime(&self.record_path(name)))
            .max_by(f64::total_cmp)?;
        Some((start, newest, false))
    }
}

/// [`DatasetDir::check_tar`] for a tar at `path`.
pub fn check_tar_file(path: &Path, record: &ShardRecord, check: TarCheck) -> Result<(), String> {
    let size = match std::fs::metadata(path) {
        Ok(meta) => meta.len(),
        Err(err) => return Err(format!("{}: {err}", path.display())),
    };
    if size != record.bytes {
        return Err(format!(
            "{} has {size} bytes, its record says {}",
            path.display(),
            record.bytes
        ));
    }
    if check == TarCheck::Size {
        return Ok(());
    }
    shard::file_matches(path, record.bytes, &record.blake3)
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

/// Checks a stored identity against this bettimill's: manifest hash, tool version, then
/// plan hash, each refusal naming what the directory holds and which bettimill built it.
pub fn check_build_info(
    dir: &Path,
    found: &BuildInfo,
    expected: &BuildInfo,
) -> Result<(), FormatError> {
    if found.manifest_hash != expected.manifest_hash {
        return Err(FormatError::DifferentManifest {
            dir: dir.to_path_buf(),
            expected: expected.manifest_hash.clone(),
            found: found.manifest_hash.clone(),
        });
    }
    if found.tool_version != expected.tool_version {
        return Err(FormatError::OtherToolVersion {
            dir: dir.to_path_buf(),
            found: found.tool_version.clone(),
            expected: expected.tool_version.clone(),
        });
    }
    if found.plan_hash != expected.plan_hash {
        return Err(FormatError::DifferentPlan {
            dir: dir.to_path_buf(),
            tool_version: found.tool_version.clone(),
            found: found.plan_hash.clone(),
            expected: expected.plan_hash.clone(),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bound(dir: &Path) -> (DatasetDir, BuildInfo) {
        let layout = DatasetDir::new(dir.join("ds"));
        let info = BuildInfo::current("m1", "p1");
        layout.bind("name = \"x\"\n", &info).unwrap();
        (layout, info)
    }

    #[test]
    fn binding_creates_the_identity_files_and_accepts_the_same_identity() {
        let tmp = tempfile::tempdir().unwrap();
        let (layout, info) = bound(tmp.path());
        assert_eq!(layout.read_build_info().unwrap(), info);
        assert_eq!(layout.read_manifest_text().unwrap(), "name = \"x\"\n");
        assert!(layout.shards_dir().is_dir() && layout.records_dir().is_dir());
        layout.bind("ignored", &info).unwrap();
        assert_eq!(layout.read_manifest_text().unwrap(), "name = \"x\"\n");
    }

    #[test]
    fn another_tool_version_or_plan_or_manifest_is_refused_naming_both() {
        let tmp = tempfile::tempdir().unwrap();
        let (layout, info) = bound(tmp.path());
        let before = std::fs::read(layout.build_info_path()).unwrap();
        // A build.json written by another bettimill version.
        let mut older = info.clone();
        older.tool_version = "0.0.9".into();
        let mut bytes = serde_json::to_vec_pretty(&older).unwrap();
        bytes.push(b'\n');
        std::fs::write(layout.build_info_path(), &bytes).unwrap();
        let err = layout.bind("x", &info).unwrap_err().to_string();
        assert!(err.contains("built by bettimill 0.0.9"), "{err}");
        assert!(
            err.contains(&format!("this is bettimill {TOOL_VERSION}")),
            "{err}"
        );
        assert_eq!(std::fs::read(layout.build_info_path()).unwrap(), bytes);

        std::fs::write(layout.build_info_path(), &before).unwrap();
        let other_plan = BuildInfo::current("m1", "p2");
        let err = layout.bind("x", &other_plan).unwrap_err().to_string();
        assert!(err.contains("holds plan p1"), "{err}");
        assert!(err.contains("as p2"), "{err}");
        assert!(
            err.contains(&format!("built by bettimill {TOOL_VERSION}")),
            "{err}"
        );

        let other_manifest = BuildInfo::current("m2", "p1");
        let err = layout.bind("x", &other_manifest).unwrap_err();
        assert!(
            matches!(err, FormatError::DifferentManifest { .. }),
            "{err}"
        );
    }

    #[test]
    fn a_non_empty_foreign_directory_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        std::fs::write(tmp.path().join("x"), b"x").unwrap();
        let err = DatasetDir::new(tmp.path())
            .bind("", &BuildInfo::current("m", "p"))
            .unwrap_err();
        assert!(matches!(err, FormatError::ForeignDirectory { .. }), "{err}");
    }

    #[test]
    fn tar_check_and_shard_state() {
        let tmp = tempfile::tempdir().unwrap();
        let (layout, _) = bound(tmp.path());
        assert_eq!(layout.shard_state("t-000000"), ShardState::Missing);
        let member = bettimill_shard::Member::new("s0.json", b"{}".to_vec());
        let (bytes, record) =
            bettimill_shard::build_shard("shards/t-000000.tar", "train", &[vec![member]]).unwrap();
        std::fs::write(layout.tar_path("t-000000"), &bytes).unwrap();
        assert!(matches!(
            layout.shard_state("t-000000"),
            ShardState::Invalid { .. }
        ));
        let completion = CompletionRecord {
            shard: record.clone(),
            regenerations: vec![],
        };
        layout.write_record("t-000000", &completion).unwrap();
        assert_eq!(
            layout.shard_state("t-000000"),
            ShardState::Complete(completion.clone())
        );
        assert_eq!(layout.record_names().unwrap(), vec!["t-000000"]);
        assert_eq!(layout.shard_names().unwrap(), vec!["t-000000"]);
        let mut flipped = bytes.clone();
        flipped[600] ^= 1;
        std::fs::write(layout.tar_path("t-000000"), &flipped).unwrap();
        assert!(layout.recorded("t-000000").is_some(), "same size");
        let ShardState::Invalid { reason } = layout.shard_state("t-000000") else {
            panic!("a flipped byte must be found");
        };
        assert!(reason.contains("blake3"), "{reason}");
        std::fs::write(layout.tar_path("t-000000"), &bytes[..1024]).unwrap();
        assert!(layout.recorded("t-000000").is_none());
        assert!(layout
            .check_tar("t-000000", &record, TarCheck::Size)
            .unwrap_err()
            .contains("1024 bytes"));
    }
}
