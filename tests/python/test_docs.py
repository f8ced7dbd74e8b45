"""The Python snippets of docs/python.md, run as written on a real dataset.

Set BETTIMILL_DATASET to a dataset directory built by ``bettimill build`` (ci/python-clients.sh
does, for each compression). The ``python`` blocks of docs/python.md are joined in order and
executed with ``root = "demo-out"`` pointed at that directory, so the documentation cannot
drift from what the clients really do. Skipped, with a message, when the variable is unset or
the dataset has no ``train`` split with a wids index (the snippets load ``train``).
"""

import json
import os
import re
from pathlib import Path

import pytest

os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("HF_DATASETS_OFFLINE", "1")

DOC = Path(__file__).resolve().parents[2] / "docs" / "python.md"


def test_python_md_snippets_load_the_dataset(tmp_path):
    root = os.environ.get("BETTIMILL_DATASET")
    if not root:
        pytest.skip("BETTIMILL_DATASET is not set")
    root = Path(root)
    if not (root / "manifest.toml").exists():
        # The snippets batch arrays, which needs one shape per dataset: true of every
        # dataset `bettimill build` writes, not of the synthetic demo_shards example.
        pytest.skip(f"{root} was not written by `bettimill build`")
    index = json.loads((root / "index.json").read_text())
    if "train" not in {shard["split"] for shard in index["shards"]}:
        pytest.skip(f"{root} has no train split")
    if not (root / "shardindex-train.json").exists():
        pytest.skip(f"{root} has no shardindex-train.json")

    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), re.S)
    assert len(blocks) >= 4, f"{DOC}: expected the index, webdataset, HF and wids snippets"
    code = "\n".join(blocks)
    assert 'root = "demo-out"' in code, f"{DOC}: the snippets must start from root = \"demo-out\""
    code = code.replace('root = "demo-out"', f"root = {str(root)!r}")
    # wids caches next to the dataset (f"{root}-wids-cache"); keep that inside tmp_path.
    code = code.replace('cache_dir=f"{root}-wids-cache"', f"cache_dir={str(tmp_path / 'wids')!r}")
    namespace = {}
    exec(compile(code, str(DOC), "exec"), namespace)

    # The names the snippets leave behind: the DataLoader batch, the HF row's Betti
    # numbers and array field, the wids dataset and its first sample.
    images, betti_batch = namespace["images"], namespace["betti"]
    sample = namespace["sample"]
    label = sample[".json"]
    index_shape = tuple(label["shape"])
    shape = tuple(images.shape)
    assert shape[1] == 1 and shape[2:] == index_shape, f"DataLoader batch {shape}, label shape {index_shape}"
    assert isinstance(betti_batch, list) and len(betti_batch) == len(index_shape), "HF betti"
    assert namespace["field"] in ("npy", "npy.gz", "npy.zst")
    assert sample[".npy"].shape == index_shape
    assert set(sample[".npy"].ravel().tolist()) <= {0, 1}
    assert len(namespace["ds"]) == sum(s["samples"] for s in index["shards"] if s["split"] == "train")


def test_dataset_card_loader_snippet_runs_in_the_dataset(monkeypatch, capsys):
    """The ``python`` block of the dataset's own README.md (the card `bettimill build`
    writes), run as written in the dataset directory: it must load every sample of its
    split, on datasets of each member compression."""
    root = os.environ.get("BETTIMILL_DATASET")
    if not root:
        pytest.skip("BETTIMILL_DATASET is not set")
    root = Path(root)
    card = root / "README.md"
    if not card.exists():
        pytest.skip(f"{root} was not written by `bettimill build` (no dataset card)")
    blocks = re.findall(r"```python\n(.*?)```", card.read_text(), re.S)
    assert len(blocks) == 1, f"{card}: expected one python block"
    monkeypatch.chdir(root)
    exec(compile(blocks[0], str(card), "exec"), {})
    lines = capsys.readouterr().out.strip().splitlines()
    index = json.loads((root / "index.json").read_text())
    first_split = index["shards"][0]["split"]
    assert len(lines) == sum(s["samples"] for s in index["shards"] if s["split"] == first_split), lines
    assert all(line.endswith("]") for line in lines), lines  # "torch.Size([...]) [b0, ...]"
