"""bettimill.betti / euler / topology against `bettimill betti --json` on the same arrays."""

import subprocess

import numpy as np
import pytest

import bettimill
from conftest import MANIFESTS, cli_betti_json

SHAPES = [(13, 17), (40, 31), (9, 8, 11), (16, 16, 16), (6, 7, 5, 6), (9, 9, 9, 9)]


@pytest.mark.parametrize("shape", SHAPES, ids=lambda s: "x".join(map(str, s)))
@pytest.mark.parametrize("density", [0.2, 0.5, 0.8])
def test_random_images_equal_the_cli(cli, tmp_path, shape, density):
    rng = np.random.default_rng(hash((shape, density)) % 2**32)
    image = (rng.random(shape) < density).astype(np.uint8)
    path = tmp_path / "image.npy"
    np.save(path, image)
    expected = cli_betti_json(cli, path)
    got = bettimill.topology(image)
    assert got.pop("components") == expected["betti"][0]
    assert got == expected
    assert bettimill.betti(image) == expected["betti"]
    assert bettimill.euler(image) == expected["euler"]
    # Every dtype and memory order the CLI reads gives the same numbers, read in place.
    for variant in (
        image.astype(bool),
        image.astype(np.int64) * 3,
        image.astype(np.uint16),
        np.asfortranarray(image),
        image.astype(">i4"),
    ):
        assert bettimill.betti(variant) == expected["betti"], variant.dtype


def test_views_are_read_in_their_logical_order(cli, tmp_path):
    rng = np.random.default_rng(3)
    base = (rng.random((20, 18, 22)) < 0.4).astype(np.uint8)
    for view in (base[::2, 1::3], base[:, ::-1], base.transpose(2, 0, 1), base[3:17, 2:9, ::2]):
        path = tmp_path / "view.npy"
        np.save(path, np.ascontiguousarray(view))
        assert bettimill.betti(view) == cli_betti_json(cli, path)["betti"]


@pytest.mark.parametrize("manifest", sorted(MANIFESTS.glob("families-*.toml")), ids=lambda p: p.stem)
def test_every_family_equals_the_cli_and_its_label(cli, tmp_path, manifest):
    plan = bettimill.Plan(manifest)
    families = set()
    for i in range(len(plan)):
        voxels, label = plan.sample(i)
        path = tmp_path / f"{label['key']}.npy"
        np.save(path, voxels)
        got = bettimill.topology(voxels, strict=True)
        assert got["betti"] == label["betti"], label["class_label"]
        assert got["betti"] == cli_betti_json(cli, path)["betti"], label["class_label"]
        families.add(label["family"])
    assert families == {s["family"] for s in plan.strata}


BAD = {
    "1 axis": np.zeros(5, np.uint8),
    "5 axes": np.zeros((2, 2, 2, 2, 2), np.uint8),
    "float": np.zeros((4, 4), np.float64),
    "empty axis": np.zeros((4, 0, 3), np.uint8),
    "value 2 (strict)": np.array([[0, 1], [2, 0]], np.int32),
}


@pytest.mark.parametrize("name", BAD)
def test_bad_arrays_raise_value_error_with_the_clis_message(cli, tmp_path, name):
    array = BAD[name]
    path = tmp_path / "bad.npy"
    np.save(path, array)
    result = subprocess.run([cli, "betti", path, "--strict"], capture_output=True, text=True)
    assert result.returncode == 2, result
    with pytest.raises(ValueError) as caught:
        bettimill.betti(array, strict=True)
    message = str(caught.value)
    assert message and message in result.stderr, (message, result.stderr)
    assert f"error: cannot use {path} as an image: {message}" in result.stderr


def test_non_binary_values_are_foreground_without_strict():
    image = np.zeros((6, 6), np.int16)
    image[1:5, 1:5] = 7
    image[2:4, 2:4] = 0
    assert bettimill.betti(image) == [1, 1]


def test_not_an_array_is_converted_and_objects_refused():
    assert bettimill.betti([[0, 1, 0], [1, 0, 1], [0, 1, 0]]) == [1, 1]
    with pytest.raises(ValueError, match="unsupported dtype"):
        bettimill.betti(np.array([["a", "b"], ["c", "d"]]))


def test_arrays_larger_than_memory_are_a_memory_error_not_an_abort():
    # A broadcast array costs numpy nothing; its copy here (10^12 voxels) used to abort the
    # interpreter with `memory allocation of 1000000000000 bytes failed`.
    huge = np.broadcast_to(np.uint8(1), (10**6, 10**6))
    with pytest.raises(MemoryError, match="needs about"):
        bettimill.betti(huge)


def test_arrays_beyond_an_address_space_limit_are_a_memory_error():
    # Under `ulimit -v 8000000` a (1024,)*3 or (300,)*4 array of ones used to abort.
    import subprocess
    import sys

    script = (
        "import resource, numpy as np, bettimill\n"
        "resource.setrlimit(resource.RLIMIT_AS, (8_000_000_000, 8_000_000_000))\n"
        "for shape in [(1024,) * 3, (300,) * 4]:\n"
        "    try:\n"
        "        bettimill.betti(np.ones(shape, dtype=np.uint8))\n"
        "    except MemoryError as err:\n"
        "        print('MemoryError', err)\n"
    )
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.count("MemoryError") == 2, result.stdout + result.stderr


def two_rings():
    ring = np.zeros((6, 6), np.uint8)
    ring[1:5, 1:5] = 1
    ring[2:4, 2:4] = 0
    disk = np.zeros((6, 6), np.uint8)
    disk[1:5, 1:5] = 1
    return np.stack([ring, disk, ring])


@pytest.mark.parametrize(
    "shape_of",
    [lambda b: b[:, None], lambda b: b, lambda b: torch_like_batch(b)],
    ids=["[B, 1, H, W]", "[B, H, W]", "list of lists"],
)
def test_betti_batch_gives_one_answer_per_item(shape_of):
    assert bettimill.betti_batch(shape_of(two_rings())) == [[1, 1], [1, 0], [1, 1]]


def torch_like_batch(batch):
    return batch[:, None].tolist()


def test_betti_batch_of_3d_items_and_a_single_image_refused():
    cube = np.zeros((2, 1, 5, 5, 5), np.uint8)
    cube[:, 0, 1:4, 1:4, 1:4] = 1
    cube[1, 0, 2, 2, 2] = 0
    assert bettimill.betti_batch(cube) == [[1, 0, 0], [1, 0, 1]]
    with pytest.raises(ValueError, match="use bettimill.betti for one image"):
        bettimill.betti_batch(np.zeros((4, 4), np.uint8))


@pytest.mark.parametrize(
    "shape,reason",
    [
        ((1, 1, 6, 6), "leading axis has size 1"),
        ((1, 6, 6), "leading axis has size 1"),
        ((3, 1, 6, 6), "[batch, channel, H, W]"),
        ((3, 6, 6, 6), "leading axis (3) differs"),
    ],
)
def test_a_batch_like_shape_warns_and_names_betti_batch(shape, reason):
    array = np.zeros(shape, np.uint8)
    with pytest.warns(bettimill.BatchShapeWarning, match="betti_batch") as caught:
        bettimill.betti(array)
    assert reason in str(caught[0].message)
    assert caught[0].filename == __file__, "the warning points at the caller's line"


def test_image_shapes_do_not_warn():
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for shape in [(6, 6), (6, 7), (5, 5, 5), (4, 5, 6), (4, 4, 4, 4), (3, 4, 5, 6)]:
            bettimill.topology(np.zeros(shape, np.uint8))
