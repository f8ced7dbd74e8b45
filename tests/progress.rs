//! What `bettimill build` tells a researcher on stderr when nobody watches a terminal (a
//! Slurm log, `nohup`, CI): plain progress lines at a steady interval, strata the plan left
//! out said at the start, and silence with `--quiet`. The tests' stderr is a pipe, as in
//! those places.

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
