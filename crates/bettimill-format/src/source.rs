//! A dataset to read, wherever it is: a directory ([`DatasetDir`]) or objects under
//! `s3://BUCKET/PREFIX` ([`BucketDir`]). The reading commands (`stats`, `preview`, `audit`)
//! go through [`DatasetSource`], so the choice between the two is made here once: the shard
//! list, records, timings, the manifest and each shard's members, a bucket's read by ranges
//! (one range in memory, whatever the shard's size).

use crate::bucket::BucketDir;
use crate::dir::{stream_checked, INDEX_FILE, MANIFEST_FILE, RECORDS_DIR, SHARDS_DIR};
use crate::{CompletionRecord, DatasetDir, FormatError, ShardStream, ShardTiming};
use std::path::{Path, PathBuf};

/// A dataset directory or a dataset in a bucket, for reading.
#[derive(Debug)]
pub enum DatasetSource {
    /// A directory on a file system.
    Dir(DatasetDir),
    /// Objects under `s3://BUCKET/PREFIX`.
    Bucket(BucketDir),
}

/// One shard of [`DatasetSource::shards`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SourceShard {
    /// Its split (`unknown` for a shard of an unfinished build without a record).
    pub split: String,
    /// Its name, `NAME-000000` (no directory, no `.tar`).
    pub name: String,
}

impl DatasetSource {
    /// Where the dataset is: the directory, or the URL.
    pub fn location(&self) -> PathBuf {
        match self {
            DatasetSource::Dir(dir) => dir.root().to_path_buf(),
            DatasetSource::Bucket(bucket) => PathBuf::from(bucket.url()),
        }
    }

    /// Where a shard's tar is: its path, or its object's URL.
    pub fn tar_location(&self, shard: &str) -> PathBuf {
        match self {
            DatasetSource::Dir(dir) => dir.tar_path(shard),
            DatasetSource::Bucket(bucket) => {
                PathBuf::from(bucket.objects().object_url(&BucketDir::tar_name(shard)))
            }
        }
    }

    /// Where a shard's completion record is: its path, or its object's URL.
    pub fn record_location(&self, shard: &str) -> PathBuf {
        match self {
            DatasetSource::Dir(dir) => dir.record_path(shard),
            DatasetSource::Bucket(bucket) => {
                PathBuf::from(bucket.objects().object_url(&BucketDir::record_name(shard)))
            }
        }
    }

    /// Whether `index.json` exists (the build is finished).
    pub fn is_finalized(&self) -> Result<bool, FormatError> {
        match self {
            DatasetSource::Dir(dir) => Ok(dir.is_finalized()),
            DatasetSource::Bucket(bucket) => Ok(bucket.objects().size(INDEX_FILE)?.is_some()),
        }
    }

    /// The shards in build order with their splits: from `index.json` (streamed) when the
    /// build is finished, otherwise every `shards/*.tar` by name, its split from its
    /// completion record (`unknown` without one). Empty when there is none.
    pub fn shards(&self) -> Result<Vec<SourceShard>, FormatError> {
        let mut shards = Vec::new();
        let mut each = |_: &crate::IndexHeader, entry: crate::IndexShard| {
            shards.push(SourceShard {
                split: entry.split,
                name: DatasetDir::shard_stem(&entry.name).to_string(),
            })
        };
        let names = match self {
            DatasetSource::Dir(dir) if dir.is_finalized() => {
                crate::read_index(&dir.index_path(), &mut each)?;
                return Ok(shards);
            }
            DatasetSource::Dir(dir) => dir.shard_names()?,
            DatasetSource::Bucket(bucket) => {
                let objects = bucket.objects();
                if let Some(size) = objects.size(INDEX_FILE)? {
                    let reader = std::io::BufReader::with_capacity(
                        1 << 16,
                        objects.reader(INDEX_FILE, size),
                    );
                    let path = PathBuf::from(objects.object_url(INDEX_FILE));
                    crate::read_index_from(reader, &path, &mut each)?;
                    return Ok(shards);
                }
                objects
                    .list_under(SHARDS_DIR)?
                    .into_iter()
                    .filter_map(|entry| {
                        let name = entry.name.strip_prefix(SHARDS_DIR)?.strip_prefix('/')?;
                        let stem = name.strip_suffix(".tar")?;
                        (!stem.is_empty() && !stem.contains('/')).then(|| stem.to_string())
                    })
                    .collect()
            }
        };
        for name in names {
            let split = match self.read_record(&name) {
                Ok(Some(record)) => record.shard.split,
                _ => "unknown".to_string(),
            };
            shards.push(SourceShard { split, name });
        }
        Ok(shards)
    }

    /// A shard's completion record; `Ok(None)` when there is none.
    pub fn read_record(&self, shard: &str) -> Result<Option<CompletionRecord>, FormatError> {
        match self {
            DatasetSource::Dir(dir) => dir.read_record(shard),
            DatasetSource::Bucket(bucket) => {
                let Some(bytes) = bucket.objects().get(&BucketDir::record_name(shard))? else {
                    return Ok(None);
                };
                serde_json::from_slice(&bytes)
                    .map(Some)
                    .map_err(|err| FormatError::Corrupt {
                        path: self.record_location(shard),
                        reason: format!("not a completion record: {err}"),
                    })
            }
        }
    }

    /// A shard's timing, `None` when it has none or it cannot be read (statistics, never
    /// data; see [`DatasetDir::read_timing`]).
    pub fn read_timing(&self, shard: &str) -> Option<ShardTiming> {
        match self {
            DatasetSource::Dir(dir) => dir.read_timing(shard),
            DatasetSource::Bucket(bucket) => {
                let bytes = bucket
                    .objects()
                    .get(&BucketDir::timing_name(shard))
                    .ok()??;
                ShardTiming::from_json(&bytes)
            }
        }
    }

    /// The stored manifest's text and where it is (its path or URL, for messages).
    pub fn read_manifest_text(&self) -> Result<(String, PathBuf), FormatError> {
        match self {
            DatasetSource::Dir(dir) => Ok((dir.read_manifest_text()?, dir.manifest_path())),
            DatasetSource::Bucket(bucket) => Ok((
                bucket.read_manifest_text()?,
                PathBuf::from(bucket.objects().object_url(MANIFEST_FILE)),
            )),
        }
    }

    /// Opens the tar of `shard` for reading member after member, checked against its
    /// completion record first as [`DatasetDir::open_tar`] checks a file: the tar must have
    /// the record's size, and a member whose header claims more than the record's largest
    /// member is refused by that header. A bucket's tar is read by ranges. A tar that does
    /// not exist is an [`FormatError::Io`] of kind `NotFound`.
    pub fn open_tar(
        &self,
        shard: &str,
        max_member_bytes: u64,
    ) -> Result<ShardStream<'_>, FormatError> {
        match self {
            DatasetSource::Dir(dir) => dir.open_tar(shard, max_member_bytes),
            DatasetSource::Bucket(bucket) => {
                let record = self.read_record(shard)?;
                let (name, size) = self.tar_object(bucket, shard)?;
                let record_location = self.record_location(shard);
                stream_checked(
                    bucket.objects().reader(&name, size),
                    size,
                    &self.tar_location(shard),
                    record
                        .as_ref()
                        .map(|r| (&r.shard, record_location.as_path())),
                    max_member_bytes,
                )
            }
        }
    }

    /// The tar of `shard` as bytes to read (a file, or an object by ranges), for comparing
    /// it with another copy; the caller bounds the reading ([`std::io::Read::take`]: a file
    /// may be a link to a device that never ends). A tar that does not exist is an
    /// [`FormatError::Io`] of kind `NotFound`.
    pub fn tar_reader(
        &self,
        shard: &str,
    ) -> Result<Box<dyn std::io::Read + Send + '_>, FormatError> {
        let location = self.tar_location(shard);
        match self {
            DatasetSource::Dir(_) => {
                let file = std::fs::File::open(&location).map_err(|source| FormatError::Io {
                    path: location.clone(),
                    source,
                })?;
                Ok(Box::new(std::io::BufReader::with_capacity(1 << 16, file)))
            }
            DatasetSource::Bucket(bucket) => {
                let (name, size) = self.tar_object(bucket, shard)?;
                Ok(Box::new(bucket.objects().reader(&name, size)))
            }
        }
    }

    /// A bucket's tar object of `shard` and its size; `NotFound` when there is none.
    fn tar_object(&self, bucket: &BucketDir, shard: &str) -> Result<(String, u64), FormatError> {
        let name = BucketDir::tar_name(shard);
        match bucket.objects().size(&name)? {
            Some(size) => Ok((name, size)),
            None => Err(FormatError::Io {
                path: self.tar_location(shard),
                source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such object"),
            }),
        }
    }
}

impl BucketDir {
    /// Copies every object of the dataset but its shards and timings into the directory
    /// `to` (which must exist): `manifest.toml`, `build.json`, the completion records and
    /// the files a finished build adds (`index.json`, `classes.json`, the card, the wids
    /// indexes), each streamed by ranges and written atomically. The copy is a dataset
    /// directory without shards, for the checks that compare the plan with the records and
    /// the finished files (`audit`); the shards stay in the bucket and are read from there.
    /// Objects under other names (a lease, anything foreign) are not copied.
    pub fn copy_metadata(&self, to: &Path) -> Result<(), FormatError> {
        let objects = self.objects();
        let records = to.join(RECORDS_DIR);
        std::fs::create_dir_all(&records).map_err(|source| FormatError::Io {
            path: records.clone(),
            source,
        })?;
        for entry in objects.list()? {
            let name = entry.name.as_str();
            let target = match name.split_once('/') {
                None => to.join(name),
                Some((RECORDS_DIR, record))
                    if record.ends_with(".json") && !record.contains('/') =>
                {
                    records.join(record)
                }
                Some(_) => continue,
            };
            // Names are the bucket's: one plain component below `to`, nothing that climbs.
            let plain = Path::new(name)
                .components()
                .all(|c| matches!(c, std::path::Component::Normal(_)));
            if !plain || name.starts_with('.') || name.contains("/.") {
                continue;
            }
            let mut file = bettimill_shard::AtomicFile::create(&target)?;
            std::io::copy(&mut objects.reader(name, entry.bytes), &mut file).map_err(|source| {
                FormatError::Io {
                    path: PathBuf::from(objects.object_url(name)),
                    source,
                }
            })?;
            file.commit()?;
        }
        Ok(())
    }
}
