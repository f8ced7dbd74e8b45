"""bettimill: binary images of 2D, 3D and 4D with exact Betti numbers (over Z/2).

- ``betti(array)``, ``euler(array)``, ``topology(array)``: what ``bettimill betti --json``
  computes for the array (same checks, same messages, same numbers).
- ``betti_batch(array)``: one answer per item of a batch ``[B, ...]`` or ``[B, 1, ...]``.
- ``presets()``: the built-in manifests (``Plan("demo-4d")`` works from any directory).
- ``Plan(manifest)``: a manifest's plan; ``plan.sample(i)`` makes sample ``i`` on demand,
  equal to ``KEY.npy`` and ``KEY.json`` of the dataset ``bettimill build`` writes.
- ``build(manifest, out)``, ``verify(dir)``: the library's build and check, in-process.
- ``set_threads(n)``, ``threads()``: the threads the computations use in this process.
- ``bettimill.torch``: ``SyntheticDataset``, ``Conv4d``, ``BettiNet4d`` (needs torch).

The computing is Rust (the extension module ``bettimill._bettimill``) and releases the GIL.
It runs on a thread pool of this process's own, made again in a child after ``fork``, so
the package works in DataLoader workers under fork, spawn and forkserver alike.
"""

import os
import shutil
import sys
import sysconfig
import warnings

import numpy

from . import _bettimill
from ._bettimill import Plan, __version__, presets

__all__ = [
    "betti",
    "betti_batch",
    "euler",
    "topology",
    "presets",
    "Plan",
    "build",
    "verify",
    "set_threads",
    "threads",
    "BatchShapeWarning",
    "__version__",
]


class BatchShapeWarning(UserWarning):
    """An array whose shape looks like a batch (``[1, H, W]``, ``[B, 1, H, W]``,
    ``[B, S, S, S]``) was given where one image is read."""

# Whether set_threads was called (in this process or, through fork, its parent): a
# DataLoader worker then keeps that count instead of the one thread it takes by default.
_threads_chosen = False


def set_threads(n):
    """Uses ``n`` threads for the computations of this process from now on (0: the
    ``RAYON_NUM_THREADS`` environment variable, else one per core); returns the count.

    ``bettimill.torch.SyntheticDataset`` uses one thread in each DataLoader worker (the
    workers are the parallelism) unless this was called before."""
    global _threads_chosen
    _threads_chosen = True
    return _bettimill.set_threads(int(n))


def threads():
    """The number of threads the computations of this process use."""
    return _bettimill.threads()


def _as_array(array):
    """A numpy view of ``array`` (no copy for an ndarray); big-endian data in native order."""
    array = numpy.asarray(array)
    if array.dtype.byteorder == ">" and array.dtype.itemsize > 1:
        array = array.astype(array.dtype.newbyteorder("="))
    return array


def _batch_like(shape):
    """Why ``shape`` looks like a batch of images rather than one image, or None."""
    if len(shape) >= 3 and shape[0] == 1:
        return "its leading axis has size 1"
    if len(shape) == 4 and shape[1] == 1:
        return "it looks like [batch, channel, H, W]"
    rest = shape[1:]
    if len(rest) >= 2 and len(set(rest)) == 1 and shape[0] != rest[0]:
        return f"its leading axis ({shape[0]}) differs from the {len(rest)} equal sides after it"
    return None


def _warn_if_batch(array, stacklevel):
    reason = _batch_like(array.shape)
    if reason is not None:
        warnings.warn(
            f"an array of shape {tuple(array.shape)} is read as ONE {array.ndim}D image, but {reason}; "
            "for one answer per image of a batch use bettimill.betti_batch(array), or index or squeeze "
            "the array first (filter bettimill.BatchShapeWarning to silence this)",
            BatchShapeWarning,
            stacklevel=stacklevel,
        )


def topology(array, strict=False):
    """The topology of a binary image: a dict with ``betti`` (b_0..b_{d-1}), ``euler``,
    ``shape``, ``hypervolume`` (foreground voxels), ``field`` ("Z/2") and ``components``.

    ``array``: a numpy bool or integer array of 2 to 4 dimensions, in any memory order
    (read in place, not copied); non-zero is foreground. With ``strict=True`` values other
    than 0 and 1 are refused. Bad arrays raise ``ValueError`` with the message of
    ``bettimill betti``. The voxel model: union of closed voxels, foreground
    (3^d-1)-adjacency, background 2d-adjacency. A shape that looks like a batch (a leading
    axis of size 1, ``[B, 1, H, W]``, ``[B, S, S, S]``) is still read as one image, with a
    ``BatchShapeWarning``: ``betti_batch`` gives one answer per image.
    """
    return _topology(array, strict, stacklevel=3)


def _topology(array, strict, stacklevel):
    array = _as_array(array)
    _warn_if_batch(array, stacklevel + 1)
    return _bettimill.topology(array, strict)


def betti(array, strict=False):
    """The Betti numbers ``[b_0, ..., b_{d-1}]`` of a binary image (see ``topology``)."""
    return _topology(array, strict, stacklevel=3)["betti"]


def euler(array, strict=False):
    """The Euler characteristic of a binary image (see ``topology``)."""
    return _topology(array, strict, stacklevel=3)["euler"]


def betti_batch(array, strict=False):
    """The Betti numbers of every image of a batch: a list with one ``[b_0, ...]`` per item
    of the leading axis. Items ``[1, *sides]`` (a channel axis of size 1, as in
    ``[B, 1, H, W]``) are read without it; each item must then have 2 to 4 axes.

    ``array``: a numpy array (or a torch tensor on the CPU, through ``numpy.asarray``)."""
    array = _as_array(array)
    if array.ndim < 3:
        raise ValueError(
            f"betti_batch takes a batch [B, ...] of 2D to 4D images, got shape {tuple(array.shape)}; "
            "use bettimill.betti for one image"
        )
    if array.ndim >= 4 and array.shape[1] == 1:
        array = array[:, 0]
    return [_bettimill.topology(item, strict)["betti"] for item in array]


def _console_script():
    """The ``bettimill`` console script of this installation, or None."""
    name = "bettimill.exe" if os.name == "nt" else "bettimill"
    candidate = os.path.join(sysconfig.get_path("scripts"), name)
    if os.path.isfile(candidate):
        return candidate
    return shutil.which("bettimill")


def build(manifest, out, workers=None, endpoint=None):
    """Builds (or resumes) the dataset of ``manifest`` in directory ``out``, as
    ``bettimill build MANIFEST --out OUT`` does, and returns its totals as a dict.

    ``manifest``: a path, TOML text, or None for the embedded demo manifest.
    ``out``: a directory, or ``s3://BUCKET/PREFIX`` (built in this process, credentials
    from the ``AWS_*`` variables, the server from ``endpoint`` or ``AWS_ENDPOINT_URL``, as
    ``bettimill build --out s3://... --endpoint URL``).
    ``workers``: None or 1 builds in this process (one core); more starts that many worker
    processes of the ``bettimill`` console script this package installs.
    """
    program = None
    if workers is not None and workers > 1:
        program = _console_script()
        if program is None:
            raise RuntimeError(
                "workers > 1 runs the `bettimill` console script, which is not installed "
                f"next to {sys.executable}; reinstall the package or use workers=1"
            )
    return _bettimill.build(manifest, os.fspath(out), workers, program, endpoint)


def verify(dir, endpoint=None):
    """Checks every shard of a built dataset against its ``index.json``; returns what
    ``bettimill verify DIR --json`` prints (``problems`` is empty when all is well).

    ``dir``: a directory, or ``s3://BUCKET/PREFIX``, read by ranges with the ``AWS_*``
    variables and ``endpoint`` (default ``AWS_ENDPOINT_URL``), as the CLI reads it."""
    return _bettimill.verify(os.fspath(dir), endpoint)
