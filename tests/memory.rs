//! Memory bounds: huge but valid manifests plan and start building in
//! bounded memory, checked under `ulimit -v` (a process over the limit gets allocation
//! failures, not swap); a sample too big for a worker's memory limit is refused with the
//! numbers before anything is written or any worker starts.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Duration;

mod common;
use common::{assert_exit, kill, run, stderr, stdout, text, wait_until, Dir, BETTIMILL};

/// Address space a huge plan or build may use (KiB): far below what the two huge manifests
/// below would take if the plan held them whole; a bounded plan needs a few MiB of it
/// (threads and allocator arenas reserve most of the rest).
const ULIMIT_KIB: u64 = 1_000_000;

/// The 4D demo with `samples` and `shard_size` replaced.
fn huge(dir: &Path, samples: u64, shard_size: u64) -> PathBuf {
    let text = std::fs::read_to_string(common::repo_root().join("manifests/demo-4d.toml"))
        .unwrap()
        .replace("samples = 64", &format!("samples = {samples}"))
        .replace("shard_size = 16", &format!("shard_size = {shard_size}"));
    let path = dir.join(format!("huge-{samples}-{shard_size}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// `bettimill ARGS` under `ulimit -v ULIMIT_KIB` (the shell execs it, so the pid is
/// bettimill's).
fn limited(args: &[&str]) -> Command {
    let mut command = Command::new("sh");
    command
        .arg("-c")
        .arg(format!("ulimit -v {ULIMIT_KIB} && exec \"$0\" \"$@\""))
        .arg(BETTIMILL)
        .args(args);
    command
}

fn tars(dir: &Path) -> usize {
    std::fs::read_dir(dir.join("shards"))
        .map(|entries| {
            entries
                .filter_map(Result::ok)
                .filter(|e| e.file_name().to_string_lossy().ends_with(".tar"))
                .count()
        })
        .unwrap_or(0)
}

#[test]
fn huge_manifests_plan_under_ulimit() {
    let tmp = Dir::new();
    for (samples, shard_size, shards) in [
        (1_000_000_000u64, 40u64, "25000000 shards"),
        (100_000_000, 1, "100000000 shards"),
    ] {
        let m = huge(tmp.path(), samples, shard_size);
        let out: Output = limited(&["plan", m.to_str().unwrap()]).output().unwrap();
        assert_exit(&out, 0);
        assert!(stdout(&out).contains(shards), "{}", stdout(&out));
        assert!(
            stdout(&out).contains("worker memory: about"),
            "{}",
            stdout(&out)
        );
    }
}

#[test]
fn huge_manifests_build_and_resume_under_ulimit() {
    let tmp = Dir::new();
    for (samples, shard_size) in [(1_000_000_000u64, 40u64), (100_000_000, 1)] {
        let m = huge(tmp.path(), samples, shard_size);
        let out = tmp.path().join(format!("out-{samples}-{shard_size}"));
        // Twice: a new build, then a resume of it; each writes shards, then is interrupted.
        for round in 1..=2 {
            let before = tars(&out);
            let mut child = limited(&[
                "build",
                m.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--workers",
                "1",
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
            wait_until(
                "a shard of the huge build",
                Duration::from_secs(120),
                || tars(&out) > before || child.try_wait().unwrap().is_some(),
            );
            kill("-INT", child.id());
            let result = child.wait_with_output().unwrap();
            let err = text(&result.stderr);
            assert_eq!(
                result.status.code(),
                Some(130),
                "{samples}/{shard_size} round {round}: {err}"
            );
            assert!(err.contains("interrupted:"), "{err}");
            assert!(!err.contains("memory allocation"), "{err}");
        }
    }
}

fn with_side(dir: &Path, side: u32) -> PathBuf {
    let text = std::fs::read_to_string(common::repo_root().join("manifests/demo-4d.toml"))
        .unwrap()
        .replace("side = 32", &format!("side = {side}"));
    let path = dir.join(format!("side-{side}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// The largest 4D side a manifest accepts (254: 4.16 billion voxels a sample) is refused
/// by its memory estimate before any worker starts; 256 is refused by the manifest itself
/// (its exact Betti numbers would need over 2^32 places).
#[test]
fn a_4d_side_254_sample_is_refused_with_the_numbers_before_any_worker_starts() {
    let tmp = Dir::new();
    let too_large = with_side(tmp.path(), 256);
    common::assert_exit_saying(
        &run(&["plan", too_large.to_str().unwrap()]),
        2,
        "256 is over 254, the largest 4D side",
    );
    let m = with_side(tmp.path(), 254);
    let m = m.to_str().unwrap();
    let expected = [
        "4D, side 254: 4162314256 voxels a sample",
        "needs about 23.3 GiB",
        "16.0 GiB allowed per worker (--max-memory 16.0 GiB)",
    ];
    let out = run(&["plan", m, "--max-memory", "16G"]);
    assert_exit(&out, 2);
    // The plan is printed, then refused.
    assert!(stdout(&out).contains("worker memory: about 23.3 GiB"));
    for needle in expected {
        assert!(
            stderr(&out).contains(needle),
            "{needle:?}: {}",
            stderr(&out)
        );
    }
    let dir = tmp.path().join("out");
    let out = run(&[
        "build",
        m,
        "--out",
        dir.to_str().unwrap(),
        "--max-memory",
        "16G",
    ]);
    assert_exit(&out, 2);
    for needle in expected {
        assert!(
            stderr(&out).contains(needle),
            "{needle:?}: {}",
            stderr(&out)
        );
    }
    assert!(!dir.exists(), "a refused build wrote {}", dir.display());
    // The same plan with the memory it needs is accepted by plan.
    let out = run(&["plan", m, "--max-memory", "80G"]);
    assert_exit(&out, 0);
}

#[test]
fn the_memory_limit_is_shared_by_the_workers_and_checked_by_each_worker() {
    let tmp = Dir::new();
    let m = with_side(tmp.path(), 32);
    let m = m.to_str().unwrap();
    // One 32^4 worker: 5 B x 2^20 voxels (the 10% phase share of an unbinned 4D stratum)
    // + 32 MiB + one sample's bytes (gzip) = 38 MiB.
    let out = run(&["plan", m, "--max-memory", "30M"]);
    common::assert_exit_saying(&out, 2, "needs about 38.0 MiB");
    let dir = tmp.path().join("out");
    let out = run(&[
        "build",
        m,
        "--out",
        dir.to_str().unwrap(),
        "--max-memory",
        "1G",
        "--workers",
        "2",
    ]);
    assert_exit(&out, 0);
    // A worker (an array task with 2 threads) refuses a limit its two samples exceed.
    let out = run(&[
        "worker",
        "--dir",
        dir.to_str().unwrap(),
        "--task-index",
        "0",
        "--task-count",
        "1",
        "--threads",
        "2",
        "--max-memory",
        "60M",
    ]);
    common::assert_exit_saying(&out, 2, "needs about 75.0 MiB");
    // Sizes that are not sizes are refused by name.
    let out = run(&["plan", m, "--max-memory", "lots"]);
    common::assert_exit_saying(&out, 2, "is not a memory size");
}

#[test]
fn slurm_checks_one_array_task_and_asks_for_its_memory() {
    let tmp = Dir::new();
    let m = with_side(tmp.path(), 32);
    let m = m.to_str().unwrap();
    let dir = tmp.path().join("cluster");
    let d = dir.to_str().unwrap();
    // Two CPUs a task: two 32^4 samples at once need about 75 MiB.
    let out = run(&[
        "slurm",
        m,
        "--out",
        d,
        "--cpus-per-task",
        "2",
        "--max-memory",
        "60M",
    ]);
    common::assert_exit_saying(&out, 2, "needs about 75.0 MiB");
    assert!(!dir.exists(), "a refused slurm wrote {d}");
    let out = run(&["slurm", m, "--out", d, "--max-memory", "1G"]);
    assert_exit(&out, 0);
    let script = std::fs::read_to_string(dir.join("slurm/build.sbatch")).unwrap();
    assert!(script.contains("#SBATCH --mem=1024M"), "{script}");
}

/// `bettimill ARGS` with the Slurm variables `vars` set (and no other SLURM_* variable).
fn in_slurm_job(args: &[&str], vars: &[(&str, &str)]) -> Output {
    let mut command = common::bettimill();
    for name in bettimill_env::names_starting_with("SLURM_") {
        command.env_remove(name);
    }
    command.args(args).envs(vars.iter().copied());
    command.output().unwrap()
}

/// An array task on a shared node checks its job's allocation, not the node's
/// MemAvailable: inside a Slurm job the limit is `SLURM_MEM_PER_NODE`, or
/// `SLURM_MEM_PER_CPU` x `SLURM_CPUS_ON_NODE`, and the message says which.
#[test]
fn inside_a_slurm_job_the_memory_limit_is_the_jobs_allocation_and_is_named() {
    let tmp = Dir::new();
    let m = with_side(tmp.path(), 32);
    let m = m.to_str().unwrap();
    let job = [("SLURM_JOB_ID", "7"), ("SLURM_MEM_PER_NODE", "16")];
    let out = in_slurm_job(&["plan", m], &job);
    common::assert_exit_saying(
        &out,
        2,
        "the Slurm job's memory: SLURM_MEM_PER_NODE 16.0 MiB",
    );
    let per_cpu = [
        ("SLURM_JOB_ID", "7"),
        ("SLURM_MEM_PER_CPU", "8"),
        ("SLURM_CPUS_ON_NODE", "2"),
    ];
    let out = in_slurm_job(&["plan", m], &per_cpu);
    common::assert_exit_saying(&out, 2, "SLURM_MEM_PER_CPU 8.0 MiB x SLURM_CPUS_ON_NODE 2");
    // The array task itself: bound by `slurm`, refused by the job's memory when it starts.
    let dir = tmp.path().join("cluster");
    let d = dir.to_str().unwrap();
    assert_exit(&run(&["slurm", m, "--out", d, "--max-memory", "1G"]), 0);
    let task = [
        "worker",
        "--dir",
        d,
        "--task-index",
        "0",
        "--task-count",
        "1",
    ];
    let out = in_slurm_job(&task, &job);
    common::assert_exit_saying(&out, 2, "SLURM_MEM_PER_NODE 16.0 MiB");
    assert_eq!(tars(&dir), 0);
    // A job with enough memory plans it; --max-memory still wins over the job.
    let enough = [("SLURM_JOB_ID", "7"), ("SLURM_MEM_PER_NODE", "4096")];
    assert_exit(&in_slurm_job(&["plan", m], &enough), 0);
    assert_exit(&in_slurm_job(&["plan", m, "--max-memory", "1G"], &job), 0);
}

/// `bettimill k8s --max-memory`: the pods ask Kubernetes for the memory and check it, rather
/// than running with none asked for and checking their node's MemAvailable.
#[test]
fn k8s_max_memory_is_checked_and_written_into_the_jobs_resources_and_command() {
    let tmp = Dir::new();
    let m = with_side(tmp.path(), 32);
    let m = m.to_str().unwrap();
    let dir = tmp.path().join("k8s");
    let d = dir.to_str().unwrap();
    let out = run(&["k8s", m, "--out", d, "--tasks", "2", "--max-memory", "20M"]);
    common::assert_exit_saying(&out, 2, "--max-memory 20.0 MiB");
    assert!(!dir.exists(), "a refused k8s wrote {d}");
    let out = run(&["k8s", m, "--out", d, "--tasks", "2", "--max-memory", "1G"]);
    assert_exit(&out, 0);
    let yaml = stdout(&out);
    assert!(
        yaml.contains("\"--threads\", \"1\", \"--max-memory\", \"1024M\"]"),
        "{yaml}"
    );
    let resources = "resources:\n            requests:\n              cpu: \"1\"\n              memory: \"1024Mi\"\n            limits:\n              memory: \"1024Mi\"\n";
    assert!(yaml.contains(resources), "{yaml}");
    // Without it, nothing is asked for.
    let out = run(&["k8s", m, "--out", d, "--tasks", "2"]);
    assert_exit(&out, 0);
    assert!(!stdout(&out).contains("memory"), "{}", stdout(&out));
}

/// The estimate bounds what a worker really holds where a 4D sample's memory is largest:
/// a binned carve stratum whose cavities take 40% of the image, targeted and deformed.
#[test]
fn a_4d_binned_carve_build_stays_under_its_memory_estimate() {
    let tmp = Dir::new();
    let m = tmp.path().join("carve.toml");
    std::fs::write(
        &m,
        "schema_version = 1\nname = \"carve\"\ndimension = 4\nside = 48\nmode = \"carve\"\n\
         samples = 2\nshard_size = 1\nseed = 5\ncompression = \"zstd\"\nresolutions = [24]\n\
         [hypervolume]\nunit = \"fraction\"\nbins = [[0.60, 0.62]]\n\
         [[deform]]\nmethod = \"erode\"\nsteps = [0, 3]\n\
         [[deform]]\nmethod = \"tentacles\"\ncount = [1, 6]\nsteps = [0, 40]\n\
         [[deform]]\nmethod = \"moves\"\nsteps = [0, 20000]\n\
         [[classes]]\nfamily = [\"handle\", \"t2_x_b2\"]\n",
    )
    .unwrap();
    let m = m.to_str().unwrap();
    let out = run(&["plan", m, "--json"]);
    assert_exit(&out, 0);
    let plan: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let estimate = plan["worker_memory_bytes"].as_u64().unwrap();
    let dir = tmp.path().join("out");
    let Some((out, peak_kib)) = common::run_with_peak(&[
        "build",
        m,
        "--out",
        dir.to_str().unwrap(),
        "--workers",
        "1",
        "--quiet",
    ]) else {
        return;
    };
    assert_exit(&out, 0);
    assert!(
        peak_kib * 1024 < estimate,
        "peak {peak_kib} KiB, estimate {estimate} bytes"
    );
}
