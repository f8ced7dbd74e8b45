//! The local coordinator: `bettimill build --workers N`.
//!
//! It takes the directory lock, removes temporary files that killed writers left behind,
//! hands out the plan's shards in order to up to N worker slots. A slot checks a shard it
//! takes against its record (a resumed build: complete shards are found as their turn comes,
//! so nothing is read or held per shard before work starts) and starts its worker process
//! (the given program and arguments, normally `bettimill worker --dir DIR`) only when it
//! has a shard to build, each in its own
//! process group so that a terminal's Ctrl-C reaches only the coordinator. Each worker is
//! driven by one task that hands it one shard at a time over the [`crate::protocol`].
//!
//! Faults: a worker that dies (killed, crashed, out of memory) or reports `Failed` counts
//! one failure against its shard, which goes back to the front of the queue; the dead
//! worker is replaced. A worker that sends nothing, not even its heartbeat
//! ([`protocol::HEARTBEAT_INTERVAL`]), for [`BuildOptions::worker_timeout`] is frozen
//! (SIGSTOP, swapped out, deadlocked): it is killed and counts as a death. A shard that fails `max_shard_failures` times is given up, the
//! other shards still finish, and the report lists it. A failed handshake (different
//! binary, different plan) stops the whole build: it would fail the same way every time.
//! On [`BuildControl::Interrupt`] (Ctrl-C, SIGTERM) every worker is killed; every write
//! is atomic, so the directory is consistent and the same command resumes.
//!
//! Progress: besides the shard events, the coordinator passes on each worker's sample
//! completions ([`BuildEvent::Sample`]) and the stages its samples reach
//! ([`BuildEvent::Stage`], rate-limited by the worker), so a display can advance within a
//! sample that takes minutes.
//!
//! Only when every shard is complete is index.json written.

use crate::protocol::{self, FromWorker, Handshake, Peer, ProtocolError, ToWorker};
use crate::{BuildError, Dataset, DirLock, LockError};
use bettimill_plan::ShardPlan;
use bettimill_sample::TOOL_VERSION;
use std::collections::{BTreeMap, VecDeque};
use std::ffi::OsString;
use std::path::PathBuf;
use std::process::Stdio;
use std::sync::{Arc, Mutex};
use tokio::process::{Child, ChildStdin, ChildStdout, Command};
use tokio::sync::{mpsc, watch};

/// The default number of failures after which a shard is given up.
pub const DEFAULT_MAX_SHARD_FAILURES: u32 = 3;

/// The default time after which a worker that sent nothing (no heartbeat, no progress) is
/// killed and its shard re-queued.
pub const DEFAULT_WORKER_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(120);

/// How to run a build.
#[derive(Clone, Debug)]
pub struct BuildOptions {
    /// Worker processes to run at once (at least 1; fewer if fewer shards are missing).
    pub workers: usize,
    /// Failures after which a shard is given up.
    pub max_shard_failures: u32,
    /// The worker program (normally the running bettimill binary).
    pub worker_program: PathBuf,
    /// Its arguments (normally `worker --dir DIR`).
    pub worker_args: Vec<OsString>,
    /// A worker silent for this long (no frame at all, heartbeats included) is killed and
    /// its shard re-queued; [`DEFAULT_WORKER_TIMEOUT`] normally. Keep it well above
    /// [`protocol::HEARTBEAT_INTERVAL`].
    pub worker_timeout: std::time::Duration,
}

/// Something that happened during a build, for progress displays.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BuildEvent {
    /// The build starts.
    Started {
        /// Shards in the plan.
        shards: u64,
        /// Samples in the plan (complete shards are found as the build goes, each told by
        /// a [`BuildEvent::ShardSkipped`]).
        samples: u64,
        /// Worker slots (each starts its process when it first has a shard to build).
        workers: usize,
    },
    /// A shard found complete (its tar matches its record, checked in one streamed pass)
    /// when its turn came: it is not built again.
    ShardSkipped {
        /// The shard's name.
        shard: String,
        /// Samples in it.
        samples: u64,
    },
    /// Worker slot `slot` started process `pid`.
    WorkerStarted {
        /// The slot (0..workers).
        slot: usize,
        /// The process id.
        pid: u32,
    },
    /// A worker starts a shard.
    ShardStarted {
        /// The slot.
        slot: usize,
        /// The shard's name.
        shard: String,
        /// Samples in it.
        samples: u64,
    },
    /// A worker verified one more sample.
    Sample {
        /// The slot.
        slot: usize,
        /// Regenerations the sample needed.
        regenerations: u32,
    },
    /// A worker started a stage of a sample (at most a few a second per worker; see
    /// [`protocol::STAGE_INTERVAL`]).
    Stage {
        /// The slot.
        slot: usize,
        /// The sample's key.
        key: String,
        /// Its attempt (0 first).
        attempt: u32,
        /// The stage starting.
        stage: protocol::Stage,
        /// Where the sample is, in thousandths (an estimate from the stage).
        thousandths: u16,
    },
    /// A shard is written.
    ShardDone {
        /// The slot.
        slot: usize,
        /// The shard's name.
        shard: String,
    },
    /// An attempt at a shard failed (the worker reported it, or died).
    ShardFailed {
        /// The slot.
        slot: usize,
        /// The shard's name.
        shard: String,
        /// Samples the failed attempt had reported (to take back from progress).
        samples_lost: u64,
        /// Why.
        reason: String,
        /// Failures of this shard so far.
        failures: u32,
        /// Whether the shard is given up.
        given_up: bool,
    },
    /// A worker process ended unexpectedly.
    WorkerDied {
        /// The slot.
        slot: usize,
        /// The process id.
        pid: u32,
        /// How it ended.
        status: String,
    },
}

/// A shard that was given up.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FailedShard {
    /// The shard's name.
    pub shard: String,
    /// The reason of each failure, oldest first.
    pub reasons: Vec<String>,
}

/// How a build ended.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BuildReport {
    /// Shards built by this run.
    pub built: u64,
    /// Shards found complete.
    pub skipped: u64,
    /// Samples generated by this run.
    pub samples_built: u64,
    /// Rejected attempts in shards built by this run.
    pub regenerations: u64,
    /// Shards given up.
    pub failed: Vec<FailedShard>,
    /// Failed attempts that were retried successfully or not (worker deaths included).
    pub retries: u64,
    /// Whether an interrupt stopped the build.
    pub interrupted: bool,
    /// Shards complete now.
    pub complete: u64,
    /// Shards in the plan.
    pub shards: u64,
    /// Whether index.json was written.
    pub finalized: bool,
}

/// Tells a running build to stop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BuildControl {
    /// Stop workers and return with `interrupted` set.
    Interrupt,
}

/// Why a build could not run at all.
#[derive(Debug, thiserror::Error)]
pub enum CoordinatorError {
    /// The directory.
    #[error(transparent)]
    Build(#[from] BuildError),
    /// The directory lock.
    #[error(transparent)]
    Lock(#[from] LockError),
    /// A worker could not be started.
    #[error("cannot start worker {program}: {source}")]
    Spawn {
        /// The program.
        program: PathBuf,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// A worker is a different program or computed a different plan.
    #[error("worker handshake failed: {0}")]
    Handshake(ProtocolError),
    /// A worker exited before its handshake.
    #[error("worker process {pid} exited before its handshake ({status}){note}")]
    WorkerDiedEarly {
        /// The process id.
        pid: u32,
        /// How it ended.
        status: String,
        /// Where to look: `; its error is printed above` when it exited with an error
        /// code (it printed one), or why nothing was printed when a signal killed it.
        note: &'static str,
    },
    /// A worker sent no handshake within the worker timeout (retried like a death).
    #[error("worker process {pid} sent no handshake within {seconds} s (--worker-timeout) and was killed")]
    WorkerSilent {
        /// The process id.
        pid: u32,
        /// The timeout.
        seconds: f64,
    },
    /// The async runtime could not start.
    #[error("cannot start the coordinator's runtime: {0}")]
    Runtime(std::io::Error),
}

/// The shards still to hand out: retried shards first (most recent first), then the
/// untried ones as ranges of plan indexes, in plan order. Its memory grows with the
/// complete shards that interrupt the ranges and with retries, not with the shards.
#[derive(Debug, Default, PartialEq, Eq)]
struct ShardQueue {
    retries: VecDeque<usize>,
    ranges: VecDeque<std::ops::Range<u64>>,
}

impl ShardQueue {
    /// Every shard below `shards`, in plan order.
    fn all(shards: u64) -> ShardQueue {
        ShardQueue {
            retries: VecDeque::new(),
            ranges: (shards > 0).then_some(0..shards).into_iter().collect(),
        }
    }

    /// The next shard, and whether it is untried in this run (then it may be complete on
    /// disk already; a retried one is known not to be).
    fn pop_front(&mut self) -> Option<(usize, bool)> {
        if let Some(retry) = self.retries.pop_front() {
            return Some((retry, false));
        }
        let range = self.ranges.front_mut()?;
        let next = range.start;
        range.start += 1;
        if range.is_empty() {
            self.ranges.pop_front();
        }
        Some((next as usize, true))
    }

    fn push_front(&mut self, shard: usize) {
        self.retries.push_front(shard);
    }
}

struct Scheduler {
    queue: ShardQueue,
    failures: BTreeMap<usize, Vec<String>>,
    given_up: Vec<FailedShard>,
    built: u64,
    skipped: u64,
    samples: u64,
    regenerations: u64,
    retries: u64,
}

enum Attempt {
    Done { regenerations: u64 },
    Failed(String),
    Died(String),
    Interrupted,
}

struct Worker {
    child: Child,
    pid: u32,
    stdin: ChildStdin,
    stdout: ChildStdout,
}

/// Runs a build with worker processes (see the module documentation). `events` receives
/// progress on the calling thread; `control` interrupts the build when it yields a value.
pub fn run(
    dataset: &Dataset,
    options: &BuildOptions,
    control: impl std::future::Future<Output = BuildControl>,
    events: impl FnMut(BuildEvent),
) -> Result<BuildReport, CoordinatorError> {
    let lock = DirLock::acquire(&dataset.dir)?;
    run_locked(dataset, &lock, options, control, events)
}

/// [`run`] under a directory lock the caller already holds (from
/// [`Dataset::bind_locked`], so that nothing takes it between the binding and the build).
pub fn run_locked(
    dataset: &Dataset,
    _lock: &DirLock,
    options: &BuildOptions,
    control: impl std::future::Future<Output = BuildControl>,
    mut events: impl FnMut(BuildEvent),
) -> Result<BuildReport, CoordinatorError> {
    dataset.remove_temporaries()?;
    // Nothing is read per shard before the workers start: the shards to build are kept as
    // ranges of plan indexes, and whether a shard is already complete (a resumed build) is
    // checked when its turn comes, off the runtime's thread. So a new build of 10^8 shards
    // starts its first worker at once, and a resumed one holds no list of complete shards.
    let shards = dataset.plan.shard_count();
    let mut report = BuildReport {
        shards,
        ..BuildReport::default()
    };
    let workers = options
        .workers
        .max(1)
        .min(usize::try_from(shards).unwrap_or(usize::MAX));
    events(BuildEvent::Started {
        shards,
        samples: dataset.plan.samples,
        workers,
    });
    let scheduler = Arc::new(Mutex::new(Scheduler {
        queue: ShardQueue::all(shards),
        failures: BTreeMap::new(),
        given_up: Vec::new(),
        built: 0,
        skipped: 0,
        samples: 0,
        regenerations: 0,
        retries: 0,
    }));

    if workers > 0 {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(CoordinatorError::Runtime)?;
        let interrupted = runtime.block_on(drive(
            dataset,
            options,
            workers,
            &scheduler,
            control,
            &mut events,
        ))?;
        report.interrupted = interrupted;
        // Workers killed mid-shard leave temporary files; they are all dead now.
        dataset.remove_temporaries()?;
    }

    let scheduler = scheduler.lock().unwrap_or_else(|e| e.into_inner());
    report.built = scheduler.built;
    report.skipped = scheduler.skipped;
    report.samples_built = scheduler.samples;
    report.regenerations = scheduler.regenerations;
    report.retries = scheduler.retries;
    report.failed = scheduler.given_up.clone();
    report.complete = report.skipped + report.built;
    if report.complete == shards && !report.interrupted {
        // Every shard was hashed when its turn came (found complete) or by the worker that
        // wrote it in this run: finalize need not read them back.
        dataset.finalize_checked(&|_| true)?;
        report.finalized = true;
    }
    Ok(report)
}

async fn drive(
    dataset: &Dataset,
    options: &BuildOptions,
    workers: usize,
    scheduler: &Arc<Mutex<Scheduler>>,
    control: impl std::future::Future<Output = BuildControl>,
    events: &mut impl FnMut(BuildEvent),
) -> Result<bool, CoordinatorError> {
    let (event_sender, mut event_receiver) = mpsc::unbounded_channel();
    let (stop_sender, stop_receiver) = watch::channel(false);
    let handshake = Handshake {
        protocol_version: protocol::PROTOCOL_VERSION,
        tool_version: TOOL_VERSION.to_string(),
        plan_hash: dataset.plan.hash(),
    };
    let shared = Arc::new(SlotContext {
        any_handshake: std::sync::atomic::AtomicBool::new(false),
        options: options.clone(),
        handshake,
        dataset: dataset.clone(),
        scheduler: scheduler.clone(),
    });
    let mut slots = tokio::task::JoinSet::new();
    for slot in 0..workers {
        slots.spawn(run_slot(
            slot,
            shared.clone(),
            event_sender.clone(),
            stop_receiver.clone(),
        ));
    }
    drop(event_sender);
    tokio::pin!(control);
    let mut interrupted = false;
    let mut fatal = None;
    loop {
        tokio::select! {
            Some(event) = event_receiver.recv() => events(event),
            _ = &mut control, if !interrupted => {
                interrupted = true;
                let _ = stop_sender.send(true);
            }
            joined = slots.join_next() => match joined {
                None => break,
                Some(Ok(Ok(()))) => {}
                Some(Ok(Err(err))) => {
                    // Stop the others; report the first fatal error.
                    let _ = stop_sender.send(true);
                    fatal.get_or_insert(err);
                }
                Some(Err(join_error)) => {
                    let _ = stop_sender.send(true);
                    fatal.get_or_insert(CoordinatorError::Runtime(std::io::Error::other(
                        format!("a worker slot task failed: {join_error}"),
                    )));
                }
            },
        }
    }
    while let Ok(event) = event_receiver.try_recv() {
        events(event);
    }
    match fatal {
        Some(err) => Err(err),
        None => Ok(interrupted),
    }
}

struct SlotContext {
    /// Whether any worker of this build has completed its handshake: after that, a worker
    /// that dies before its handshake (killed, out of memory) is a fault to retry, not a
    /// broken installation.
    any_handshake: std::sync::atomic::AtomicBool,
    options: BuildOptions,
    handshake: Handshake,
    dataset: Dataset,
    scheduler: Arc<Mutex<Scheduler>>,
}

impl SlotContext {
    fn lock(&self) -> std::sync::MutexGuard<'_, Scheduler> {
        self.scheduler.lock().unwrap_or_else(|e| e.into_inner())
    }
}

async fn start_worker(context: &SlotContext) -> Result<Worker, CoordinatorError> {
    let program = &context.options.worker_program;
    let mut command = Command::new(program);
    command
        .args(&context.options.worker_args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .kill_on_drop(true);
    #[cfg(unix)]
    command.process_group(0);
    let mut child = command.spawn().map_err(|source| CoordinatorError::Spawn {
        program: program.clone(),
        source,
    })?;
    let pid = child.id().unwrap_or(0);
    let mut stdin = child.stdin.take().expect("stdin is piped");
    let mut stdout = child.stdout.take().expect("stdout is piped");
    // Both sides send first, so neither waits for the other.
    let sent = protocol::write_frame_async(&mut stdin, &context.handshake, "worker").await;
    let timeout = context.options.worker_timeout;
    let theirs = match tokio::time::timeout(
        timeout,
        protocol::read_frame_async::<Handshake>(&mut stdout, "worker"),
    )
    .await
    {
        Ok(theirs) => theirs,
        Err(_) => {
            let _ = child.start_kill();
            let _ = child.wait().await;
            return Err(CoordinatorError::WorkerSilent {
                pid,
                seconds: timeout.as_secs_f64(),
            });
        }
    };
    let theirs = match (sent, theirs) {
        (Ok(()), Ok(Some(theirs))) => theirs,
        (_, Err(err @ (ProtocolError::Decode { .. } | ProtocolError::BadLength { .. }))) => {
            return Err(CoordinatorError::Handshake(err))
        }
        _ => {
            let (status, note) = match child.wait().await {
                Ok(status) => (describe_exit(status), early_death_note(status)),
                Err(err) => (err.to_string(), ""),
            };
            return Err(CoordinatorError::WorkerDiedEarly { pid, status, note });
        }
    };
    protocol::check_handshake(&context.handshake, &theirs, Peer::Worker)
        .map_err(CoordinatorError::Handshake)?;
    context
        .any_handshake
        .store(true, std::sync::atomic::Ordering::Relaxed);
    Ok(Worker {
        child,
        pid,
        stdin,
        stdout,
    })
}

async fn run_slot(
    slot: usize,
    context: Arc<SlotContext>,
    events: mpsc::UnboundedSender<BuildEvent>,
    mut stop: watch::Receiver<bool>,
) -> Result<(), CoordinatorError> {
    let mut worker: Option<Worker> = None;
    loop {
        if *stop.borrow() {
            break;
        }
        let Some((shard_index, untried)) = context.lock().queue.pop_front() else {
            break;
        };
        let shard = context.dataset.plan.shard(shard_index as u64);
        if untried && is_complete(&context, &shard, &mut stop).await {
            context.lock().skipped += 1;
            let _ = events.send(BuildEvent::ShardSkipped {
                shard: shard.name,
                samples: shard.samples,
            });
            continue;
        }
        if *stop.borrow() {
            context.lock().queue.push_front(shard_index);
            break;
        }
        let ShardPlan { name, samples, .. } = shard;
        let mut early_death = None;
        if worker.is_none() {
            match start_worker(&context).await {
                Ok(w) => {
                    let _ = events.send(BuildEvent::WorkerStarted { slot, pid: w.pid });
                    worker = Some(w);
                }
                Err(CoordinatorError::WorkerDiedEarly { pid, status, .. })
                    if context
                        .any_handshake
                        .load(std::sync::atomic::Ordering::Relaxed) =>
                {
                    early_death = Some(format!(
                        "worker process {pid} exited before its handshake ({status})"
                    ));
                }
                Err(silent @ CoordinatorError::WorkerSilent { .. }) => {
                    early_death = Some(silent.to_string());
                }
                Err(err) => {
                    context.lock().queue.push_front(shard_index);
                    return Err(err);
                }
            }
        }
        let mut samples_reported = 0u64;
        let attempt = match (early_death, worker.as_mut()) {
            (Some(reason), _) => Attempt::Died(reason),
            (None, Some(current)) => {
                let _ = events.send(BuildEvent::ShardStarted {
                    slot,
                    shard: name.clone(),
                    samples,
                });
                tokio::select! {
                    attempt = attempt_shard(current, shard_index as u64, slot, &events, &mut samples_reported, &context) => attempt,
                    _ = stop.wait_for(|stopped| *stopped) => Attempt::Interrupted,
                }
            }
            (None, None) => unreachable!("a worker was just started or its death recorded"),
        };
        let died = matches!(attempt, Attempt::Died(_));
        match attempt {
            Attempt::Done { regenerations } => {
                let mut scheduler = context.lock();
                scheduler.built += 1;
                scheduler.samples += samples;
                scheduler.regenerations += regenerations;
                drop(scheduler);
                let _ = events.send(BuildEvent::ShardDone { slot, shard: name });
            }
            Attempt::Interrupted => {
                context.lock().queue.push_front(shard_index);
                break;
            }
            Attempt::Failed(reason) | Attempt::Died(reason) => {
                if let Some(mut dead) = worker.take_if(|_| died) {
                    let _ = dead.child.start_kill();
                    let status = match dead.child.wait().await {
                        Ok(status) => describe_exit(status),
                        Err(err) => err.to_string(),
                    };
                    let _ = events.send(BuildEvent::WorkerDied {
                        slot,
                        pid: dead.pid,
                        status,
                    });
                }
                let max = context.options.max_shard_failures.max(1);
                let mut scheduler = context.lock();
                scheduler.retries += 1;
                let reasons = scheduler.failures.entry(shard_index).or_default();
                reasons.push(reason.clone());
                let failures = reasons.len() as u32;
                let given_up = failures >= max;
                if given_up {
                    let reasons = reasons.clone();
                    scheduler.given_up.push(FailedShard {
                        shard: name.clone(),
                        reasons,
                    });
                } else {
                    scheduler.queue.push_front(shard_index);
                }
                drop(scheduler);
                let _ = events.send(BuildEvent::ShardFailed {
                    slot,
                    shard: name,
                    samples_lost: samples_reported,
                    reason,
                    failures,
                    given_up,
                });
            }
        }
    }
    if let Some(mut worker) = worker {
        if *stop.borrow() {
            let _ = worker.child.start_kill();
        } else {
            let _ =
                protocol::write_frame_async(&mut worker.stdin, &ToWorker::Shutdown, "worker").await;
        }
        drop(worker.stdin);
        let _ = worker.child.wait().await;
    }
    Ok(())
}

/// Whether the shard is complete on disk already (the record is read and the tar hashed
/// against it on the blocking pool, so the other slots' pipes are served meanwhile). A
/// shard without a record costs one failed open. On an interrupt the slot stops at once;
/// the check itself only reads, and the runtime's shutdown waits for it to return.
async fn is_complete(
    context: &Arc<SlotContext>,
    shard: &ShardPlan,
    stop: &mut watch::Receiver<bool>,
) -> bool {
    let (context, shard) = (context.clone(), shard.clone());
    let check = tokio::task::spawn_blocking(move || context.dataset.completed(&shard).is_some());
    tokio::select! {
        complete = check => complete.unwrap_or(false),
        _ = stop.wait_for(|stopped| *stopped) => false,
    }
}

/// `Some(how it ended)` if the worker process has exited (waiting briefly: a worker whose
/// pipe broke is about to).
async fn worker_is_dead(worker: &mut Worker) -> Option<String> {
    match tokio::time::timeout(std::time::Duration::from_millis(200), worker.child.wait()).await {
        Ok(Ok(status)) => Some(describe_exit(status)),
        Ok(Err(err)) => Some(err.to_string()),
        Err(_) => None,
    }
}

/// What to tell about a worker that ended before its handshake: a worker that exits with an
/// error code has printed its error (its stderr is the build's), one killed by a signal
/// printed nothing.
fn early_death_note(status: std::process::ExitStatus) -> &'static str {
    if status.code().is_some_and(|code| code != 0) {
        "; its error is printed above"
    } else if status.code().is_none() {
        "; it printed nothing (killed from outside, or by the kernel for lack of memory)"
    } else {
        ""
    }
}

fn describe_exit(status: std::process::ExitStatus) -> String {
    #[cfg(unix)]
    {
        use std::os::unix::process::ExitStatusExt;
        if let Some(signal) = status.signal() {
            return format!("killed by signal {signal}");
        }
    }
    status.to_string()
}

async fn attempt_shard(
    worker: &mut Worker,
    shard_index: u64,
    slot: usize,
    events: &mpsc::UnboundedSender<BuildEvent>,
    samples_reported: &mut u64,
    context: &SlotContext,
) -> Attempt {
    let timeout = context.options.worker_timeout;
    let request = ToWorker::Build { shard_index };
    if let Err(err) = protocol::write_frame_async(&mut worker.stdin, &request, "worker").await {
        return Attempt::Died(format!("worker process {} is gone: {err}", worker.pid));
    }
    loop {
        // Any frame, heartbeats included, proves the worker alive; a timed-out read is
        // abandoned with the worker, which the caller kills.
        let Ok(frame) = tokio::time::timeout(
            timeout,
            protocol::read_frame_async::<FromWorker>(&mut worker.stdout, "worker"),
        )
        .await
        else {
            return Attempt::Died(format!(
                "worker process {} sent nothing, not even a heartbeat, for {} s (--worker-timeout); \
                 it is frozen or stopped and was killed",
                worker.pid,
                timeout.as_secs_f64()
            ));
        };
        match frame {
            Ok(Some(FromWorker::Heartbeat)) => {}
            Ok(Some(FromWorker::Stage {
                shard_index: of,
                sample,
                attempt,
                stage,
                thousandths,
            })) if of == shard_index => {
                let key = context
                    .dataset
                    .plan
                    .task(sample)
                    .map_or_else(|| format!("sample {sample}"), |task| task.key);
                let _ = events.send(BuildEvent::Stage {
                    slot,
                    key,
                    attempt,
                    stage,
                    thousandths: thousandths.min(1000),
                });
            }
            Ok(Some(FromWorker::Progress { regenerations, .. })) => {
                *samples_reported += 1;
                let _ = events.send(BuildEvent::Sample {
                    slot,
                    regenerations,
                });
            }
            Ok(Some(FromWorker::Done {
                shard_index: done,
                regenerations,
                ..
            })) if done == shard_index => return Attempt::Done { regenerations },
            Ok(Some(FromWorker::Failed {
                shard_index: failed,
                reason,
            })) if failed == shard_index => return Attempt::Failed(reason),
            Ok(Some(other)) => {
                return Attempt::Failed(format!(
                    "worker process {} answered {other:?} to a request for shard {shard_index}",
                    worker.pid
                ))
            }
            Ok(None) => {
                let status = match worker_is_dead(worker).await {
                    Some(status) => status,
                    None => "closed its output".to_string(),
                };
                return Attempt::Died(format!(
                    "worker process {} died in the middle of the shard ({status})",
                    worker.pid
                ));
            }
            Err(err) => {
                return Attempt::Died(format!("worker process {}: {err}", worker.pid));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(unix)]
    #[test]
    fn an_early_death_says_its_error_is_above_only_when_it_printed_one() {
        use std::os::unix::process::ExitStatusExt;
        let exited = std::process::ExitStatus::from_raw(2 << 8);
        let killed = std::process::ExitStatus::from_raw(9);
        let message = |status| {
            CoordinatorError::WorkerDiedEarly {
                pid: 7,
                status: describe_exit(status),
                note: early_death_note(status),
            }
            .to_string()
        };
        assert!(
            message(exited).ends_with("its error is printed above"),
            "{}",
            message(exited)
        );
        let text = message(killed);
        assert!(text.contains("(killed by signal 9)"), "{text}");
        assert!(!text.contains("printed above"), "{text}");
        assert!(text.contains("it printed nothing"), "{text}");
    }

    fn drain(mut queue: ShardQueue) -> Vec<(usize, bool)> {
        std::iter::from_fn(|| queue.pop_front()).collect()
    }

    #[test]
    fn the_queue_hands_out_every_shard_in_order_without_a_word_per_shard() {
        let untried = |shards: &[usize]| shards.iter().map(|&s| (s, true)).collect::<Vec<_>>();
        assert_eq!(drain(ShardQueue::all(6)), untried(&[0, 1, 2, 3, 4, 5]));
        assert_eq!(drain(ShardQueue::all(0)), untried(&[]));
        let huge = ShardQueue::all(100_000_000);
        assert_eq!(huge.ranges.len(), 1);
        assert_eq!(
            std::mem::size_of_val(&huge),
            std::mem::size_of::<ShardQueue>()
        );
        // A retried shard comes first and is known not to be complete.
        let mut queue = ShardQueue::all(4);
        assert_eq!(queue.pop_front(), Some((0, true)));
        assert_eq!(queue.pop_front(), Some((1, true)));
        queue.push_front(0);
        assert_eq!(drain(queue), vec![(0, false), (2, true), (3, true)]);
    }
}
