"""The package snippets of docs/python.md (its ``py`` blocks) and the manifest of the
README, run as written from an empty temporary directory (so they need no clone of the
repository: presets are built in). The ``python`` blocks, which read built datasets, are
tests/python's.

In a ``py`` block every ``print(...)`` carries a comment ``# -> OUTPUT`` that is exactly
what it prints, so the documentation shows true output."""

import re

import pytest

import bettimill
from conftest import REPO

DOC = REPO / "docs" / "python.md"
README = REPO / "README.md"
BLOCKS = re.findall(r"```py\n(.*?)```", DOC.read_text(), re.S)
SHOWN = re.compile(r"^\s*print\(.*\)\s*# -> (.*)$")


def test_there_are_package_snippets():
    assert len(BLOCKS) >= 4


@pytest.mark.parametrize("number", range(len(BLOCKS)))
def test_snippet_runs_from_anywhere_and_prints_what_it_says(tmp_path, monkeypatch, number):
    block = BLOCKS[number]
    monkeypatch.chdir(tmp_path)
    promised = []
    for line in block.splitlines():
        if re.match(r"^\s*print\(", line):
            shown = SHOWN.match(line)
            assert shown, f"py block {number + 1}: a print without '# -> OUTPUT': {line}"
            promised.append(shown.group(1).strip())
    printed = []

    def record(*args, sep=" ", end="\n"):
        printed.append(sep.join(map(str, args)))

    exec(compile(block, f"{DOC} py block {number + 1}", "exec"), {"print": record})
    assert printed == promised


def test_readme_manifest_builds_a_plan(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    blocks = re.findall(r"```toml\n(.*?)```", README.read_text(), re.S)
    assert blocks, "README.md shows a manifest in a ```toml block"
    for block in blocks:
        plan = bettimill.Plan(block)
        assert len(plan) > 0 and plan.strata
