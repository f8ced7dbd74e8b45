//! Batch schedulers: Slurm array scripts, Kubernetes Indexed Jobs, submission, status.
//!
//! The dataset directory on a shared file system is the only coordination: array task `t`
//! of `N` runs `bettimill worker --dir DIR --task-index-from-env --task-count N`, which
//! builds the incomplete shards `s` with `s % N == t` (see [`crate::worker::run_task`]),
//! and a final job runs `bettimill finalize DIR`, which writes index.json once every shard
//! is complete. Seeds come from the plan, so a resubmission rebuilds missing or invalid
//! shards with the same seeds and the same bytes.
//!
//! Files written by [`write_slurm_scripts`]:
//!
//! ```text
//! DIR/slurm/build.sbatch     the array job (only tasks that still have incomplete shards)
//! DIR/slurm/finalize.sbatch  runs `bettimill finalize DIR`
//! DIR/slurm/logs/            one log per array task (%A_%a.out) and per finalize job
//! ```
//!
//! A dataset under `s3://BUCKET/PREFIX` has no directory for them: the same two scripts
//! and `logs/` go in a directory the caller names ([`write_bucket_slurm_scripts`]), and
//! the tasks reach the bucket with the credentials of the environment sbatch passes on.

use crate::{BuildError, Dataset, ShardState};
use std::path::{Path, PathBuf};

/// Why a scheduler step failed.
#[derive(Debug, thiserror::Error)]
pub enum ClusterError {
    /// The directory.
    #[error(transparent)]
    Build(#[from] BuildError),
    /// A parameter out of range.
    #[error("{0}")]
    Invalid(String),
    /// sbatch could not be run or refused the job.
    #[error("sbatch {script}: {reason}")]
    Submit {
        /// The script.
        script: PathBuf,
        /// What happened.
        reason: String,
    },
}

/// The most names [`status`] keeps of each state (the counts are exact), so that its
/// memory does not grow with the number of shards.
pub const STATUS_NAMES: usize = 10_000;

/// The shards of a dataset by state: exact counts, and the names of the first
/// [`STATUS_NAMES`] shards of each state in plan order.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct StatusReport {
    /// The dataset directory.
    pub dir: PathBuf,
    /// Shards in the plan.
    pub shards: u64,
    /// Complete shards.
    pub complete_count: u64,
    /// Shards with nothing on disk.
    pub missing_count: u64,
    /// Shards with something on disk that is not a complete shard.
    pub invalid_count: u64,
    /// Names of complete shards (the first [`STATUS_NAMES`]).
    pub complete: Vec<String>,
    /// Names of shards with nothing on disk (the first [`STATUS_NAMES`]).
    pub missing: Vec<String>,
    /// Shards with something on disk that is not a complete shard, and why (the first
    /// [`STATUS_NAMES`]).
    pub invalid: Vec<InvalidShard>,
    /// Whether index.json exists.
    pub finalized: bool,
}

/// A shard whose files do not make a complete shard.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct InvalidShard {
    /// The shard's name.
    pub shard: String,
    /// What is wrong.
    pub reason: String,
}

/// Judges every shard from the directory alone.
///
/// `shards/` and `records/` are each listed once; a planned shard with neither a tar nor a
/// record there is missing without a file being opened, so the time grows with the shards
/// on disk (each checked whole), not with the shards planned: a plan of 10^7 shards costs
/// no open per missing one.
pub fn status(dataset: &Dataset) -> StatusReport {
    let mut report = StatusReport {
        dir: dataset.dir.clone(),
        shards: dataset.plan.shard_count(),
        finalized: dataset.layout().is_finalized(),
        ..StatusReport::default()
    };
    let layout = dataset.layout();
    // Both sorted; `None` when a directory cannot be listed (each shard is then looked at
    // on its own, and says why).
    let on_disk = match (layout.shard_names(), layout.record_names()) {
        (Ok(tars), Ok(records)) => Some((tars, records)),
        _ => None,
    };
    for shard in dataset.plan.shards() {
        let present = on_disk.as_ref().is_none_or(|(tars, records)| {
            tars.binary_search(&shard.name).is_ok() || records.binary_search(&shard.name).is_ok()
        });
        let state = if present {
            dataset.shard_state(&shard)
        } else {
            ShardState::Missing
        };
        match state {
            ShardState::Complete(_) => {
                report.complete_count += 1;
                if report.complete.len() < STATUS_NAMES {
                    report.complete.push(shard.name);
                }
            }
            ShardState::Missing => {
                report.missing_count += 1;
                if report.missing.len() < STATUS_NAMES {
                    report.missing.push(shard.name);
                }
            }
            ShardState::Invalid { reason } => {
                report.invalid_count += 1;
                if report.invalid.len() < STATUS_NAMES {
                    report.invalid.push(InvalidShard {
                        shard: shard.name,
                        reason,
                    });
                }
            }
        }
    }
    report
}

/// Quotes a string for a POSIX shell.
pub fn shell_quote(text: &str) -> String {
    format!("'{}'", text.replace('\'', r"'\''"))
}

/// Settings of the Slurm array job.
#[derive(Clone, Debug)]
pub struct SlurmOptions {
    /// Array tasks (shards are dealt round-robin).
    pub tasks: u64,
    /// Tasks running at once (`%K`), if limited.
    pub throttle: Option<u64>,
    /// CPUs per task (threads each task uses).
    pub cpus_per_task: u64,
    /// The bettimill binary the jobs run (on the shared file system).
    pub program: PathBuf,
    /// Extra `#SBATCH` lines' contents, e.g. `--partition=debug`.
    pub extra: Vec<String>,
}

/// The scripts written by [`write_slurm_scripts`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SlurmScripts {
    /// The array job, if any task has work left.
    pub build: Option<PathBuf>,
    /// The finalize job.
    pub finalize: PathBuf,
    /// Array task indices that have incomplete shards.
    pub tasks_with_work: Vec<u64>,
    /// Incomplete shards.
    pub incomplete_shards: u64,
}

fn absolute(path: &Path) -> Result<PathBuf, BuildError> {
    std::path::absolute(path).map_err(|source| BuildError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Writes `DIR/slurm/build.sbatch` and `DIR/slurm/finalize.sbatch` (see the module
/// documentation). The array lists only tasks that still have incomplete shards.
pub fn write_slurm_scripts(
    dataset: &Dataset,
    options: &SlurmOptions,
) -> Result<SlurmScripts, ClusterError> {
    let dir = absolute(&dataset.dir)?;
    let incomplete: Vec<u64> = dataset
        .plan
        .shards()
        .filter(|s| dataset.completed(s).is_none())
        .map(|s| s.index)
        .collect();
    write_scripts(
        &dir.to_string_lossy(),
        &dataset.plan.name,
        &incomplete,
        &dir.join("slurm"),
        "",
        options,
    )
}

/// Writes `build.sbatch`, `finalize.sbatch` and `logs/` into `scripts` (a directory every
/// node sees) for the dataset `name` at `url` (`s3://BUCKET/PREFIX`, bound already), whose
/// shards `incomplete` (plan indices) the bucket lacks. The scripts hold no credentials:
/// the tasks read `AWS_*` from the environment sbatch passes on (its default, `--export=ALL`).
pub fn write_bucket_slurm_scripts(
    url: &str,
    name: &str,
    incomplete: &[u64],
    scripts: &Path,
    options: &SlurmOptions,
) -> Result<SlurmScripts, ClusterError> {
    write_scripts(
        url,
        name,
        incomplete,
        &absolute(scripts)?,
        "# The tasks reach the bucket with AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY (and\n\
         # AWS_ENDPOINT_URL for a server other than AWS S3) from the submitting environment.\n",
        options,
    )
}

/// The scripts of [`write_slurm_scripts`] for the dataset at `location` (an absolute
/// directory or a URL), in `slurm_dir`; `note` is comment lines for the array script.
fn write_scripts(
    location: &str,
    name: &str,
    incomplete: &[u64],
    slurm_dir: &Path,
    note: &str,
    options: &SlurmOptions,
) -> Result<SlurmScripts, ClusterError> {
    if options.tasks == 0 {
        return Err(ClusterError::Invalid("--tasks must be at least 1".into()));
    }
    if options.throttle == Some(0) {
        return Err(ClusterError::Invalid(
            "--throttle must be at least 1".into(),
        ));
    }
    let program = absolute(&options.program)?;
    let logs = slurm_dir.join("logs");
    std::fs::create_dir_all(&logs).map_err(|source| BuildError::Io {
        path: logs.clone(),
        source,
    })?;
    let mut tasks_with_work: Vec<u64> = incomplete.iter().map(|s| s % options.tasks).collect();
    tasks_with_work.sort_unstable();
    tasks_with_work.dedup();
    let program_text = program.to_string_lossy();
    let extra: String = options
        .extra
        .iter()
        .map(|line| format!("#SBATCH {line}\n"))
        .collect();

    let build = if tasks_with_work.is_empty() {
        None
    } else {
        let list: Vec<String> = tasks_with_work.iter().map(u64::to_string).collect();
        let throttle = options
            .throttle
            .map(|k| format!("%{k}"))
            .unwrap_or_default();
        let script = format!(
            "#!/bin/bash\n\
             # Written by `bettimill slurm`: array task t builds the incomplete shards s with\n\
             # s % {tasks} == t of the dataset in {dir_q}. Resubmitting is safe: complete shards\n\
             # are skipped and the rest are rebuilt with the same seeds.\n\
             {note}\
             #SBATCH --job-name=bettimill-{name}\n\
             #SBATCH --array={array}{throttle}\n\
             #SBATCH --cpus-per-task={cpus}\n\
             #SBATCH --output={logs}/%A_%a.out\n\
             {extra}\
             set -euo pipefail\n\
             exec {program} worker --dir {dir_q} --task-index-from-env --task-count {tasks} --threads \"${{SLURM_CPUS_PER_TASK:-{cpus}}}\"\n",
            tasks = options.tasks,
            dir_q = shell_quote(location),
            array = list.join(","),
            cpus = options.cpus_per_task.max(1),
            logs = logs.to_string_lossy(),
            program = shell_quote(&program_text),
        );
        let path = slurm_dir.join("build.sbatch");
        bettimill_shard::write_atomic(&path, script.as_bytes()).map_err(BuildError::from)?;
        Some(path)
    };
    let script = format!(
        "#!/bin/bash\n\
         # Written by `bettimill slurm`: writes index.json once every shard is complete;\n\
         # exits 2 naming the incomplete shards otherwise.\n\
         #SBATCH --job-name=bettimill-{name}-finalize\n\
         #SBATCH --cpus-per-task=1\n\
         #SBATCH --output={logs}/finalize-%j.out\n\
         {extra}\
         set -euo pipefail\n\
         exec {program} finalize {dir_q}\n",
        logs = logs.to_string_lossy(),
        program = shell_quote(&program_text),
        dir_q = shell_quote(location),
    );
    let finalize = slurm_dir.join("finalize.sbatch");
    bettimill_shard::write_atomic(&finalize, script.as_bytes()).map_err(BuildError::from)?;
    if build.is_none() {
        // A stale array script from an earlier submission must not be run by mistake.
        let stale = slurm_dir.join("build.sbatch");
        if stale.exists() {
            std::fs::remove_file(&stale).map_err(|source| BuildError::Io {
                path: stale.clone(),
                source,
            })?;
        }
    }
    Ok(SlurmScripts {
        build,
        finalize,
        tasks_with_work,
        incomplete_shards: incomplete.len() as u64,
    })
}

/// Runs `sbatch --parsable [args] script` and returns the job id.
pub fn sbatch(script: &Path, args: &[String]) -> Result<String, ClusterError> {
    let submit_error = |reason: String| ClusterError::Submit {
        script: script.to_path_buf(),
        reason,
    };
    let output = std::process::Command::new("sbatch")
        .arg("--parsable")
        .args(args)
        .arg(script)
        .output()
        .map_err(|err| {
            submit_error(format!(
                "cannot run sbatch (is Slurm installed and on PATH?): {err}"
            ))
        })?;
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    let job = stdout
        .lines()
        .next()
        .unwrap_or("")
        .split(';')
        .next()
        .unwrap_or("")
        .trim()
        .to_string();
    if !job.is_empty() && job.chars().all(|c| c.is_ascii_digit()) {
        if !output.status.success() {
            return Err(submit_error(format!(
                "job {job} ended with {}: {}",
                output.status,
                stderr.trim()
            )));
        }
        return Ok(job);
    }
    Err(submit_error(format!(
        "{} and printed no job id: {}",
        output.status,
        stderr.trim()
    )))
}

/// Settings of the Kubernetes Indexed Job.
#[derive(Clone, Debug)]
pub struct KubernetesOptions {
    /// Completions (array tasks).
    pub tasks: u64,
    /// Pods at once.
    pub parallelism: u64,
    /// Container image holding the same bettimill binary.
    pub image: String,
    /// PersistentVolumeClaim holding the dataset directory.
    pub claim: String,
    /// Memory of one pod in bytes: asked for and limited to (`resources`), and passed to
    /// the worker as `--max-memory` (rounded up to whole MiB).
    pub max_memory: Option<u64>,
}

/// A name made of lower-case letters, digits and '-' (DNS-1123 label, at most 63 bytes).
fn dns_label(text: &str) -> String {
    let mut label: String = text
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '-'
            }
        })
        .collect();
    label.truncate(50);
    let label = label.trim_matches('-');
    if label.is_empty() {
        "dataset".to_string()
    } else {
        label.to_string()
    }
}

fn yaml_string(text: &str) -> String {
    serde_json::to_string(text).expect("strings serialise")
}

/// A Kubernetes Indexed Job whose pod `t` runs array task `t` (from JOB_COMPLETION_INDEX).
/// The dataset directory must be on the claim, mounted at the same path in every pod.
pub fn kubernetes_job(
    dataset: &Dataset,
    options: &KubernetesOptions,
) -> Result<String, ClusterError> {
    if options.tasks == 0 || options.parallelism == 0 {
        return Err(ClusterError::Invalid(
            "--tasks and --parallelism must be at least 1".into(),
        ));
    }
    let dir = absolute(&dataset.dir)?;
    let dir_text = dir.to_string_lossy();
    let name = dns_label(&format!("bettimill-{}", dataset.plan.name));
    // Whole MiB: `--max-memory 512M` for the worker, `512Mi` for Kubernetes.
    let memory = options
        .max_memory
        .map(|bytes| format!("{}M", bytes.div_ceil(1 << 20)));
    Ok(format!(
        "# Written by `bettimill k8s`: pod t builds the incomplete shards s with s % {tasks} == t of\n\
         # the dataset in {dir_text}, which must be on the claim {claim} mounted at that path.\n\
         # Resubmitting is safe. When the Job completes, run: bettimill finalize {dir_text}\n\
         apiVersion: batch/v1\n\
         kind: Job\n\
         metadata:\n  name: {name}\n\
         spec:\n  completionMode: Indexed\n  completions: {tasks}\n  parallelism: {parallelism}\n  backoffLimit: {backoff}\n\
         \x20 template:\n    spec:\n      restartPolicy: Never\n      containers:\n\
         \x20       - name: worker\n          image: {image}\n\
         \x20         command: [\"bettimill\", \"worker\", \"--dir\", {dir_y}, \"--task-index-from-env\", \"--task-count\", \"{tasks}\", \"--threads\", \"1\"{memory_arg}]\n\
         \x20         resources:\n            requests:\n              cpu: \"1\"\n{memory_resources}\
         \x20         volumeMounts:\n            - name: data\n              mountPath: {dir_y}\n\
         \x20     volumes:\n        - name: data\n          persistentVolumeClaim:\n            claimName: {claim_y}\n",
        tasks = options.tasks,
        parallelism = options.parallelism.min(options.tasks),
        backoff = options.tasks.saturating_mul(2).max(6),
        claim = options.claim,
        image = yaml_string(&options.image),
        dir_y = yaml_string(&dir_text),
        claim_y = yaml_string(&options.claim),
        memory_arg = memory
            .as_ref()
            .map(|m| format!(", \"--max-memory\", \"{m}\""))
            .unwrap_or_default(),
        memory_resources = memory
            .as_ref()
            .map(|m| {
                let quantity = format!("{}Mi", m.trim_end_matches('M'));
                format!(
                    "              memory: \"{quantity}\"\n            limits:\n              memory: \"{quantity}\"\n"
                )
            })
            .unwrap_or_default(),
    ))
}

/// The Kubernetes Indexed Job of a dataset under `s3://BUCKET/PREFIX`: as
/// [`kubernetes_job`], with no volume: each pod reads the stored manifest from the bucket,
/// builds its shards and uploads them, with the credentials (and `AWS_ENDPOINT_URL` for an
/// S3-compatible server) from the Secret `secret` as its environment.
pub fn kubernetes_bucket_job(
    url: &str,
    dataset_name: &str,
    secret: &str,
    options: &KubernetesOptions,
) -> Result<String, ClusterError> {
    if options.tasks == 0 || options.parallelism == 0 {
        return Err(ClusterError::Invalid(
            "--tasks and --parallelism must be at least 1".into(),
        ));
    }
    let name = dns_label(&format!("bettimill-{dataset_name}"));
    let memory = options
        .max_memory
        .map(|bytes| format!("{}M", bytes.div_ceil(1 << 20)));
    Ok(format!(
        "# Written by `bettimill k8s`: pod t builds the incomplete shards s with s % {tasks} == t of\n\
         # the dataset at {url} and uploads them; no volume is needed. The Secret {secret} holds\n\
         # AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY (and AWS_ENDPOINT_URL for a server other than\n\
         # AWS S3). Resubmitting is safe. When the Job completes, run: bettimill finalize {url}\n\
         apiVersion: batch/v1\n\
         kind: Job\n\
         metadata:\n  name: {name}\n\
         spec:\n  completionMode: Indexed\n  completions: {tasks}\n  parallelism: {parallelism}\n  backoffLimit: {backoff}\n\
         \x20 template:\n    spec:\n      restartPolicy: Never\n      containers:\n\
         \x20       - name: worker\n          image: {image}\n\
         \x20         command: [\"bettimill\", \"worker\", \"--dir\", {url_y}, \"--task-index-from-env\", \"--task-count\", \"{tasks}\"{memory_arg}]\n\
         \x20         envFrom:\n            - secretRef:\n                name: {secret_y}\n\
         \x20         resources:\n            requests:\n              cpu: \"1\"\n{memory_resources}",
        tasks = options.tasks,
        parallelism = options.parallelism.min(options.tasks),
        backoff = options.tasks.saturating_mul(2).max(6),
        image = yaml_string(&options.image),
        url_y = yaml_string(url),
        secret_y = yaml_string(secret),
        memory_arg = memory
            .as_ref()
            .map(|m| format!(", \"--max-memory\", \"{m}\""))
            .unwrap_or_default(),
        memory_resources = memory
            .as_ref()
            .map(|m| {
                let quantity = format!("{}Mi", m.trim_end_matches('M'));
                format!(
                    "              memory: \"{quantity}\"\n            limits:\n              memory: \"{quantity}\"\n"
                )
            })
            .unwrap_or_default(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shell_quoting_survives_quotes_and_spaces() {
        assert_eq!(shell_quote("a b"), "'a b'");
        assert_eq!(shell_quote("it's"), r"'it'\''s'");
    }

    #[test]
    fn dns_labels_are_valid() {
        assert_eq!(dns_label("bettimill-Demo_3D"), "bettimill-demo-3d");
        assert_eq!(dns_label("___"), "dataset");
        assert!(dns_label(&"x".repeat(200)).len() <= 63);
    }
}
