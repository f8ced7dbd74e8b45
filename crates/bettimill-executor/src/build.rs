//! The one entry point of a build, into a directory or `s3://BUCKET/PREFIX`: [`build`]
//! takes a [`BuildRequest`] and returns a [`BuildReport`]. It owns what every caller of a build must do the same way: the plan
//! refused before anything is written when one sample cannot fit the memory limit (see
//! [`crate::memory`]), the directory bound, the choice between this process and worker
//! processes ([`Runner`]), the workers' command line (`worker --dir DIR`, with the same
//! `--max-memory` the plan was checked against) and the progress events. The CLI's `build`
//! and the Python binding's `build` only translate their arguments into a request and the
//! report into their output.

use crate::coordinator::{self, BuildControl, BuildEvent, BuildOptions, CoordinatorError};
use crate::{BuildError, Dataset, LockError};
use bettimill_env::EnvVars;
use bettimill_manifest::Manifest;
use bettimill_plan::memory::MemoryError;
use bettimill_plan::{Plan, PlanError};
use std::ffi::OsString;
use std::path::PathBuf;
use std::time::Duration;

/// Where the shards are built.
#[derive(Clone, Debug)]
pub enum Runner {
    /// In this process, one shard after the other.
    InProcess,
    /// By up to `count` worker processes of `program` (a bettimill binary or console
    /// script, run as `program worker --dir DIR`), driven by the [`coordinator`].
    Workers {
        /// Worker processes at once (at least 1).
        count: usize,
        /// The program the workers run.
        program: PathBuf,
    },
}

/// What to build.
#[derive(Clone, Debug)]
pub struct BuildRequest {
    /// The dataset directory (new, or a partial build of the same manifest).
    pub out: PathBuf,
    /// The manifest's text, stored byte for byte in the directory.
    pub manifest_text: String,
    /// The parsed manifest.
    pub manifest: Manifest,
    /// Where the shards are built.
    pub runner: Runner,
    /// Memory one worker may use; `None` for the machine's default (see
    /// [`crate::memory::memory_limit`]).
    pub max_memory: Option<u64>,
    /// Failures after which a shard is given up (worker processes only).
    pub max_shard_failures: u32,
    /// A silent worker is killed after this long (worker processes only).
    pub worker_timeout: Duration,
    /// The endpoint and uploads of an `s3://BUCKET/PREFIX` output (unused for a directory).
    pub object: crate::remote::ObjectOptions,
}

/// Progress of a [`build`], in the order it happens.
pub enum BuildProgress<'a> {
    /// The directory is bound and nothing is built yet.
    Bound(&'a Dataset),
    /// An event of the coordinator (worker processes).
    Workers(BuildEvent),
    /// An in-process build finished a shard: (shards done, shards in the plan).
    Shard(u64, u64),
}

/// How a build ended.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BuildReport {
    /// The totals; an in-process build fills the same fields as the coordinator.
    pub totals: coordinator::BuildReport,
    /// Samples in the plan.
    pub samples: u64,
    /// The dataset's `index.json` (written when every shard is complete).
    pub index: PathBuf,
}

/// Why a build could not run.
#[derive(Debug, thiserror::Error)]
pub enum BuildFailure {
    /// The manifest has no valid plan.
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// One sample of the plan needs more memory than a worker may use.
    #[error(transparent)]
    Memory(#[from] Box<MemoryError>),
    /// The directory was refused.
    #[error(transparent)]
    Dataset(BuildError),
    /// An in-process build failed (a shard could not be written, finalize failed).
    #[error(transparent)]
    InProcess(BuildError),
    /// Another process (a build or a finalize) holds the directory lock.
    #[error(transparent)]
    Lock(#[from] LockError),
    /// The worker processes could not run the build.
    #[error(transparent)]
    Coordinator(#[from] CoordinatorError),
}

/// Builds (or resumes) the dataset of `request` (see the module documentation). `control`
/// interrupts a build by worker processes when it yields; `progress` receives the events on
/// the calling thread.
pub fn build(
    request: BuildRequest,
    control: impl std::future::Future<Output = BuildControl>,
    mut progress: impl FnMut(BuildProgress<'_>),
) -> Result<BuildReport, BuildFailure> {
    let BuildRequest {
        out,
        manifest_text,
        manifest,
        runner,
        max_memory,
        max_shard_failures,
        worker_timeout,
        object,
    } = request;
    // Refused before anything is written or any worker starts: a sample that cannot fit
    // would otherwise kill every worker attempt after minutes.
    let plan = Plan::new(&manifest)?;
    let workers = match &runner {
        Runner::InProcess => 1,
        Runner::Workers { count, .. } => *count as u64,
    };
    let running = workers.min(plan.shard_count()).max(1);
    let memory_limit = crate::memory::memory_limit(max_memory, running);
    if let Some((limit, origin)) = &memory_limit {
        bettimill_plan::memory::check(&plan, 1, *limit, origin)?;
    }
    drop(plan);
    if let Some(url) = out
        .to_str()
        .filter(|o| bettimill_shard::object::is_object_url(o))
    {
        return build_to_bucket(url, &manifest_text, manifest, &object, progress);
    }
    // The lock is held from here to the end, so a `finalize` started meanwhile waits for
    // this build instead of taking the lock between the binding and the build.
    let (dataset, lock) =
        Dataset::bind_locked(&out, &manifest_text, manifest).map_err(|err| match err {
            BuildError::Format(bettimill_format::FormatError::Lock(err)) => BuildFailure::Lock(err),
            err => BuildFailure::Dataset(err),
        })?;
    // Test hook: a test signals the build while it waits here, in the middle of start-up.
    if let Some(pause) = bettimill_env::seconds(EnvVars::BETTIMILL_TEST_PAUSE_AT_STARTUP) {
        std::thread::sleep(pause);
    }
    progress(BuildProgress::Bound(&dataset));
    let totals = match runner {
        Runner::InProcess => {
            let summary = dataset
                .build_in_process(|done, total| progress(BuildProgress::Shard(done, total)))
                .map_err(BuildFailure::InProcess)?;
            in_process_totals(&summary, dataset.plan.shard_count())
        }
        Runner::Workers { count, program } => {
            let options = BuildOptions {
                workers: count,
                max_shard_failures,
                worker_program: program,
                worker_args: worker_args(&out, memory_limit.map(|(limit, _)| limit)),
                worker_timeout,
            };
            coordinator::run_locked(&dataset, &lock, &options, control, |event| {
                progress(BuildProgress::Workers(event))
            })?
        }
    };
    drop(lock);
    Ok(BuildReport {
        totals,
        samples: dataset.plan.samples,
        index: dataset.layout().index_path(),
    })
}

/// The totals of a build made in this process, which ends with every shard complete and
/// the dataset finalized.
fn in_process_totals(summary: &crate::BuildSummary, shards: u64) -> coordinator::BuildReport {
    coordinator::BuildReport {
        built: summary.built,
        skipped: summary.skipped,
        samples_built: summary.samples_built,
        regenerations: summary.regenerations,
        complete: shards,
        shards,
        finalized: true,
        ..coordinator::BuildReport::default()
    }
}

/// A build into object storage (see [`crate::remote`]): the bucket is checked and its lease
/// taken before any work; shards are made in this process, on all its threads.
fn build_to_bucket(
    url: &str,
    manifest_text: &str,
    manifest: Manifest,
    object: &crate::remote::ObjectOptions,
    mut progress: impl FnMut(BuildProgress<'_>),
) -> Result<BuildReport, BuildFailure> {
    let build = crate::remote::BucketBuild::bind(url, manifest_text, manifest, object)
        .map_err(BuildFailure::Dataset)?;
    if let Some(pause) = bettimill_env::seconds(EnvVars::BETTIMILL_TEST_PAUSE_AT_STARTUP) {
        std::thread::sleep(pause);
    }
    progress(BuildProgress::Bound(&build.dataset));
    let shards = build.dataset.plan.shard_count();
    let samples = build.dataset.plan.samples;
    let index = PathBuf::from(build.index_url());
    let summary = build
        .run(|done, total| progress(BuildProgress::Shard(done, total)))
        .map_err(BuildFailure::InProcess)?;
    Ok(BuildReport {
        totals: in_process_totals(&summary, shards),
        samples,
        index,
    })
}

/// A coordinator worker's arguments: `worker --dir DIR`, and `--max-memory` with the limit
/// the plan was checked against, so that each worker checks the same limit.
fn worker_args(out: &std::path::Path, max_memory: Option<u64>) -> Vec<OsString> {
    [
        OsString::from("worker"),
        OsString::from("--dir"),
        out.as_os_str().to_owned(),
    ]
    .into_iter()
    .chain(max_memory.iter().flat_map(|limit| {
        [
            OsString::from("--max-memory"),
            OsString::from(limit.to_string()),
        ]
    }))
    .collect()
}
