//! The environment variables (one documented constant each) and their readers.

/// The names of the environment variables bettimill reads. Internal ones (test hooks and
/// the test suite's settings) are marked so and hidden from the documentation.
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

    /// Internal, the test suite: the multiplier of every fuzz test's number of cases.
    #[doc(hidden)]
    pub const BETTIMILL_FUZZ_CASES: &'static str = "BETTIMILL_FUZZ_CASES";

    /// Internal, the test suite: `1` runs the system tests (those that install packages,
    /// start daemons, mount file systems or need root); `ci/test.sh` sets it.
    #[doc(hidden)]
    pub const BETTIMILL_SYSTEM_TESTS: &'static str = "BETTIMILL_SYSTEM_TESTS";

    /// Internal, the test suite: `true` or `1` in CI, where a test whose outside tool is
    /// missing fails instead of skipping.
    #[doc(hidden)]
    pub const CI: &'static str = "CI";
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
