//! The dataset directory: where each file lives, the identity file, completion records,
//! and the one check of a shard against its record.

use crate::tar_check::{self, TarMismatch};
use crate::NoRecord;
use crate::ShardRecord;
use crate::{FormatError, TOOL_VERSION};
use bettimill_shard as shard;
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
/// `DIR/timings/`: when and how long each shard took to build ([`ShardTiming`]). Not part
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

/// What a directory without `build.json` holds (see [`DatasetDir::unbound_state`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Unbound {
    /// It does not exist, is empty, or holds only the lock: nothing was written yet.
    Empty,
    /// What a creation that stopped before `build.json` leaves (killed, or the disk was
    /// full): some of [`CREATION_FILES`], temporaries of them or of `build.json`, the lock.
    Unfinished {
        /// Whether `manifest.toml` was written.
        manifest: bool,
        /// The temporaries (`.manifest.toml.tmp-PID`, `.build.json.tmp-PID`).
        temporaries: Vec<PathBuf>,
    },
    /// Anything else: not a bettimill directory.
    Foreign,
}

/// When and how long a shard took to build, written by the process that built it to
/// `DIR/timings/NAME.json` after its record. Outside the hashed data on purpose (times are
/// never the same twice); `bettimill stats` reports the build time from these files.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardTiming {
    /// When the shard's first sample was started, in seconds since the Unix epoch.
    pub started_unix: f64,
    /// Seconds from then until its record was written.
    pub seconds: f64,
    /// Samples in the shard.
    pub samples: u64,
}

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
    pub fn index_file(&self, name: &str) -> Result<crate::IndexFile, FormatError> {
        let path = self.root.join(name);
        let mut file = std::fs::File::open(&path).map_err(io(&path))?;
        let mut hasher = blake3::Hasher::new();
        let bytes = std::io::copy(&mut file, &mut hasher).map_err(io(&path))?;
        Ok(crate::IndexFile {
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

    /// What the directory holds while it has no `build.json`: nothing yet, the leftovers
    /// of a creation that stopped half-way, or something foreign. Reads only the listing.
    pub fn unbound_state(&self) -> Result<Unbound, FormatError> {
        let dir = &self.root;
        let entries = match std::fs::read_dir(dir) {
            Ok(entries) => entries,
            Err(err) if err.kind() == std::io::ErrorKind::NotFound => return Ok(Unbound::Empty),
            Err(source) => return Err(io(dir)(source)),
        };
        let mut manifest = false;
        let mut temporaries = Vec::new();
        for entry in entries {
            let entry = entry.map_err(io(dir))?;
            let name = entry.file_name();
            let Some(name) = name.to_str() else {
                return Ok(Unbound::Foreign);
            };
            let is_file = entry.file_type().map_err(io(dir))?.is_file();
            if name == LOCK_FILE && is_file {
                continue;
            }
            if name == MANIFEST_FILE && is_file {
                manifest = true;
                continue;
            }
            let temporary_of = |file: &str| {
                name.strip_prefix('.')
                    .and_then(|rest| rest.strip_prefix(file))
                    .and_then(|rest| rest.strip_prefix(".tmp-"))
                    .is_some_and(|pid| !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()))
            };
            if is_file
                && (CREATION_FILES.iter().any(|f| temporary_of(f)) || temporary_of(BUILD_INFO_FILE))
            {
                temporaries.push(entry.path());
                continue;
            }
            return Ok(Unbound::Foreign);
        }
        if !manifest && temporaries.is_empty() {
            return Ok(Unbound::Empty);
        }
        temporaries.sort();
        Ok(Unbound::Unfinished {
            manifest,
            temporaries,
        })
    }

    /// Binds the directory to `expected`: checks a stored `build.json` against it in full
    /// (manifest hash, then tool version, then plan hash), or, when there is none, creates
    /// the directory with `manifest.toml` and `build.json`. Creation takes the directory
    /// lock before writing anything, and finishes a creation that stopped half-way
    /// ([`Unbound::Unfinished`], when its `manifest.toml` is this manifest byte for byte);
    /// a directory holding anything else is refused untouched. Creates `shards/` and
    /// `records/` in both cases, and refuses them if they are symbolic links (bettimill
    /// never writes through a link inside the directory).
    pub fn bind(&self, manifest_text: &str, expected: &BuildInfo) -> Result<(), FormatError> {
        let dir = &self.root;
        if !self.has_build_info() {
            // Refused before anything (even the lock) is written into it; checked again
            // under the lock.
            match self.unbound_state()? {
                // (Unless another build has just finished creating it.)
                Unbound::Foreign if !self.has_build_info() => {
                    return Err(FormatError::ForeignDirectory {
                        dir: dir.to_path_buf(),
                    })
                }
                Unbound::Unfinished { manifest: true, .. } => {
                    self.check_stored_manifest(manifest_text)?
                }
                _ => {}
            }
            std::fs::create_dir_all(dir).map_err(io(dir))?;
            let _lock = crate::lock::DirLock::acquire(dir)?;
            // Under the lock: another build may have created it meanwhile.
            if !self.has_build_info() {
                self.create(manifest_text, expected)?;
            }
        }
        let found = self.read_build_info()?;
        check_build_info(dir, &found, expected)?;
        for path in [self.shards_dir(), self.records_dir()] {
            ensure_real_dir(&path)?;
        }
        Ok(())
    }

    /// Writes `manifest.toml` and `build.json` into a directory that has no `build.json`,
    /// finishing a creation that stopped half-way. Call it under the directory lock.
    fn create(&self, manifest_text: &str, expected: &BuildInfo) -> Result<(), FormatError> {
        let dir = &self.root;
        let (manifest, temporaries) = match self.unbound_state()? {
            Unbound::Foreign => {
                return Err(FormatError::ForeignDirectory {
                    dir: dir.to_path_buf(),
                })
            }
            Unbound::Empty => (false, Vec::new()),
            Unbound::Unfinished {
                manifest,
                temporaries,
            } => (manifest, temporaries),
        };
        if manifest {
            self.check_stored_manifest(manifest_text)?;
        }
        // Leftovers of the stopped creation (its writer is dead: we hold the lock).
        for path in temporaries {
            match std::fs::remove_file(&path) {
                Err(err) if err.kind() != std::io::ErrorKind::NotFound => {
                    return Err(io(&path)(err))
                }
                _ => {}
            }
        }
        if !manifest {
            shard::write_atomic(&self.manifest_path(), manifest_text.as_bytes())?;
        }
        let mut bytes = serde_json::to_vec_pretty(expected).expect("build info serialises");
        bytes.push(b'\n');
        shard::write_atomic(&self.build_info_path(), &bytes)?;
        Ok(())
    }

    /// Refuses an unfinished creation whose `manifest.toml` is not `manifest_text`.
    fn check_stored_manifest(&self, manifest_text: &str) -> Result<(), FormatError> {
        let path = self.manifest_path();
        let stored = std::fs::read(&path).map_err(io(&path))?;
        if stored != manifest_text.as_bytes() {
            return Err(FormatError::UnfinishedOtherManifest {
                dir: self.root.clone(),
            });
        }
        Ok(())
    }

    /// Refuses a directory that is not a dataset for reading commands: `Ok` when it has a
    /// `build.json`; otherwise an error that tells an unfinished creation (rerun the
    /// build) from a directory that holds no dataset.
    pub fn require_bound(&self) -> Result<(), FormatError> {
        if self.has_build_info() {
            return Ok(());
        }
        match self.unbound_state()? {
            Unbound::Unfinished { .. } => Err(FormatError::Unfinished {
                dir: self.root.clone(),
            }),
            _ => Err(FormatError::NoDataset {
                dir: self.root.clone(),
            }),
        }
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
    /// `crate::verify`), streaming the index and each shard. `progress` gets
    /// (shards checked, shards in the index).
    pub fn verify(
        &self,
        progress: &mut dyn FnMut(u64, u64),
    ) -> Result<crate::VerifyReport, FormatError> {
        if !self.index_path().exists() {
            return Err(FormatError::NotADataset {
                dir: self.root.clone(),
                found: self.describe_unfinished(),
            });
        }
        let mut records = |entry: &crate::IndexShard| -> Result<ShardRecord, NoRecord> {
            let name = DatasetDir::shard_stem(&entry.name);
            let path = self.record_path(name);
            match self.read_record_hashed(name)? {
                Some((record, hash)) if hash == entry.record_blake3 => Ok(record.shard),
                Some((_, found)) => Err(NoRecord::HashDiffers {
                    path,
                    found,
                    indexed: entry.record_blake3.clone(),
                }),
                None => Err(NoRecord::Missing { path }),
            }
        };
        let mut report =
            crate::verify_with_progress(&self.root, REQUIRED_FILES, &mut records, progress)?;
        // The index's identity must be the directory's: build.json is itself covered by the
        // index's `files`, so an edit of either is found.
        if let Some(header) = report.header.clone() {
            match self.read_build_info() {
                Ok(info) => {
                    for (field, indexed, built) in [
                        ("tool_version", &header.tool_version, &info.tool_version),
                        ("manifest_hash", &header.manifest_hash, &info.manifest_hash),
                        ("plan_hash", &header.plan_hash, &info.plan_hash),
                    ] {
                        if indexed != built {
                            report.problems.push(crate::Problem::File {
                                path: INDEX_FILE.into(),
                                reason: format!("{field} is {indexed}, build.json says {built}"),
                            });
                        }
                    }
                }
                Err(err) => report.problems.push(crate::Problem::File {
                    path: BUILD_INFO_FILE.into(),
                    reason: err.to_string(),
                }),
            }
        }
        Ok(report)
    }

    /// What a directory without `index.json` holds, said for a person: a build that has
    /// not finished, a dataset one level down, or the entries it has.
    fn describe_unfinished(&self) -> String {
        let root = &self.root;
        if !root.exists() {
            return "it does not exist".to_string();
        }
        if !root.is_dir() {
            return "it is a file; give the dataset's directory (the --out of `bettimill build`)"
                .to_string();
        }
        if root.join(BUILD_INFO_FILE).exists() {
            let records = std::fs::read_dir(root.join(RECORDS_DIR))
                .map(|entries| entries.filter_map(Result::ok).count())
                .unwrap_or(0);
            return format!(
                "it holds a build that has not finished ({BUILD_INFO_FILE} and {records} completed shard(s)); run the same `bettimill build MANIFEST --out {}` again to finish it",
                root.display()
            );
        }
        let mut names: Vec<String> = match std::fs::read_dir(root) {
            Ok(entries) => entries
                .filter_map(Result::ok)
                .map(|entry| entry.file_name().to_string_lossy().into_owned())
                .collect(),
            Err(err) => return format!("it cannot be listed ({err})"),
        };
        // Sorted: the message is the same on every file system.
        names.sort();
        if let Some(inner) = names
            .iter()
            .find(|name| root.join(name).join(INDEX_FILE).is_file())
        {
            return format!(
                "it holds a dataset one level down: {}",
                root.join(inner).display()
            );
        }
        if names.is_empty() {
            return "it is empty".to_string();
        }
        let shown: Vec<&str> = names.iter().take(5).map(String::as_str).collect();
        let more = names.len().saturating_sub(shown.len());
        let tail = if more > 0 {
            format!(" and {more} more")
        } else {
            String::new()
        };
        format!(
            "it holds {} entr{} ({}{tail}) and none of a dataset's files",
            names.len(),
            if names.len() == 1 { "y" } else { "ies" },
            shown.join(", ")
        )
    }

    /// Reads `index.json` through once, if it exists, and says why it cannot be used (such
    /// as an index of an older format version); `Ok` when there is none yet.
    pub fn check_index(&self) -> Result<(), FormatError> {
        if !self.is_finalized() {
            return Ok(());
        }
        crate::read_index(&self.index_path(), &mut |_, _| {})?;
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
    pub fn open_tar(&self, shard: &str, max_member_bytes: u64) -> Result<ShardStream, FormatError> {
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

    /// The names (`NAME`, without `.json`) of every completion record, sorted.
    pub fn record_names(&self) -> Result<Vec<String>, FormatError> {
        list_stems(&self.records_dir(), "json")
    }

    /// The names (`NAME`, without `.tar`) of every shard file, sorted.
    pub fn shard_names(&self) -> Result<Vec<String>, FormatError> {
        list_stems(&self.shards_dir(), "tar")
    }

    /// Writes a shard's timing (atomically; creates `timings/`, refusing a link there).
    /// Write it after the shard's record.
    pub fn write_timing(&self, shard: &str, timing: &ShardTiming) -> Result<(), FormatError> {
        ensure_real_dir(&self.root.join(TIMINGS_DIR))?;
        let mut bytes = serde_json::to_vec_pretty(timing).expect("timings serialise");
        bytes.push(b'\n');
        Ok(shard::write_atomic(&self.timing_path(shard), &bytes)?)
    }

    /// A shard's timing, `None` when it has none or it cannot be read (a timing is
    /// statistics, never data: a shard built before timings existed, or whose builder was
    /// killed between its record and its timing, simply has none).
    pub fn read_timing(&self, shard: &str) -> Option<ShardTiming> {
        let bytes = std::fs::read(self.timing_path(shard)).ok()?;
        let timing: ShardTiming = serde_json::from_slice(&bytes).ok()?;
        (timing.started_unix.is_finite() && timing.seconds.is_finite() && timing.seconds >= 0.0)
            .then_some(timing)
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
fn ensure_real_dir(path: &Path) -> Result<(), FormatError> {
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

/// A shard opened by [`DatasetDir::open_tar`] or [`open_tar_file`]: its members one at a
/// time through a fixed buffer, reading bounded by the expected size.
pub type ShardStream = shard::TarStream<std::io::Take<std::io::BufReader<std::fs::File>>>;

/// The size of the regular file at `path`; an error naming it for anything else (a device
/// such as `/dev/zero`, which reports no size and never ends, a directory, a FIFO).
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
) -> Result<ShardStream, FormatError> {
    let size = regular_file_len(path)?;
    let (expected, limit) = match record {
        Some((record, record_path)) => {
            if size != record.bytes {
                return Err(FormatError::Corrupt {
                    path: path.to_path_buf(),
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
    let file = std::fs::File::open(path).map_err(io(path))?;
    let reader = std::io::Read::take(std::io::BufReader::with_capacity(1 << 16, file), expected);
    Ok(shard::TarStream::new(reader, path, limit))
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
mod tests;
