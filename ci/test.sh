#!/usr/bin/env bash
# The project's test command (README: "Run the tests"). CI's .ci/run calls exactly this.
# It checks formatting and lints, runs every Rust test, then the tests that need real
# outside parts: Python clients reading our shards and the Python package (both in the one
# venv of ci/python-env.sh: $BETTIMILL_VENV, default .venv, made once and reused), a
# real single-node Slurm (ci/slurm-up.sh), a local S3 server (ci/s3-up.sh), the HTML viewer
# in headless Chromium (ci/browser.sh). In CI (CI=true) those parts are installed and
# must work; locally they are installed too, so a green run here means the same as in CI.
set -euo pipefail
cd "$(dirname "$0")/.."

# A full run needs several GiB for the build and the venv; a full disk shows up later as a
# linker killed by SIGBUS, so say up front how much room there is.
echo "== disk space for the build"
df -h . "${CARGO_TARGET_DIR:-target}" 2>/dev/null || df -h .

# A run from a clean checkout builds everything once, so incremental caches only take disk
# (about a quarter of the test build's target directory).
export CARGO_INCREMENTAL=0

echo "== cargo fmt --check"
cargo fmt --all --check

echo "== cargo clippy (warnings are errors)"
cargo clippy --workspace --all-targets --locked -- -D warnings

echo "== cargo doc (warnings are errors: broken and private links fail)"
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --locked

echo "== headless Chromium for the HTML viewer's test (ci/browser.sh)"
ci/browser.sh

# The local S3 server (moto_server on loopback, ci/s3-up.sh) the object-storage tests use;
# they start it too (idempotent), so this only puts its installation and start-up here, in
# the log, before the tests. Stopped by its PID when this script ends.
echo "== local S3 server (ci/s3-up.sh)"
ci/s3-up.sh
# The disk left at the end (or at a failure) shows how close a run came to filling it.
trap 'ci/s3-down.sh; df -h . | tail -n 1' EXIT

# The system tests (a real Slurm started by ci/slurm-up.sh, tmpfs mounts as root, the
# viewer in headless Chromium) run
# only with BETTIMILL_SYSTEM_TESTS=1; a plain `cargo test` leaves them out.
echo "== cargo test, system tests included (with CI=true they fail, not skip, without Slurm or root)"
BETTIMILL_SYSTEM_TESTS=1 cargo test --workspace --locked

if [ -x ci/python-clients.sh ]; then
  echo "== Python clients"
  ci/python-clients.sh
fi

if [ -x ci/python-package.sh ]; then
  echo "== Python package (python/tests, system tests included: the local S3 server)"
  BETTIMILL_SYSTEM_TESTS=1 ci/python-package.sh
fi

echo "== all tests passed"
