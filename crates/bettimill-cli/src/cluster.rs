//! Cluster subcommands: the hidden `worker` (a coordinator's child or an array task),
//! `slurm` (sbatch scripts for the same plan) and `k8s` (an Indexed Job). Everything but
//! argument handling and printing lives in `bettimill_executor` (`worker`, `cluster`).
//! Exit codes: 0 success, 2 failure.

use crate::build_display::{human_seconds, Periodic};
use crate::commands::{load_manifest, ExitStatus};
use crate::printer::Printer;
use anyhow::{bail, Context};
use bettimill_executor::cluster::{self, KubernetesOptions, SlurmOptions};
use bettimill_executor::worker;
use bettimill_executor::{Dataset, SampleEvent};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Arguments of the hidden `bettimill worker` subcommand.
#[derive(clap::Args, Debug)]
pub struct WorkerArgs {
    /// The dataset directory (made by `build`, `slurm` or `k8s`).
    #[arg(long)]
    dir: PathBuf,
    /// Run as array task: read the task index from SLURM_ARRAY_TASK_ID,
    /// JOB_COMPLETION_INDEX, PBS_ARRAY_INDEX, SGE_TASK_ID (1-based) or LSB_JOBINDEX (1-based).
    #[arg(long, requires = "task_count", conflicts_with = "task_index")]
    task_index_from_env: bool,
    /// Run as array task with this 0-based index.
    #[arg(long, requires = "task_count")]
    task_index: Option<u64>,
    /// Number of array tasks; task t builds the shards s with s % N == t.
    #[arg(long)]
    task_count: Option<u64>,
    /// Threads for an array task (default: all cores). Coordinator workers use one.
    #[arg(long)]
    threads: Option<usize>,
    /// Memory this worker may use, e.g. 8G (default: 80% of MemAvailable): a plan whose
    /// samples (one per thread) need more is refused before any work.
    #[arg(long, value_name = "SIZE", value_parser = crate::commands::parse_memory)]
    max_memory: Option<u64>,
    /// Array tasks: seconds between the lines that say which stage each sample still in
    /// progress has reached (a line per finished sample comes at once).
    #[arg(long, default_value_t = 10.0)]
    progress_interval: f64,
}

/// An array task whose dataset is under `s3://BUCKET/PREFIX`: builds its shards on all its
/// threads (or `--threads`) and uploads them; `finalize` writes the index.
fn bucket_worker(url: &str, args: &WorkerArgs, printer: Printer) -> anyhow::Result<ExitStatus> {
    let Some(count) = args.task_count.filter(|&c| c > 0) else {
        bail!("worker --dir {url}: an s3:// dataset is built by array tasks (--task-count N) or by `bettimill build --out {url}`");
    };
    let index = match args.task_index {
        Some(index) if index < count => index,
        Some(index) => bail!("--task-index {index} is not below --task-count {count}"),
        None => {
            let found = worker::task_index_from_environment(count)?;
            printer.note(format_args!(
                "task index {} from {}",
                found.index, found.variable
            ));
            found.index
        }
    };
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(threads) = args.threads {
        pool = pool.num_threads(threads.max(1));
    }
    let pool = pool.build().context("cannot start the thread pool")?;
    // The stored manifest's plan against the memory this task may use, before any work.
    let text = bettimill_executor::remote::open_bucket(url, None)?.read_manifest_text()?;
    let plan =
        bettimill_plan::Plan::new(&bettimill_manifest::Manifest::parse(&text, Path::new(url))?)?;
    let threads = pool.current_num_threads() as u64;
    bettimill_executor::memory::check(&plan, args.max_memory, 1, threads)?;
    drop(plan);
    let options = bettimill_executor::remote::ObjectOptions::default();
    let summary =
        pool.install(|| bettimill_executor::remote::bucket_task(url, &options, index, count))?;
    printer.note(format_args!(
        "task {index} of {count}: built {}, already complete {} (of every task's)",
        summary.built, summary.skipped
    ));
    Ok(ExitStatus::Success)
}

/// What an array task is doing, for its log lines (see [`TaskLines`]).
#[derive(Default)]
struct TaskState {
    /// Samples in progress by index: key, shard, stage, attempt, started.
    working: BTreeMap<u64, (String, String, String, u32, Instant)>,
    samples_done: u64,
}

/// An array task's sample-level log lines on stderr (a Slurm job's log): one per finished
/// sample at once, and every interval one per sample still in progress, with its stage.
struct TaskLines {
    lines: Periodic<TaskState>,
    started: Instant,
    printer: Printer,
}

impl TaskLines {
    fn start(interval: Duration, printer: Printer) -> TaskLines {
        let lines = Periodic::start(interval, TaskState::default(), move |state| {
            for (key, shard, stage, attempt, since) in state.working.values() {
                printer.note(format_args!(
                    "working: {key} (shard {shard}) {stage}{}, {} in",
                    attempt_note(*attempt),
                    human_seconds(since.elapsed().as_secs_f64())
                ));
            }
        });
        TaskLines {
            lines,
            started: Instant::now(),
            printer,
        }
    }

    fn event(&self, shard: &str, event: SampleEvent<'_>) {
        match event {
            SampleEvent::Stage { task, progress } => self.lines.update(|state| {
                let entry = state.working.entry(task.index).or_insert_with(|| {
                    (
                        task.key.clone(),
                        shard.to_string(),
                        String::new(),
                        0,
                        Instant::now(),
                    )
                });
                entry.2 = progress.stage.to_string();
                entry.3 = progress.attempt;
            }),
            SampleEvent::Done {
                task,
                regenerations,
            } => self.lines.update(|state| {
                let took = state
                    .working
                    .remove(&task.index)
                    .map(|w| w.4.elapsed().as_secs_f64())
                    .unwrap_or(0.0);
                state.samples_done += 1;
                // Printed under the lock, so two threads' lines never interleave.
                self.printer.note(format_args!(
                    "sample {} done (shard {shard}) in {}, {regenerations} regenerations; {} samples by this task, {} elapsed",
                    task.key,
                    human_seconds(took),
                    state.samples_done,
                    human_seconds(self.started.elapsed().as_secs_f64()),
                ));
            }),
        }
    }
}

/// ` (attempt 2)` after a regeneration, nothing for the first attempt.
fn attempt_note(attempt: u32) -> String {
    if attempt == 0 {
        String::new()
    } else {
        format!(" (attempt {})", attempt + 1)
    }
}

/// `bettimill worker`.
pub fn worker(args: WorkerArgs, printer: Printer) -> anyhow::Result<ExitStatus> {
    if let Some(url) = crate::commands::object_url(&args.dir) {
        return bucket_worker(url, &args, printer);
    }
    let dataset = Dataset::open(&args.dir)?;
    let threads = match (args.task_count, args.threads) {
        (None, _) => 1,
        (Some(_), Some(threads)) => threads.max(1),
        (Some(_), None) => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    bettimill_executor::memory::check(&dataset.plan, args.max_memory, 1, threads as u64)?;
    let Some(count) = args.task_count else {
        // Served by a coordinator: exit as soon as it goes away (its pipe closes).
        worker::serve(&dataset, std::io::stdin(), std::io::stdout(), || {
            std::process::exit(0)
        })?;
        return Ok(ExitStatus::Success);
    };
    if count == 0 {
        bail!("--task-count must be at least 1");
    }
    let index = match args.task_index {
        Some(index) if index < count => index,
        Some(index) => bail!("--task-index {index} is not below --task-count {count}"),
        None => {
            let found = worker::task_index_from_environment(count)?;
            printer.note(format_args!(
                "task index {} from {}",
                found.index, found.variable
            ));
            found.index
        }
    };
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(threads) = args.threads {
        pool = pool.num_threads(threads.max(1));
    }
    let pool = pool.build().context("cannot start the thread pool")?;
    if !(args.progress_interval.is_finite() && args.progress_interval > 0.0) {
        bail!(
            "--progress-interval must be a positive number of seconds, got {}",
            args.progress_interval
        );
    }
    let lines = printer
        .shows_notes()
        .then(|| TaskLines::start(Duration::from_secs_f64(args.progress_interval), printer));
    let report = pool.install(|| {
        worker::run_task(
            &dataset,
            index,
            count,
            |shard, result| match result {
                Ok(()) => printer.note(format_args!("built {shard}")),
                Err(reason) => printer.note(format_args!("error: {shard}: {reason}")),
            },
            &|shard, event| {
                if let Some(lines) = &lines {
                    lines.event(shard, event);
                }
            },
        )
    });
    drop(lines);
    let report = report?;
    printer.note(format_args!(
        "task {index} of {count}: built {}, already complete {}, failed {}",
        report.built.len(),
        report.skipped.len(),
        report.failed.len()
    ));
    Ok(if report.failed.is_empty() {
        ExitStatus::Success
    } else {
        ExitStatus::Failure
    })
}

/// Arguments of `bettimill slurm`.
#[derive(clap::Args, Debug)]
pub struct SlurmArgs {
    /// The manifest (TOML). Without it, the embedded demo manifest.
    manifest: Option<PathBuf>,
    /// Dataset directory on a file system every node sees (new, or a partial build of the
    /// same manifest); or s3://BUCKET/PREFIX (the tasks upload their shards).
    #[arg(long)]
    out: PathBuf,
    /// For an s3:// --out: the directory, on a file system every node sees, for the sbatch
    /// scripts and the tasks' logs (a directory --out keeps them in DIR/slurm).
    #[arg(long, value_name = "DIR")]
    scripts: Option<PathBuf>,
    /// Array tasks; shards are dealt round-robin (default: one per shard, at most 1000).
    #[arg(long)]
    tasks: Option<u64>,
    /// At most this many tasks run at once (`--array=...%K`).
    #[arg(long)]
    throttle: Option<u64>,
    /// CPUs (threads) per array task.
    #[arg(long, default_value_t = 1)]
    cpus_per_task: u64,
    /// An extra `#SBATCH` option for both scripts, e.g. --sbatch-option=--partition=debug
    /// (repeatable).
    #[arg(long = "sbatch-option", allow_hyphen_values = true)]
    sbatch_options: Vec<String>,
    /// Memory of one array task, e.g. 16G: the plan is refused if a task's samples (one per
    /// CPU) need more, and the array job asks Slurm for it (`#SBATCH --mem`). Without it,
    /// each task checks its node's own MemAvailable when it starts.
    #[arg(long, value_name = "SIZE", value_parser = crate::commands::parse_memory)]
    max_memory: Option<u64>,
    /// Submit with sbatch: the array job, then finalize with --dependency=afterok.
    #[arg(long)]
    submit: bool,
    /// With --submit: wait until the finalize job ends (sbatch --wait) and exit with its code.
    #[arg(long, requires = "submit")]
    wait: bool,
}

/// `bettimill slurm`.
pub fn slurm(args: SlurmArgs, printer: Printer) -> anyhow::Result<ExitStatus> {
    crate::commands::check_out_dir(&args.out)?;
    let (text, manifest) = load_manifest(args.manifest.as_deref())?;
    let mut extra = args.sbatch_options.clone();
    if let Some(limit) = args.max_memory {
        let plan = bettimill_plan::Plan::new(&manifest)?;
        bettimill_executor::memory::check(&plan, Some(limit), 1, args.cpus_per_task.max(1))?;
        extra.push(format!("--mem={}M", limit.div_ceil(1 << 20)));
    }
    let program = crate::own_program()?;
    let options = |shards: u64| SlurmOptions {
        tasks: args.tasks.unwrap_or_else(|| shards.clamp(1, 1000)),
        throttle: args.throttle,
        cpus_per_task: args.cpus_per_task,
        program: program.clone(),
        extra: extra.clone(),
    };
    // The scripts, and where the tasks' logs go.
    let (scripts, tasks, logs) = match crate::commands::object_url(&args.out) {
        Some(url) => {
            let Some(dir) = &args.scripts else {
                bail!(
                    "slurm --out {url}: give --scripts DIR, a directory every node sees, for \
                     the sbatch scripts and the array tasks' logs"
                );
            };
            let shards = bettimill_plan::Plan::new(&manifest)?.shard_count();
            let object = bettimill_executor::remote::ObjectOptions::default();
            let name = bettimill_executor::remote::bucket_bind(url, &text, manifest, &object)?;
            let incomplete = bettimill_executor::remote::bucket_incomplete_shards(url, None)?;
            let options = options(shards);
            let scripts =
                cluster::write_bucket_slurm_scripts(url, &name, &incomplete, dir, &options)?;
            (scripts, options.tasks, dir.join("logs"))
        }
        None => {
            if let Some(dir) = &args.scripts {
                bail!(
                    "--scripts {} is for an s3:// --out; the scripts of a directory go in {}",
                    dir.display(),
                    args.out.join("slurm").display()
                );
            }
            let dataset = Dataset::bind(&args.out, &text, manifest)?;
            let options = options(dataset.plan.shard_count());
            let scripts = cluster::write_slurm_scripts(&dataset, &options)?;
            (scripts, options.tasks, args.out.join("slurm/logs"))
        }
    };
    match &scripts.build {
        Some(path) => printer.note(format_args!(
            "{}: {} incomplete shard(s) in {} of {tasks} array task(s)",
            path.display(),
            scripts.incomplete_shards,
            scripts.tasks_with_work.len()
        )),
        None => printer.note("every shard is complete; only finalize is left"),
    }
    printer.note(scripts.finalize.display());
    if !args.submit {
        let build = scripts
            .build
            .as_ref()
            .map(|p| format!("JOB=$(sbatch --parsable {}) && ", p.display()))
            .unwrap_or_default();
        let dependency = if scripts.build.is_some() {
            "--dependency=afterok:$JOB "
        } else {
            ""
        };
        printer.note(format_args!(
            "submit with: {build}sbatch {dependency}{}",
            scripts.finalize.display()
        ));
        return Ok(ExitStatus::Success);
    }
    let mut finalize_args = Vec::new();
    if let Some(build) = &scripts.build {
        let job = cluster::sbatch(build, &[])?;
        outln!("build job {job}");
        finalize_args.push(format!("--dependency=afterok:{job}"));
        // Without this a failed array leaves finalize pending forever (and --wait hanging).
        finalize_args.push("--kill-on-invalid-dep=yes".to_string());
    }
    if args.wait {
        finalize_args.push("--wait".to_string());
    }
    match cluster::sbatch(&scripts.finalize, &finalize_args) {
        Ok(job) => {
            outln!("finalize job {job}");
            Ok(ExitStatus::Success)
        }
        Err(err) if args.wait => {
            Printer::always(format_args!(
                "error: {err}\nsee `bettimill status {}` and the logs in {}",
                args.out.display(),
                logs.display()
            ));
            Ok(ExitStatus::Failure)
        }
        Err(err) => Err(err.into()),
    }
}

/// Arguments of `bettimill k8s`.
#[derive(clap::Args, Debug)]
pub struct KubernetesArgs {
    /// The manifest (TOML). Without it, the embedded demo manifest.
    manifest: Option<PathBuf>,
    /// Dataset directory: on the claim, mounted at this same path in every pod; or
    /// s3://BUCKET/PREFIX (no volume: the pods upload their shards).
    #[arg(long)]
    out: PathBuf,
    /// Completions (array tasks).
    #[arg(long)]
    tasks: u64,
    /// Pods at once (default: --tasks).
    #[arg(long)]
    parallelism: Option<u64>,
    /// Container image with the same bettimill binary.
    #[arg(long, default_value = concat!("bettimill:", env!("CARGO_PKG_VERSION")))]
    image: String,
    /// PersistentVolumeClaim holding the dataset directory.
    #[arg(long, default_value = "bettimill-data")]
    claim: String,
    /// For an s3:// --out: the Secret whose keys (AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY,
    /// AWS_ENDPOINT_URL) become every pod's environment.
    #[arg(long, default_value = "bettimill-s3")]
    secret: String,
    /// Memory of one pod, e.g. 4G: the plan is refused if a pod's sample needs more, and
    /// the Job asks for it and limits each pod to it (`resources`), its worker checking
    /// against it (`--max-memory`). Without it, each pod checks its node's MemAvailable
    /// when it starts.
    #[arg(long, value_name = "SIZE", value_parser = crate::commands::parse_memory)]
    max_memory: Option<u64>,
}

/// `bettimill k8s`: prints the Indexed Job on stdout.
pub fn kubernetes(args: KubernetesArgs) -> anyhow::Result<ExitStatus> {
    crate::commands::check_out_dir(&args.out)?;
    let (text, manifest) = load_manifest(args.manifest.as_deref())?;
    if let Some(limit) = args.max_memory {
        let plan = bettimill_plan::Plan::new(&manifest)?;
        bettimill_executor::memory::check(&plan, Some(limit), 1, 1)?;
    }
    if let Some(url) = crate::commands::object_url(&args.out) {
        let options = bettimill_executor::remote::ObjectOptions::default();
        let name = bettimill_executor::remote::bucket_bind(url, &text, manifest, &options)?;
        let yaml = cluster::kubernetes_bucket_job(
            url,
            &name,
            &args.secret,
            &KubernetesOptions {
                tasks: args.tasks,
                parallelism: args.parallelism.unwrap_or(args.tasks),
                image: args.image,
                claim: args.claim,
                max_memory: args.max_memory,
            },
        )?;
        Printer::data(yaml.as_bytes())?;
        return Ok(ExitStatus::Success);
    }
    let dataset = Dataset::bind(&args.out, &text, manifest)?;
    let yaml = cluster::kubernetes_job(
        &dataset,
        &KubernetesOptions {
            tasks: args.tasks,
            parallelism: args.parallelism.unwrap_or(args.tasks),
            image: args.image,
            claim: args.claim,
            max_memory: args.max_memory,
        },
    )?;
    Printer::data(yaml.as_bytes())?;
    Ok(ExitStatus::Success)
}
