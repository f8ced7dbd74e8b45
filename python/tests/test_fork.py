"""The package in DataLoader workers under fork, spawn and forkserver, after the parent has
already used it (its thread pool then exists in the parent, and a forked child has none of
its threads). Each case runs in its own interpreter with a timeout, so a hang fails the
test instead of stopping the suite."""

import json
import os
import signal
import subprocess
import sys

import pytest

TIMEOUT = 300

MANIFEST = """\
schema_version = 1
name = "fork{dimension}d"
dimension = {dimension}
side = {side}
mode = ["embed", "carve"]
samples = 8
shard_size = 8
seed = 3

[[classes]]
family = ["ball", "handle"]
"""

SCRIPT = r"""
import json, sys
import numpy as np
import torch
import bettimill
from bettimill.torch import SyntheticDataset, betti_targets

text, context = sys.argv[1], sys.argv[2]
plan = bettimill.Plan(text)
# The parent uses the package first: a sample, and Betti numbers of a 4D array, each on the
# package's threads.
expected = [plan.sample(i) for i in range(len(plan))]
assert bettimill.betti(np.ones((9, 9, 9, 9), np.uint8)) == [1, 0, 0, 0]
threads_before = bettimill.threads()
dataset = SyntheticDataset(plan, transform=betti_targets)
loader = torch.utils.data.DataLoader(dataset, batch_size=3, num_workers=2, multiprocessing_context=context)
images, betti = zip(*loader)
images, betti = torch.cat(images), torch.cat(betti)
same = all(torch.equal(images[i, 0], torch.from_numpy(v).float()) and betti[i].tolist() == l["betti"]
           for i, (v, l) in enumerate(expected))
# And the parent still works after its workers are gone.
after = bettimill.betti(np.ones((5, 5, 5, 5), np.uint8))
print(json.dumps({"samples": len(images), "same": same, "after": after, "threads": threads_before}))
"""


@pytest.mark.parametrize("context", ["fork", "spawn", "forkserver"])
@pytest.mark.parametrize("dimension,side", [(2, 32), (3, 32), (4, 16)])
def test_dataloader_workers_after_the_parent_used_the_package(dimension, side, context):
    text = MANIFEST.format(dimension=dimension, side=side)
    child = subprocess.Popen(
        [sys.executable, "-c", SCRIPT, text, context],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        out, err = child.communicate(timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        # The interpreter and its DataLoader workers share the new session's group.
        os.killpg(child.pid, signal.SIGKILL)
        out, err = child.communicate()
        pytest.fail(f"{dimension}D under {context}: no answer in {TIMEOUT} s (a worker hangs)\n{err[-2000:]}")
    assert child.returncode == 0, err
    result = json.loads(out.strip().splitlines()[-1])
    assert result == {"samples": 8, "same": True, "after": [1, 0, 0, 0], "threads": result["threads"]}
    assert result["threads"] >= 1


def test_set_threads_applies_and_is_reported():
    import bettimill

    try:
        assert bettimill.set_threads(1) == 1
        assert bettimill.threads() == 1
        assert bettimill.betti([[0, 1, 0], [1, 0, 1], [0, 1, 0]]) == [1, 1]  # a diagonal ring
        assert bettimill.set_threads(3) == 3
    finally:
        bettimill.set_threads(0)
        bettimill._threads_chosen = False
