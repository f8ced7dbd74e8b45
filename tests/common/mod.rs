//! The one harness of the end-to-end test files in `tests/` (ripgrep's `tests/util.rs` in
//! spirit): start the real `bettimill` binary, in a fresh temporary directory when the
//! working directory matters, compare its exit code, stdout and stderr, and look at its
//! child processes and output directory. Helpers shared with the tests of other crates
//! (the fuzz runner, the seeded generator, fail-in-CI for missing tools) live in
//! `bettimill-testkit`.
//!
//! Each test binary uses a different subset, so unused ones are expected.
#![allow(dead_code)]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The binary under test.
pub const BETTIMILL: &str = env!("CARGO_BIN_EXE_bettimill");

/// The repository root.
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A `bettimill` command (working directory inherited: give it absolute paths, or use
/// [`Dir::command`]).
pub fn bettimill() -> Command {
    Command::new(BETTIMILL)
}

/// Runs `bettimill ARGS` to its end.
pub fn run(args: &[&str]) -> Output {
    bettimill().args(args).output().expect("bettimill runs")
}

/// Runs `bettimill ARGS` to its end with `dir` as its working directory.
pub fn run_in(dir: &Path, args: &[&str]) -> Output {
    bettimill()
        .args(args)
        .current_dir(dir)
        .output()
        .expect("bettimill runs")
}

/// A fresh temporary directory, removed when dropped; the commands it makes run in it.
pub struct Dir(tempfile::TempDir);

impl Dir {
    /// A fresh directory under the system's temporary directory.
    pub fn new() -> Dir {
        Dir(tempfile::tempdir().expect("a temporary directory"))
    }

    /// A fresh directory under `parent`, its name starting with `prefix`.
    pub fn new_in(parent: &str, prefix: &str) -> Dir {
        Dir(tempfile::Builder::new()
            .prefix(prefix)
            .tempdir_in(parent)
            .expect("a temporary directory"))
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        self.0.path()
    }

    /// A path inside the directory.
    pub fn join(&self, name: impl AsRef<Path>) -> PathBuf {
        self.0.path().join(name)
    }

    /// A `bettimill` command whose working directory is this one.
    pub fn command(&self) -> Command {
        let mut command = bettimill();
        command.current_dir(self.path());
        command
    }

    /// Runs `bettimill ARGS` to its end in this directory.
    pub fn run(&self, args: &[&str]) -> Output {
        run_in(self.path(), args)
    }
}

/// The manifest most end-to-end tests build: balls and handles, embedded and carved,
/// with the given dataset name, sizes and seed, written to `path` (returned).
#[allow(clippy::too_many_arguments)]
pub fn ball_and_handle(
    path: PathBuf,
    name: &str,
    dimension: u32,
    side: u32,
    samples: u32,
    shard_size: u32,
    seed: u64,
) -> PathBuf {
    std::fs::write(
        &path,
        format!(
            "schema_version = 1\nname = \"{name}\"\ndimension = {dimension}\nside = {side}\n\
             mode = [\"embed\", \"carve\"]\nsamples = {samples}\nshard_size = {shard_size}\n\
             seed = {seed}\n\n[[classes]]\nfamily = \"ball\"\n\n[[classes]]\nfamily = \"handle\"\n"
        ),
    )
    .unwrap();
    path
}

/// Bytes as text (invalid UTF-8 replaced).
pub fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// A finished command's stdout as text.
pub fn stdout(out: &Output) -> String {
    text(&out.stdout)
}

/// A finished command's stderr as text.
pub fn stderr(out: &Output) -> String {
    text(&out.stderr)
}

/// Asserts that a finished command exited with `code`; the failure message shows its
/// stdout and stderr.
#[track_caller]
pub fn assert_exit(out: &Output, code: i32) {
    assert_eq!(
        out.status.code(),
        Some(code),
        "exit status {}, expected {code}\n--- stdout\n{}\n--- stderr\n{}",
        out.status,
        stdout(out),
        stderr(out)
    );
}

pub fn build(manifest: &Path, out: &Path, workers: u32) -> Output {
    run(&[
        "build",
        manifest.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--workers",
        &workers.to_string(),
    ])
}

/// The child processes of `pid` (from /proc; Linux only).
pub fn children(pid: u32) -> Vec<u32> {
    let mut out = Vec::new();
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return out;
    };
    for task in tasks.flatten() {
        if let Ok(list) = std::fs::read_to_string(task.path().join("children")) {
            out.extend(
                list.split_whitespace()
                    .filter_map(|p| p.parse::<u32>().ok()),
            );
        }
    }
    out
}

pub fn shard_files(out: &Path) -> Vec<String> {
    std::fs::read_dir(out.join("shards"))
        .map(|rd| {
            rd.flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default()
}

/// Every file under `dir`, by relative path, with its bytes (a file that vanishes while the
/// directory is walked, such as a temporary being renamed, reads as empty), except a
/// dataset's build timings (`timings/`: statistics outside the hashed data, never the same
/// twice).
pub fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if d == dir && path.file_name() == Some(std::ffi::OsStr::new("timings")) {
                continue;
            }
            if path.is_dir() {
                stack.push(path);
            } else {
                let rel = path.strip_prefix(dir).unwrap().to_path_buf();
                out.insert(rel, std::fs::read(&path).unwrap_or_default());
            }
        }
    }
    out
}

/// Every finished file (the lock and temporaries, whose names start with a dot, aside; and
/// `timings/`, which [`snapshot`] leaves out) is the same in both directories, and `a` is a
/// finished dataset.
pub fn assert_same(a: &Path, b: &Path) {
    let finished = |dir: &Path| -> BTreeMap<PathBuf, Vec<u8>> {
        snapshot(dir)
            .into_iter()
            .filter(|(p, _)| !p.file_name().unwrap().to_string_lossy().starts_with('.'))
            .collect()
    };
    let (sa, sb) = (finished(a), finished(b));
    assert!(sa.contains_key(Path::new("index.json")), "{}", a.display());
    assert_eq!(
        sa.keys().collect::<Vec<_>>(),
        sb.keys().collect::<Vec<_>>(),
        "{} and {} hold different files",
        a.display(),
        b.display()
    );
    for (name, bytes) in &sa {
        assert!(bytes == &sb[name], "{} differs", name.display());
    }
}

/// `bettimill build MANIFEST --out OUT --workers N` started in the background, with extra
/// environment variables; stdout discarded, stderr captured.
pub fn spawn_build(manifest: &Path, out: &Path, workers: u32, env: &[(&str, &str)]) -> Child {
    let mut command = bettimill();
    command
        .args(["build", manifest.to_str().unwrap(), "--out"])
        .arg(out)
        .args(["--workers", &workers.to_string()])
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    for (k, v) in env {
        command.env(k, v);
    }
    command.spawn().unwrap()
}

/// Sends `signal` (`-9`, `-TERM`, ...) to process `pid` with kill(1); whether it was sent.
pub fn kill(signal: &str, pid: u32) -> bool {
    Command::new("kill")
        .args([signal, &pid.to_string()])
        .stderr(Stdio::null())
        .status()
        .map(|s| s.success())
        .unwrap_or(false)
}

/// Whether process `pid` is running (a zombie is dead for our purposes).
pub fn alive(pid: u32) -> bool {
    match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
        Ok(stat) => !matches!(
            stat.rsplit(')')
                .next()
                .and_then(|s| s.split_whitespace().next()),
            Some("Z") | Some("X")
        ),
        Err(_) => false,
    }
}

/// Polls `check` every 10 ms until it holds; fails the test after `limit`.
pub fn wait_until(what: &str, limit: Duration, mut check: impl FnMut() -> bool) {
    let start = Instant::now();
    while !check() {
        assert!(start.elapsed() < limit, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Runs `bettimill ARGS` to its end under GNU time and returns its output and peak
/// resident set in KiB (getrusage of the child, `%M`); `None` (the test returns) when
/// /usr/bin/time is missing outside CI.
pub fn run_with_peak(args: &[&str]) -> Option<(Output, u64)> {
    run_with_peak_in(args, |_| {})
}

/// [`run_with_peak`] with the command set up by `configure` first (for example a local S3
/// server's environment).
pub fn run_with_peak_in(
    args: &[&str],
    configure: impl FnOnce(&mut Command),
) -> Option<(Output, u64)> {
    const TIME: &str = "/usr/bin/time";
    if !Path::new(TIME).exists() {
        bettimill_testkit::skip_unless_ci("GNU time", "/usr/bin/time is not installed");
        return None;
    }
    let report = tempfile::NamedTempFile::new().expect("a temporary file");
    let mut command = Command::new(TIME);
    command
        .arg("-f")
        .arg("%M")
        .arg("-o")
        .arg(report.path())
        .arg(BETTIMILL)
        .args(args);
    configure(&mut command);
    let output = command.output().expect("time runs bettimill");
    let text = std::fs::read_to_string(report.path()).expect("time wrote its report");
    // GNU time writes "Command exited with non-zero status N" before the figures.
    let kib = text
        .lines()
        .filter_map(|l| l.trim().parse::<u64>().ok())
        .next_back()
        .unwrap_or_else(|| panic!("no peak in GNU time's report: {text:?}"));
    Some((output, kib))
}

/// Asserts that a finished command exited with `code` and that its stderr says `needle`.
#[track_caller]
pub fn assert_exit_saying(out: &Output, code: i32, needle: &str) {
    assert_exit(out, code);
    assert!(stderr(out).contains(needle), "{}", stderr(out));
}

/// Builds `manifest` into `parent/clean` with `workers` workers (it must succeed) and
/// returns that directory: the reference the builds a test interrupts are compared with.
#[track_caller]
pub fn clean_build(manifest: &Path, parent: &Path, workers: u32) -> PathBuf {
    let clean = parent.join("clean");
    assert_exit(&build(manifest, &clean, workers), 0);
    clean
}

/// Reruns the build of `manifest` into `out` (it must succeed) and asserts that `out` is
/// then file for file the same as `clean` (see [`assert_same`]).
#[track_caller]
pub fn assert_rebuilds_identically(manifest: &Path, out: &Path, workers: u32, clean: &Path) {
    assert_exit(&build(manifest, out, workers), 0);
    assert_same(clean, out);
}

/// Starts Slurm; `false` (skip) only outside CI.
pub fn slurm_up() -> bool {
    let script = repo_root().join("ci/slurm-up.sh");
    let out = Command::new("bash").arg(&script).output();
    let reason = match out {
        Ok(out) if out.status.success() => return true,
        Ok(out) => format!(
            "{} exited with {}:\n{}{}",
            script.display(),
            out.status,
            text(&out.stdout),
            text(&out.stderr)
        ),
        Err(err) => format!("cannot run {}: {err}", script.display()),
    };
    assert!(
        bettimill_env::var(bettimill_env::EnvVars::BETTIMILL_SLURM_REQUIRED)
            .is_none_or(|v| v != "1"),
        "Slurm is required here (BETTIMILL_SLURM_REQUIRED=1) but unavailable: {reason}"
    );
    bettimill_testkit::skip_unless_ci("Slurm", &reason);
    false
}

/// `sbatch --wait` of a script (up to 5 minutes); returns its exit code. Its output goes to
/// the test's stderr, for the diagnosis of a failing run.
#[allow(clippy::print_stderr)]
pub fn sbatch_wait(script: &Path, env: &[(&str, &str)]) -> Option<i32> {
    let mut command = Command::new("timeout");
    command
        .args(["300", "sbatch", "--wait", "--parsable"])
        .arg(script);
    for (k, v) in env {
        command.env(k, v);
    }
    let out = command.output().expect("sbatch runs");
    eprintln!(
        "sbatch --wait {}: {} {}{}",
        script.display(),
        out.status,
        text(&out.stdout),
        text(&out.stderr)
    );
    assert_ne!(out.status.code(), Some(124), "sbatch --wait timed out");
    out.status.code()
}
