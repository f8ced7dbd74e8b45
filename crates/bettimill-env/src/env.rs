//! The environment variables (one documented constant each) and their readers.

/// The names of the environment variables bettimill reads, and its tests, examples and ci/
/// scripts too: the one list of them. Internal ones (test hooks, the settings of the tests
/// and scripts) are marked so, say who reads them, and are hidden from the documentation.
pub struct EnvVars;

impl EnvVars {
    /// Slurm: the array task's index (0-based), read by `worker --task-index-from-env`.
    pub const SLURM_ARRAY_TASK_ID: &'static str = "SLURM_ARRAY_TASK_ID";

    /// Kubernetes Indexed Jobs: the pod's completion index (0-based), read by
    /// `worker --task-index-from-env`.
    pub const JOB_COMPLETION_INDEX: &'static str = "JOB_COMPLETION_INDEX";

    /// PBS: the array task's index (0-based), read by `worker --task-index-from-env`.
    pub const PBS_ARRAY_INDEX: &'static str = "PBS_ARRAY_INDEX";

    /// SGE: the array task's index (1-based; `undefined` counts as unset), read by
    /// `worker --task-index-from-env`.
    pub const SGE_TASK_ID: &'static str = "SGE_TASK_ID";

    /// LSF: the array task's index (1-based), read by `worker --task-index-from-env`.
    pub const LSB_JOBINDEX: &'static str = "LSB_JOBINDEX";

    /// Slurm: set inside a job; there the job's cgroup memory limit replaces MemAvailable
    /// as the default memory limit.
    pub const SLURM_JOB_ID: &'static str = "SLURM_JOB_ID";

    /// Slurm: the job's memory per node in MiB (`--mem`), the default memory limit inside
    /// a job.
    pub const SLURM_MEM_PER_NODE: &'static str = "SLURM_MEM_PER_NODE";

    /// Slurm: the job's memory per CPU in MiB (`--mem-per-cpu`), times
    /// [`EnvVars::SLURM_CPUS_ON_NODE`], the default memory limit inside a job without
    /// [`EnvVars::SLURM_MEM_PER_NODE`].
    pub const SLURM_MEM_PER_CPU: &'static str = "SLURM_MEM_PER_CPU";

    /// Slurm: the job's CPUs on this node (multiplies [`EnvVars::SLURM_MEM_PER_CPU`]).
    pub const SLURM_CPUS_ON_NODE: &'static str = "SLURM_CPUS_ON_NODE";

    /// Object storage (`s3://` outputs and datasets): the access key id.
    pub const AWS_ACCESS_KEY_ID: &'static str = "AWS_ACCESS_KEY_ID";

    /// Object storage: the secret access key.
    pub const AWS_SECRET_ACCESS_KEY: &'static str = "AWS_SECRET_ACCESS_KEY";

    /// Object storage: the session token of temporary credentials.
    pub const AWS_SESSION_TOKEN: &'static str = "AWS_SESSION_TOKEN";

    /// Object storage: the region (default [`EnvVars::AWS_DEFAULT_REGION`], then
    /// `us-east-1`).
    pub const AWS_REGION: &'static str = "AWS_REGION";

    /// Object storage: the region when [`EnvVars::AWS_REGION`] is unset.
    pub const AWS_DEFAULT_REGION: &'static str = "AWS_DEFAULT_REGION";

    /// Object storage: the server's base URL, for S3-compatible servers (MinIO, R2, Garage,
    /// Hugging Face Buckets); `--endpoint` overrides it. Unset: AWS S3.
    pub const AWS_ENDPOINT_URL: &'static str = "AWS_ENDPOINT_URL";

    /// Internal test hook: the array task with this index fails before doing any work (exit
    /// code 2, as any failed task).
    #[doc(hidden)]
    pub const BETTIMILL_TEST_FAIL_TASK: &'static str = "BETTIMILL_TEST_FAIL_TASK";

    /// Internal test hook: every attempt at the shard with this index fails (nothing is
    /// written).
    #[doc(hidden)]
    pub const BETTIMILL_TEST_FAIL_SHARD: &'static str = "BETTIMILL_TEST_FAIL_SHARD";

    /// Internal test hook: the version a served worker claims in its handshake, to exercise
    /// the coordinator's mismatch message with real processes.
    #[doc(hidden)]
    pub const BETTIMILL_TEST_WORKER_VERSION: &'static str = "BETTIMILL_TEST_WORKER_VERSION";

    /// Internal test hook: seconds a shard's atomic write waits between its durable
    /// temporary file and the rename, so tests can kill a build in exactly that window.
    #[doc(hidden)]
    pub const BETTIMILL_TEST_PAUSE_BEFORE_RENAME: &'static str =
        "BETTIMILL_TEST_PAUSE_BEFORE_RENAME";

    /// Internal test hook: seconds a build waits once its directory is bound, before any
    /// worker starts, so a test can signal it in the middle of start-up.
    #[doc(hidden)]
    pub const BETTIMILL_TEST_PAUSE_AT_STARTUP: &'static str = "BETTIMILL_TEST_PAUSE_AT_STARTUP";

    /// Internal, read by the test suite: the multiplier of every fuzz test's number of cases.
    #[doc(hidden)]
    pub const BETTIMILL_FUZZ_CASES: &'static str = "BETTIMILL_FUZZ_CASES";

    /// Internal, read by the test suite and the Python tests: `1` runs the system tests
    /// (those that install packages, start daemons, mount file systems or need root);
    /// `ci/test.sh` sets it.
    #[doc(hidden)]
    pub const BETTIMILL_SYSTEM_TESTS: &'static str = "BETTIMILL_SYSTEM_TESTS";

    /// Internal, read by the test suite, the Python tests and ci/slurm-test.sh: `true` (or
    /// `1`, in the Rust tests) in CI, where a test whose outside tool is missing fails
    /// instead of skipping.
    #[doc(hidden)]
    pub const CI: &'static str = "CI";

    /// Internal, read by the test suite: the cargo that runs the tests (Cargo sets it), which the
    /// tidy checks ask for the workspace's metadata.
    #[doc(hidden)]
    pub const CARGO: &'static str = "CARGO";

    /// Internal, read by the test suite (`tests/common`) and ci/slurm-test.sh: `1` makes a
    /// test that needs Slurm fail instead of skipping when Slurm is unavailable, outside CI
    /// too.
    #[doc(hidden)]
    pub const BETTIMILL_SLURM_REQUIRED: &'static str = "BETTIMILL_SLURM_REQUIRED";

    /// Internal, read by the test suite (`tests/viewer.rs`): the browser that renders the
    /// HTML viewer (default `chromium`).
    #[doc(hidden)]
    pub const BETTIMILL_CHROMIUM: &'static str = "BETTIMILL_CHROMIUM";

    /// Internal, read by the test suite (`tests/reliability.rs`): the number of kills of
    /// the long soak; unset, the short one runs.
    #[doc(hidden)]
    pub const BETTIMILL_SOAK_KILLS: &'static str = "BETTIMILL_SOAK_KILLS";

    /// Internal, read by the test suite (`tests/cli_ux.rs`): set, the CLI's snapshots are
    /// rewritten instead of compared.
    #[doc(hidden)]
    pub const UPDATE_SNAPSHOTS: &'static str = "UPDATE_SNAPSHOTS";

    /// Internal, read by the test suite (bettimill-sample's plan-then-build property): set,
    /// the manifests the plan refuses are printed with the reason.
    #[doc(hidden)]
    pub const SHOW_REFUSALS: &'static str = "SHOW_REFUSALS";

    /// Internal, read by bettimill-shapes' `shape_report` example: the number of shapes
    /// whose rate it measures.
    #[doc(hidden)]
    pub const SHAPES_RATE_COUNT: &'static str = "SHAPES_RATE_COUNT";

    /// Internal, read by the Python tests (`python/tests/conftest.py`): the `bettimill`
    /// binary the CLI tests run (default: the one on `PATH`).
    #[doc(hidden)]
    pub const BETTIMILL_CLI: &'static str = "BETTIMILL_CLI";

    /// Internal, read by ci/s3-up.sh, ci/s3-down.sh and the Python tests: the local S3
    /// server's directory (PID file, variables file, log; default `/tmp/bettimill-s3`); the
    /// test suite sets it for a server of a test's own.
    #[doc(hidden)]
    pub const S3_CI_DIR: &'static str = "S3_CI_DIR";

    /// Internal, read by ci/s3-up.sh: the local S3 server's port on 127.0.0.1 (default
    /// 29768).
    #[doc(hidden)]
    pub const S3_CI_PORT: &'static str = "S3_CI_PORT";

    /// Internal, read by ci/s3-up.sh: `1` keeps the local S3 server's objects across a
    /// restart (default 0).
    #[doc(hidden)]
    pub const S3_CI_KEEP: &'static str = "S3_CI_KEEP";

    /// Internal, read by ci/s3-up.sh: the local S3 server's virtual environment (default
    /// `REPO/.venv-s3`).
    #[doc(hidden)]
    pub const S3_CI_VENV: &'static str = "S3_CI_VENV";

    /// Internal, read by ci/slurm-up.sh, ci/slurm-smoke.sh, ci/slurm-down.sh: the local
    /// Slurm's directory (configuration, state, logs; default `/tmp/slurm`).
    #[doc(hidden)]
    pub const SLURM_CI_DIR: &'static str = "SLURM_CI_DIR";

    /// Internal, read by ci/slurm-up.sh: seconds to wait for the local Slurm node to become
    /// idle (default 60).
    #[doc(hidden)]
    pub const SLURM_CI_WAIT: &'static str = "SLURM_CI_WAIT";

    /// Internal, read by ci/slurm-up.sh: the local Slurm's partition name (default
    /// `debug`).
    #[doc(hidden)]
    pub const SLURM_CI_PARTITION: &'static str = "SLURM_CI_PARTITION";

    /// Internal, read by ci/slurm-up.sh: the local Slurm's MinJobAge, seconds a finished
    /// job stays visible.
    #[doc(hidden)]
    pub const SLURM_CI_MIN_JOB_AGE: &'static str = "SLURM_CI_MIN_JOB_AGE";

    /// Internal, read by ci/slurm-smoke.sh: seconds per `sbatch --wait` (default 120).
    #[doc(hidden)]
    pub const SLURM_SMOKE_TIMEOUT: &'static str = "SLURM_SMOKE_TIMEOUT";

    /// Internal, read by ci/slurm-smoke.sh's job script, set by Slurm: the array job's id.
    #[doc(hidden)]
    pub const SLURM_ARRAY_JOB_ID: &'static str = "SLURM_ARRAY_JOB_ID";

    /// Internal, read by ci/slurm-smoke.sh's job script, set by Slurm: the array's number
    /// of tasks.
    #[doc(hidden)]
    pub const SLURM_ARRAY_TASK_COUNT: &'static str = "SLURM_ARRAY_TASK_COUNT";

    /// Internal, read by ci/slurm-smoke.sh's job script, set by Slurm: the array's lowest
    /// task index.
    #[doc(hidden)]
    pub const SLURM_ARRAY_TASK_MIN: &'static str = "SLURM_ARRAY_TASK_MIN";

    /// Internal, read by ci/slurm-smoke.sh's job script, set by Slurm: the array's highest
    /// task index.
    #[doc(hidden)]
    pub const SLURM_ARRAY_TASK_MAX: &'static str = "SLURM_ARRAY_TASK_MAX";

    /// Internal, read by ci/ scripts (test.sh, soak.sh, python-package.sh, python-
    /// clients.sh, bench-lib.sh): Cargo's target directory, where they find the built
    /// binary (default `target`).
    #[doc(hidden)]
    pub const CARGO_TARGET_DIR: &'static str = "CARGO_TARGET_DIR";

    /// Internal, read by ci/python-env.sh, python-package.sh, python-clients.sh: the Python
    /// virtual environment (default `REPO/.venv`).
    #[doc(hidden)]
    pub const BETTIMILL_VENV: &'static str = "BETTIMILL_VENV";

    /// Internal, read by ci/python-env.sh and ci/s3-up.sh: the Python that makes a virtual
    /// environment (default `python3`).
    #[doc(hidden)]
    pub const PYTHON: &'static str = "PYTHON";

    /// Internal, read by ci/python-env.sh: the repository (default: the script's own).
    #[doc(hidden)]
    pub const REPO: &'static str = "REPO";

    /// Internal, read by ci/python-clients.sh: a dataset directory to run the client tests
    /// on instead of building the demos.
    #[doc(hidden)]
    pub const BETTIMILL_DATASET: &'static str = "BETTIMILL_DATASET";

    /// Internal, read by ci/bench-lib.sh (the benchmark scripts): the `bettimill` binary to
    /// time (default: a fresh build).
    #[doc(hidden)]
    pub const BETTIMILL: &'static str = "BETTIMILL";

    /// Internal, read by ci/calibrate-plan.sh: which cases run (`quick`, `extra`, `all`).
    #[doc(hidden)]
    pub const CASES: &'static str = "CASES";

    /// Internal, read by ci/soak.sh: the seed of the kill times and signals (default 2026).
    #[doc(hidden)]
    pub const SOAK_SEED: &'static str = "SOAK_SEED";

    /// Internal, read by ci/soak.sh: the build's worker count (default 2).
    #[doc(hidden)]
    pub const SOAK_WORKERS: &'static str = "SOAK_WORKERS";

    /// Internal, read by ci/soak.sh: the demo manifests it builds (default `demo-2d demo-3d
    /// demo-4d`).
    #[doc(hidden)]
    pub const SOAK_DEMOS: &'static str = "SOAK_DEMOS";

    /// Internal, read by ci/soak.sh: `1` (the default, as root) adds the disk-full rounds.
    #[doc(hidden)]
    pub const SOAK_DISK_FULL: &'static str = "SOAK_DISK_FULL";

    /// Internal, read by ci/soak.sh: the number of disk-full rounds (default 10).
    #[doc(hidden)]
    pub const SOAK_DISK_FULL_ROUNDS: &'static str = "SOAK_DISK_FULL_ROUNDS";
}

/// The names of the set variables that start with `prefix` (for a test that clears a
/// scheduler's variables from a child's environment).
pub fn names_starting_with(prefix: &str) -> Vec<String> {
    let mut names: Vec<String> = std::env::vars_os()
        .filter_map(|(name, _)| name.into_string().ok())
        .filter(|name| name.starts_with(prefix))
        .collect();
    names.sort();
    names
}

/// The value of the variable `name`, or `None` when it is unset or not Unicode.
pub fn var(name: &str) -> Option<String> {
    std::env::var(name).ok()
}

/// The variable `name` parsed as a number; `None` when it is unset or does not parse.
pub fn number<T: std::str::FromStr>(name: &str) -> Option<T> {
    var(name)?.parse().ok()
}

/// The variable `name` as a positive, finite number of seconds; `None` otherwise.
pub fn seconds(name: &str) -> Option<std::time::Duration> {
    number::<f64>(name)
        .filter(|s| s.is_finite() && *s > 0.0)
        .map(std::time::Duration::from_secs_f64)
}
