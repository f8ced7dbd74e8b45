//! Multi-process builds with real processes: `bettimill build --workers N` with worker
//! deaths, coordinator deaths (kill -9 at several points, including between a shard's
//! temporary file and its rename), a second concurrent build, a shard that keeps failing,
//! and SIGTERM. Every finished directory must be byte-identical to a clean build.

use std::path::{Path, PathBuf};
use std::process::Child;
use std::time::Duration;

mod common;
use common::{
    alive, assert_exit, assert_same, ball_and_handle, build, children, kill, run, shard_files,
    spawn_build, text, wait_until, Dir,
};

fn manifest(dir: &Path, dimension: u32, side: u32, samples: u32, shard_size: u32) -> PathBuf {
    let path = dir.join(format!("m{dimension}d-{side}-{samples}-{shard_size}.toml"));
    let name = format!("w{dimension}d");
    ball_and_handle(path, &name, dimension, side, samples, shard_size, 11)
}

/// User plus system CPU time of a process in clock ticks (usually 1/100 s).
fn cpu_ticks(pid: u32) -> u64 {
    let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
        return 0;
    };
    // Fields after the command name: state is field 3, utime 14, stime 15.
    let fields: Vec<&str> = stat
        .rsplit(')')
        .next()
        .unwrap_or("")
        .split_whitespace()
        .collect();
    let field = |n: usize| {
        fields
            .get(n - 3)
            .and_then(|f| f.parse::<u64>().ok())
            .unwrap_or(0)
    };
    field(14) + field(15)
}

fn finish(child: Child) -> (Option<i32>, String) {
    let out = child.wait_with_output().unwrap();
    (out.status.code(), text(&out.stderr))
}

#[test]
fn one_and_two_workers_build_identical_bytes() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 3, 18, 16, 3);
    let (one, two) = (tmp.path().join("one"), tmp.path().join("two"));
    let out = build(&m, &one, 1);
    assert_exit(&out, 0);
    let out = build(&m, &two, 2);
    assert_exit(&out, 0);
    assert!(
        text(&out.stderr).contains("2 workers"),
        "{}",
        text(&out.stderr)
    );
    assert_same(&one, &two);
    let out = run(&["verify", one.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stdout));
    // The status of a finished directory: every shard complete.
    let out = run(&["status", two.to_str().unwrap(), "--json"]);
    let status: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(status["complete"].as_array().unwrap().len(), 6);
    assert_eq!(status["missing"], serde_json::json!([]));
    assert_eq!(status["finalized"], serde_json::json!(true));
}

#[test]
fn a_worker_killed_in_the_middle_of_a_shard_is_replaced_and_the_build_is_identical() {
    let tmp = Dir::new();
    // Shards of forty-eight 4D samples are slow enough for the kill to land inside a shard
    // (a shard takes several times the 15 ticks below).
    let m = manifest(tmp.path(), 4, 48, 96, 48);
    let clean = tmp.path().join("clean");
    assert_eq!(build(&m, &clean, 1).status.code(), Some(0));

    let out = tmp.path().join("killed");
    let coordinator = spawn_build(&m, &out, 1, &[]);
    let mut first = 0;
    wait_until("a worker", Duration::from_secs(30), || {
        first = children(coordinator.id()).first().copied().unwrap_or(0);
        first != 0
    });
    // Kill it once it has computed for a while (so it is inside its first shard, whatever
    // the machine's load), which is well before the shard can be finished.
    wait_until("the worker to compute", Duration::from_secs(60), || {
        cpu_ticks(first) >= 15
    });
    assert!(
        !shard_files(&out).iter().any(|n| n.ends_with(".tar")),
        "a shard finished before the kill; the test needs slower samples"
    );
    assert!(kill("-9", first), "kill -9 {}", first);
    let (code, stderr) = finish(coordinator);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stderr.contains("killed by signal 9"), "{stderr}");
    assert!(stderr.contains("re-queued"), "{stderr}");
    assert_same(&clean, &out);
}

#[test]
fn a_coordinator_killed_between_write_and_rename_leaves_nothing_visible_and_resumes() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 20, 12, 3);
    let clean = tmp.path().join("clean");
    assert_eq!(build(&m, &clean, 2).status.code(), Some(0));

    let out = tmp.path().join("paused");
    let coordinator = spawn_build(&m, &out, 2, &[("BETTIMILL_TEST_PAUSE_BEFORE_RENAME", "60")]);
    wait_until("a temporary shard file", Duration::from_secs(60), || {
        shard_files(&out).iter().any(|n| n.contains(".tmp-"))
    });
    let workers = children(coordinator.id());
    assert!(!workers.is_empty());

    // While it runs, a second build of the same directory is refused.
    let second = build(&m, &out, 1);
    assert_eq!(second.status.code(), Some(2));
    assert!(
        text(&second.stderr).contains("another bettimill build or finalize is running"),
        "{}",
        text(&second.stderr)
    );

    assert!(kill("-9", coordinator.id()), "kill -9 {}", coordinator.id());
    let _ = finish(coordinator);
    // Orphaned workers notice that their coordinator is gone and exit.
    for pid in workers {
        wait_until(
            "an orphaned worker to exit",
            Duration::from_secs(10),
            || !alive(pid),
        );
    }
    // Nothing partial is visible: only temporary files, no tar.
    let files = shard_files(&out);
    assert!(files.iter().all(|n| n.starts_with('.')), "{files:?}");
    let status = run(&["status", out.to_str().unwrap(), "--json"]);
    let status: serde_json::Value = serde_json::from_slice(&status.stdout).unwrap();
    assert_eq!(status["invalid"], serde_json::json!([]), "{status}");
    assert_eq!(status["complete"], serde_json::json!([]), "{status}");

    // The lock died with its process: the same command resumes and matches a clean build.
    let out_resume = build(&m, &out, 2);
    assert_exit(&out_resume, 0);
    assert_same(&clean, &out);
}

#[test]
fn a_coordinator_killed_at_several_points_resumes_to_identical_bytes() {
    let tmp = Dir::new();
    // 12 one-sample 4D shards, each held 0.3 s before its rename (the samples alone are
    // too quick to be caught), so that each kill lands inside the build.
    let m = manifest(tmp.path(), 4, 24, 12, 1);
    let clean = tmp.path().join("clean");
    assert_eq!(build(&m, &clean, 2).status.code(), Some(0));

    let out = tmp.path().join("killed");
    let records = |out: &Path| {
        std::fs::read_dir(out.join("records"))
            .map(|rd| {
                rd.flatten()
                    .filter(|e| !e.file_name().to_string_lossy().starts_with('.'))
                    .count()
            })
            .unwrap_or(0)
    };
    let mut complete_counts = Vec::new();
    // Kill once the workers are up, then after 2, 5 and 8 complete shards.
    for target in [0usize, 2, 5, 8] {
        let coordinator = spawn_build(
            &m,
            &out,
            2,
            &[("BETTIMILL_TEST_PAUSE_BEFORE_RENAME", "0.3")],
        );
        wait_until("workers and progress", Duration::from_secs(60), || {
            children(coordinator.id()).len() == 2 && records(&out) >= target
        });
        let workers = children(coordinator.id());
        assert!(kill("-9", coordinator.id()), "kill -9 {}", coordinator.id());
        let _ = finish(coordinator);
        for pid in workers {
            wait_until(
                "an orphaned worker to exit",
                Duration::from_secs(10),
                || !alive(pid),
            );
        }
        let status = run(&["status", out.to_str().unwrap(), "--json"]);
        let status: serde_json::Value = serde_json::from_slice(&status.stdout).unwrap();
        // A tar without its record can exist (killed between the two renames); it is
        // reported as invalid and rebuilt. A tar that does not match its record never is.
        for invalid in status["invalid"].as_array().unwrap() {
            let reason = invalid["reason"].as_str().unwrap();
            assert!(reason.contains("no completion record"), "{status}");
        }
        assert!(
            !out.join("index.json").exists(),
            "the build finished before the kill"
        );
        complete_counts.push(status["complete"].as_array().unwrap().len());
    }
    let resumed = build(&m, &out, 2);
    assert_exit(&resumed, 0);
    assert_same(&clean, &out);
    // Progress survived the kills.
    assert!(
        complete_counts.windows(2).all(|w| w[0] <= w[1]) && complete_counts[3] >= 8,
        "{complete_counts:?}"
    );
}

#[test]
fn a_shard_that_keeps_failing_is_given_up_while_the_others_finish() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 20, 12, 3);
    let out = tmp.path().join("out");
    let coordinator = spawn_build(&m, &out, 2, &[("BETTIMILL_TEST_FAIL_SHARD", "1")]);
    let (code, stderr) = finish(coordinator);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("1 shard failed 3 times"), "{stderr}");
    assert!(
        stderr.contains("w2d-000001: BETTIMILL_TEST_FAIL_SHARD"),
        "{stderr}"
    );
    assert!(!out.join("index.json").exists());
    let status = run(&["status", out.to_str().unwrap(), "--json"]);
    let status: serde_json::Value = serde_json::from_slice(&status.stdout).unwrap();
    assert_eq!(
        status["missing"],
        serde_json::json!(["w2d-000001"]),
        "{status}"
    );
    assert_eq!(status["complete"].as_array().unwrap().len(), 3, "{status}");
    let out_finalize = run(&["finalize", out.to_str().unwrap()]);
    assert_eq!(out_finalize.status.code(), Some(2));
    assert!(text(&out_finalize.stderr).contains("w2d-000001"));

    // With the cause gone, the same command finishes the dataset.
    let resumed = build(&m, &out, 2);
    assert_exit(&resumed, 0);
    let clean = tmp.path().join("clean");
    assert_eq!(build(&m, &clean, 1).status.code(), Some(0));
    assert_same(&clean, &out);
}

#[test]
fn sigterm_stops_the_workers_and_says_how_to_resume() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 20, 12, 3);
    let out = tmp.path().join("out");
    let coordinator = spawn_build(&m, &out, 2, &[("BETTIMILL_TEST_PAUSE_BEFORE_RENAME", "60")]);
    wait_until("a temporary shard file", Duration::from_secs(60), || {
        shard_files(&out).iter().any(|n| n.contains(".tmp-"))
    });
    let workers = children(coordinator.id());
    assert!(
        kill("-TERM", coordinator.id()),
        "kill -TERM {}",
        coordinator.id()
    );
    let (code, stderr) = finish(coordinator);
    assert_eq!(code, Some(130), "{stderr}");
    assert!(stderr.contains("interrupted"), "{stderr}");
    assert!(stderr.contains("resume with: bettimill build"), "{stderr}");
    for pid in workers {
        assert!(!alive(pid), "worker {pid} outlived its coordinator");
    }
    // A clean stop leaves no temporary files either.
    assert!(shard_files(&out).is_empty(), "{:?}", shard_files(&out));
}

#[test]
fn a_worker_of_another_version_is_refused_with_what_to_do() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 20, 6, 3);
    let out = tmp.path().join("out");
    let coordinator = spawn_build(&m, &out, 1, &[("BETTIMILL_TEST_WORKER_VERSION", "9.9.9")]);
    let (code, stderr) = finish(coordinator);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("worker is bettimill 9.9.9")
            && stderr.contains(&format!(
                "coordinator is bettimill {}",
                env!("CARGO_PKG_VERSION")
            ))
            && stderr.contains("rebuild or reinstall so that both are the same binary"),
        "{stderr}"
    );
    assert!(!out.join("index.json").exists());
}

/// `bettimill build MANIFEST --out OUT --workers 1 --worker-timeout SECONDS` in the
/// background; stdout discarded, stderr captured.
fn spawn_build_with_timeout(manifest: &Path, out: &Path, seconds: u32) -> Child {
    spawn_build_with_timeout_env(manifest, out, seconds, &[])
}

/// [`spawn_build_with_timeout`] with extra environment variables.
fn spawn_build_with_timeout_env(
    manifest: &Path,
    out: &Path,
    seconds: u32,
    env: &[(&str, &str)],
) -> Child {
    common::bettimill()
        .envs(env.iter().copied())
        .args(["build", manifest.to_str().unwrap(), "--out"])
        .arg(out)
        .args(["--workers", "1", "--worker-timeout", &seconds.to_string()])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap()
}

#[test]
fn a_frozen_worker_is_killed_after_the_worker_timeout_and_the_build_is_identical() {
    let tmp = Dir::new();
    // Shards long enough for the worker to be stopped inside its first one, as above.
    let m = manifest(tmp.path(), 4, 48, 96, 48);
    let clean = tmp.path().join("clean");
    assert_eq!(build(&m, &clean, 1).status.code(), Some(0));

    let out = tmp.path().join("frozen");
    let coordinator = spawn_build_with_timeout(&m, &out, 3);
    let mut first = 0;
    wait_until("a worker", Duration::from_secs(30), || {
        first = children(coordinator.id()).first().copied().unwrap_or(0);
        first != 0
    });
    wait_until("the worker to compute", Duration::from_secs(60), || {
        cpu_ticks(first) >= 15
    });
    // Stopped, not dead: its pipes stay open, so only the missing heartbeat tells.
    assert!(kill("-STOP", first), "kill -STOP {first}");
    let started = std::time::Instant::now();
    let (code, stderr) = finish(coordinator);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("not even a heartbeat, for 3 s (--worker-timeout)"),
        "{stderr}"
    );
    assert!(stderr.contains("re-queued"), "{stderr}");
    assert!(!alive(first), "the frozen worker {first} was not killed");
    assert!(started.elapsed() >= Duration::from_secs(3));
    assert_same(&clean, &out);
}

#[test]
fn a_worker_busy_with_one_long_sample_is_kept_alive_by_its_heartbeat() {
    let tmp = Dir::new();
    // The worker is held for 6 s inside its shard, between writing the tar and renaming it
    // (the documented test hook), sending nothing but heartbeats: twice the 3 s timeout,
    // whatever the machine's speed (a real sample's time would depend on it).
    let m = manifest(tmp.path(), 2, 16, 2, 2);
    let out = tmp.path().join("slow");
    let started = std::time::Instant::now();
    let (code, stderr) = finish(spawn_build_with_timeout_env(
        &m,
        &out,
        3,
        &[("BETTIMILL_TEST_PAUSE_BEFORE_RENAME", "6")],
    ));
    assert_eq!(code, Some(0), "{stderr}");
    assert!(started.elapsed() > Duration::from_secs(6));
    assert!(stderr.contains("0 retried shard attempts"), "{stderr}");
    assert!(!stderr.contains("heartbeat"), "{stderr}");
}

#[test]
fn a_worker_timeout_shorter_than_three_heartbeats_is_refused() {
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 16, 2, 1);
    let out = run(&[
        "build",
        m.to_str().unwrap(),
        "--out",
        tmp.path().join("o").to_str().unwrap(),
        "--worker-timeout",
        "1",
    ]);
    assert_exit(&out, 2);
    assert!(
        text(&out.stderr).contains("at least 3 s"),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn status_counts_every_shard_and_lists_the_first_ten_thousand_of_each_state() {
    // 10,003 one-sample shards, none built: `slurm` (not submitted) only creates the
    // directory, so every shard is missing.
    let tmp = Dir::new();
    let manifest = manifest(tmp.path(), 2, 16, 10_003, 1);
    let dir = tmp.path().join("many");
    let d = dir.to_str().unwrap();
    let out = run(&["slurm", manifest.to_str().unwrap(), "--out", d]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let out = run(&["status", d, "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let status: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(status["shards"], 10_003);
    assert_eq!(status["missing_count"], 10_003);
    assert_eq!(status["complete_count"], 0);
    let missing = status["missing"].as_array().unwrap();
    assert_eq!(missing.len(), 10_000);
    assert_eq!(missing[9_999], "w2d-009999");
    let out = run(&["status", d]);
    let listing = text(&out.stdout);
    assert!(
        listing.contains("0 of 10003 shards complete, 10003 missing"),
        "{listing}"
    );
    assert!(
        listing.ends_with("... and 3 more missing shards (the first 10000 are listed)\n"),
        "{listing}"
    );
    let out = run(&["finalize", d]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains("10003 of 10003 shards are not complete: w2d-000000, "),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn a_resumed_build_starts_its_first_missing_shard_before_it_checks_the_complete_ones() {
    use bettimill_executor::coordinator::{self, BuildEvent, BuildOptions};
    let tmp = Dir::new();
    let m = manifest(tmp.path(), 2, 24, 6, 1);
    let (out, clean) = (tmp.path().join("out"), tmp.path().join("clean"));
    assert_exit(&build(&m, &out, 1), 0);
    assert_exit(&build(&m, &clean, 1), 0);
    let text_of = std::fs::read_to_string(&m).unwrap();
    let manifest = bettimill_manifest::Manifest::parse(&text_of, &m).unwrap();
    let dataset = bettimill_executor::Dataset::bind(&out, &text_of, manifest).unwrap();
    // Shard 0 is lost (tar and record), the five after it are complete, the index is stale.
    let first = dataset.plan.shard(0).name;
    for path in [
        out.join("shards").join(format!("{first}.tar")),
        out.join("records").join(format!("{first}.json")),
        out.join("index.json"),
    ] {
        std::fs::remove_file(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    }
    let options = BuildOptions {
        workers: 1,
        max_shard_failures: 1,
        worker_program: common::BETTIMILL.into(),
        worker_args: vec!["worker".into(), "--dir".into(), out.clone().into()],
        worker_timeout: coordinator::DEFAULT_WORKER_TIMEOUT,
    };
    let mut events = Vec::new();
    let report = coordinator::run(&dataset, &options, std::future::pending(), |event| {
        events.push(event)
    })
    .unwrap();
    assert_eq!((report.built, report.skipped), (1, 5), "{report:?}");
    assert!(report.finalized, "{report:?}");
    // Nothing is read per shard before work starts: the one worker builds shard 0 first,
    // and the complete shards are found (each hashed against its record) as their turn
    // comes, after it.
    let kinds: Vec<&str> = events
        .iter()
        .map(|event| match event {
            BuildEvent::Started { .. } => "started",
            BuildEvent::WorkerStarted { .. } => "worker",
            BuildEvent::ShardStarted { .. } => "shard",
            BuildEvent::ShardDone { .. } => "done",
            BuildEvent::ShardSkipped { .. } => "skipped",
            _ => "other",
        })
        .filter(|kind| *kind != "other")
        .collect();
    assert_eq!(
        kinds,
        [
            "started", "worker", "shard", "done", "skipped", "skipped", "skipped", "skipped",
            "skipped"
        ],
        "{events:?}"
    );
    assert!(matches!(
        &events[0],
        BuildEvent::Started {
            shards: 6,
            samples: 6,
            workers: 1
        }
    ));
    assert_same(&out, &clean);
}
