"""bettimill: binary images of 2D, 3D and 4D with exact Betti numbers (over Z/2).

- ``betti(array)``, ``euler(array)``, ``topology(array)``: what ``bettimill betti --json``
  computes for the array (same checks, same messages, same numbers).
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

import numpy

from . import _bettimill
from ._bettimill import Plan, __version__, presets

__all__ = ["betti", "euler", "topology", "presets", "Plan", "build", "verify", "set_threads", "threads", "__version__"]

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


def topology(array, strict=False):
    """The topology of a binary image: a dict with ``betti`` (b_0..b_{d-1}), ``euler``,
    ``shape``, ``hypervolume`` (foreground voxels), ``field`` ("Z/2") and ``components``.

    ``array``: a numpy bool or integer array of 2 to 4 dimensions, in any memory order
    (read in place, not copied); non-zero is foreground. With ``strict=True`` values other
    than 0 and 1 are refused. Bad arrays raise ``ValueError`` with the message of
    ``bettimill betti``. The voxel model: union of closed voxels, foreground
    (3^d-1)-adjacency, background 2d-adjacency.
    """
    return _bettimill.topology(_as_array(array), strict)


def betti(array, strict=False):
    """The Betti numbers ``[b_0, ..., b_{d-1}]`` of a binary image (see ``topology``)."""
    return topology(array, strict)["betti"]


def euler(array, strict=False):
    """The Euler characteristic of a binary image (see ``topology``)."""
    return topology(array, strict)["euler"]


def _console_script():
    """The ``bettimill`` console script of this installation, or None."""
    name = "bettimill.exe" if os.name == "nt" else "bettimill"
    candidate = os.path.join(sysconfig.get_path("scripts"), name)
    if os.path.isfile(candidate):
        return candidate
    return shutil.which("bettimill")


def build(manifest, out, workers=None):
    """Builds (or resumes) the dataset of ``manifest`` in directory ``out``, as
    ``bettimill build MANIFEST --out OUT`` does, and returns its totals as a dict.

    ``manifest``: a path, TOML text, or None for the embedded demo manifest.
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
    return _bettimill.build(manifest, os.fspath(out), workers, program)


def verify(dir):
    """Checks every shard of a built dataset against its ``index.json``; returns what
    ``bettimill verify DIR --json`` prints (``problems`` is empty when all is well)."""
    return _bettimill.verify(os.fspath(dir))
