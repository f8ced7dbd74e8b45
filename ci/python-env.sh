#!/usr/bin/env bash
# Creates (or brings up to date) the Python environment that tests/python runs in:
# $REPO/.venv with the exact packages of ci/python-requirements.txt (numpy, torch,
# webdataset, wids, HF datasets, zstandard, pytest and their dependencies).
#
# Safe to re-run: `uv pip sync` is a no-op (about a second) when the venv already holds
# exactly these packages, and the import smoke test only runs when the requirements file
# changed since the last success (a stamp in the venv holds its sha256).
#
# Installation uses uv (pinned, installed from PyPI into the venv itself) because it
# downloads in parallel and links from its cache. Measured on a 2-core machine: about 2 min
# with a cold cache (about 3.2 GB of wheels, most of it the nvidia-* libraries that PyPI's
# torch wheel links against; PyPI has no CPU-only x86_64 torch), a few seconds with a warm
# cache, against about 4.5 min for plain pip.
#
# Environment: REPO (default: this script's repository), BETTIMILL_VENV (default
# $REPO/.venv), PYTHON (default python3, must be >= 3.10), UV_CACHE_DIR (uv's default
# cache, ~/.cache/uv, if unset).
set -euo pipefail

REPO="${REPO:-$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)}"
VENV="${BETTIMILL_VENV:-$REPO/.venv}"
PYTHON="${PYTHON:-python3}"
REQUIREMENTS="$REPO/ci/python-requirements.txt"
UV_VERSION="0.13.8"
STAMP="$VENV/.bettimill-requirements.sha256"

say() { echo "python-env: $*" >&2; }

want="$(sha256sum "$REQUIREMENTS" | cut -d' ' -f1)"
start=$(date +%s)
if ! "$PYTHON" -c 'import sys; sys.exit(sys.version_info < (3, 10))'; then
    say "$PYTHON is $("$PYTHON" --version 2>&1); Python >= 3.10 is needed"
    exit 1
fi
if [[ ! -x "$VENV/bin/python" ]]; then
    say "creating $VENV with $("$PYTHON" --version 2>&1)"
    "$PYTHON" -m venv "$VENV"
else
    say "reusing $VENV"
fi

if [[ "$("$VENV/bin/uv" --version 2>/dev/null || true)" != "uv $UV_VERSION"* ]]; then
    say "installing uv $UV_VERSION into the venv (pip)"
    # `uv pip sync` removes pip from the venv (it is not in the requirements), so bring it
    # back if an earlier run left a venv without uv.
    "$VENV/bin/python" -m pip --version >/dev/null 2>&1 || "$VENV/bin/python" -m ensurepip --upgrade >&2
    "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps "uv==$UV_VERSION"
fi

say "installing ci/python-requirements.txt with uv (exact versions; removes anything else)"
"$VENV/bin/uv" pip sync --python "$VENV/bin/python" --no-progress "$REQUIREMENTS"

if [[ -f "$STAMP" && "$(cat "$STAMP")" == "$want" ]]; then
    say "$VENV matches ci/python-requirements.txt (sha256 ${want:0:12}); nothing else to do"
    exit 0
fi
say "checking the imports and a torch DataLoader with num_workers=2"
"$VENV/bin/python" - <<'PY'
import numpy, torch, webdataset, wids, datasets, zstandard, pytest, s3fs
from torch.utils.data import DataLoader

seen = sorted(int(x) for batch in DataLoader(list(range(10)), batch_size=3, num_workers=2) for x in batch)
assert seen == list(range(10)), seen
import sys
print(f"python-env: torch {torch.__version__} (cuda available: {torch.cuda.is_available()}), "
      f"numpy {numpy.__version__}, webdataset {webdataset.__version__}, datasets {datasets.__version__}", file=sys.stderr)
PY
echo "$want" > "$STAMP"
say "ready in $(( $(date +%s) - start )) s: activate with 'source $VENV/bin/activate'"
