"""The package snippets of docs/python.md (its ``py`` blocks), run as written from the
repository root; the ``python`` blocks, which read built datasets, are tests/python's."""

import re

import pytest

from conftest import REPO

DOC = REPO / "docs" / "python.md"
BLOCKS = re.findall(r"```py\n(.*?)```", DOC.read_text(), re.S)


def test_there_are_package_snippets():
    assert len(BLOCKS) >= 4


@pytest.mark.parametrize("number", range(len(BLOCKS)))
def test_snippet_runs_as_written(monkeypatch, number):
    monkeypatch.chdir(REPO)
    exec(compile(BLOCKS[number], f"{DOC} py block {number + 1}", "exec"), {})
