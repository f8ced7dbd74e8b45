//! A dataset under `s3://BUCKET/PREFIX`: the layout of a dataset directory, as object
//! names relative to the prefix (`build.json`, `shards/NAME.tar`, `records/NAME.json`, ...),
//! so that a dataset in a bucket and one on disk hold the same names and the same bytes.
//!
//! Object storage has no rename, so the directory's guarantees are kept by other means: an
//! object appears only complete (one put, or for a large file the server's create-only copy
//! of a finished multipart upload), every write is create-only, and an object that
//! exists already is compared with what would be written instead of being overwritten
//! ([`BucketDir::put_same`]). A shard is complete when its record exists and its tar has the
//! record's size (a tar object cannot be half-written); `verify` hashes every byte.

use crate::dir::{BUILD_INFO_FILE, MANIFEST_FILE, RECORDS_DIR, TIMINGS_DIR};
use crate::{check_build_info, BuildInfo, CompletionRecord, DatasetDir, FormatError};
use bettimill_shard::object::{ObjectDir, ObjectEntry, ObjectError, S3Config, UPLOADS_DIR};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

/// A dataset's objects under one `s3://BUCKET/PREFIX`.
#[derive(Debug)]
pub struct BucketDir {
    objects: Arc<ObjectDir>,
}

/// What the bucket says about one shard (see [`BucketDir::shard_state`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BucketShard {
    /// Its record exists, the record's bytes are what bettimill writes, and the tar has
    /// the record's size.
    Complete {
        /// The record.
        record: CompletionRecord,
        /// Its object's bytes.
        bytes: Vec<u8>,
    },
    /// There is no record (a tar without one is left from a build stopped between the
    /// two puts: building the shard again compares its bytes with it).
    Missing,
    /// A record exists but does not make a complete shard. Objects are never overwritten,
    /// so such a shard needs its objects deleted by hand.
    Invalid {
        /// What is wrong, naming the objects.
        reason: String,
    },
}

impl BucketDir {
    /// Connects to `url` and checks the server, the credentials and the bucket with one
    /// request (see [`ObjectDir::open`]).
    pub fn open(url: &str, config: &S3Config) -> Result<BucketDir, ObjectError> {
        Ok(BucketDir {
            objects: Arc::new(ObjectDir::open(url, config)?),
        })
    }

    /// The objects themselves (one connection, shared by every thread that uses it).
    pub fn objects(&self) -> &Arc<ObjectDir> {
        &self.objects
    }

    /// The dataset's URL.
    pub fn url(&self) -> &str {
        self.objects.url()
    }

    /// The URL as a path, for errors that name a directory.
    fn url_path(&self) -> PathBuf {
        PathBuf::from(self.url())
    }

    /// The object of a shard's tar: `shards/NAME.tar`.
    pub fn tar_name(shard: &str) -> String {
        DatasetDir::relative_tar_name(shard)
    }

    /// The object of a shard's completion record: `records/NAME.json`.
    pub fn record_name(shard: &str) -> String {
        format!("{RECORDS_DIR}/{shard}.json")
    }

    /// The object of a shard's build timing: `timings/NAME.json`.
    pub fn timing_name(shard: &str) -> String {
        format!("{TIMINGS_DIR}/{shard}.json")
    }

    /// Every object's size by name (one listing).
    pub fn sizes(&self) -> Result<BTreeMap<String, u64>, FormatError> {
        Ok(self
            .objects
            .list()?
            .into_iter()
            .map(|ObjectEntry { name, bytes }| (name, bytes))
            .collect())
    }

    /// Writes `bytes` as the object `name`, create-only. An object that exists already is
    /// accepted when it holds the same bytes (compared by blake3, fetched by ranges: another
    /// writer, or an earlier run of this build, wrote it) and refused otherwise.
    pub fn put_same(&self, name: &str, bytes: Vec<u8>) -> Result<(), FormatError> {
        let expected = (bytes.len() as u64, blake3::hash(&bytes));
        match self.objects.put_new(name, bytes) {
            Err(ObjectError::Exists { url }) => self.same_or_refused(name, url, expected),
            other => Ok(other?),
        }
    }

    /// The answer to a create-only write that found `name` existing (at `url`): accepted
    /// when the object holds the bytes this build writes (`expected`: size and blake3),
    /// refused otherwise, since objects are never overwritten.
    fn same_or_refused(
        &self,
        name: &str,
        url: String,
        expected: (u64, blake3::Hash),
    ) -> Result<(), FormatError> {
        if self.hash(name)? == Some(expected) {
            Ok(())
        } else {
            Err(FormatError::Corrupt {
                path: PathBuf::from(url),
                reason: "exists and differs from what this build writes; objects are never \
                         overwritten: delete it and build again"
                    .into(),
            })
        }
    }

    /// Writes the file `file` as the object `name`, create-only, streamed (see
    /// [`ObjectDir::put_file_new`]: memory holds a few parts of it, whatever its size). An
    /// object that exists already is accepted when it holds the file's bytes (both hashed by
    /// blake3, streamed) and refused otherwise, as by [`BucketDir::put_same`].
    pub fn put_file_same(&self, name: &str, file: &std::path::Path) -> Result<(), FormatError> {
        match self.objects.put_file_new(name, file) {
            Err(ObjectError::Exists { url }) => {
                let io = |source| FormatError::Io {
                    path: file.to_path_buf(),
                    source,
                };
                let mut hasher = blake3::Hasher::new();
                let size = std::io::copy(&mut std::fs::File::open(file).map_err(io)?, &mut hasher)
                    .map_err(io)?;
                self.same_or_refused(name, url, (size, hasher.finalize()))
            }
            other => Ok(other?),
        }
    }

    /// Deletes the temporary objects of streamed uploads that a killed writer left (see
    /// [`ObjectDir::put_file_new`]). Only for a writer that holds the lease with every
    /// shard complete (finalize): a writer still uploading would lose its temporary.
    pub fn remove_upload_leftovers(&self) -> Result<(), FormatError> {
        for entry in self.objects.list_under(UPLOADS_DIR)? {
            self.objects.delete(&entry.name)?;
        }
        Ok(())
    }

    /// The size and blake3 of the object `name` (streamed by ranges), or `None`.
    pub fn hash(&self, name: &str) -> Result<Option<(u64, blake3::Hash)>, FormatError> {
        let Some(size) = self.objects.size(name)? else {
            return Ok(None);
        };
        let mut hasher = blake3::Hasher::new();
        let read =
            std::io::copy(&mut self.objects.reader(name, size), &mut hasher).map_err(|source| {
                FormatError::Io {
                    path: PathBuf::from(self.objects.object_url(name)),
                    source,
                }
            })?;
        Ok(Some((read, hasher.finalize())))
    }

    /// Binds the prefix to a dataset: checks a stored `build.json` against `expected` in
    /// full, or, when there is none, writes `manifest.toml` then `build.json` (the bytes a
    /// local directory of the same manifest holds), create-only. A prefix that holds other
    /// objects and no `build.json` is refused untouched. Take the lease first.
    pub fn bind(
        &self,
        manifest: &[u8],
        build_info: &[u8],
        expected: &BuildInfo,
    ) -> Result<(), FormatError> {
        if self.objects.get(BUILD_INFO_FILE)?.is_none() {
            let foreign = self.objects.list()?.into_iter().any(|entry| {
                entry.name != MANIFEST_FILE && !entry.name.starts_with(crate::lease::LEASE_DIR)
            });
            if foreign && self.objects.get(BUILD_INFO_FILE)?.is_none() {
                return Err(FormatError::ForeignDirectory {
                    dir: self.url_path(),
                });
            }
            self.put_same(MANIFEST_FILE, manifest.to_vec())
                .map_err(|err| match err {
                    FormatError::Corrupt { .. } => FormatError::UnfinishedOtherManifest {
                        dir: self.url_path(),
                    },
                    err => err,
                })?;
            self.put_same(BUILD_INFO_FILE, build_info.to_vec())?;
        }
        let found = self.read_build_info()?;
        check_build_info(&self.url_path(), &found, expected)
    }

    /// Reads `build.json`.
    pub fn read_build_info(&self) -> Result<BuildInfo, FormatError> {
        let url = self.objects.object_url(BUILD_INFO_FILE);
        let bytes = self
            .objects
            .get(BUILD_INFO_FILE)?
            .ok_or_else(|| FormatError::NoDataset {
                dir: self.url_path(),
            })?;
        serde_json::from_slice(&bytes).map_err(|err| FormatError::Corrupt {
            path: PathBuf::from(url),
            reason: format!("not a bettimill build record: {err}"),
        })
    }

    /// Reads the stored manifest text.
    pub fn read_manifest_text(&self) -> Result<String, FormatError> {
        let url = self.objects.object_url(MANIFEST_FILE);
        let bytes = self
            .objects
            .get(MANIFEST_FILE)?
            .ok_or_else(|| FormatError::NoDataset {
                dir: self.url_path(),
            })?;
        String::from_utf8(bytes).map_err(|_| FormatError::Corrupt {
            path: PathBuf::from(url),
            reason: "not UTF-8".into(),
        })
    }

    /// The state of `shard` from the bucket: its record read and checked against the tar's
    /// size in `sizes` (a listing, [`BucketDir::sizes`]).
    pub fn shard_state(
        &self,
        shard: &str,
        sizes: &BTreeMap<String, u64>,
    ) -> Result<BucketShard, FormatError> {
        let record_name = Self::record_name(shard);
        let tar_name = Self::tar_name(shard);
        if !sizes.contains_key(&record_name) {
            return Ok(BucketShard::Missing);
        }
        let record_url = self.objects.object_url(&record_name);
        let Some(bytes) = self.objects.get(&record_name)? else {
            return Ok(BucketShard::Missing);
        };
        let record: CompletionRecord = match serde_json::from_slice(&bytes) {
            Ok(record) => record,
            Err(err) => {
                return Ok(BucketShard::Invalid {
                    reason: format!("{record_url}: not a completion record: {err}"),
                })
            }
        };
        if record.to_json_bytes() != bytes {
            return Ok(BucketShard::Invalid {
                reason: format!("{record_url}: not the bytes bettimill writes for its record"),
            });
        }
        if record.shard.name != tar_name {
            return Ok(BucketShard::Invalid {
                reason: format!("{record_url}: it records {}", record.shard.name),
            });
        }
        match sizes.get(&tar_name) {
            Some(&size) if size == record.shard.bytes => {
                Ok(BucketShard::Complete { record, bytes })
            }
            Some(&size) => Ok(BucketShard::Invalid {
                reason: format!(
                    "{}: {size} bytes, its record says {}",
                    self.objects.object_url(&tar_name),
                    record.shard.bytes
                ),
            }),
            None => Ok(BucketShard::Invalid {
                reason: format!(
                    "{record_url} exists, its tar {} does not",
                    self.objects.object_url(&tar_name)
                ),
            }),
        }
    }
}

impl BucketDir {
    /// `verify` of a dataset in a bucket: every shard listed in `index.json` against its
    /// record (whose blake3 the index keeps) and byte for byte against the record's layout,
    /// every other file against the index's `files`, and any tar under `shards/` the index
    /// does not list. Objects are read by ranges ([`ObjectDir::reader`]), one at a time:
    /// memory holds one range, whatever the sizes. `progress` gets (shards checked, shards
    /// in the index).
    pub fn verify(
        &self,
        progress: &mut dyn FnMut(u64, u64),
    ) -> Result<crate::VerifyReport, FormatError> {
        use crate::tar_check::{file_problems, record_problems, Depth};
        use crate::{NoRecord, Problem};
        let sizes = self.sizes()?;
        let index_name = crate::dir::INDEX_FILE;
        let Some(&index_size) = sizes.get(index_name) else {
            return Err(FormatError::NotADataset {
                dir: self.url_path(),
                found: if sizes.contains_key(BUILD_INFO_FILE) {
                    "a build that is not finished; run the same build again to resume it".into()
                } else {
                    "no bettimill dataset".into()
                },
            });
        };
        let mut report = crate::VerifyReport::default();
        let mut started = false;
        let index_url = PathBuf::from(self.objects.object_url(index_name));
        let header = crate::read_index_from(
            std::io::BufReader::with_capacity(1 << 16, self.objects.reader(index_name, index_size)),
            &index_url,
            &mut |header, entry| {
                if !started {
                    progress(0, header.shard_count);
                    started = true;
                }
                report.shards_checked += 1;
                report.samples_checked += entry.samples;
                let problems = &mut report.problems;
                let stem = DatasetDir::shard_stem(&entry.name).to_string();
                let record_name = Self::record_name(&stem);
                let record_url = PathBuf::from(self.objects.object_url(&record_name));
                let record = match self.objects.get(&record_name) {
                    Ok(Some(bytes)) => {
                        let found = bettimill_shard::blake3_hex(&bytes);
                        if found != entry.record_blake3 {
                            Err(NoRecord::HashDiffers {
                                path: record_url,
                                found,
                                indexed: entry.record_blake3.clone(),
                            })
                        } else {
                            serde_json::from_slice::<CompletionRecord>(&bytes).map_err(|err| {
                                NoRecord::Unreadable(FormatError::Corrupt {
                                    path: record_url,
                                    reason: format!("not a completion record: {err}"),
                                })
                            })
                        }
                    }
                    Ok(None) => Err(NoRecord::Missing { path: record_url }),
                    Err(err) => Err(NoRecord::Unreadable(err.into())),
                };
                let size = sizes.get(&entry.name).copied();
                let record = match record {
                    Ok(record) => record.shard,
                    Err(reason) => {
                        problems.push(Problem::RecordInconsistent {
                            shard: entry.name.clone(),
                            reason: reason.to_string(),
                        });
                        match self.hash(&entry.name) {
                            Ok(None) => problems.push(Problem::MissingShard {
                                shard: entry.name.clone(),
                            }),
                            Ok(Some((bytes, hash)))
                                if bytes == entry.bytes
                                    && hash.to_hex().as_str() == entry.blake3 =>
                            {
                                report.bytes_checked += bytes
                            }
                            Ok(Some(_)) => problems.push(Problem::RecordInconsistent {
                                shard: entry.name.clone(),
                                reason: "its size or blake3 differs from index.json's".into(),
                            }),
                            Err(err) => problems.push(Problem::Unreadable {
                                path: self.objects.object_url(&entry.name),
                                error: err.to_string(),
                            }),
                        }
                        progress(report.shards_checked, header.shard_count);
                        return;
                    }
                };
                if let Some(reason) = record.disagreement(&entry) {
                    problems.push(Problem::RecordInconsistent {
                        shard: entry.name.clone(),
                        reason,
                    });
                }
                let consistent = record_problems(&record, problems);
                match size {
                    None => problems.push(Problem::MissingShard {
                        shard: record.name.clone(),
                    }),
                    Some(len) if !consistent => match self.hash(&entry.name) {
                        Ok(Some((bytes, hash)))
                            if bytes == record.bytes && hash.to_hex().as_str() == record.blake3 =>
                        {
                            report.bytes_checked += bytes
                        }
                        Ok(_) => problems.push(Problem::RecordInconsistent {
                            shard: entry.name.clone(),
                            reason: format!("{len} bytes, not the record's size and blake3"),
                        }),
                        Err(err) => problems.push(Problem::Unreadable {
                            path: self.objects.object_url(&entry.name),
                            error: err.to_string(),
                        }),
                    },
                    Some(len) => {
                        let mut reader = self.objects.reader(&entry.name, len);
                        match file_problems(&record, &mut reader, len, Depth::All, problems) {
                            Ok(read) => report.bytes_checked += read,
                            Err(err) => problems.push(Problem::Unreadable {
                                path: self.objects.object_url(&entry.name),
                                error: err.to_string(),
                            }),
                        }
                    }
                }
                progress(report.shards_checked, header.shard_count);
            },
        )?;
        if !started {
            progress(0, header.shard_count);
        }
        for name in crate::REQUIRED_FILES {
            if !header.files.iter().any(|f| f.name == *name) {
                report.problems.push(Problem::File {
                    path: name.to_string(),
                    reason: "not listed in index.json's files".into(),
                });
            }
        }
        for file in &header.files {
            report.files_checked += 1;
            let reason = match self.hash(&file.name) {
                Ok(None) => Some("missing".to_string()),
                Ok(Some((bytes, _))) if bytes != file.bytes => {
                    Some(format!("{bytes} bytes, index.json says {}", file.bytes))
                }
                Ok(Some((_, hash))) if hash.to_hex().as_str() != file.blake3 => Some(format!(
                    "blake3 {}, index.json says {}",
                    hash.to_hex(),
                    file.blake3
                )),
                Ok(Some(_)) => None,
                Err(err) => Some(err.to_string()),
            };
            if let Some(reason) = reason {
                report.problems.push(Problem::File {
                    path: file.name.clone(),
                    reason,
                });
            }
        }
        // Tars the index does not list: the listing's names, less the index's (read again,
        // so no list of the index's names is kept beside the listing).
        let mut extra: std::collections::BTreeSet<&String> = sizes
            .keys()
            .filter(|name| name.starts_with(crate::dir::SHARDS_DIR) && name.contains('/'))
            .collect();
        crate::read_index_from(
            std::io::BufReader::with_capacity(1 << 16, self.objects.reader(index_name, index_size)),
            &index_url,
            &mut |_, entry| {
                extra.remove(&entry.name);
            },
        )?;
        for path in extra {
            report
                .problems
                .push(Problem::ExtraFile { path: path.clone() });
        }
        // The index's identity must be the dataset's, as in a directory.
        let problems = crate::dir::identity_problems(&header, self.read_build_info());
        report.problems.extend(problems);
        report.header = Some(header);
        Ok(report)
    }
}
