//! Helpers shared by the test files of several crates; a dev-dependency only, never a
//! dependency of a library or of the binary.
//!
//! - [`fuzz`]: the one proptest runner of the fuzz tests (`*_fuzz.rs`), scaled by
//!   `BETTIMILL_FUZZ_CASES`, counting and reporting its executions;
//! - [`hostile`]: the hostile-manifest generator (presets with lines, values and bytes
//!   mutated), shared by the parser's fuzz test and the plan-then-build property;
//! - [`Xorshift`]: the seeded generator of the tests that do without proptest;
//! - [`in_ci`] and [`skip_unless_ci`]: a test that needs an outside tool (GNU tar, Slurm,
//!   root) fails in CI when the tool is missing, and skips with a message elsewhere;
//! - [`s3`]: the local S3 server of the object-storage tests (ci/s3-up.sh), shared or a
//!   test's own.

// A test helper: its reports go to the (captured) stderr of the test that calls it, like
// a test's own messages. Library crates of the product never print.
#![allow(clippy::print_stderr)]

pub mod hostile;
pub mod s3;

use proptest::strategy::Strategy;
use proptest::test_runner::{Config, TestCaseError, TestRunner};
use std::sync::atomic::{AtomicU64, Ordering};

/// The multiplier of every fuzz test's number of cases: `BETTIMILL_FUZZ_CASES` (default 1;
/// the longer run in docs/reliability.md uses 200).
pub fn fuzz_scale() -> u32 {
    bettimill_env::number(bettimill_env::EnvVars::BETTIMILL_FUZZ_CASES).unwrap_or(1)
}

/// Runs `cases * fuzz_scale()` inputs from `strategy` through `check` (no failure
/// persistence: every run is self-contained), panics with `name` and the minimal failing
/// input on the first failure, prints the number of executions and returns it.
pub fn fuzz<S: Strategy>(
    name: &str,
    cases: u32,
    strategy: S,
    check: impl Fn(S::Value) -> Result<(), TestCaseError>,
) -> u64 {
    let count = AtomicU64::new(0);
    let mut runner = TestRunner::new(Config {
        cases: cases * fuzz_scale(),
        failure_persistence: None,
        ..Config::default()
    });
    let result = runner.run(&strategy, |value| {
        count.fetch_add(1, Ordering::Relaxed);
        check(value)
    });
    if let Err(err) = result {
        panic!("{name}: {err}");
    }
    let n = count.into_inner();
    eprintln!("fuzz {name}: {n} executions");
    n
}

/// A seeded xorshift64* generator: the same inputs on every run, so a failure is named by
/// its seed. The state must not be zero.
#[derive(Clone, Debug)]
pub struct Xorshift(pub u64);

impl Xorshift {
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// A number in `0..n` (0 when `n` is 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }

    /// `n` random bytes.
    pub fn bytes(&mut self, n: usize) -> Vec<u8> {
        (0..n).map(|_| self.next_u64() as u8).collect()
    }
}

/// Whether this run is CI (`CI=true` or `CI=1`).
pub fn in_ci() -> bool {
    bettimill_env::var(bettimill_env::EnvVars::CI).is_some_and(|v| v == "true" || v == "1")
}

/// What a test does when something it needs from outside (`what`: GNU tar, Slurm, root)
/// is unavailable for `reason`: in CI it fails (panics), elsewhere it prints a SKIPPED
/// line, and the caller returns.
#[track_caller]
pub fn skip_unless_ci(what: &str, reason: &str) {
    assert!(
        !in_ci(),
        "{what} is required in CI (CI=true) but unavailable: {reason}"
    );
    eprintln!("SKIPPED: {what} is unavailable ({reason}); CI runs this test for real");
}

/// The variable that turns the system tests on: `BETTIMILL_SYSTEM_TESTS=1`.
pub const SYSTEM_TESTS: &str = bettimill_env::EnvVars::BETTIMILL_SYSTEM_TESTS;

/// Whether the system tests run: those that install packages, start daemons (Slurm),
/// mount file systems or need root. Only with `BETTIMILL_SYSTEM_TESTS=1`, which
/// `ci/test.sh` sets, so that a plain `cargo test` reads and writes temporary directories
/// only; once on, a system test whose tool is missing fails in CI as any other
/// ([`skip_unless_ci`]).
pub fn system_tests() -> bool {
    bettimill_env::var(SYSTEM_TESTS).is_some_and(|v| v == "1")
}

/// What a system test (`what`: what it needs) does first: `true` when the system tests
/// run ([`system_tests`]); otherwise it prints a SKIPPED line naming the variable that
/// turns it on, and the caller returns.
#[track_caller]
pub fn system_test(what: &str) -> bool {
    if system_tests() {
        return true;
    }
    eprintln!("SKIPPED: {what}: a system test, run with {SYSTEM_TESTS}=1 (ci/test.sh sets it)");
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn xorshift_is_the_xorshift64_star_sequence() {
        let mut rng = Xorshift(1);
        // x ^= x >> 12 (1), x ^= x << 25 (1 + 2^25), x ^= x >> 27 (unchanged), times M.
        let x: u64 = 1 + (1 << 25);
        assert_eq!(rng.next_u64(), x.wrapping_mul(0x2545_F491_4F6C_DD1D));
        assert!(rng.below(0) == 0 && rng.below(1) == 0);
        assert_eq!(rng.bytes(5).len(), 5);
    }

    #[test]
    fn fuzz_runs_every_case_and_fails_on_a_failing_check() {
        assert_eq!(
            fuzz("all pass", 50, 0u8..10, |_| Ok(())),
            50 * fuzz_scale() as u64
        );
        let failed = std::panic::catch_unwind(|| {
            fuzz("one fails", 50, 0u8..10, |v| {
                proptest::prop_assert!(v < 5);
                Ok(())
            })
        });
        let message = failed.unwrap_err();
        let message = message.downcast_ref::<String>().unwrap();
        assert!(message.starts_with("one fails: "), "{message}");
    }
}
