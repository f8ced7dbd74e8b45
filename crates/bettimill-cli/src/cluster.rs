//! Multi-process and cluster subcommands: `build` (coordinator and workers), `worker`,
//! `slurm`, `k8s`, `finalize` and `status`.
//!
//! Everything but argument handling and printing lives in `bettimill_executor`
//! (`coordinator`, `worker`, `cluster`); this module renders progress with indicatif on
//! stderr (hidden when stderr is not a terminal or with --quiet) and maps outcomes to
//! exit codes: 0 success, 2 failed build / refused directory / incomplete dataset,
//! 3 an array task failed on purpose (test hook), 130 interrupted.

use crate::commands::{load_manifest, Status};
use anyhow::{bail, Context};
use bettimill_executor::cluster::{self, KubernetesOptions, SlurmOptions};
use bettimill_executor::coordinator::{self, BuildControl, BuildEvent, BuildOptions};
use bettimill_executor::worker::{self, WorkerError};
use bettimill_executor::Dataset;
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use std::ffi::OsString;
use std::path::{Path, PathBuf};

/// `bettimill build`.
pub fn build(
    manifest: Option<&Path>,
    out: &Path,
    workers: Option<usize>,
    max_shard_failures: u32,
    quiet: bool,
) -> anyhow::Result<Status> {
    let manifest_path = manifest;
    let (text, manifest) = load_manifest(manifest)?;
    let dataset = Dataset::create(out, &text, manifest)?;
    let workers = workers.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    });
    if workers == 0 {
        bail!("--workers must be at least 1");
    }
    let program = std::env::current_exe().context("cannot find the running bettimill binary")?;
    let options = BuildOptions {
        workers,
        max_shard_failures,
        worker_program: program,
        worker_args: vec![
            OsString::from("worker"),
            OsString::from("--dir"),
            out.as_os_str().to_owned(),
        ],
    };
    let started = std::time::Instant::now();
    let mut display = Display::new(quiet);
    let control = async {
        #[cfg(unix)]
        {
            use tokio::signal::unix::{signal, SignalKind};
            match signal(SignalKind::terminate()) {
                Ok(mut term) => {
                    tokio::select! {
                        _ = tokio::signal::ctrl_c() => {}
                        _ = term.recv() => {}
                    }
                }
                Err(_) => {
                    let _ = tokio::signal::ctrl_c().await;
                }
            }
        }
        #[cfg(not(unix))]
        let _ = tokio::signal::ctrl_c().await;
        BuildControl::Interrupt
    };
    let report = coordinator::run(&dataset, &options, control, |event| display.event(event))?;
    display.finish();
    let seconds = started.elapsed().as_secs_f64();
    let resume = format!(
        "bettimill build {}--out {}",
        manifest_path
            .map(|m| format!("{} ", m.display()))
            .unwrap_or_default(),
        out.display()
    );
    if report.interrupted {
        eprintln!(
            "interrupted: {} of {} shards complete, nothing partial is visible; resume with: {resume}",
            report.complete, report.shards
        );
        return Ok(Status::Interrupted);
    }
    if !report.failed.is_empty() {
        eprintln!(
            "error: {} shard(s) failed {} times and were given up ({} of {} shards complete; index.json not written):",
            report.failed.len(),
            max_shard_failures,
            report.complete,
            report.shards
        );
        for failed in &report.failed {
            eprintln!(
                "  {}: {}",
                failed.shard,
                failed.reasons.last().map(String::as_str).unwrap_or("")
            );
        }
        eprintln!("fix the cause, then resume with: {resume}");
        return Ok(Status::Failure);
    }
    if !quiet {
        let rate = if seconds > 0.0 {
            report.samples as f64 / seconds
        } else {
            0.0
        };
        eprintln!(
            "built {} shards, skipped {} complete ones; {} samples in {:.1} s ({:.2} samples/s, {} workers), {} regenerations, {} retried shard attempts\n{}",
            report.built,
            report.skipped,
            report.samples,
            seconds,
            rate,
            display.workers,
            report.regenerations,
            report.retries,
            dataset.layout().index_path().display()
        );
    }
    Ok(Status::Success)
}

/// Progress bars for a build.
struct Display {
    multi: MultiProgress,
    overall: Option<ProgressBar>,
    slots: Vec<ProgressBar>,
    regenerations: u64,
    failures: u64,
    quiet: bool,
    workers: usize,
}

impl Display {
    fn new(quiet: bool) -> Display {
        Display {
            multi: MultiProgress::with_draw_target(crate::progress::target(quiet)),
            overall: None,
            slots: Vec::new(),
            regenerations: 0,
            failures: 0,
            quiet,
            workers: 0,
        }
    }

    fn message(&self) -> String {
        format!(
            "{} regenerations, {} failed attempts",
            self.regenerations, self.failures
        )
    }

    fn event(&mut self, event: BuildEvent) {
        match event {
            BuildEvent::Started {
                shards,
                skipped,
                samples,
                workers,
            } => {
                self.workers = workers;
                if !self.quiet && skipped > 0 {
                    let _ = self
                        .multi
                        .println(format!("{skipped} of {shards} shards already complete"));
                }
                let overall = self.multi.add(ProgressBar::new(samples));
                overall.set_style(crate::progress::style("samples"));
                overall.set_message(self.message());
                self.overall = Some(overall);
                for slot in 0..workers {
                    let bar = self.multi.add(ProgressBar::new(0));
                    bar.set_style(
                        ProgressStyle::with_template("  worker {prefix}: {msg} {pos}/{len}")
                            .expect("the template is valid"),
                    );
                    bar.set_prefix(slot.to_string());
                    bar.set_message("starting");
                    self.slots.push(bar);
                }
            }
            BuildEvent::WorkerStarted { slot, pid } => {
                if let Some(bar) = self.slots.get(slot) {
                    bar.set_message(format!("pid {pid}"));
                }
            }
            BuildEvent::ShardStarted {
                slot,
                shard,
                samples,
            } => {
                if let Some(bar) = self.slots.get(slot) {
                    bar.set_length(samples);
                    bar.set_position(0);
                    bar.set_message(shard);
                }
            }
            BuildEvent::Sample {
                slot,
                regenerations,
            } => {
                self.regenerations += u64::from(regenerations);
                if let Some(bar) = self.slots.get(slot) {
                    bar.inc(1);
                }
                if let Some(overall) = &self.overall {
                    overall.inc(1);
                    overall.set_message(self.message());
                }
            }
            BuildEvent::ShardDone { slot, shard } => {
                if let Some(bar) = self.slots.get(slot) {
                    bar.set_message(format!("{shard} done"));
                }
            }
            BuildEvent::ShardFailed {
                shard,
                samples_lost,
                reason,
                failures,
                given_up,
                ..
            } => {
                self.failures += 1;
                if let Some(overall) = &self.overall {
                    overall.set_position(overall.position().saturating_sub(samples_lost));
                    overall.set_message(self.message());
                }
                let what = if given_up { "given up" } else { "re-queued" };
                self.note(format!(
                    "shard {shard} failed (attempt {failures}, {what}): {reason}"
                ));
            }
            BuildEvent::WorkerDied { slot, pid, status } => {
                self.note(format!(
                    "worker {slot} (pid {pid}) ended: {status}; starting a new one"
                ));
            }
        }
    }

    /// A line above the bars, or on stderr when bars are hidden (never with --quiet).
    fn note(&self, line: String) {
        if self.quiet {
            return;
        }
        if self.multi.is_hidden() {
            eprintln!("{line}");
        } else {
            let _ = self.multi.println(line);
        }
    }

    fn finish(&self) {
        for bar in &self.slots {
            bar.finish_and_clear();
        }
        if let Some(overall) = &self.overall {
            overall.finish_and_clear();
        }
    }
}

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
}

/// `bettimill worker`.
pub fn worker(args: WorkerArgs, quiet: bool) -> anyhow::Result<Status> {
    let dataset = Dataset::open(&args.dir)?;
    let Some(count) = args.task_count else {
        // Served by a coordinator: exit as soon as it goes away (its pipe closes).
        worker::serve(&dataset, std::io::stdin(), std::io::stdout(), || {
            std::process::exit(0)
        })?;
        return Ok(Status::Success);
    };
    if count == 0 {
        bail!("--task-count must be at least 1");
    }
    let index = match args.task_index {
        Some(index) if index < count => index,
        Some(index) => bail!("--task-index {index} is not below --task-count {count}"),
        None => {
            let found = worker::task_index_from_env(|name| std::env::var(name).ok(), count)?;
            if !quiet {
                eprintln!("task index {} from {}", found.index, found.variable);
            }
            found.index
        }
    };
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(threads) = args.threads {
        pool = pool.num_threads(threads.max(1));
    }
    let pool = pool.build().context("cannot start the thread pool")?;
    let report = pool.install(|| {
        worker::run_task(&dataset, index, count, |shard, result| {
            if quiet {
                return;
            }
            match result {
                Ok(()) => eprintln!("built {shard}"),
                Err(reason) => eprintln!("error: {shard}: {reason}"),
            }
        })
    });
    let report = match report {
        Ok(report) => report,
        Err(err @ WorkerError::InjectedTaskFailure { .. }) => {
            eprintln!("error: {err}");
            return Ok(Status::Code(3));
        }
        Err(err) => return Err(err.into()),
    };
    if !quiet {
        eprintln!(
            "task {index} of {count}: built {}, already complete {}, failed {}",
            report.built.len(),
            report.skipped.len(),
            report.failed.len()
        );
    }
    Ok(if report.failed.is_empty() {
        Status::Success
    } else {
        Status::Failure
    })
}

/// Arguments of `bettimill slurm`.
#[derive(clap::Args, Debug)]
pub struct SlurmArgs {
    /// The manifest (TOML). Without it, the embedded demo manifest.
    manifest: Option<PathBuf>,
    /// Dataset directory on a file system every node sees (new, or a partial build of the
    /// same manifest).
    #[arg(long)]
    out: PathBuf,
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
    /// Submit with sbatch: the array job, then finalize with --dependency=afterok.
    #[arg(long)]
    submit: bool,
    /// With --submit: wait until the finalize job ends (sbatch --wait) and exit with its code.
    #[arg(long, requires = "submit")]
    wait: bool,
}

/// `bettimill slurm`.
pub fn slurm(args: SlurmArgs, quiet: bool) -> anyhow::Result<Status> {
    let (text, manifest) = load_manifest(args.manifest.as_deref())?;
    let dataset = Dataset::create(&args.out, &text, manifest)?;
    let tasks = args
        .tasks
        .unwrap_or_else(|| dataset.plan.shard_count().clamp(1, 1000));
    let program = std::env::current_exe().context("cannot find the running bettimill binary")?;
    let scripts = cluster::write_slurm_scripts(
        &dataset,
        &SlurmOptions {
            tasks,
            throttle: args.throttle,
            cpus_per_task: args.cpus_per_task,
            program,
            extra: args.sbatch_options.clone(),
        },
    )?;
    if !quiet {
        match &scripts.build {
            Some(path) => eprintln!(
                "{}: {} incomplete shard(s) in {} of {tasks} array task(s)",
                path.display(),
                scripts.incomplete_shards,
                scripts.tasks_with_work.len()
            ),
            None => eprintln!("every shard is complete; only finalize is left"),
        }
        eprintln!("{}", scripts.finalize.display());
    }
    if !args.submit {
        if !quiet {
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
            eprintln!(
                "submit with: {build}sbatch {dependency}{}",
                scripts.finalize.display()
            );
        }
        return Ok(Status::Success);
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
            Ok(Status::Success)
        }
        Err(err) if args.wait => {
            eprintln!(
                "error: {err}\nsee `bettimill status {}` and the logs in {}",
                args.out.display(),
                args.out.join("slurm/logs").display()
            );
            Ok(Status::Failure)
        }
        Err(err) => Err(err.into()),
    }
}

/// Arguments of `bettimill k8s`.
#[derive(clap::Args, Debug)]
pub struct KubernetesArgs {
    /// The manifest (TOML). Without it, the embedded demo manifest.
    manifest: Option<PathBuf>,
    /// Dataset directory: on the claim, mounted at this same path in every pod.
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
}

/// `bettimill k8s`: prints the Indexed Job on stdout.
pub fn kubernetes(args: KubernetesArgs) -> anyhow::Result<Status> {
    let (text, manifest) = load_manifest(args.manifest.as_deref())?;
    let dataset = Dataset::create(&args.out, &text, manifest)?;
    let yaml = cluster::kubernetes_job(
        &dataset,
        &KubernetesOptions {
            tasks: args.tasks,
            parallelism: args.parallelism.unwrap_or(args.tasks),
            image: args.image,
            claim: args.claim,
        },
    )?;
    print!("{yaml}");
    Ok(Status::Success)
}

/// `bettimill finalize DIR`.
pub fn finalize(dir: &Path, quiet: bool) -> anyhow::Result<Status> {
    let dataset = Dataset::open(dir)?;
    let status = cluster::status(&dataset);
    let incomplete: Vec<&str> = status
        .missing
        .iter()
        .map(String::as_str)
        .chain(status.invalid.iter().map(|s| s.shard.as_str()))
        .collect();
    if !incomplete.is_empty() {
        const SHOWN: usize = 20;
        let mut names = incomplete[..incomplete.len().min(SHOWN)].join(", ");
        if incomplete.len() > SHOWN {
            names.push_str(&format!(
                " and {} more (`bettimill status {}` lists them all)",
                incomplete.len() - SHOWN,
                dir.display()
            ));
        }
        eprintln!(
            "error: {} of {} shards are not complete: {}\nindex.json not written; build them (resubmit `bettimill slurm ... --submit`, or run `bettimill build ... --out {}`), then finalize again",
            incomplete.len(),
            status.shards,
            names,
            dir.display()
        );
        return Ok(Status::Failure);
    }
    // Every shard is complete, so no writer has work left: leftovers of killed ones can go.
    dataset.remove_temporaries()?;
    // `status` has just hashed every shard: finalize checks their records and sizes only,
    // so a standalone finalize reads every byte once, not twice.
    let checked: std::collections::BTreeSet<&str> =
        status.complete.iter().map(String::as_str).collect();
    dataset.finalize_checked(&|shard| checked.contains(shard.name.as_str()))?;
    if !quiet {
        eprintln!(
            "{} shards complete; wrote {}",
            status.shards,
            dataset.layout().index_path().display()
        );
    }
    Ok(Status::Success)
}

/// `bettimill status DIR`.
pub fn status(dir: &Path, json: bool) -> anyhow::Result<Status> {
    if !bettimill_format::DatasetDir::new(dir).has_build_info() {
        bail!(
            "{} holds no bettimill dataset (no build.json)",
            dir.display()
        );
    }
    let dataset = Dataset::open(dir)?;
    let report = cluster::status(&dataset);
    let mut text = String::new();
    if json {
        text = serde_json::to_string_pretty(&report)?;
        text.push('\n');
    } else {
        text.push_str(&format!(
            "{}: {} of {} shards complete, {} missing, {} invalid; index.json {}\n",
            dir.display(),
            report.complete.len(),
            report.shards,
            report.missing.len(),
            report.invalid.len(),
            if report.finalized {
                "written"
            } else {
                "not written"
            }
        ));
        for name in &report.missing {
            text.push_str(&format!("missing {name}\n"));
        }
        for invalid in &report.invalid {
            text.push_str(&format!("invalid {}: {}\n", invalid.shard, invalid.reason));
        }
    }
    // A reader that stops early (`| head`) is not an error.
    let mut stdout = std::io::stdout().lock();
    match std::io::Write::write_all(&mut stdout, text.as_bytes()) {
        Err(err) if err.kind() != std::io::ErrorKind::BrokenPipe => {
            return Err(err).context("cannot write to stdout")
        }
        _ => {}
    }
    Ok(Status::Success)
}
