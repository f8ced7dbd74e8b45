"""The dataset card is one the Hugging Face Hub and `datasets` understand.

`datasets.load_dataset(DIR)` with no other argument reads the card's YAML front matter
(`configs` with `data_files` per split) and must load every split of a built dataset with
every sample, on each member compression. It runs in a child process with its own HF_HOME
(the cache goes to the test's temporary directory, not the user's) and offline.
"""

import json
import os
import subprocess
import sys

import pytest

from conftest import run_cli

LOAD = """
import json, sys
from datasets import load_dataset

ds = load_dataset(sys.argv[1])
row = ds["train"][0]
print(json.dumps({
    "splits": {name: len(split) for name, split in ds.items()},
    "columns": sorted(row),
    "betti": row["json"]["betti"],
    "field": next(k for k in row if k.startswith("npy")),
    "shape": list(__import__("numpy").asarray(row[next(k for k in row if k.startswith("npy"))]).shape),
    "label_shape": row["json"]["shape"],
}))
"""


@pytest.mark.parametrize("compression", ["none", "gzip", "zstd"])
def test_load_dataset_of_the_directory_loads_every_split(cli, tmp_path, compression):
    manifest = tmp_path / "hub.toml"
    manifest.write_text(
        f"""schema_version = 1
name = "hub2d{compression}"
dimension = 2
side = 16
mode = ["embed", "carve"]
samples = 20
shard_size = 4
seed = 11
compression = "{compression}"

[splits]
train = 10
holdout = 6
test = 4

[[classes]]
family = "ball"

[[classes]]
family = "handle"
"""
    )
    out = tmp_path / "out"
    run_cli(cli, "build", manifest, "--quiet", "--out", out)
    card = (out / "README.md").read_text()
    assert card.startswith("---\nlicense: "), card[:200]

    env = dict(os.environ, HF_HOME=str(tmp_path / "hf"), HF_HUB_OFFLINE="1", HF_DATASETS_OFFLINE="1")
    result = subprocess.run(
        [sys.executable, "-c", LOAD, str(out)], capture_output=True, text=True, env=env, cwd=tmp_path
    )
    assert result.returncode == 0, result.stderr[-4000:]
    loaded = json.loads(result.stdout.strip().splitlines()[-1])

    index = json.loads((out / "index.json").read_text())
    expected = {}
    for shard in index["shards"]:
        expected[shard["split"]] = expected.get(shard["split"], 0) + shard["samples"]
    assert loaded["splits"] == expected == {"train": 10, "holdout": 6, "test": 4}
    assert {"cls", "json", loaded["field"]} <= set(loaded["columns"])
    assert loaded["field"] == {"none": "npy", "gzip": "npy.gz", "zstd": "npy.zst"}[compression]
    assert len(loaded["betti"]) == 2
    assert loaded["shape"] == loaded["label_shape"] == [16, 16]
