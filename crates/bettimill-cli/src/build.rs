//! `bettimill build`: a local build, in this process or with worker processes (the
//! coordinator), rendered by [`crate::build_display`]. Exit codes: 0 success, 2 a failed
//! build or a refused directory, 130 interrupted (rerun to resume).

use crate::build_display::{count, Display};
use crate::commands::{load_manifest, ExitStatus};
use crate::printer::Printer;
use anyhow::bail;
use bettimill_executor::coordinator::BuildControl;
use bettimill_executor::{BuildProgress, BuildRequest, Runner};
use std::path::Path;

/// The build's limits on its workers: `--worker-timeout` and `--max-memory`.
pub struct Limits {
    /// A worker silent this long is killed and its shard retried.
    pub worker_timeout: std::time::Duration,
    /// Memory per worker (default: a share of MemAvailable divided by the workers).
    pub max_memory: Option<u64>,
    /// The endpoint and uploads of an s3:// output.
    pub object: bettimill_executor::remote::ObjectOptions,
}

/// `bettimill build`.
pub fn build(
    manifest: Option<&Path>,
    out: &Path,
    workers: Option<usize>,
    max_shard_failures: u32,
    progress_interval: f64,
    limits: Limits,
    printer: Printer,
) -> anyhow::Result<ExitStatus> {
    if !(progress_interval.is_finite() && progress_interval > 0.0) {
        bail!("--progress-interval must be a positive number of seconds, got {progress_interval}");
    }
    let manifest_path = manifest;
    let resume = format!(
        "bettimill build {}--out {}",
        manifest_path
            .map(|m| format!("{} ", m.display()))
            .unwrap_or_default(),
        out.display()
    );
    crate::signals::set_resume_command(&resume);
    crate::commands::check_out_dir(out)?;
    let (text, manifest) = load_manifest(manifest)?;
    let workers = workers.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    });
    if workers == 0 {
        bail!("--workers must be at least 1");
    }
    let max_uploads = limits.object.max_uploads.max(1);
    let request = BuildRequest {
        out: out.to_path_buf(),
        manifest_text: text,
        manifest,
        runner: Runner::Workers {
            count: workers,
            program: crate::own_program()?,
        },
        max_memory: limits.max_memory,
        max_shard_failures,
        worker_timeout: limits.worker_timeout,
        object: limits.object,
    };
    let mut started = std::time::Instant::now();
    let mut display = None;
    let mut last_shard_line: Option<std::time::Instant> = None;
    let to_bucket = crate::commands::object_url(out).is_some();
    // Signals set a flag while the workers run (the coordinator polls this future first,
    // before it starts any worker); before and after, they end the process with 130.
    let control = async {
        let _watching = crate::signals::Watching::start();
        while !crate::signals::interrupted() {
            tokio::time::sleep(std::time::Duration::from_millis(20)).await;
        }
        BuildControl::Interrupt
    };
    let report = bettimill_executor::build(request, control, |progress| match progress {
        BuildProgress::Bound(dataset) => {
            if !dataset.plan.infeasible.is_empty() {
                // Said at the start, not only by `plan`: a researcher should know what the
                // dataset will not contain before it is built.
                printer.note(format_args!(
                    "left out of the plan ({} that cannot be built; the dataset card lists them too):",
                    if dataset.plan.infeasible.len() == 1 {
                        "1 combination".to_string()
                    } else {
                        format!("{} combinations", dataset.plan.infeasible.len())
                    }
                ));
                for item in &dataset.plan.infeasible {
                    printer.note(format_args!("  {}: {}", item.label, item.reason));
                }
            }
            started = std::time::Instant::now();
            // Worker processes report through the display; an s3:// build, made in this
            // process, by its own lines below.
            if !to_bucket {
                display = Some(Display::new(
                    printer,
                    std::time::Duration::from_secs_f64(progress_interval),
                ));
            }
        }
        BuildProgress::Workers(event) => {
            if let Some(display) = &mut display {
                display.event(event);
            }
        }
        // An s3:// build makes its shards in this process: a line per interval (and at
        // the last shard) says how far it is.
        BuildProgress::Shard(done, total) => {
            let interval = std::time::Duration::from_secs_f64(progress_interval);
            if done == total || last_shard_line.is_none_or(|at| at.elapsed() >= interval) {
                last_shard_line = Some(std::time::Instant::now());
                printer.note(format_args!(
                    "progress: {done}/{total} shards made or found complete, {} elapsed",
                    crate::build_display::human_seconds(started.elapsed().as_secs_f64())
                ));
            }
        }
    })?;
    // A build that returns was bound first, so the display exists.
    let mut display = display.unwrap_or_else(|| {
        Display::new(
            printer,
            std::time::Duration::from_secs_f64(progress_interval),
        )
    });
    display.finish();
    let (report, index) = (report.totals, report.index);
    let seconds = started.elapsed().as_secs_f64();
    if report.interrupted {
        Printer::always(format_args!(
            "interrupted: {} of {} shards complete, nothing partial is visible; resume with: {resume}",
            report.complete, report.shards
        ));
        return Ok(ExitStatus::Interrupted);
    }
    if !report.failed.is_empty() {
        Printer::always(format_args!(
            "error: {} failed {} times and were given up ({} of {} shards complete; index.json not written):",
            count(report.failed.len() as u64, "shard"),
            max_shard_failures,
            report.complete,
            report.shards
        ));
        for failed in &report.failed {
            Printer::always(format_args!(
                "  {}: {}",
                failed.shard,
                failed.reasons.last().map(String::as_str).unwrap_or("")
            ));
        }
        Printer::always(format_args!("fix the cause, then resume with: {resume}"));
        return Ok(ExitStatus::Failure);
    }
    // Worker processes make a local build's shards; an s3:// build makes them in this
    // process, on rayon's pool (`--workers` does not apply), while its uploads run.
    let makers = if to_bucket {
        format!(
            "{} in one process, up to {} at a time",
            count(rayon::current_num_threads() as u64, "thread"),
            count(max_uploads as u64, "upload")
        )
    } else {
        count(display.workers as u64, "worker")
    };
    printer.note(format_args!(
        "built {}, skipped {} complete; {} in {} ({}, {}), {}, {}\n{}",
        count(report.built, "shard"),
        report.skipped,
        count(report.samples_built, "sample"),
        crate::build_display::human_seconds(seconds),
        crate::build_display::rate(report.samples_built, seconds),
        makers,
        count(report.regenerations, "regeneration"),
        count(report.retries, "retried shard attempt"),
        index.display()
    ));
    Ok(ExitStatus::Success)
}
