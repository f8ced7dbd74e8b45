"""bettimill.torch: SyntheticDataset in DataLoaders, Conv4d against a direct 4D
convolution, and examples/train_4d.py against its majority baseline."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

import bettimill
from bettimill.torch import BettiNet4d, Conv4d, SyntheticDataset, betti_targets
from conftest import MANIFESTS

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "train_4d.py"


@pytest.mark.parametrize("context", ["fork", "spawn"])
def test_dataloader_with_two_workers(context):
    plan = bettimill.Plan(MANIFESTS / "families-3d.toml")
    dataset = SyntheticDataset(plan, transform=betti_targets)
    loader = torch.utils.data.DataLoader(dataset, batch_size=5, num_workers=2, multiprocessing_context=context)
    images, betti = zip(*loader)
    images, betti = torch.cat(images), torch.cat(betti)
    assert images.shape == (len(plan), 1, 48, 48, 48) and images.dtype == torch.float32
    for i in range(len(plan)):
        voxels, label = plan.sample(i)
        assert torch.equal(images[i, 0], torch.from_numpy(voxels).float())
        assert betti[i].tolist() == label["betti"]


def test_dataset_split_and_raw_items():
    text = (MANIFESTS / "families-2d.toml").read_text() + "\n[splits]\ntrain = 5\ntest = 3\n"
    test = SyntheticDataset(text, split="test")
    assert len(test) == 3
    voxels, label = test[0]
    assert voxels.dtype == torch.uint8 and label["key"].endswith("5")


def direct_conv4d(x, weight, bias, stride, padding, dilation):
    """The definition: out[n, o, p] = bias[o] + sum over c and kernel offsets k of
    weight[o, c, k] * xpad[n, c, stride * p + dilation * k], one kernel offset at a time."""
    x = torch.nn.functional.pad(x, [p for pad in reversed(padding) for p in (pad, pad)])
    k = weight.shape[2:]
    out_shape = [(x.shape[2 + a] - dilation[a] * (k[a] - 1) - 1) // stride[a] + 1 for a in range(4)]
    out = torch.zeros(x.shape[0], weight.shape[0], *out_shape, dtype=x.dtype)
    for offset in np.ndindex(*k):
        index = tuple(
            slice(dilation[a] * offset[a], dilation[a] * offset[a] + stride[a] * (out_shape[a] - 1) + 1, stride[a])
            for a in range(4)
        )
        patch = x[(slice(None), slice(None)) + index]
        out += torch.einsum("ncwxyz,oc->nowxyz", patch, weight[(slice(None), slice(None)) + offset])
    return out + bias.view(1, -1, 1, 1, 1, 1)


@pytest.mark.parametrize(
    "kernel,stride,padding,dilation",
    [(3, 1, 0, 1), (3, 1, 1, 1), ((2, 3, 1, 2), (2, 1, 3, 1), (1, 0, 2, 1), 1), (3, 2, 2, (2, 1, 1, 3)), (1, 1, 0, 1)],
)
def test_conv4d_equals_a_direct_4d_convolution(kernel, stride, padding, dilation):
    torch.manual_seed(0)
    conv = Conv4d(2, 3, kernel, stride=stride, padding=padding, dilation=dilation).double()
    x = torch.randn(2, 2, 7, 6, 8, 7, dtype=torch.float64)
    expected = direct_conv4d(x, conv.weight, conv.bias, conv.stride, conv.padding, conv.dilation)
    got = conv(x)
    assert got.shape == expected.shape
    assert torch.allclose(got, expected, atol=1e-10)


def test_reference_model_shapes():
    model = BettiNet4d(dimension=4, max_betti=3, width=2)
    assert model(torch.zeros(2, 1, 8, 8, 8, 8)).shape == (2, 4, 4)


def test_train_4d_beats_the_majority_baseline():
    result = subprocess.run(
        [sys.executable, EXAMPLE, "--tiny", "--seed", "0", "--json"], capture_output=True, text=True, timeout=1800
    )
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout.strip().splitlines()[-1])
    accuracy, baseline, varies = summary["accuracy"], summary["baseline"], summary["varies"]
    # Ball, handle and S2xB2, embedded and carved, one or two copies: every b_k varies.
    assert varies == [True, True, True, True], result.stdout
    assert sum(accuracy) > sum(baseline), result.stdout
    assert summary["exact"] > summary["exact_baseline"], result.stdout
