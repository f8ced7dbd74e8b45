#!/usr/bin/env bash
# Builds the bettimill Python package (python/, the bettimill-python extension crate) into
# the project venv of ci/python-env.sh and runs python/tests against the cargo-built CLI.
#
# The extension is built with the dev profile (MATURIN_PEP517_ARGS; opt-level 2, the
# workspace's deps at 3) into the same CARGO_TARGET_DIR as the cargo tests, so it reuses
# their compiled crates: a minute or two instead of a release build's several. Installed
# with the venv's pinned maturin (--no-build-isolation), the way the README's
# `pip install ./python` does, so the console script and the package are the real ones.
set -euo pipefail
cd "$(dirname "$0")/.."
REPO="$(pwd)"
# The one venv both Python suites use (ci/python-env.sh makes it; BETTIMILL_VENV moves it).
VENV="${BETTIMILL_VENV:-$REPO/.venv}"

bash ci/python-env.sh
echo "python-package: building and installing ./python into $VENV (dev profile)" >&2
start=$(date +%s)
MATURIN_PEP517_ARGS="--profile dev" "$VENV/bin/uv" pip install --quiet --python "$VENV/bin/python" \
    --no-build-isolation --reinstall-package bettimill ./python
echo "python-package: installed in $(( $(date +%s) - start )) s" >&2
cargo build --quiet --locked -p bettimill-cli
target="${CARGO_TARGET_DIR:-$REPO/target}/debug"
BETTIMILL_CLI="$target/bettimill" PATH="$VENV/bin:$PATH" \
    "$VENV/bin/python" -m pytest -q -rs -p no:cacheprovider python/tests
