//! A real single-node Slurm builds a dataset as an array job, survives a failing task by
//! resubmission of only the missing shards, and ends byte-identical to a local build.
//!
//! A system test: it runs only with BETTIMILL_SYSTEM_TESTS=1 (ci/test.sh sets it), because
//! it starts Slurm itself with ci/slurm-up.sh (idempotent; a no-op when it is up), which
//! installs packages, writes /etc/slurm and starts daemons. When Slurm cannot be started it
//! fails in CI (CI=true or BETTIMILL_SLURM_REQUIRED=1) and is skipped with a message
//! elsewhere (for example without root).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

mod common;
use bettimill_testkit::system_test;
use common::{assert_exit, ball_and_handle, run, sbatch_wait, slurm_up, text, Dir};

/// The dataset's files (everything but the lock, the Slurm scripts and logs, and the build
/// timings, never the same twice).
fn dataset_files(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            let rel = path.strip_prefix(dir).unwrap().to_path_buf();
            if rel == Path::new("slurm") || rel == Path::new(".lock") || rel == Path::new("timings")
            {
                continue;
            }
            if path.is_dir() {
                stack.push(path);
            } else {
                out.insert(rel, std::fs::read(&path).unwrap());
            }
        }
    }
    out
}

fn assert_same(local: &Path, cluster: &Path) {
    let (a, b) = (dataset_files(local), dataset_files(cluster));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (name, bytes) in &a {
        assert!(
            bytes == &b[name],
            "{} differs from the local build",
            name.display()
        );
    }
}

fn status(dir: &Path) -> serde_json::Value {
    let out = run(&["status", dir.to_str().unwrap(), "--json"]);
    assert_exit(&out, 0);
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn slurm_array_builds_resubmits_and_matches_a_local_build() {
    if !system_test("a real Slurm (ci/slurm-up.sh)") || !slurm_up() {
        return;
    }
    let tmp = Dir::new_in("/tmp", "bettimill-slurm-");
    let manifest = ball_and_handle(tmp.join("s.toml"), "s2d", 2, 20, 18, 3, 5);
    let m = manifest.to_str().unwrap();
    let local = tmp.path().join("local");
    let out = run(&[
        "build",
        m,
        "--out",
        local.to_str().unwrap(),
        "--workers",
        "2",
    ]);
    assert_exit(&out, 0);

    // 1. A clean array job: 6 shards over 3 tasks, at most 2 at once.
    let a = tmp.path().join("a");
    let out = run(&[
        "slurm",
        m,
        "--out",
        a.to_str().unwrap(),
        "--tasks",
        "3",
        "--throttle",
        "2",
    ]);
    assert_exit(&out, 0);
    let script = a.join("slurm/build.sbatch");
    let body = std::fs::read_to_string(&script).unwrap();
    assert!(body.contains("#SBATCH --array=0,1,2%2"), "{body}");
    assert_eq!(sbatch_wait(&script, &[]), Some(0));
    assert_eq!(status(&a)["complete"].as_array().unwrap().len(), 6);
    let out = run(&["finalize", a.to_str().unwrap()]);
    assert_exit(&out, 0);
    assert_same(&local, &a);
    let logs = std::fs::read_dir(a.join("slurm/logs")).unwrap().count();
    assert_eq!(logs, 3, "one log per array task");
    // Each task's log says each of its samples as it is done (2 shards of 3 samples each).
    for log in std::fs::read_dir(a.join("slurm/logs")).unwrap() {
        let log = std::fs::read_to_string(log.unwrap().path()).unwrap();
        let samples = log
            .lines()
            .filter(|l| l.starts_with("sample ") && l.contains(" done (shard s2d-"))
            .count();
        assert_eq!(samples, 6, "{log}");
    }

    // 2. Task 1 fails before doing any work: its shards (1 and 4) stay missing.
    let b = tmp.path().join("b");
    let out = run(&["slurm", m, "--out", b.to_str().unwrap(), "--tasks", "3"]);
    assert_exit(&out, 0);
    let code = sbatch_wait(
        &b.join("slurm/build.sbatch"),
        &[("BETTIMILL_TEST_FAIL_TASK", "1")],
    );
    assert_ne!(code, Some(0), "a failing task must make sbatch --wait fail");
    let s = status(&b);
    assert_eq!(
        s["missing"],
        serde_json::json!(["s2d-000001", "s2d-000004"]),
        "{s}"
    );
    assert_eq!(s["complete"].as_array().unwrap().len(), 4, "{s}");
    let out = run(&["finalize", b.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains("s2d-000001, s2d-000004"),
        "{}",
        text(&out.stderr)
    );
    assert!(!b.join("index.json").exists());
    let before: BTreeMap<_, _> = dataset_files_partial(&b);

    // 3. Resubmission runs only task 1, then finalize (afterok), and waits for it.
    let out = run(&[
        "slurm",
        m,
        "--out",
        b.to_str().unwrap(),
        "--tasks",
        "3",
        "--submit",
        "--wait",
    ]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{stdout}{}", text(&out.stderr));
    assert!(
        stdout.contains("build job ") && stdout.contains("finalize job "),
        "{stdout}"
    );
    let body = std::fs::read_to_string(b.join("slurm/build.sbatch")).unwrap();
    assert!(body.contains("#SBATCH --array=1\n"), "{body}");
    // The shards built the first time were not touched.
    for (name, bytes) in before {
        assert_eq!(
            std::fs::read(b.join(&name)).unwrap(),
            bytes,
            "{}",
            name.display()
        );
    }
    assert_same(&local, &b);
    let out = run(&["verify", b.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stdout));
}

/// The shards present in a partial build, with their bytes.
fn dataset_files_partial(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    for entry in std::fs::read_dir(dir.join("shards")).unwrap() {
        let path = entry.unwrap().path();
        out.insert(
            path.strip_prefix(dir).unwrap().to_path_buf(),
            std::fs::read(&path).unwrap(),
        );
    }
    out
}
