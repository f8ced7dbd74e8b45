//! Builds into object storage (`--out s3://BUCKET/PREFIX`) with the guarantees of a local
//! build: the same objects, byte for byte, as the files of a local build of the manifest;
//! create-only writes; records after their tars, `index.json` last; a lease instead of the
//! directory lock; a build killed at any moment resumes against the bucket.
//!
//! Shards are made exactly as on disk ([`Dataset::write_shard`]) into a local staging
//! directory, a dataset directory of the same manifest under the system's temporary
//! directory, and uploaded from there by up to `max_uploads` threads while the next shard
//! is made. A shard's tar leaves the staging directory as soon as its objects are in the
//! bucket, so local disk holds at most `max_uploads + 1` shards; the records (small) stay
//! there until `index.json` is written from them, as a local finalize writes it. Tars are
//! streamed from the staging files by multipart uploads (see
//! [`bettimill_shard::object::ObjectDir::put_file_new`]), so the uploads hold a few parts
//! each in memory, not shards.

use crate::{BuildError, BuildSummary, Dataset};
use bettimill_env::EnvVars;
use bettimill_format::bucket::{BucketDir, BucketShard};
use bettimill_format::lease::Lease;
use bettimill_format::FormatError;
use bettimill_manifest::Manifest;
use bettimill_plan::ShardPlan;
use bettimill_shard::object::{ObjectError, S3Config};
use std::path::Path;
use std::sync::{Arc, Mutex};

/// Shards uploaded at once by default (`--max-uploads`).
pub const DEFAULT_MAX_UPLOADS: usize = 4;

/// How to reach object storage for an `s3://` output.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ObjectOptions {
    /// The server's base URL (`--endpoint`); `None` reads `AWS_ENDPOINT_URL`, and without
    /// it the server is AWS S3.
    pub endpoint: Option<String>,
    /// Shards uploaded at once (at least 1); the staging directory holds at most one more.
    pub max_uploads: usize,
}

impl Default for ObjectOptions {
    fn default() -> Self {
        ObjectOptions {
            endpoint: None,
            max_uploads: DEFAULT_MAX_UPLOADS,
        }
    }
}

/// The endpoint and credentials: `endpoint` when given, else `AWS_ENDPOINT_URL`; the key,
/// secret, session token and region from the standard AWS variables.
pub fn s3_config(endpoint: Option<&str>) -> S3Config {
    let var = bettimill_env::var;
    S3Config {
        endpoint: endpoint
            .map(str::to_string)
            .or_else(|| var(EnvVars::AWS_ENDPOINT_URL))
            .filter(|e| !e.is_empty()),
        access_key_id: var(EnvVars::AWS_ACCESS_KEY_ID),
        secret_access_key: var(EnvVars::AWS_SECRET_ACCESS_KEY),
        session_token: var(EnvVars::AWS_SESSION_TOKEN).filter(|t| !t.is_empty()),
        region: var(EnvVars::AWS_REGION)
            .or_else(|| var(EnvVars::AWS_DEFAULT_REGION))
            .filter(|r| !r.is_empty()),
    }
}

/// Opens `url` with `endpoint` and the AWS variables: a wrong key, a missing bucket or an
/// unreachable server is an error here, naming the URL.
pub fn open_bucket(url: &str, endpoint: Option<&str>) -> Result<BucketDir, ObjectError> {
    BucketDir::open(url, &s3_config(endpoint))
}

/// The staging directories' names under the temporary directory: this prefix, the
/// process id, a random part.
const STAGING_PREFIX: &str = "bettimill-staging-";

/// Removes the staging directories of processes that are gone (a build killed with its
/// shards in flight leaves them); those of live processes, and any that cannot be read,
/// stay.
fn remove_dead_staging() {
    let Ok(entries) = std::fs::read_dir(std::env::temp_dir()) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name
            .to_str()
            .and_then(|n| n.strip_prefix(STAGING_PREFIX))
            .and_then(|rest| rest.split_once('-'))
            .and_then(|(pid, _)| pid.parse::<u32>().ok())
        else {
            continue;
        };
        let gone = !Path::new(&format!("/proc/{pid}")).exists();
        if gone && entry.file_type().is_ok_and(|t| t.is_dir()) {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// Refuses, before the bucket is touched, a manifest whose shards could be larger than an
/// object a streamed upload can name (see
/// [`bettimill_plan::Plan::check_object_storage`]).
fn check_plan(manifest: &Manifest) -> Result<(), BuildError> {
    bettimill_plan::Plan::new(manifest)?.check_object_storage(manifest)?;
    Ok(())
}

/// A bucket bound to a build, with its lease (none for an array task) and its staging
/// directory.
pub(crate) struct BucketBuild {
    bucket: BucketDir,
    lease: Option<Lease>,
    staging: tempfile::TempDir,
    /// The staging directory's dataset: the plan, and the writer of shards and records.
    pub(crate) dataset: Dataset,
    max_uploads: usize,
}

impl BucketBuild {
    /// Opens the bucket (checking the server, the credentials and the bucket), takes the
    /// lease, creates the staging directory and binds the prefix to the manifest.
    pub(crate) fn bind(
        url: &str,
        manifest_text: &str,
        manifest: Manifest,
        options: &ObjectOptions,
    ) -> Result<BucketBuild, BuildError> {
        check_plan(&manifest)?;
        let bucket = open_bucket(url, options.endpoint.as_deref()).map_err(FormatError::from)?;
        let lease = Some(Lease::acquire(&bucket)?);
        Self::bind_opened(bucket, lease, manifest_text, manifest, options)
    }

    /// Binds the dataset already in the bucket, from its stored manifest: with the lease
    /// (finalize), or without it (an array task, which builds disjoint shards as on a
    /// shared file system, where tasks take no lock either).
    fn bind_stored(
        url: &str,
        options: &ObjectOptions,
        leased: bool,
    ) -> Result<BucketBuild, BuildError> {
        let bucket = open_bucket(url, options.endpoint.as_deref()).map_err(FormatError::from)?;
        let text = bucket.read_manifest_text()?;
        let manifest = Manifest::parse(
            &text,
            Path::new(
                &bucket
                    .objects()
                    .object_url(bettimill_format::dir::MANIFEST_FILE),
            ),
        )?;
        check_plan(&manifest)?;
        let lease = if leased {
            Some(Lease::acquire(&bucket)?)
        } else {
            None
        };
        Self::bind_opened(bucket, lease, &text, manifest, options)
    }

    fn bind_opened(
        bucket: BucketDir,
        lease: Option<Lease>,
        manifest_text: &str,
        manifest: Manifest,
        options: &ObjectOptions,
    ) -> Result<BucketBuild, BuildError> {
        remove_dead_staging();
        let staging = tempfile::Builder::new()
            .prefix(&format!("{STAGING_PREFIX}{}-", std::process::id()))
            .tempdir()
            .map_err(|source| BuildError::Io {
                path: std::env::temp_dir(),
                source,
            })?;
        let dataset = Dataset::bind(staging.path(), manifest_text, manifest)?;
        let layout = dataset.layout();
        let read = |path: &Path| {
            std::fs::read(path).map_err(|source| BuildError::Io {
                path: path.to_path_buf(),
                source,
            })
        };
        let info = layout.read_build_info()?;
        bucket.bind(
            &read(&layout.manifest_path())?,
            &read(&layout.build_info_path())?,
            &info,
        )?;
        Ok(BucketBuild {
            bucket,
            lease,
            staging,
            dataset,
            max_uploads: options.max_uploads.max(1),
        })
    }

    /// The URL of `index.json`.
    pub(crate) fn index_url(&self) -> String {
        self.bucket
            .objects()
            .object_url(bettimill_format::dir::INDEX_FILE)
    }

    /// Builds every shard the bucket lacks, then writes the finalized files, `index.json`
    /// last. `progress` gets (shards done, shards in the plan) as each shard is made and
    /// handed to an uploader.
    pub(crate) fn run(self, progress: impl FnMut(u64, u64)) -> Result<BuildSummary, BuildError> {
        let summary = self.build_shards(&|_| true, progress)?;
        self.finalize()?;
        Ok(summary)
    }

    /// Builds the shards `ours` accepts that the bucket lacks; the records of every
    /// complete shard come into the staging directory.
    fn build_shards(
        &self,
        ours: &dyn Fn(&ShardPlan) -> bool,
        mut progress: impl FnMut(u64, u64),
    ) -> Result<BuildSummary, BuildError> {
        let dataset = &self.dataset;
        let total = dataset.plan.shard_count();
        let mut summary = BuildSummary {
            dataset_samples: dataset.plan.samples,
            ..BuildSummary::default()
        };
        // One listing; then the records of complete shards come into the staging
        // directory, for index.json.
        let sizes = self.bucket.sizes()?;
        let mut missing = Vec::new();
        for shard in dataset.plan.shards() {
            match self.bucket.shard_state(&shard.name, &sizes)? {
                BucketShard::Complete { record, .. }
                    if record.shard.split == shard.split
                        && record.shard.samples == shard.samples =>
                {
                    dataset.layout().write_record(&shard.name, &record)?;
                    summary.skipped += 1;
                }
                BucketShard::Complete { .. } => {
                    return Err(self.invalid(&shard, "its record disagrees with the plan"))
                }
                BucketShard::Invalid { reason } => return Err(self.invalid(&shard, &reason)),
                BucketShard::Missing if ours(&shard) => missing.push(shard),
                BucketShard::Missing => {}
            }
        }
        progress(summary.skipped, total);
        let failure: Mutex<Option<BuildError>> = Mutex::new(None);
        let failed = || failure.lock().map(|f| f.is_some()).unwrap_or(true);
        let this = self;
        std::thread::scope(|scope| -> Result<(), BuildError> {
            // A rendezvous channel: a made shard waits until an uploader is free, so at
            // most `max_uploads` shards are staged besides the one being made.
            let (send, receive) = std::sync::mpsc::sync_channel::<ShardPlan>(0);
            let receive = Arc::new(Mutex::new(receive));
            for _ in 0..this.max_uploads {
                let receive = Arc::clone(&receive);
                let failure = &failure;
                scope.spawn(move || loop {
                    let next = receive.lock().ok().and_then(|r| r.recv().ok());
                    let Some(shard) = next else { return };
                    if let Err(err) = this.upload(&shard) {
                        if let Ok(mut failure) = failure.lock() {
                            failure.get_or_insert(err);
                        }
                    }
                });
            }
            for shard in missing {
                if failed() {
                    break;
                }
                this.check_lease()?;
                let record = dataset.write_shard(&shard)?;
                summary.built += 1;
                summary.samples_built += shard.samples;
                summary.regenerations += record.regenerations.iter().map(|r| r.1).sum::<u64>();
                if send.send(shard).is_err() {
                    break;
                }
                // Made and handed to an uploader (the index waits for every upload).
                progress(summary.skipped + summary.built, total);
            }
            Ok(())
        })?;
        if let Some(err) = failure.into_inner().ok().flatten() {
            return Err(err);
        }
        Ok(summary)
    }

    /// Writes the finalized files once every shard is complete, `index.json` last; then
    /// releases the lease and removes the staging directory.
    fn finalize(self) -> Result<(), BuildError> {
        let dataset = &self.dataset;
        self.check_lease()?;
        let unfinished = dataset
            .plan
            .shards()
            .filter(|shard| !dataset.record_path(shard).exists())
            .count();
        if unfinished > 0 {
            return Err(BuildError::Corrupt {
                path: self.bucket.url().into(),
                reason: format!(
                    "{unfinished} of {} shards are not complete (index.json not written): \
                     run the array tasks that build them, or `bettimill build MANIFEST --out {}`",
                    dataset.plan.shard_count(),
                    self.bucket.url()
                ),
            });
        }
        // Every shard is complete: a temporary of a streamed upload left now is a killed
        // writer's.
        self.bucket.remove_upload_leftovers()?;
        // The finalized files from the plan and the records, as a local finalize makes
        // them; index.json comes last, so its presence means the dataset is complete.
        let root = dataset.dir.clone();
        for (path, bytes) in dataset.finalized_bytes()? {
            let name = path
                .strip_prefix(&root)
                .map(|p| p.to_string_lossy().replace('\\', "/"))
                .unwrap_or_default();
            self.check_lease()?;
            self.bucket.put_same(&name, bytes)?;
        }
        drop(self.lease);
        drop(self.staging);
        Ok(())
    }

    /// Uploads a staged shard: its tar (streamed from the staging file: memory holds a few
    /// parts of it, not the shard), then its record, then (statistics only) its timing;
    /// then removes its tar and timing from the staging directory.
    fn upload(&self, shard: &ShardPlan) -> Result<(), BuildError> {
        let layout = self.dataset.layout();
        let read = |path: &Path| {
            std::fs::read(path).map_err(|source| BuildError::Io {
                path: path.to_path_buf(),
                source,
            })
        };
        let tar = layout.tar_path(&shard.name);
        self.check_lease()?;
        self.bucket
            .put_file_same(&BucketDir::tar_name(&shard.name), &tar)?;
        self.check_lease()?;
        self.bucket.put_same(
            &BucketDir::record_name(&shard.name),
            read(&layout.record_path(&shard.name))?,
        )?;
        let timing = layout.timing_path(&shard.name);
        if let Ok(bytes) = std::fs::read(&timing) {
            // Times differ between runs: an earlier run's timing stays.
            let _ = self
                .bucket
                .objects()
                .put_new(&BucketDir::timing_name(&shard.name), bytes);
        }
        for path in [tar, timing] {
            match std::fs::remove_file(&path) {
                Err(err) if err.kind() != std::io::ErrorKind::NotFound => {
                    return Err(BuildError::Io { path, source: err })
                }
                _ => {}
            }
        }
        Ok(())
    }

    fn check_lease(&self) -> Result<(), BuildError> {
        if let Some(lease) = self.lease.as_ref().filter(|lease| lease.lost()) {
            return Err(BuildError::Corrupt {
                path: lease.url().into(),
                reason: "another build took this build's lease (it could not renew it in time); \
                         stopping: run the build again once the other one is done"
                    .into(),
            });
        }
        Ok(())
    }

    fn invalid(&self, shard: &ShardPlan, reason: &str) -> BuildError {
        BuildError::Corrupt {
            path: self
                .bucket
                .objects()
                .object_url(&BucketDir::tar_name(&shard.name))
                .into(),
            reason: format!(
                "{reason}; objects are never overwritten: delete {} and its record, then build again",
                BucketDir::tar_name(&shard.name)
            ),
        }
    }
}

/// The state of every planned shard of the dataset at `url`, in plan order, from one
/// listing and the records (a record that disagrees with the plan makes its shard
/// invalid); the plan comes from the stored manifest, checked against `build.json` as a
/// directory's is. Returns the plan and whether `index.json` exists.
fn bucket_shards(
    url: &str,
    endpoint: Option<&str>,
    mut each: impl FnMut(ShardPlan, BucketShard),
) -> Result<(bettimill_plan::Plan, bool), BuildError> {
    let bucket = open_bucket(url, endpoint).map_err(FormatError::from)?;
    let text = bucket.read_manifest_text()?;
    let manifest = Manifest::parse(&text, Path::new(url))?;
    let plan = bettimill_plan::Plan::new(&manifest)?;
    let expected = bettimill_format::BuildInfo::current(plan.manifest_hash.clone(), plan.hash());
    bettimill_format::check_build_info(Path::new(url), &bucket.read_build_info()?, &expected)?;
    let sizes = bucket.sizes()?;
    for shard in plan.shards() {
        let state = match bucket.shard_state(&shard.name, &sizes)? {
            BucketShard::Complete { record, .. }
                if record.shard.split != shard.split || record.shard.samples != shard.samples =>
            {
                BucketShard::Invalid {
                    reason: format!(
                        "its record says {} samples of split {}, the plan has {} of split {}",
                        record.shard.samples, record.shard.split, shard.samples, shard.split
                    ),
                }
            }
            state => state,
        };
        each(shard, state);
    }
    let finalized = sizes.contains_key(bettimill_format::dir::INDEX_FILE);
    Ok((plan, finalized))
}

/// `status` of a dataset in a bucket: every planned shard complete (its record, and a tar
/// of the record's size), missing or invalid (a record that disagrees with the plan).
pub fn bucket_status(
    url: &str,
    endpoint: Option<&str>,
) -> Result<crate::cluster::StatusReport, BuildError> {
    use crate::cluster::{InvalidShard, StatusReport, STATUS_NAMES};
    let mut report = StatusReport {
        dir: url.into(),
        ..StatusReport::default()
    };
    let (plan, finalized) = bucket_shards(url, endpoint, |shard, state| match state {
        BucketShard::Complete { .. } => {
            report.complete_count += 1;
            if report.complete.len() < STATUS_NAMES {
                report.complete.push(shard.name);
            }
        }
        BucketShard::Missing => {
            report.missing_count += 1;
            if report.missing.len() < STATUS_NAMES {
                report.missing.push(shard.name);
            }
        }
        BucketShard::Invalid { reason } => {
            report.invalid_count += 1;
            if report.invalid.len() < STATUS_NAMES {
                report.invalid.push(InvalidShard {
                    shard: shard.name,
                    reason,
                });
            }
        }
    })?;
    report.shards = plan.shard_count();
    report.finalized = finalized;
    Ok(report)
}

/// The plan indices of the shards of the dataset at `url` that are not complete (missing
/// or invalid), in plan order: the array tasks a resubmission still needs.
pub fn bucket_incomplete_shards(url: &str, endpoint: Option<&str>) -> Result<Vec<u64>, BuildError> {
    let mut incomplete = Vec::new();
    bucket_shards(url, endpoint, |shard, state| {
        if !matches!(state, BucketShard::Complete { .. }) {
            incomplete.push(shard.index);
        }
    })?;
    Ok(incomplete)
}

/// An array task of a dataset in a bucket (`worker --dir s3://... --task-count N`): builds
/// the shards `s` with `s % task_count == task_index` that the bucket lacks, from the stored
/// manifest, on the current rayon pool; `index.json` is [`bucket_finalize`]'s.
pub fn bucket_task(
    url: &str,
    options: &ObjectOptions,
    task_index: u64,
    task_count: u64,
) -> Result<BuildSummary, BuildError> {
    let build = BucketBuild::bind_stored(url, options, false)?;
    let count = task_count.max(1);
    build.build_shards(&|shard| shard.index % count == task_index, |_, _| {})
}

/// `finalize` of a dataset in a bucket: under the lease, once every shard is complete,
/// writes the wids indexes, the class table, the card and `index.json` (last).
pub fn bucket_finalize(url: &str, options: &ObjectOptions) -> Result<(), BuildError> {
    let build = BucketBuild::bind_stored(url, options, true)?;
    build.build_shards(&|_| false, |_, _| {})?;
    build.finalize()
}

/// Binds a bucket prefix to a manifest (under the lease, released at once): what
/// `bettimill k8s` does before array tasks run. Returns the dataset's name.
pub fn bucket_bind(
    url: &str,
    manifest_text: &str,
    manifest: Manifest,
    options: &ObjectOptions,
) -> Result<String, BuildError> {
    BucketBuild::bind(url, manifest_text, manifest, options).map(|b| b.dataset.plan.name.clone())
}

/// A dataset in a bucket opened for the checks that compare it with its plan (`audit`):
/// a local copy of everything but its shards and timings (the manifest, `build.json`, the
/// records, the finished files; see [`BucketDir::copy_metadata`]) opened as a dataset
/// directory, and the bucket, from which the shards are read by ranges. Nothing in the
/// bucket is written; the copy is removed when this is dropped.
pub struct BucketCopy {
    /// The dataset of the local copy: the plan, from the stored manifest, checked against
    /// the stored `build.json`.
    pub dataset: Dataset,
    /// The bucket, to read the shards from.
    pub source: bettimill_format::DatasetSource,
    /// The copy's directory (held for its removal).
    _copy: tempfile::TempDir,
}

/// Opens `url` with `endpoint` and the AWS variables and copies its metadata into a
/// temporary directory (see [`BucketCopy`]).
pub fn bucket_copy(url: &str, endpoint: Option<&str>) -> Result<BucketCopy, BuildError> {
    let bucket = open_bucket(url, endpoint).map_err(FormatError::from)?;
    bucket.read_build_info()?;
    let copy = tempfile::Builder::new()
        .prefix("bettimill-bucket-copy-")
        .tempdir()
        .map_err(|source| BuildError::Io {
            path: std::env::temp_dir(),
            source,
        })?;
    bucket.copy_metadata(copy.path())?;
    let dataset = Dataset::open(copy.path())?;
    Ok(BucketCopy {
        dataset,
        source: bettimill_format::DatasetSource::Bucket(bucket),
        _copy: copy,
    })
}
