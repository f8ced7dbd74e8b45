//! The worker side: serving a coordinator over pipes, and cluster array tasks.
//!
//! Two ways to run a worker:
//!
//! - [`serve`]: `bettimill worker --dir DIR` started by `bettimill build`. It speaks the
//!   [`crate::protocol`] on stdin/stdout, builds the shards it is asked for on a rayon pool
//!   of one thread (so N workers use N cores), and exits as soon as its stdin reaches end of
//!   file, which is how it notices that its coordinator died.
//! - [`run_task`]: `bettimill worker --dir DIR --task-index-from-env --task-count N` in a
//!   Slurm/Kubernetes/PBS/SGE/LSF array job. Task `t` builds the shards `s` with
//!   `s % N == t` that are not complete yet; the directory is the only coordination.
//!
//! Test hooks (internal, listed in `bettimill_env::EnvVars`; never set them otherwise):
//! `BETTIMILL_TEST_FAIL_TASK` makes array task `t` fail before any work,
//! `BETTIMILL_TEST_FAIL_SHARD` makes every attempt at one shard fail, and
//! `BETTIMILL_TEST_WORKER_VERSION` makes a served worker claim another version.

use crate::protocol::{self, FromWorker, Handshake, Peer, ProtocolError, ToWorker};
use crate::{BuildError, Dataset, SampleEvent};
use bettimill_env::EnvVars;
use bettimill_sample::TOOL_VERSION;
use std::io::{Read, Write};
use std::sync::Mutex;

/// Why a worker stopped.
#[derive(Debug, thiserror::Error)]
pub enum WorkerError {
    /// The dataset could not be opened.
    #[error(transparent)]
    Build(#[from] BuildError),
    /// The session with the coordinator broke.
    #[error(transparent)]
    Protocol(#[from] ProtocolError),
    /// A worker pool could not be made.
    #[error("cannot start the worker's thread pool: {0}")]
    Pool(String),
    /// No array index in the environment.
    #[error("no array task index in the environment: set one of {}, or pass --task-index", TASK_INDEX_VARIABLES.iter().map(|v| v.0).collect::<Vec<_>>().join(", "))]
    NoTaskIndex,
    /// An array index that is not a number in range.
    #[error("{variable}={value} is not a task index below --task-count {count} ({base}-based)")]
    BadTaskIndex {
        /// The variable read.
        variable: String,
        /// Its value.
        value: String,
        /// The task count.
        count: u64,
        /// 0 or 1.
        base: u64,
    },
    /// A build or a finalize holds the directory (array tasks do not write beside it).
    #[error(transparent)]
    Lock(#[from] crate::LockError),
    /// The failure-injection hook fired.
    #[error(
        "{}={index}: failing array task {index} on purpose (test hook)",
        EnvVars::BETTIMILL_TEST_FAIL_TASK
    )]
    InjectedTaskFailure {
        /// The task index.
        index: u64,
    },
}

/// Environment variables that carry an array task index, with the index of the first task.
pub const TASK_INDEX_VARIABLES: [(&str, u64); 5] = [
    (EnvVars::SLURM_ARRAY_TASK_ID, 0),
    (EnvVars::JOB_COMPLETION_INDEX, 0),
    (EnvVars::PBS_ARRAY_INDEX, 0),
    (EnvVars::SGE_TASK_ID, 1),
    (EnvVars::LSB_JOBINDEX, 1),
];

/// Where a task index came from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TaskIndex {
    /// The 0-based index.
    pub index: u64,
    /// The variable it was read from.
    pub variable: &'static str,
}

/// This process's array task index, from the scheduler's variables (see
/// [`task_index_from_env`]).
pub fn task_index_from_environment(count: u64) -> Result<TaskIndex, WorkerError> {
    task_index_from_env(bettimill_env::var, count)
}

/// Reads the array task index from the first of [`TASK_INDEX_VARIABLES`] that is set
/// (SGE's "undefined" counts as unset) in `lookup`, converting 1-based schedulers to 0-based.
pub fn task_index_from_env(
    lookup: impl Fn(&str) -> Option<String>,
    count: u64,
) -> Result<TaskIndex, WorkerError> {
    for (variable, base) in TASK_INDEX_VARIABLES {
        let Some(value) = lookup(variable) else {
            continue;
        };
        let value = value.trim().to_string();
        if value.is_empty() || value == "undefined" {
            continue;
        }
        let bad = || WorkerError::BadTaskIndex {
            variable: variable.to_string(),
            value: value.clone(),
            count,
            base,
        };
        let raw: u64 = value.parse().map_err(|_| bad())?;
        let index = raw.checked_sub(base).ok_or_else(bad)?;
        if index >= count {
            return Err(bad());
        }
        return Ok(TaskIndex { index, variable });
    }
    Err(WorkerError::NoTaskIndex)
}

fn injected_shard_failure(shard_index: u64) -> bool {
    bettimill_env::number::<u64>(EnvVars::BETTIMILL_TEST_FAIL_SHARD) == Some(shard_index)
}

fn our_handshake(dataset: &Dataset) -> Handshake {
    Handshake {
        protocol_version: protocol::PROTOCOL_VERSION,
        tool_version: bettimill_env::var(EnvVars::BETTIMILL_TEST_WORKER_VERSION)
            .unwrap_or_else(|| TOOL_VERSION.to_string()),
        plan_hash: dataset.plan.hash(),
    }
}

/// Serves one coordinator: handshake, then shards on request until `Shutdown` or end of
/// input. `input` is read on its own thread; when it ends (the coordinator closed the pipe
/// or died), `on_end_of_input` runs there, and the binary passes a function that exits the
/// process at once, abandoning any shard in progress (its writes are atomic). If it
/// returns, the current shard is finished first.
pub fn serve(
    dataset: &Dataset,
    input: impl Read + Send + 'static,
    output: impl Write + Send,
    on_end_of_input: impl FnOnce() + Send + 'static,
) -> Result<(), WorkerError> {
    let ours = our_handshake(dataset);
    let output = Mutex::new(output);
    let send = |message: &FromWorker| -> Result<(), ProtocolError> {
        let mut out = output.lock().unwrap_or_else(|e| e.into_inner());
        protocol::write_frame(&mut *out, message, "coordinator")
    };
    {
        let mut out = output.lock().unwrap_or_else(|e| e.into_inner());
        protocol::write_frame(&mut *out, &ours, "coordinator")?;
    }
    let mut input = input;
    let Some(theirs) = protocol::read_frame::<Handshake>(&mut input, "coordinator")? else {
        return Ok(());
    };
    protocol::check_handshake(&ours, &theirs, Peer::Coordinator)?;

    let (requests, received) = std::sync::mpsc::channel::<Result<ToWorker, ProtocolError>>();
    std::thread::spawn(move || {
        loop {
            match protocol::read_frame::<ToWorker>(&mut input, "coordinator") {
                Ok(Some(message)) => {
                    if requests.send(Ok(message)).is_err() {
                        return;
                    }
                }
                Ok(None) => break,
                Err(err) => {
                    let _ = requests.send(Err(err));
                    break;
                }
            }
        }
        on_end_of_input();
    });

    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| WorkerError::Pool(e.to_string()))?;
    // The heartbeat runs on its own thread, so it keeps coming while a sample takes
    // minutes; it stops when serving ends (or when the pipe breaks: the coordinator is gone).
    // The same thread sends the stage frames the rate limit held back (see StageFrames).
    let (stop_heartbeat, heartbeat_stopped) = std::sync::mpsc::channel::<()>();
    let stages = StageFrames::new();
    std::thread::scope(|scope| {
        let send = &send;
        let stages = &stages;
        scope.spawn(move || {
            let mut last_heartbeat = std::time::Instant::now();
            while let Err(std::sync::mpsc::RecvTimeoutError::Timeout) =
                heartbeat_stopped.recv_timeout(protocol::STAGE_INTERVAL)
            {
                if stages.flush(send, std::time::Instant::now()).is_err() {
                    break;
                }
                if last_heartbeat.elapsed() >= protocol::HEARTBEAT_INTERVAL {
                    last_heartbeat = std::time::Instant::now();
                    if send(&FromWorker::Heartbeat).is_err() {
                        break;
                    }
                }
            }
        });
        let served = serve_requests(dataset, &pool, &received, send, stages);
        drop(stop_heartbeat);
        served
    })
}

/// The request loop of [`serve`].
fn serve_requests(
    dataset: &Dataset,
    pool: &rayon::ThreadPool,
    received: &std::sync::mpsc::Receiver<Result<ToWorker, ProtocolError>>,
    send: &SendFrame<'_>,
    stages: &StageFrames,
) -> Result<(), WorkerError> {
    while let Ok(request) = received.recv() {
        let shard_index = match request? {
            ToWorker::Shutdown => break,
            ToWorker::Build { shard_index } => shard_index,
        };
        let Some(shard) =
            (shard_index < dataset.plan.shard_count()).then(|| dataset.plan.shard(shard_index))
        else {
            send(&FromWorker::Failed {
                shard_index,
                reason: format!(
                    "the plan has {} shards, there is no shard {shard_index}",
                    dataset.plan.shard_count()
                ),
            })?;
            continue;
        };
        if injected_shard_failure(shard_index) {
            send(&FromWorker::Failed {
                shard_index,
                reason: format!(
                    "{}={shard_index}: failing on purpose (test hook)",
                    EnvVars::BETTIMILL_TEST_FAIL_SHARD
                ),
            })?;
            continue;
        }
        let observe = |event: SampleEvent<'_>| {
            // A broken pipe here means the coordinator is gone; the reader thread ends the
            // process, so the errors need no handling of their own.
            match event {
                SampleEvent::Done { regenerations, .. } => {
                    let _ = stages.sample_done(
                        send,
                        &FromWorker::Progress {
                            shard_index,
                            regenerations,
                        },
                    );
                }
                SampleEvent::Stage { task, progress } => {
                    let _ = stages.stage(
                        send,
                        FromWorker::Stage {
                            shard_index,
                            sample: task.index,
                            attempt: progress.attempt,
                            stage: progress.stage,
                            thousandths: (progress.fraction * 1000.0).round().clamp(0.0, 1000.0)
                                as u16,
                        },
                        std::time::Instant::now(),
                    );
                }
            }
        };
        let result = pool.install(|| dataset.write_shard_observed(&shard, &observe));
        stages.discard();
        match result {
            Ok(record) => send(&FromWorker::Done {
                shard_index,
                regenerations: record.regenerations.iter().map(|r| r.1).sum(),
                bytes: record.shard.bytes,
            })?,
            Err(err) => send(&FromWorker::Failed {
                shard_index,
                reason: err.to_string(),
            })?,
        }
    }
    Ok(())
}

/// How the worker sends a frame.
type SendFrame<'a> = dyn Fn(&FromWorker) -> Result<(), ProtocolError> + Sync + 'a;

/// The stage frames of a served session: at most one per [`protocol::STAGE_INTERVAL`]
/// whatever the samples' size. A stage that starts too soon after the last frame is kept
/// (the latest one only) and sent by the heartbeat thread once the interval has passed, so a
/// long stage that follows a short one is shown as itself, not as the short one; it is
/// dropped if its sample finishes first. A worker makes one sample at a time (one thread).
struct StageFrames {
    limit: RateLimit,
    pending: Mutex<Option<FromWorker>>,
}

impl StageFrames {
    fn new() -> StageFrames {
        StageFrames {
            limit: RateLimit::new(protocol::STAGE_INTERVAL),
            pending: Mutex::new(None),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Option<FromWorker>> {
        self.pending.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A stage starts: sent now if the limit allows, else kept for [`StageFrames::flush`].
    fn stage(
        &self,
        send: &SendFrame<'_>,
        frame: FromWorker,
        now: std::time::Instant,
    ) -> Result<(), ProtocolError> {
        let mut pending = self.lock();
        if self.limit.allow(now) {
            *pending = None;
            send(&frame)
        } else {
            *pending = Some(frame);
            Ok(())
        }
    }

    /// Sends the kept stage, if any and if the limit allows. The lock is held while it is
    /// sent, so it never follows its sample's `Progress`.
    fn flush(&self, send: &SendFrame<'_>, now: std::time::Instant) -> Result<(), ProtocolError> {
        let mut pending = self.lock();
        if pending.is_some() && self.limit.allow(now) {
            if let Some(frame) = pending.take() {
                return send(&frame);
            }
        }
        Ok(())
    }

    /// The sample is done: its kept stage is stale; `progress` is sent.
    fn sample_done(
        &self,
        send: &SendFrame<'_>,
        progress: &FromWorker,
    ) -> Result<(), ProtocolError> {
        let mut pending = self.lock();
        *pending = None;
        send(progress)
    }

    /// The shard is over (written or failed): nothing kept is sent after it.
    fn discard(&self) {
        *self.lock() = None;
    }
}

/// At most one event per interval: [`RateLimit::allow`] says yes to the first event and
/// then to the first one at least `interval` after the last it allowed.
#[derive(Debug)]
pub struct RateLimit {
    interval: std::time::Duration,
    last: Mutex<Option<std::time::Instant>>,
}

impl RateLimit {
    /// A limit of one event per `interval`.
    pub fn new(interval: std::time::Duration) -> RateLimit {
        RateLimit {
            interval,
            last: Mutex::new(None),
        }
    }

    /// Whether an event at `now` may pass (and if so, it counts as the last one).
    pub fn allow(&self, now: std::time::Instant) -> bool {
        let mut last = self.last.lock().unwrap_or_else(|e| e.into_inner());
        match *last {
            Some(previous) if now.saturating_duration_since(previous) < self.interval => false,
            _ => {
                *last = Some(now);
                true
            }
        }
    }
}

/// What one array task did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TaskReport {
    /// Shards this task built now.
    pub built: Vec<String>,
    /// Shards of this task that were already complete.
    pub skipped: Vec<String>,
    /// Shards that failed, with the reason.
    pub failed: Vec<(String, String)>,
}

/// Builds the incomplete shards of array task `task_index` of `task_count` (every shard `s`
/// with `s % task_count == task_index`), on the current rayon pool, holding the directory
/// lock shared (tasks write side by side; a build or a finalize running there refuses the
/// task, and a build started meanwhile is refused). A failing shard is reported and the
/// others are still built. `on_shard` is called after each shard, and
/// `on_sample` with each of its samples' stages and completions (from the pool's threads;
/// see [`Dataset::write_shard_observed`]), with the shard's name.
pub fn run_task(
    dataset: &Dataset,
    task_index: u64,
    task_count: u64,
    mut on_shard: impl FnMut(&str, Result<(), &str>),
    on_sample: &(dyn Fn(&str, SampleEvent<'_>) + Sync),
) -> Result<TaskReport, WorkerError> {
    if bettimill_env::number::<u64>(EnvVars::BETTIMILL_TEST_FAIL_TASK) == Some(task_index) {
        return Err(WorkerError::InjectedTaskFailure { index: task_index });
    }
    let _lock = crate::DirLock::share(&dataset.dir)?;
    let mut report = TaskReport::default();
    let shard_count = if task_count > 0 {
        dataset.plan.shard_count()
    } else {
        0
    };
    // Only this task's shards are computed: an array task of a 10^7-shard plan does not walk
    // every shard.
    for shard_index in (task_index..shard_count).step_by(task_count.max(1) as usize) {
        let shard = &dataset.plan.shard(shard_index);
        if dataset.completed(shard).is_some() {
            report.skipped.push(shard.name.clone());
            continue;
        }
        let result = if injected_shard_failure(shard.index) {
            Err(format!(
                "{}={}: failing on purpose (test hook)",
                EnvVars::BETTIMILL_TEST_FAIL_SHARD,
                shard.index
            ))
        } else {
            dataset
                .write_shard_observed(shard, &|event| on_sample(&shard.name, event))
                .map(|_| ())
                .map_err(|e| e.to_string())
        };
        match result {
            Ok(()) => {
                on_shard(&shard.name, Ok(()));
                report.built.push(shard.name.clone());
            }
            Err(reason) => {
                on_shard(&shard.name, Err(&reason));
                report.failed.push((shard.name.clone(), reason));
            }
        }
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::Stage;

    fn check(vars: &[(&str, &str)], count: u64) -> Result<(u64, &'static str), String> {
        let lookup = |name: &str| {
            vars.iter()
                .find(|(n, _)| *n == name)
                .map(|(_, v)| v.to_string())
        };
        task_index_from_env(lookup, count)
            .map(|t| (t.index, t.variable))
            .map_err(|e| e.to_string())
    }

    #[test]
    fn task_indices_from_every_scheduler() {
        assert_eq!(
            check(&[("SLURM_ARRAY_TASK_ID", "2")], 4),
            Ok((2, "SLURM_ARRAY_TASK_ID"))
        );
        assert_eq!(
            check(&[("JOB_COMPLETION_INDEX", "0")], 4),
            Ok((0, "JOB_COMPLETION_INDEX"))
        );
        assert_eq!(
            check(&[("PBS_ARRAY_INDEX", "3")], 4),
            Ok((3, "PBS_ARRAY_INDEX"))
        );
        assert_eq!(check(&[("SGE_TASK_ID", "1")], 4), Ok((0, "SGE_TASK_ID")));
        assert_eq!(check(&[("LSB_JOBINDEX", "4")], 4), Ok((3, "LSB_JOBINDEX")));
        // SGE sets "undefined" outside array jobs; the next variable is used.
        assert_eq!(
            check(&[("SGE_TASK_ID", "undefined"), ("LSB_JOBINDEX", "2")], 4),
            Ok((1, "LSB_JOBINDEX"))
        );
        // Slurm wins over the others.
        assert_eq!(
            check(&[("LSB_JOBINDEX", "1"), ("SLURM_ARRAY_TASK_ID", "3")], 4),
            Ok((3, "SLURM_ARRAY_TASK_ID"))
        );
    }

    #[test]
    fn bad_task_indices_are_refused_with_the_variable() {
        let err = check(&[("SLURM_ARRAY_TASK_ID", "4")], 4).unwrap_err();
        assert!(
            err.contains("SLURM_ARRAY_TASK_ID=4") && err.contains("4"),
            "{err}"
        );
        let err = check(&[("SGE_TASK_ID", "0")], 4).unwrap_err();
        assert!(err.contains("1-based"), "{err}");
        let err = check(&[("PBS_ARRAY_INDEX", "x")], 4).unwrap_err();
        assert!(err.contains("PBS_ARRAY_INDEX=x"), "{err}");
        let err = check(&[], 4).unwrap_err();
        assert!(err.contains("JOB_COMPLETION_INDEX"), "{err}");
    }

    /// Serves a whole session in this process (handshake, the shards, `Shutdown`) and
    /// returns the worker's frames after its handshake.
    fn serve_session(dataset: &Dataset, shards: u64) -> Vec<FromWorker> {
        let mut input = protocol::encode_frame(&our_handshake(dataset));
        for shard_index in 0..shards {
            input.extend(protocol::encode_frame(&ToWorker::Build { shard_index }));
        }
        input.extend(protocol::encode_frame(&ToWorker::Shutdown));
        let mut output = Vec::new();
        serve(dataset, std::io::Cursor::new(input), &mut output, || {}).unwrap();
        let mut reader = &output[..];
        let theirs = protocol::read_frame::<Handshake>(&mut reader, "worker")
            .unwrap()
            .unwrap();
        assert_eq!(theirs.protocol_version, protocol::PROTOCOL_VERSION);
        std::iter::from_fn(|| protocol::read_frame::<FromWorker>(&mut reader, "worker").unwrap())
            .collect()
    }

    #[test]
    fn a_served_small_sample_build_sends_few_stage_frames_and_every_sample() {
        const MANIFEST: &str = "schema_version = 1\nname = \"w\"\ndimension = 2\nside = 20\n\
            mode = [\"embed\", \"carve\"]\nsamples = 24\nshard_size = 8\nseed = 3\n\
            resolutions = [10]\n[[classes]]\nfamily = [\"ball\", \"handle\"]\n";
        let dir = tempfile::tempdir().unwrap();
        let manifest =
            bettimill_manifest::Manifest::parse(MANIFEST, std::path::Path::new("w.toml")).unwrap();
        let dataset = Dataset::bind(dir.path(), MANIFEST, manifest).unwrap();
        let started = std::time::Instant::now();
        let frames = serve_session(&dataset, 3);
        let elapsed = started.elapsed();
        let stages: Vec<&FromWorker> = frames
            .iter()
            .filter(|f| matches!(f, FromWorker::Stage { .. }))
            .collect();
        let progress = frames
            .iter()
            .filter(|f| matches!(f, FromWorker::Progress { .. }))
            .count();
        let done = frames
            .iter()
            .filter(|f| matches!(f, FromWorker::Done { .. }))
            .count();
        assert_eq!((progress, done), (24, 3), "{frames:?}");
        // Stages per sample here: generate, verify, downscale r10, encode.
        assert!(stages.len() <= 24 * 4, "{} stage frames", stages.len());
        // At most one per STAGE_INTERVAL of the session, and at least the first.
        let allowed = elapsed.as_secs_f64() / protocol::STAGE_INTERVAL.as_secs_f64();
        assert!(
            !stages.is_empty() && stages.len() as f64 <= allowed.floor() + 1.0,
            "{} stage frames in {elapsed:?}",
            stages.len()
        );
        for stage in stages {
            let FromWorker::Stage {
                shard_index,
                sample,
                thousandths,
                ..
            } = stage
            else {
                unreachable!()
            };
            let shard = dataset.plan.shard(*shard_index);
            assert!((shard.first_sample..shard.first_sample + shard.samples).contains(sample));
            assert!(*thousandths <= 1000);
        }
    }

    #[test]
    fn a_held_back_stage_is_sent_later_unless_its_sample_is_done() {
        let sent = Mutex::new(Vec::new());
        let send = |frame: &FromWorker| {
            sent.lock().unwrap().push(frame.clone());
            Ok(())
        };
        let stage = |stage| FromWorker::Stage {
            shard_index: 0,
            sample: 0,
            attempt: 0,
            stage,
            thousandths: 0,
        };
        let start = std::time::Instant::now();
        let at = |ms: u64| start + std::time::Duration::from_millis(ms);
        let frames = StageFrames::new();
        frames.stage(&send, stage(Stage::Generate), at(0)).unwrap();
        frames
            .stage(&send, stage(Stage::Hypervolume), at(10))
            .unwrap();
        frames.stage(&send, stage(Stage::Verify), at(20)).unwrap();
        frames.flush(&send, at(100)).unwrap();
        assert_eq!(*sent.lock().unwrap(), [stage(Stage::Generate)]);
        // The latest held stage goes out once the interval has passed, once.
        frames.flush(&send, at(300)).unwrap();
        frames.flush(&send, at(400)).unwrap();
        assert_eq!(
            *sent.lock().unwrap(),
            [stage(Stage::Generate), stage(Stage::Verify)]
        );
        // A stage held when its sample finishes is never sent after the sample.
        // The last frame went out at 300 ms, so a stage at 450 ms is held.
        frames.stage(&send, stage(Stage::Encode), at(450)).unwrap();
        let progress = FromWorker::Progress {
            shard_index: 0,
            regenerations: 0,
        };
        frames.sample_done(&send, &progress).unwrap();
        frames.flush(&send, at(2000)).unwrap();
        assert_eq!(
            *sent.lock().unwrap(),
            [stage(Stage::Generate), stage(Stage::Verify), progress]
        );
    }

    #[test]
    fn the_rate_limit_lets_one_event_through_per_interval() {
        let limit = RateLimit::new(std::time::Duration::from_millis(250));
        let start = std::time::Instant::now();
        let at = |ms: u64| start + std::time::Duration::from_millis(ms);
        // 1000 events over 1 s (one a millisecond): the first, then one per 250 ms.
        let allowed: Vec<u64> = (0..1000).filter(|&ms| limit.allow(at(ms))).collect();
        assert_eq!(allowed, vec![0, 250, 500, 750]);
        // A clock that goes backwards (another thread's older instant) is held back too.
        assert!(!limit.allow(at(700)));
        assert!(limit.allow(at(1000)));
    }
}
