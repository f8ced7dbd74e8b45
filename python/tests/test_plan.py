"""bettimill.Plan against the datasets the CLI builds, and build/verify in Python."""

import gzip
import hashlib
import io
import json
import pickle
import tarfile

import numpy as np
import pytest
import zstandard

import bettimill
from conftest import MANIFESTS, REPO, run_cli

DEMOS = [REPO / "manifests" / f"demo-{d}.toml" for d in ("2d", "3d", "4d")]


def shard_members(directory):
    """{KEY: {field: bytes}} of every shard of a built dataset, read with tarfile."""
    index = json.loads((directory / "index.json").read_text())
    samples = {}
    for shard in index["shards"]:
        with tarfile.open(directory / shard["name"]) as tar:
            for member in tar.getmembers():
                key, field = member.name.split(".", 1)
                data = tar.extractfile(member).read()
                if field.endswith(".gz"):
                    data, field = gzip.decompress(data), field[:-3]
                elif field.endswith(".zst"):
                    data, field = zstandard.ZstdDecompressor().decompress(data), field[:-4]
                samples.setdefault(key, {})[field] = data
    return samples


@pytest.mark.parametrize("manifest", DEMOS, ids=lambda p: p.stem)
def test_every_sample_equals_the_built_shards(built, manifest):
    directory = built(manifest)
    plan = bettimill.Plan(manifest)
    members = shard_members(directory)
    assert len(members) == len(plan)
    for key, fields in sorted(members.items()):
        index = int(key[1:])
        voxels, label = plan.sample(index)
        stored = np.load(io.BytesIO(fields["npy"]))
        assert voxels.dtype == np.uint8 and voxels.flags.c_contiguous
        assert stored.dtype == voxels.dtype and stored.shape == voxels.shape, key
        assert np.array_equal(stored, voxels), key
        assert json.loads(fields["json"]) == label, key
        assert int(fields["cls"]) == label["class_index"]
        for side in plan.resolutions:
            small, _ = plan.sample(index, resolution=side)
            assert np.array_equal(np.load(io.BytesIO(fields[f"r{side}.npy"])), small), key


def test_plan_fields(tmp_path):
    plan = bettimill.Plan(REPO / "manifests" / "demo-3d.toml")
    assert plan.dimension == 3 and plan.name == "demo-3d"
    assert sum(s["count"] for s in plan.strata) == len(plan)
    assert [s["cls"] for s in plan.strata] == list(range(len(plan.strata)))
    assert set(plan.strata[0]) == {"cls", "name", "family", "mode", "components", "bin", "betti", "count"}
    assert list(plan.split("train")) == list(range(len(plan)))
    with pytest.raises(ValueError, match="no split"):
        plan.split("nope")
    with pytest.raises(IndexError):
        plan.sample(len(plan))
    assert plan.sample(-1)[1]["key"] == plan.sample(len(plan) - 1)[1]["key"]
    # The text and the path give the same plan; None is the CLI's embedded demo.
    text = (REPO / "manifests" / "demo-3d.toml").read_text()
    assert bettimill.Plan(text).hash == plan.hash
    assert len(bettimill.Plan()) == 240
    # A pickled plan (a DataLoader worker under spawn) makes the same samples.
    again = pickle.loads(pickle.dumps(plan))
    assert again.hash == plan.hash and again.sample(5)[1] == plan.sample(5)[1]


@pytest.mark.parametrize("manifest", DEMOS[:2], ids=lambda p: p.stem)
def test_classes_equal_the_built_classes_json(built, manifest):
    plan = bettimill.Plan(manifest)
    classes = plan.classes
    assert classes == json.loads((built(manifest) / "classes.json").read_text())
    assert classes["classes"] == len(plan.strata)
    assert [s["cls"] for s in classes["strata"]] == [s["cls"] for s in plan.strata]
    assert sum(t["samples"] for t in classes["topology"]) == len(plan)


def test_named_splits_are_contiguous_ranges():
    text = (MANIFESTS / "families-2d.toml").read_text() + "\n[splits]\ntrain = 5\ntest = 3\n"
    plan = bettimill.Plan(text)
    assert plan.splits == {"train": 5, "test": 3}
    assert plan.split("train") == range(0, 5) and plan.split("test") == range(5, 8)


def test_bad_manifests_name_the_file_and_field(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text((MANIFESTS / "families-2d.toml").read_text().replace('"curve"', '"nope"'))
    with pytest.raises(ValueError, match=r"bad\.toml:\d+: field `classes`"):
        bettimill.Plan(bad)
    with pytest.raises(FileNotFoundError):
        bettimill.Plan(tmp_path / "missing.toml")


def tar_hashes(directory):
    index = json.loads((directory / "index.json").read_text())
    return {s["name"]: hashlib.sha256((directory / s["name"]).read_bytes()).hexdigest() for s in index["shards"]}


@pytest.mark.parametrize("workers", [None, 2])
def test_build_and_verify_in_python_equal_the_cli(built, tmp_path, workers):
    manifest = MANIFESTS / "families-2d.toml"
    out = tmp_path / "py"
    summary = bettimill.build(manifest, out, workers=workers)
    assert summary["built"] == summary["shards"] == 2 and summary["samples"] == 8
    assert tar_hashes(out) == tar_hashes(built(manifest))
    report = bettimill.verify(out)
    assert report["problems"] == [] and report["shards_checked"] == 2
    assert bettimill.build(manifest, out, workers=workers)["skipped"] == 2
    # A damaged shard is a problem, as `bettimill verify` says.
    shard = next((out / "shards").iterdir())
    shard.write_bytes(shard.read_bytes()[:-1] + b"x")
    assert bettimill.verify(out)["problems"]


def test_console_script_is_the_cli(cli, tmp_path):
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    script = Path(sys.executable).parent / "bettimill"
    assert script.is_file(), "pip install puts the bettimill console script next to python"
    image = np.zeros((5, 5), np.uint8)
    image[1:4, 1:4] = 1
    image[2, 2] = 0
    np.save(tmp_path / "a.npy", image)
    for args in (["betti", tmp_path / "a.npy", "--json"], ["plan", MANIFESTS / "families-2d.toml"], ["--version"],
                 ["nonsense"], ["betti", tmp_path / "missing.npy"], ["verify", tmp_path]):
        ours = subprocess.run([script, *map(str, args)], capture_output=True, text=True)
        theirs = subprocess.run([cli, *map(str, args)], capture_output=True, text=True)
        assert (ours.returncode, ours.stdout, ours.stderr) == (theirs.returncode, theirs.stdout, theirs.stderr), args
    # build with worker processes: the workers are the console script again.
    out = tmp_path / "built"
    result = subprocess.run([script, "build", MANIFESTS / "families-2d.toml", "--out", out, "--workers", "2", "--quiet"])
    assert result.returncode == 0
    assert run_cli(cli, "verify", out).returncode == 0
    assert shutil.which("bettimill") is not None


def test_a_sample_beyond_memory_is_a_memory_error_not_an_abort():
    # The CLI refuses a 4D side-254 plan with its memory estimate; Plan.sample used to make
    # the sample anyway and abort the interpreter under an address-space limit.
    import subprocess
    import sys

    text = (
        'schema_version = 1\nname = "huge"\ndimension = 4\nside = 254\nmode = "embed"\n'
        'samples = 1\nshard_size = 1\nseed = 1\n[[classes]]\nfamily = "ball"\n'
    )
    script = (
        "import resource, sys, bettimill\n"
        "resource.setrlimit(resource.RLIMIT_AS, (8_000_000_000, 8_000_000_000))\n"
        "try:\n"
        "    bettimill.Plan(sys.argv[1]).sample(0)\n"
        "except MemoryError as err:\n"
        "    print('MemoryError', err)\n"
    )
    result = subprocess.run([sys.executable, "-c", script, text], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert "MemoryError sample 0 (4D, 4162314256 voxels) needs about" in result.stdout, result.stdout


def test_empty_and_oversized_manifest_text_is_refused_like_a_file():
    # Plan('') used to say `cannot read the manifest : no such file`; text over 1 MiB was
    # accepted where a file over 1 MiB is refused.
    with pytest.raises(ValueError, match="the manifest is an empty string"):
        bettimill.Plan("")
    text = (REPO / "manifests" / "demo-3d.toml").read_text()
    padded = text + "# padding\n" * (1 << 17)
    with pytest.raises(ValueError, match="larger than 1048576 bytes"):
        bettimill.Plan(padded)


def test_a_megabyte_of_text_without_newline_is_refused_and_not_repeated():
    # One comment line over 1 MiB has no newline and no `=`, so it was taken for a path;
    # the error then printed the whole megabyte back.
    with pytest.raises(ValueError, match="larger than 1048576 bytes") as refused:
        bettimill.Plan("#" + "x" * 2**20)
    assert len(str(refused.value)) < 300, len(str(refused.value))
    # Under the limit it is a name that is no file and no preset: shown shortened.
    with pytest.raises(FileNotFoundError, match="no such file") as missing:
        bettimill.Plan("x" * 2**19)
    assert len(str(missing.value)) < 600, len(str(missing.value))
    assert "more characters" in str(missing.value)


def test_presets_are_built_in_and_an_unknown_name_lists_them(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    presets = bettimill.presets()
    assert sorted(presets) == sorted(p.stem for p in (REPO / "manifests").glob("*.toml"))
    for name, text in presets.items():
        assert text == (REPO / "manifests" / f"{name}.toml").read_text()
    plan = bettimill.Plan("demo-4d")
    assert plan.hash == bettimill.Plan(REPO / "manifests" / "demo-4d.toml").hash
    with pytest.raises(FileNotFoundError, match="no preset of that name .the presets: 4d-mixed-128, demo-2d"):
        bettimill.Plan("demo-5d")
    # A file of that name in the working directory is read instead.
    (tmp_path / "demo-4d").write_text(presets["demo-2d"])
    assert bettimill.Plan("demo-4d").dimension == 2


def test_a_misspelt_key_is_named_with_the_nearest_known_one():
    text = bettimill.presets()["demo-2d"]
    with pytest.raises(ValueError, match="unknown field `famliy`: did you mean `family`?"):
        bettimill.Plan(text.replace("family =", "famliy ="))
    with pytest.raises(ValueError, match="unknown field `sed`: did you mean `seed`?"):
        bettimill.Plan(text.replace("seed =", "sed ="))


def test_verify_of_a_non_dataset_says_what_it_found(tmp_path):
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(ValueError, match=r"not a finished bettimill dataset \(no index.json\): it holds 1 entry \(notes.txt\)"):
        bettimill.verify(tmp_path)


def test_construction_is_the_undeformed_shape_the_sample_was_made_from():
    plan = bettimill.Plan("demo-3d")
    voxels, label = plan.sample(0)
    built = plan.construction(0, label["attempt"])
    assert built.shape == voxels.shape and built.dtype == np.uint8
    # The demo deforms its cavities: the sample differs from its construction, but the
    # solid's outer layers (never edited) are the same.
    assert (built != voxels).any()
    assert (built[0] == voxels[0]).all() and (built[-1] == voxels[-1]).all()
    assert label["deform"], "the demo deforms"
    with pytest.raises(ValueError, match="attempts"):
        plan.construction(0, 99)
