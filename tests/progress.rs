//! What `bettimill build` tells a researcher on stderr when nobody watches a terminal (a
//! Slurm log, `nohup`, CI): plain progress lines at a steady interval, strata the plan left
//! out said at the start, and silence with `--quiet`; the lines advance within a sample that
//! takes seconds (its stage, as a fraction), and an array task's log has a line per sample
//! and the stage of a long one. The tests' stderr is a pipe, as in those places.

mod common;
use common::{assert_exit, repo_root, stderr, Dir};

fn demo_4d() -> String {
    repo_root()
        .join("manifests/demo-4d.toml")
        .to_string_lossy()
        .into_owned()
}

#[test]
fn a_build_whose_stderr_is_not_a_terminal_writes_plain_progress_lines() {
    let dir = Dir::new();
    let out = dir.run(&[
        "build",
        &demo_4d(),
        "--out",
        "d",
        "--workers",
        "1",
        "--progress-interval",
        "0.05",
    ]);
    assert_exit(&out, 0);
    let err = stderr(&out);
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with("progress: "))
        .collect();
    // 64 4D samples take seconds; at 20 lines a second some must have been written.
    assert!(!lines.is_empty(), "no progress line in:\n{err}");
    for line in &lines {
        assert!(line.contains("/64 samples, "), "{line}");
        assert!(line.contains("/4 shards, "), "{line}");
        assert!(line.contains(" regenerations, "), "{line}");
    }
    // The closing summary prints its rate with sensible precision.
    let summary = err.lines().find(|l| l.starts_with("built ")).unwrap();
    assert!(
        summary.contains("samples/s") || summary.contains("s per sample"),
        "{summary}"
    );

    // A resumed build that has nothing to do says so without a meaningless rate.
    let again = dir.run(&["build", &demo_4d(), "--out", "d"]);
    assert_exit(&again, 0);
    assert!(
        stderr(&again).contains("no sample built yet"),
        "{}",
        stderr(&again)
    );
}

#[test]
fn quiet_builds_write_no_progress_and_bad_intervals_are_refused_before_anything_is_written() {
    let dir = Dir::new();
    let out = dir.run(&[
        "--quiet",
        "build",
        &demo_4d(),
        "--out",
        "d",
        "--progress-interval",
        "0.05",
    ]);
    assert_exit(&out, 0);
    assert_eq!(stderr(&out), "");
    let bad = dir.run(&[
        "build",
        &demo_4d(),
        "--out",
        "e",
        "--progress-interval",
        "0",
    ]);
    assert_exit(&bad, 2);
    assert!(
        stderr(&bad).contains("--progress-interval"),
        "{}",
        stderr(&bad)
    );
    assert!(!dir.join("e").exists());
}

#[test]
fn strata_the_plan_leaves_out_are_said_when_the_build_starts() {
    let dir = Dir::new();
    std::fs::write(
        dir.join("m.toml"),
        "schema_version = 1\nname = \"inf\"\ndimension = 3\nside = 20\n\
         mode = [\"embed\", \"carve\"]\nsamples = 4\nshard_size = 2\nseed = 1\n\
         [[classes]]\nfamily = \"tunnel\"\nintervals = 1\n",
    )
    .unwrap();
    let out = dir.run(&["build", "m.toml", "--out", "d"]);
    assert_exit(&out, 0);
    let err = stderr(&out);
    assert!(err.contains("left out of the plan (1 combination"), "{err}");
    assert!(
        err.contains("tunnel(intervals=1,circle=false)/embed: "),
        "{err}"
    );
}

/// One 4D sample big enough that its stages are reported while it is made (side 128, carved
/// T2xB2, no copies, gzip members). A worker sends at most one stage frame a quarter second,
/// so each stage up to the last, encoding, must outlast that to be seen.
fn one_big_sample(dir: &Dir) -> String {
    std::fs::write(
        dir.join("big.toml"),
        "schema_version = 1\nname = \"big\"\ndimension = 4\nside = 128\nmode = \"carve\"\n\
         samples = 1\nshard_size = 1\nseed = 7\ncompression = \"gzip\"\n\
         [[classes]]\nfamily = \"t2_x_b2\"\n",
    )
    .unwrap();
    "big.toml".to_string()
}

#[test]
fn progress_lines_advance_within_a_sample_before_it_completes() {
    let dir = Dir::new();
    let manifest = one_big_sample(&dir);
    let out = dir.run(&[
        "build",
        &manifest,
        "--out",
        "d",
        "--workers",
        "1",
        "--progress-interval",
        "0.05",
    ]);
    assert_exit(&out, 0);
    let err = stderr(&out);
    let lines: Vec<&str> = err.lines().collect();
    let stages = [
        "generate",
        "hypervolume targeting",
        "verify",
        "downscale r",
        "encode",
    ];
    // A line that names the sample and its stage, while no sample is complete yet.
    let in_flight = lines
        .iter()
        .position(|l| {
            l.starts_with("progress: ")
                && l.contains("; worker 0: s000000 ")
                && stages.iter().any(|s| l.ends_with(s))
        })
        .unwrap_or_else(|| panic!("no line with a stage in:\n{err}"));
    let completed = lines
        .iter()
        .position(|l| l.starts_with("progress: 1/1 samples") || l.starts_with("built "))
        .unwrap_or_else(|| panic!("no completion in:\n{err}"));
    assert!(in_flight < completed, "{err}");
    // Lines before the completion count only whole samples done as done: 0 or a fraction.
    for line in &lines[..completed] {
        if let Some(rest) = line.strip_prefix("progress: ") {
            let done = rest.split('/').next().unwrap();
            let done: f64 = done.parse().unwrap_or_else(|_| panic!("{line}"));
            assert!((0.0..1.0).contains(&done), "{line}");
        }
    }
    // The stage reached counts: encoding starts at 0.9 of a sample (docs/cluster.md; the
    // carved solid's verification, at 0.3, is over between two lines).
    assert!(
        lines
            .iter()
            .any(|l| l.starts_with("progress: 0.9/1 samples") && l.ends_with(" encode")),
        "{err}"
    );
    // Once the sample is done, no line names it any more.
    assert!(
        lines[completed..].iter().all(|l| !l.contains("worker 0: ")),
        "{err}"
    );
}

#[test]
fn an_array_task_logs_each_sample_and_the_stage_of_a_long_one() {
    let dir = Dir::new();
    let manifest = one_big_sample(&dir);
    // `slurm` binds the directory and writes the scripts; the task is what sbatch would run.
    let scripts = dir.run(&["slurm", &manifest, "--out", "d"]);
    assert_exit(&scripts, 0);
    let out = dir
        .command()
        .args([
            "worker",
            "--dir",
            "d",
            "--task-index-from-env",
            "--task-count",
            "1",
            "--progress-interval",
            "0.05",
        ])
        .env("SLURM_ARRAY_TASK_ID", "0")
        .output()
        .unwrap();
    assert_exit(&out, 0);
    let err = stderr(&out);
    let lines: Vec<&str> = err.lines().collect();
    let working = lines
        .iter()
        .position(|l| l.starts_with("working: s000000 (shard big-000000) "))
        .unwrap_or_else(|| panic!("no stage line in:\n{err}"));
    let done = lines
        .iter()
        .position(|l| l.starts_with("sample s000000 done (shard big-000000) in "))
        .unwrap_or_else(|| panic!("no sample line in:\n{err}"));
    let built = lines
        .iter()
        .position(|l| *l == "built big-000000")
        .unwrap_or_else(|| panic!("no shard line in:\n{err}"));
    assert!(working < done && done < built, "{err}");
    assert!(
        lines[done].contains("0 regenerations; 1 samples by this task"),
        "{err}"
    );
    assert!(lines[built..].iter().all(|l| !l.starts_with("working: ")));
    assert!(
        lines
            .last()
            .unwrap()
            .starts_with("task 0 of 1: built 1, already complete 0, failed 0"),
        "{err}"
    );

    // --quiet: not a line.
    let quiet = dir
        .command()
        .args([
            "--quiet",
            "worker",
            "--dir",
            "d",
            "--task-index",
            "0",
            "--task-count",
            "1",
        ])
        .output()
        .unwrap();
    assert_exit(&quiet, 0);
    assert_eq!(stderr(&quiet), "");
}
