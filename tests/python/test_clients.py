"""A bettimill dataset read by the real Python clients.

Set BETTIMILL_DATASET to a dataset directory (``index.json`` plus ``shards/*.tar``, and
optionally ``*shardindex*.json`` wids indexes). Every test is skipped, with a message saying
so, only when the variable is unset; when it is set, a missing or broken dataset fails.

Run inside the environment ``ci/python-env.sh`` creates::

    bash ci/python-env.sh
    cargo run -p bettimill-shard --example demo_shards -- /tmp/demo --compression zstd
    BETTIMILL_DATASET=/tmp/demo .venv/bin/python -m pytest tests/python

What is checked, for every sample of every split listed in ``index.json``:

- webdataset.WebDataset(...).decode() feeding a torch DataLoader with num_workers=2 yields
  every sample exactly once; the array is uint8, 0/1, with the shape in the sample's JSON;
  ``betti`` is a list of non-negative ints whose alternating sum is ``euler``; ``.cls`` is
  an int.
- HF ``datasets.load_dataset("webdataset", data_files=...)`` loads every split with the
  right row count and arrays.
- GNU tar lists each shard with the members of the index, in order, read-only and owned by
  ``bettimill``, and extracts them; numpy.load reads every extracted array.
- Each wids index opens with ``wids.ShardListDataset`` and indexes every sample.

Compressed members: ``KEY.npy.gz`` is decompressed by webdataset, wids and HF datasets on
their own. ``KEY.npy.zst`` is decompressed by HF datasets (with ``zstandard`` installed)
but left as raw bytes by webdataset 1.0.2 and wids 0.1.11; for those, add the one-line
handler :func:`zst_handler` (webdataset: ``.decode(zst_handler)``; wids: see
:func:`wids_transform`).
"""

import collections
import gzip
import io
import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

# Everything here is local; never let the HF libraries try the network.
os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("HF_DATASETS_OFFLINE", "1")

import numpy as np  # noqa: E402
import zstandard  # noqa: E402

DATASET_VAR = "BETTIMILL_DATASET"
NPY_FIELDS = ("npy", "npy.gz", "npy.zst")


def zst_handler(key, data):
    """webdataset handler for ``.zst`` members: decompress, then let the default
    decoders see the inner extension (so ``KEY.npy.zst`` becomes a numpy array)."""
    import webdataset

    if key.endswith(".zst"):
        return webdataset.autodecode.Continue(key[: -len(".zst")], zstandard.ZstdDecompressor().decompress(data))
    return None


def decompress_member(name, data):
    """Bytes of a member with its ``.gz`` / ``.zst`` compression removed."""
    if name.endswith(".gz"):
        return gzip.decompress(data)
    if name.endswith(".zst"):
        return zstandard.ZstdDecompressor().decompress(data)
    return data


def member_key(name):
    """WebDataset key of a member name: up to the first dot of the last component."""
    head, _, last = name.rpartition("/")
    base = last.split(".", 1)[0]
    return f"{head}/{base}" if head else base


class Dataset:
    """The dataset directory and its index, with the expectations derived from it."""

    def __init__(self, root):
        self.root = root
        index_path = root / "index.json"
        assert index_path.is_file(), f"{DATASET_VAR}={root}: no index.json there"
        self.index = json.loads(index_path.read_text())
        assert self.index.get("format") == "bettimill-index", f"{index_path}: format is {self.index.get('format')!r}"
        assert self.index["shards"], f"{index_path}: lists no shards"
        self.splits = collections.OrderedDict()
        for shard in self.index["shards"]:
            path = root / shard["name"]
            assert path.is_file(), f"{path}: listed in index.json but missing"
            assert path.stat().st_size == shard["bytes"], f"{path}: size differs from index.json"
            # index.json (format version 3) lists shards; each shard's members (name, offset,
            # bytes, blake3) are in its completion record, records/NAME.json.
            stem = shard["name"].removeprefix("shards/").removesuffix(".tar")
            record = json.loads((root / "records" / f"{stem}.json").read_text())
            assert record["shard"]["name"] == shard["name"], f"{stem}: record of another shard"
            assert record["shard"]["blake3"] == shard["blake3"], f"{stem}: record and index.json disagree"
            shard["members"] = record["shard"]["members"]
            self.splits.setdefault(shard["split"], []).append(shard)

    def shard_paths(self, split):
        return [str(self.root / shard["name"]) for shard in self.splits[split]]

    def expected_keys(self, split):
        """Sample keys of a split in shard order, as readers group members."""
        return [key for shard in self.splits[split] for key in shard_keys(shard)]


def shard_keys(shard):
    """Sample keys of one shard record, grouping consecutive members as readers do."""
    keys = []
    for member in shard["members"]:
        key = member_key(member["name"])
        if not keys or keys[-1] != key:
            keys.append(key)
    assert len(keys) == shard["samples"], f"{shard['name']}: {len(keys)} keys, index says {shard['samples']} samples"
    return keys


@pytest.fixture(scope="module")
def dataset():
    value = os.environ.get(DATASET_VAR)
    if not value:
        pytest.skip(f"{DATASET_VAR} is not set: point it at a bettimill dataset directory (index.json + shards/) to run the Python client tests")
    return Dataset(Path(value))


def npy_field(sample):
    fields = [f for f in NPY_FIELDS if f in sample]
    assert len(fields) == 1, f"sample {sample.get('__key__')!r} has npy fields {fields}; expected exactly one of {NPY_FIELDS}"
    return fields[0]


def check_labels(key, labels, cls):
    """The JSON labels and class of one sample."""
    assert labels["key"] == key, f"{key}: json key is {labels['key']!r}"
    betti = labels["betti"]
    assert isinstance(betti, list) and betti, f"{key}: betti {betti!r} is not a non-empty list"
    assert all(type(b) is int and b >= 0 for b in betti), f"{key}: betti {betti!r} is not a list of non-negative ints"
    euler = sum(b if k % 2 == 0 else -b for k, b in enumerate(betti))
    assert labels["euler"] == euler, f"{key}: euler {labels['euler']} but betti {betti} gives {euler}"
    shape = labels["shape"]
    assert isinstance(shape, list) and all(type(n) is int and n > 0 for n in shape), f"{key}: shape {shape!r}"
    assert labels["dim"] == len(shape), f"{key}: dim {labels['dim']} but shape {shape}"
    assert type(cls) is int and cls >= 0, f"{key}: cls {cls!r} is not a non-negative int"
    for field in ("hypervolume", "seed", "family", "mode", "tool_version", "construction"):
        assert field in labels, f"{key}: json has no {field!r}"
    return tuple(shape)


def check_array(key, array, shape, hypervolume=None):
    """A decoded image: uint8, the labelled shape, only 0 and 1."""
    array = np.asarray(array)
    assert array.dtype == np.uint8, f"{key}: dtype {array.dtype}, expected uint8"
    assert array.shape == shape, f"{key}: shape {array.shape}, json says {shape}"
    assert np.isin(array, (0, 1)).all(), f"{key}: values other than 0 and 1"
    if hypervolume is not None:
        assert int(array.sum()) == hypervolume, f"{key}: {int(array.sum())} foreground voxels, json hypervolume {hypervolume}"


def test_webdataset_feeds_a_torch_dataloader_with_two_workers(dataset):
    import torch
    import webdataset as wds

    for split in dataset.splits:
        pipeline = wds.WebDataset(dataset.shard_paths(split), shardshuffle=False, empty_check=False).decode(zst_handler)
        loader = torch.utils.data.DataLoader(pipeline, batch_size=None, num_workers=2)
        seen = []
        for sample in loader:
            key = sample["__key__"]
            shape = check_labels(key, sample["json"], sample["cls"])
            tensor = sample[npy_field(sample)]
            assert isinstance(tensor, torch.Tensor), f"{key}: DataLoader gave {type(tensor)}"
            assert tensor.dtype == torch.uint8, f"{key}: tensor dtype {tensor.dtype}"
            check_array(key, tensor.numpy(), shape, sample["json"]["hypervolume"])
            seen.append(key)
        expected = dataset.expected_keys(split)
        duplicates = [k for k, n in collections.Counter(seen).items() if n > 1]
        assert not duplicates, f"{split}: samples seen twice: {duplicates[:5]}"
        assert sorted(seen) == sorted(expected), f"{split}: DataLoader saw {len(seen)} samples, index has {len(expected)}"


def test_hf_datasets_loads_every_split(dataset, tmp_path):
    import datasets

    data_files = {split: dataset.shard_paths(split) for split in dataset.splits}
    loaded = datasets.load_dataset("webdataset", data_files=data_files, cache_dir=str(tmp_path / "hf-cache"))
    for split in dataset.splits:
        table = loaded[split]
        expected = dataset.expected_keys(split)
        assert table.num_rows == len(expected), f"{split}: HF loaded {table.num_rows} rows, index has {len(expected)}"
        assert table["__key__"] == expected, f"{split}: HF keys differ from the index order"
        field = npy_field(set(table.column_names))
        for row in table:
            key = row["__key__"]
            shape = check_labels(key, row["json"], int(row["cls"]))
            array = np.asarray(row[field], dtype=np.uint8)
            check_array(key, array, shape, row["json"]["hypervolume"])


def test_gnu_tar_lists_and_extracts_numpy_reads(dataset, tmp_path):
    tar = shutil.which("tar")
    assert tar, "tar is not on PATH (the Python client tests need GNU tar)"
    version = subprocess.run([tar, "--version"], capture_output=True, text=True, check=True).stdout
    assert "GNU tar" in version, f"{tar} is not GNU tar: {version.splitlines()[0]!r}"
    for shard in dataset.index["shards"]:
        path = dataset.root / shard["name"]
        listing = subprocess.run([tar, "-tvf", str(path)], capture_output=True, text=True, check=True).stdout.splitlines()
        names = [line.split()[-1] for line in listing]
        assert names == [m["name"] for m in shard["members"]], f"{path}: tar lists members other than the index's"
        for line in listing:
            mode, owner = line.split()[:2]
            assert mode == "-r--r--r--" and owner == "bettimill/bettimill", f"{path}: {line!r}"
        out = tmp_path / shard["name"].replace("/", "_")
        out.mkdir()
        subprocess.run([tar, "-xf", str(path), "-C", str(out)], check=True)
        labels = {}
        arrays = {}
        classes = {}
        for member in shard["members"]:
            name = member["name"]
            data = (out / name).read_bytes()
            assert len(data) == member["bytes"], f"{path}: {name} extracted to {len(data)} bytes, index says {member['bytes']}"
            key = member_key(name)
            field = name[len(key) + 1 :]
            if field in NPY_FIELDS:
                arrays[key] = np.load(io.BytesIO(decompress_member(name, data)), allow_pickle=False)
            elif field == "json":
                labels[key] = json.loads(data)
            elif field == "cls":
                text = data.decode("ascii")
                assert text.isdigit(), f"{path}: {name} is {text!r}, not an ASCII decimal"
                classes[key] = int(text)
        assert labels.keys() == arrays.keys() == classes.keys(), f"{path}: samples without npy, json and cls"
        for key, label in labels.items():
            shape = check_labels(key, label, classes[key])
            check_array(key, arrays[key], shape, label["hypervolume"])


def wids_transform(sample):
    """wids transformation: its own gzip and basic decoders, plus ``.zst``."""
    from wids.wids_decode import decode_all_gz, decode_basic

    for key in [k for k in sample if k.endswith(".zst")]:
        sample[key[: -len(".zst")]] = io.BytesIO(zstandard.ZstdDecompressor().decompress(sample.pop(key).read()))
    return decode_basic(decode_all_gz(sample, update_key=True))


def test_wids_index_opens_with_shard_list_dataset(dataset, tmp_path):
    import wids

    indexes = sorted(dataset.root.glob("*shardindex*.json"))
    if not indexes:
        pytest.skip(f"{dataset.root} has no wids index (*shardindex*.json)")
    for index_path in indexes:
        spec = json.loads(index_path.read_text())
        assert spec["__kind__"] == "wids-shard-index-v1", f"{index_path}: __kind__ {spec['__kind__']!r}"
        # A fresh cache directory per index: wids caches shards by file name, and a stale
        # copy from another dataset with the same shard names would be read instead.
        ds = wids.ShardListDataset(str(index_path), cache_dir=str(tmp_path / index_path.stem), transformations=[wids_transform])
        urls = [entry["url"] for entry in spec["shardlist"]]
        split_shards = [s for s in dataset.index["shards"] if s["name"] in urls]
        assert [s["name"] for s in split_shards] == urls, f"{index_path}: shards not in index.json order"
        expected = [key for shard in split_shards for key in shard_keys(shard)]
        assert len(ds) == len(expected), f"{index_path}: wids counts {len(ds)} samples, index.json {len(expected)}"
        for i in range(len(ds)):
            sample = ds[i]
            key = sample["__key__"]
            assert key == expected[i], f"{index_path}: sample {i} is {key!r}, expected {expected[i]!r}"
            shape = check_labels(key, sample[".json"], sample[".cls"])
            check_array(key, sample[".npy"], shape, sample[".json"]["hypervolume"])
        ds.close()


def test_classes_json_says_what_every_cls_means(dataset):
    """classes.json (datasets built by the CLI) names every cls value: the stratum's Betti
    numbers are the label's, and its topology class is the one of that Betti vector."""
    import tarfile

    listed = [f["name"] for f in dataset.index["files"]]
    if "classes.json" not in listed:
        assert not (dataset.root / "build.json").exists(), "a CLI-built dataset lists classes.json in index.json"
        pytest.skip("built by the bettimill-shard example, which writes no class table")
    table = json.loads((dataset.root / "classes.json").read_text())
    assert table["classes"] == len(table["strata"])
    assert [s["cls"] for s in table["strata"]] == list(range(table["classes"]))
    seen = 0
    for shards in dataset.splits.values():
        for shard in shards:
            with tarfile.open(dataset.root / shard["name"]) as tar:
                members = {m.name: tar.extractfile(m).read() for m in tar.getmembers()}
            for name, data in members.items():
                if not name.endswith(".json"):
                    continue
                label = json.loads(data)
                cls = int(members[name.removesuffix(".json") + ".cls"])
                stratum = table["strata"][cls]
                assert stratum["betti"] == label["betti"], f"{name}: cls {cls}"
                assert stratum["name"] == label["class_label"], f"{name}: cls {cls}"
                topology = table["topology"][stratum["topology_class"]]
                assert topology["betti"] == label["betti"] and cls in topology["strata"]
                seen += 1
    assert seen == dataset.index["samples"]
