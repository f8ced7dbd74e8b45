"""Shared fixtures of python/tests: the repository, and the real `bettimill` CLI.

The CLI the tests compare against is the cargo-built binary named by BETTIMILL_CLI
(ci/test.sh sets it), else the `bettimill` on PATH. With CI=true a missing CLI fails the
tests that need it, as the project's rule for outside tools says; locally they skip.
"""

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
MANIFESTS = Path(__file__).resolve().parent / "manifests"


def _cli_path():
    path = os.environ.get("BETTIMILL_CLI") or shutil.which("bettimill")
    if path and Path(path).is_file():
        return path
    message = "no bettimill CLI: set BETTIMILL_CLI to the cargo-built binary"
    if os.environ.get("CI") == "true":
        pytest.fail(message)
    pytest.skip(message)


@pytest.fixture(scope="session")
def cli():
    return _cli_path()


def run_cli(cli, *args, check=True):
    result = subprocess.run([cli, *map(str, args)], capture_output=True, text=True)
    if check and result.returncode != 0:
        raise AssertionError(f"bettimill {' '.join(map(str, args))}: exit {result.returncode}\n{result.stderr}")
    return result


def cli_betti_json(cli, path):
    return json.loads(run_cli(cli, "betti", path, "--json").stdout)


@pytest.fixture(scope="session")
def built(cli, tmp_path_factory):
    """Builds a manifest with the CLI once per session: built(path) -> dataset directory."""
    root = tmp_path_factory.mktemp("built")
    cache = {}

    def build(manifest):
        manifest = Path(manifest)
        if manifest not in cache:
            out = root / manifest.stem
            run_cli(cli, "build", manifest, "--quiet", "--out", out)
            cache[manifest] = out
        return cache[manifest]

    return build
