"""PyTorch parts: a Dataset that makes samples on demand, a 4D convolution, a small 4D model.

Only this module imports torch (``pip install "bettimill[torch]"``).

- ``SyntheticDataset(plan, split=None, transform=None, resolution=None)``: a map-style
  Dataset over a plan's samples, each made when asked (``plan.sample(i)``), equal to the
  sample the dataset's shards hold. Works in a DataLoader with ``num_workers > 0`` under
  fork, spawn and forkserver (the plan pickles as its manifest text); each worker makes its
  samples on one thread unless ``bettimill.set_threads`` was called.
- ``Conv4d``: a 4D convolution assembled from ``Conv3d`` (one per kernel offset along the
  first spatial axis), with padding, stride, dilation and bias.
- ``BettiNet4d``: a small 4D CNN (four blocks, batch normalisation) that predicts each Betti
  number as a class (0..max).
"""

import os

import torch
from torch import nn

import bettimill
from . import Plan

__all__ = ["SyntheticDataset", "Conv4d", "BettiNet4d", "betti_targets"]


def _as_tuple4(value, name):
    if isinstance(value, int):
        return (value,) * 4
    value = tuple(int(v) for v in value)
    if len(value) != 4:
        raise ValueError(f"{name} must be an int or 4 ints, got {value!r}")
    return value


class SyntheticDataset(torch.utils.data.Dataset):
    """Samples of a plan, generated on demand.

    ``plan``: a ``bettimill.Plan``, or what ``Plan`` accepts (a manifest path or TOML text).
    ``split``: only that split's samples (``plan.split(name)``); None for all of them.
    ``resolution``: the side of a downscaled copy the manifest asks for (``resolutions``).
    ``transform(voxels, label)``: maps the uint8 tensor of shape ``[side] * dimension`` and
    the label dict to the item; without one an item is ``(voxels, label)`` with voxels a
    ``uint8`` tensor (convert to float in the model or the transform: 1 byte a voxel until
    then).
    """

    def __init__(self, plan, split=None, transform=None, resolution=None):
        self.plan = plan if isinstance(plan, Plan) else Plan(plan)
        self.indices = range(len(self.plan)) if split is None else self.plan.split(split)
        self.transform = transform
        self.resolution = resolution
        self._pid = os.getpid()

    def __len__(self):
        return len(self.indices)

    def __getitem__(self, item):
        if self._pid != os.getpid():
            # The first item in a new process: in a DataLoader worker, one thread, because
            # the workers already use the cores and threads would only add their overhead.
            self._pid = os.getpid()
            if not bettimill._threads_chosen and torch.utils.data.get_worker_info() is not None:
                bettimill._bettimill.set_threads(1)
        voxels, label = self.plan.sample(self.indices[item], self.resolution)
        voxels = torch.from_numpy(voxels)
        if self.transform is not None:
            return self.transform(voxels, label)
        return voxels, label


def betti_targets(voxels, label):
    """A transform for ``SyntheticDataset``: ``(float voxels [1, *shape], betti int64)``."""
    return voxels.unsqueeze(0).float(), torch.tensor(label["betti"], dtype=torch.int64)


class Conv4d(nn.Module):
    """A 4D convolution over inputs ``[N, C, D0, D1, D2, D3]``, assembled from ``Conv3d``.

    Output ``o`` along the first axis is ``sum_k conv3d_k(x[:, :, s*o + d*k - p0])`` over the
    kernel's ``k0`` offsets (``s``, ``d``, ``p0`` the first axis' stride, dilation and zero
    padding); the other three axes are the ``Conv3d``'s own. Weights are those of a 4D
    kernel ``[out, in, k0, k1, k2, k3]`` (``weight``), initialised as ``Conv3d`` does for
    each slice, with one bias.
    """

    def __init__(self, in_channels, out_channels, kernel_size, stride=1, padding=0, dilation=1, bias=True):
        super().__init__()
        self.kernel_size = _as_tuple4(kernel_size, "kernel_size")
        self.stride = _as_tuple4(stride, "stride")
        self.padding = _as_tuple4(padding, "padding")
        self.dilation = _as_tuple4(dilation, "dilation")
        self.in_channels = in_channels
        self.out_channels = out_channels
        self.slices = nn.ModuleList(
            nn.Conv3d(
                in_channels,
                out_channels,
                self.kernel_size[1:],
                stride=self.stride[1:],
                padding=self.padding[1:],
                dilation=self.dilation[1:],
                bias=False,
            )
            for _ in range(self.kernel_size[0])
        )
        if bias:
            fan_in = in_channels * self.kernel_size[0] * self.kernel_size[1] * self.kernel_size[2] * self.kernel_size[3]
            bound = 1.0 / fan_in**0.5
            self.bias = nn.Parameter(torch.empty(out_channels).uniform_(-bound, bound))
        else:
            self.register_parameter("bias", None)

    @property
    def weight(self):
        """The 4D kernel ``[out, in, k0, k1, k2, k3]``."""
        return torch.stack([s.weight for s in self.slices], dim=2)

    def forward(self, x):
        if x.dim() != 6:
            raise ValueError(f"Conv4d takes [N, C, D0, D1, D2, D3], got shape {tuple(x.shape)}")
        n, c, d0 = x.shape[:3]
        k0, s0, p0, g0 = self.kernel_size[0], self.stride[0], self.padding[0], self.dilation[0]
        out0 = (d0 + 2 * p0 - g0 * (k0 - 1) - 1) // s0 + 1
        if out0 < 1:
            raise ValueError(f"Conv4d: input length {d0} on axis 0 is too small for the kernel")
        if p0:
            x = nn.functional.pad(x, (0, 0, 0, 0, 0, 0, p0, p0))
        # Every 3D slice the output needs, for every kernel offset, batched through each
        # offset's Conv3d at once.
        out = None
        for k, conv in enumerate(self.slices):
            start = k * g0
            picked = x[:, :, start : start + s0 * (out0 - 1) + 1 : s0]  # [N, C, out0, D1, D2, D3]
            flat = picked.transpose(1, 2).reshape(n * out0, c, *x.shape[3:])
            y = conv(flat)
            out = y if out is None else out + y
        out = out.reshape(n, out0, self.out_channels, *out.shape[2:]).transpose(1, 2)
        if self.bias is not None:
            out = out + self.bias.view(1, -1, 1, 1, 1, 1)
        return out.contiguous()


class _ChannelNorm(nn.Module):
    """Batch normalisation of each channel over the batch and every spatial axis (any
    number of them): ``nn.BatchNorm1d`` on the flattened voxels."""

    def __init__(self, channels):
        super().__init__()
        self.norm = nn.BatchNorm1d(channels)

    def forward(self, x):
        return self.norm(x.flatten(2)).view(x.shape)


class BettiNet4d(nn.Module):
    """A small 4D CNN: four ``Conv4d`` blocks (strides 2, 2, 1, 2; widths ``width``,
    ``2 width``, ``4 width``, ``4 width``; each convolution followed by batch normalisation and
    ReLU), global max and mean pooling, and one classification head per Betti number
    (``b_k`` in ``0..max_betti``).

    The third block keeps the resolution: a fourth block of reach where the picture is a
    quarter of the input's side, where a block is cheap (``benches/learnability.py``
    measures the model on kinds of shapes it never saw).

    ``forward`` returns logits ``[N, dimension, max_betti + 1]``; train with cross entropy
    against the label's Betti vector (values above ``max_betti`` clipped by the caller).
    """

    def __init__(self, dimension=4, max_betti=4, width=8):
        super().__init__()
        self.dimension = dimension
        self.max_betti = max_betti
        layers = []
        channels = 1
        for stride, out in zip((2, 2, 1, 2), (width, 2 * width, 4 * width, 4 * width)):
            layers += [Conv4d(channels, out, 3, stride=stride, padding=1, bias=False), _ChannelNorm(out), nn.ReLU()]
            channels = out
        self.features = nn.Sequential(*layers)
        self.head = nn.Linear(2 * channels, dimension * (max_betti + 1))

    def forward(self, x):
        x = self.features(x)
        flat = x.flatten(2)
        pooled = torch.cat([flat.amax(dim=2), flat.mean(dim=2)], dim=1)
        return self.head(pooled).view(-1, self.dimension, self.max_betti + 1)
