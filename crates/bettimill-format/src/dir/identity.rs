//! The directory's identity (`build.json`, [`BuildInfo`]) and how a directory becomes a
//! dataset: binding checks a stored identity in full, creation writes `manifest.toml` and
//! `build.json` under the lock, and the leftovers of a creation that stopped half-way
//! ([`Unbound`]) are told from a foreign directory.

use super::layout::{ensure_real_dir, BUILD_INFO_FILE, CREATION_FILES, LOCK_FILE, MANIFEST_FILE};
use super::{io, DatasetDir};
use crate::{FormatError, TOOL_VERSION};
use bettimill_shard as shard;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

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

impl DatasetDir {
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
        self.bind_holding(manifest_text, expected, false).map(drop)
    }

    /// [`DatasetDir::bind`] for a build: takes the directory lock in every case (a
    /// directory that exists too) and returns it held, so that no other process (a
    /// `finalize`) can take it between the binding and the build. Refuses with
    /// [`crate::lock::LockError::Busy`] when another process holds it.
    pub fn bind_locked(
        &self,
        manifest_text: &str,
        expected: &BuildInfo,
    ) -> Result<crate::lock::DirLock, FormatError> {
        let lock = self.bind_holding(manifest_text, expected, true)?;
        Ok(lock.expect("bind_holding returns the lock it was asked to hold"))
    }

    fn bind_holding(
        &self,
        manifest_text: &str,
        expected: &BuildInfo,
        hold: bool,
    ) -> Result<Option<crate::lock::DirLock>, FormatError> {
        let dir = &self.root;
        let mut held = None;
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
            let lock = crate::lock::DirLock::acquire(dir)?;
            // Under the lock: another build may have created it meanwhile.
            if !self.has_build_info() {
                self.create(manifest_text, expected)?;
            }
            held = Some(lock);
        }
        let found = self.read_build_info()?;
        check_build_info(dir, &found, expected)?;
        if hold && held.is_none() {
            held = Some(crate::lock::DirLock::acquire(dir)?);
        }
        for path in [self.shards_dir(), self.records_dir()] {
            ensure_real_dir(&path)?;
        }
        Ok(held.filter(|_| hold))
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

/// What verify reports when an index's identity is not the dataset's: each of the index
/// header's `tool_version`, `manifest_hash` and `plan_hash` that differs from `build.json`'s,
/// or why `build.json` cannot be read. The same for a directory and a bucket.
pub(crate) fn identity_problems(
    header: &crate::IndexHeader,
    info: Result<BuildInfo, FormatError>,
) -> Vec<crate::Problem> {
    let info = match info {
        Ok(info) => info,
        Err(err) => {
            return vec![crate::Problem::File {
                path: BUILD_INFO_FILE.into(),
                reason: err.to_string(),
            }]
        }
    };
    [
        ("tool_version", &header.tool_version, &info.tool_version),
        ("manifest_hash", &header.manifest_hash, &info.manifest_hash),
        ("plan_hash", &header.plan_hash, &info.plan_hash),
    ]
    .into_iter()
    .filter(|(_, indexed, built)| indexed != built)
    .map(|(field, indexed, built)| crate::Problem::File {
        path: super::INDEX_FILE.into(),
        reason: format!("{field} is {indexed}, build.json says {built}"),
    })
    .collect()
}
