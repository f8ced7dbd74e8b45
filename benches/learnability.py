#!/usr/bin/env python3
"""Learnability: does a CNN trained on bettimill's data see holes in shapes it never saw?

Trains ``bettimill.torch.BettiNet4d`` (the package's 4D CNN) on 4D side-16 samples of one
KIND at a time and scores exact-Betti-vector accuracy (all four Betti numbers right) on
held-out samples of every kind. The kinds:

- ``canonical``: the constructions as built, no deformation;
- one kind per deformation method, that method alone (``moves``, ``dilate``, ``erode``,
  and ``tentacles``, ``walk`` when the installed bettimill knows them);
- ``binned``: the canonical constructions brought into hypervolume bins (BINS) that every
  class reaches, so that the foreground count does not tell the class; without bins each
  class's count sits in a narrow band of its own, and a model can read the label off it;
- ``binned-chain``: binned, and every deformation in turn with strengths drawn per sample
  from none upward (CHAIN), as the 4d-mixed-128 preset does, and necks (`pinch`) besides;
- ``families``: binned-chain over several constructions of each class (FAMILIES: curves,
  loops, bumpy spheres, objects with tentacles, pairs of different objects), not the
  canonical one alone;
- ``mix``: canonical and every deformation, in equal shares; ``mix-no-X``: the same
  without the deformation X (X is then a kind that model never saw); ``all``: every
  bettimill kind in equal shares;
- ``independent``: shapes of a generator written here in numpy, which no bettimill
  construction uses: thickened random-walk curves, unions of randomly oriented
  ellipsoids, closed random polygons, bumpy and bent 2-spheres, hollow bumpy blobs, in
  random 4D frames, splatted voxel by voxel. Each is labelled by ``bettimill.betti`` of its
  voxels (the verifier); a shape whose label is not the class it was drawn for is drawn
  again, so the held-out set has the same classes, in the same shares, as the others;
- ``independent-matched``: the same generator with every class at the same sizes (each
  shape scaled to a foreground fraction drawn from MATCHED), since as drawn its classes
  differ in size and the foreground count alone tells most of them apart.

Every kind has the same label classes, balanced (chance is 1/classes; the table's chance
row is the held-out set's most common class): Betti vectors [1,0,0,0], [1,1,0,0],
[2,0,0,0], [1,0,1,0], [1,0,0,1] in embed mode (a ball, S1xB3, two balls, S2xB2, a
thickened 3-sphere); in carve mode the carved cube's vectors of the same objects as
cavities, [1 + b3, b2, b1, b0], of those bettimill can carve at side 16 (the others are
left out with the plan's reason; [1,2,1,0], T2xB2, fits neither mode at side 16).
bettimill makes each class with its canonical construction (``betti = [...]`` classes of
the manifest).

Rows of the table are what a model trained on, columns the held-out kinds (and a row of
what the foreground count alone tells, per kind: the score with no hole seen); a model is
trained on each single kind (``independent`` included: the ceiling of this small set-up on
that generator), on the mix and on each mix that leaves one deformation out. Seeds are
fixed (numpy, torch, the manifests' seed; torch on one thread), so a re-run prints the
same table on the same machine. The run prints wall seconds per training. A training's
score on a held-out kind it never saw moves by up to about 0.1 with its seed alone;
``--repeats N`` trains each row N times from different seeds and shows the mean (and each
score's range over the trainings). ``--first-repeat K`` runs only trainings K to N-1 of those
N (their seeds unchanged), so that several processes can share one row's trainings.

Probes of what limits the transfer: ``--fresh`` trains a single kind on ``--train`` x
``--epochs`` distinct samples, each seen once (as an on-the-fly loader would), instead of
the same ``--train`` samples every epoch; ``--augment`` shows each batch in a random
symmetry of the 4D cube; ``--side 24`` gives the constructions room to vary (at side 16 a
handle needs a bounding radius of 5.25 voxels and the image offers 5.5), with the
independent generator's shapes scaled to keep their proportions; ``--kinds`` makes only
the listed kinds (a side-24 run of every kind takes hours); ``--confusion`` prints, for
every training and held-out kind, the share of each class answered right and the wrong
answer it gets most (which shapes a model misreads, and as what); ``--scales N`` trains
nothing and prints, per kind and class, how wide the holes and gaps of N held-out samples
are (the fewest Chebyshev dilations after which a Betti number is smaller) and how thin
their parts (the fewest erosions that change them); ``--min-closing K`` trains a single
kind only on its samples whose closing scale is at least K (their narrowest hole or gap
survives K - 1 dilations), taken from its training set and ``--extra`` more samples, the
classes balanced; the held-out sets stay as made.

Run by hand (not in CI), from the repository root, with bettimill and torch installed
(``ci/python-env.sh`` makes a venv with torch; build the package into it with
``pip install ./python`` or ``ci/python-package.sh``):

    python benches/learnability.py                     # embed mode, the table of BENCHMARKS.md
    python benches/learnability.py --mode carve        # the same classes as cavities
    python benches/learnability.py --quick             # 48 samples a kind, 2 epochs: a smoke run
    python benches/learnability.py --train 2400 --mix 4800 --repeats 3 \
        --rows canonical,binned,binned-chain,families,independent,all   # the transfer table
    python benches/learnability.py --train 2400 --rows families --fresh   # a probe
    python benches/learnability.py --side 24 --train 4800 --rows families,independent,independent-matched \
        --kinds families,independent,independent-matched   # the other generator, sizes matched

On a shared 2-core machine the default run takes about 20 minutes with the three older
deformations, nearly all of it training (one torch thread; a training of 480 samples
takes about a minute, a mix of 960 about two); the samples are made on 2 threads
(``--threads``). ``--cache DIR`` keeps the made samples
(``.npz`` per kind, named by the manifest's text and bettimill's build) for re-runs.
"""

import argparse
import concurrent.futures
import hashlib
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
import torch

import bettimill
from bettimill.torch import BettiNet4d

SIDE = 16
# The objects' Betti vectors; carve mode asks for the carved cube's vectors of the same
# objects as cavities (see `carved`).
CLASSES = [[1, 0, 0, 0], [1, 1, 0, 0], [2, 0, 0, 0], [1, 0, 1, 0], [1, 0, 0, 1]]
MAX_BETTI = 2

# Deformations, each alone, in the manifest's `[[deform]]` steps with ranges drawn per
# sample (the current schema) ...
DEFORMS = {
    "moves": [{"method": "moves", "steps": [100, 600], "noise_frequency": [0.05, 0.3]}],
    "dilate": [{"method": "dilate", "steps": [1, 6], "noise_frequency": [0.05, 0.3],
                "growth_probability": [0.2, 0.8]}],
    "erode": [{"method": "erode", "steps": [1, 6], "noise_frequency": [0.05, 0.3],
               "growth_probability": [0.2, 0.8]}],
    "tentacles": [{"method": "tentacles", "steps": [3, 8], "count": [1, 4]}],
    "walk": [{"method": "walk", "steps": [8, 30], "count": [1, 3]}],
}
# Hypervolume bins (fractions of the 16^4 image) that every class reaches at side 16: with
# them each class spans the same foreground counts, so the count alone does not tell the
# class (without bins each class's count sits in a narrow band of its own). They span the
# sizes other shapes take, not only ours: the independent generator's balls and loops hold
# 0.1-1% of the image, its hollow blobs 3-8%, and a model trained on 0.4-6% read nearly
# every hollow blob as a 2-sphere. The smallest bin stays above the thinnest 4D shell
# (about 140 voxels, 0.2%).
# The manifests' `clearance` (--clearance), `inner_gap` (--inner-gap) and
# `survives_dilations` (--survives-dilations); None leaves each out.
CLEARANCE = None
INNER_GAP = None
SURVIVES = None
# A smaller bin for the families' classes that reach it (all but the hollow ones, whose
# wall around a cavity that survives a dilation needs more voxels). The other generator's
# balls, pairs and loops hold 0.1-1% of a side-24 image, four in ten of its pairs less than
# BINS' smallest bin; models trained without this bin read four in five of those as one.
SMALL_BIN = [0.001, 0.0025]
BINS = [[0.0025, 0.004], [0.004, 0.01], [0.01, 0.02], [0.02, 0.035], [0.035, 0.06], [0.06, 0.09]]
# Every deformation in turn, each sample drawing its strengths (from none) per step, as
# the 4d-mixed-128 preset does, with necks besides: without them the other generator's
# chains of blobs read as two parts.
CHAIN = [
    {"method": "erode", "steps": [0, 3], "noise_frequency": [0.05, 0.3], "growth_probability": [0.2, 0.8]},
    {"method": "dilate", "steps": [0, 3], "noise_frequency": [0.05, 0.3], "growth_probability": [0.2, 0.8]},
    {"method": "pinch", "steps": [0, 6], "count": [1, 2], "growth_probability": [0.5, 1.0]},
    {"method": "tentacles", "steps": [0, 8], "count": [1, 4]},
    {"method": "walk", "steps": [0, 30], "count": [1, 3]},
    {"method": "moves", "steps": [0, 600], "noise_frequency": [0.05, 0.3]},
]
# Constructions of each object class beyond the canonical one, as `[[classes]]` bodies:
# long thin curves, closed curves that are not round, spheres that are not round, objects
# with tentacles, two objects (two curves among them). Without them
# every one-component training object is compact and a long or spread-out shape reads as
# two components (the families that fit at side 16; knots and links need a larger side).
FAMILIES = {
    (1, 0, 0, 0): ['family = "ball"', 'family = "curve"',
                   'family = "tentacled"\ntentacles = 2\nobject = { family = "ball" }',
                   'family = "tentacled"\ntentacles = 3\nobject = { family = "curve" }'],
    (1, 1, 0, 0): ['family = "handle"', 'family = "loop"',
                   'family = "tentacled"\ntentacles = 1\nobject = { family = "loop" }',
                   'family = "tentacled"\ntentacles = 3\nobject = { family = "loop" }',
                   'family = "tentacled"\ntentacles = 2\nobject = { family = "handle" }'],
    (2, 0, 0, 0): ['family = "scene"\nobjects = [{ family = "ball" }, { family = "ball" }]',
                   'family = "scene"\nobjects = [{ family = "tentacled", tentacles = 1, object = { family = "ball" } }, { family = "ball" }]',
                   'family = "scene"\nobjects = [{ family = "tentacled", tentacles = 1, object = { family = "curve" } }, { family = "ball" }]',
                   'family = "scene"\nobjects = [{ family = "curve" }, { family = "curve" }]',
                   'family = "scene"\nobjects = [{ family = "tentacled", tentacles = 2, object = { family = "curve" } }, { family = "curve" }]'],
    (1, 0, 1, 0): ['family = "s2_x_b2"', 'family = "bumpy_s2_x_b2"'],
    (1, 0, 0, 1): ['family = "shell"', 'family = "bumpy_shell"'],
}
# ... or, for a bettimill whose `[deform]` is one table of fixed values: the strengths
# first measured (dilate x4, moves x300) and erode like dilate.
DEFORMS_SINGLE = {
    "moves": {"method": "moves", "steps": 300},
    "dilate": {"method": "dilate", "steps": 4},
    "erode": {"method": "erode", "steps": 4},
}


def carved(betti):
    """The carved cube's Betti vector when the object with vector `betti` is its cavity
    (Alexander duality): b0 = 1 + b3, b1 = b2, b2 = b1, b3 = b0 of the object."""
    return [1 + betti[3], betti[2], betti[1], betti[0]]


def toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    return "[" + ", ".join(toml_value(x) for x in v) + "]"


def manifest(kind_deform, mode, samples, seed, single, classes=CLASSES, bins=None):
    """A manifest of `samples` samples of the object classes `classes` (as the carved
    cube's vectors in carve mode), with the deformation `kind_deform` (steps, or one table
    when `single`)."""
    classes = classes if mode == "embed" else [carved(c) for c in classes]
    lines = [
        "schema_version = 1",
        'name = "learnability"',
        "dimension = 4",
        f"side = {SIDE}",
        f'mode = "{mode}"',
        f"samples = {samples}",
        f"shard_size = {samples}",
        f"seed = {seed}",
    ]
    if CLEARANCE is not None:
        lines.append(f"clearance = {CLEARANCE}")
    if INNER_GAP is not None:
        lines.append(f"inner_gap = {INNER_GAP}")
    if SURVIVES is not None:
        lines.append(f"survives_dilations = {SURVIVES}")
    for c in classes:
        lines += ["", "[[classes]]", f"betti = {toml_value(c)}"]
    if kind_deform is not None:
        steps = [kind_deform] if single else kind_deform
        for step in steps:
            lines += ["", "[deform]" if single else "[[deform]]"]
            lines += [f"{k} = {toml_value(v)}" for k, v in step.items()]
    if bins is not None:
        lines += ["", "[hypervolume]", 'unit = "fraction"', f"bins = {toml_value(bins)}"]
    return "\n".join(lines) + "\n"


def feasible(mode):
    """The classes of CLASSES that bettimill builds at side SIDE in this mode (each class
    planned alone); the others are logged with the plan's reason."""
    keep = []
    for c in CLASSES:
        try:
            bettimill.Plan(manifest(None, mode, 1, 1, False, [c]))
            # The binned kinds need every bin: a class that fits but cannot be brought into
            # one (a carved hollow ball's thin shell stays above the smallest cavity bin at
            # side 16) is left out too, rather than binned differently from the others.
            try:
                bettimill.Plan(manifest(None, mode, 1, 1, False, [c], bins(mode)))
            except ValueError as err:
                if "field `bins`" in str(err):
                    raise
            keep.append(c)
        except ValueError as err:
            log(f"class {c if mode == 'embed' else carved(c)} left out: {str(err).splitlines()[-1]}")
    if len(keep) < 2:
        sys.exit(f"fewer than two classes can be built in {mode} mode at side {SIDE}")
    return keep


def deformations(mode, classes):
    """The deformation kinds the installed bettimill accepts, and whether its `[deform]` is
    the single-table schema. Probed by planning a one-step manifest per method."""
    kinds = {}
    for name, steps in DEFORMS.items():
        try:
            bettimill.Plan(manifest(steps, mode, 5, 1, False, classes))
            kinds[name] = steps
        except ValueError:
            pass
    if kinds:
        return kinds, False
    for name, table in DEFORMS_SINGLE.items():
        bettimill.Plan(manifest(table, mode, 5, 1, True, classes))
        kinds[name] = table
    return kinds, True


# ---------------------------------------------------------------- bettimill's samples


def plan_samples(text, count, threads):
    """Voxels [count, SIDE^4] uint8 and Betti vectors [count, 4] of a plan's first samples
    (plan.sample releases the GIL, so threads make them in parallel)."""
    plan = bettimill.Plan(text)
    with concurrent.futures.ThreadPoolExecutor(threads) as pool:
        made = list(pool.map(plan.sample, range(count)))
    voxels = np.stack([v for v, _ in made])
    betti = np.array([label["betti"] for _, label in made], dtype=np.int64)
    return voxels, betti


# ---------------------------------------------------------------- the independent generator

def scale():
    """The generator's lengths are written for side 16; at another side every length
    (positions, radii, gaps) is multiplied by SIDE / 16, so its shapes keep their
    proportions to the image."""
    return SIDE / 16


def grid():
    """Every voxel's coordinates in the generator's side-16 units, [SIDE]*4 + [4]."""
    return np.stack(np.meshgrid(*[np.arange(SIDE) / scale()] * 4, indexing="ij"), -1)


def splat(points, radii):
    """A boolean image: the voxels (centres at integer coordinates) within radii[i] of
    points[i] for some i (both in side-16 units)."""
    points, radii = points * scale(), radii * scale()
    image = np.zeros((SIDE,) * 4, bool)
    # Integer offsets of the voxels near a point's floor, far enough for the largest radius.
    reach = int(np.ceil(radii.max())) + 1
    every = np.stack(np.meshgrid(*[np.arange(-reach, reach + 2)] * 4, indexing="ij"), -1).reshape(-1, 4)
    gap = np.sqrt((np.maximum(0, np.maximum(-every, every - 1)) ** 2).sum(1))
    offsets = every[gap <= radii.max()]
    for start in range(0, len(points), 512):
        p = points[start:start + 512]
        r = radii[start:start + 512]
        cells = np.floor(p).astype(np.int64)[:, None, :] + offsets[None]
        near = ((cells - p[:, None, :]) ** 2).sum(-1) <= (r[:, None] ** 2)
        inside = ((cells >= 0) & (cells < SIDE)).all(-1)
        hit = cells[near & inside]
        image[tuple(hit.T)] = True
    return image


def frame(rng):
    """A random orthonormal basis of R^4 (rows)."""
    q, r = np.linalg.qr(rng.normal(size=(4, 4)))
    return (q * np.sign(np.diag(r))).T


def polyline(vertices, closed, spacing=0.25):
    if closed:
        vertices = np.vstack([vertices, vertices[:1]])
    out = []
    for a, b in zip(vertices[:-1], vertices[1:]):
        n = max(2, int(np.ceil(np.linalg.norm(b - a) / spacing)))
        out.append(a + (b - a) * np.linspace(0, 1, n, endpoint=False)[:, None])
    return np.vstack(out)


def wavy_radii(rng, n, lo, hi, s=1.0):
    """Tube radii along a curve of n points: a random level with a slow wave on it (all
    lengths times `s`)."""
    base = rng.uniform(lo, hi)
    wave = rng.uniform(0.0, 0.3) * np.sin(np.linspace(0, rng.uniform(2, 12), n) + rng.uniform(0, 6.3))
    return np.clip(base * (1 + wave), 1.05, 2.4) * s


def walk(rng, lo, hi, s=1.0):
    """A thickened open random walk inside the box [lo, hi]^4 (a ball, if it does not cross
    itself); steps and radii times `s`."""
    vertices = [rng.uniform(lo + 1.5, hi - 1.5, 4)]
    for _ in range(rng.integers(2, 7)):
        step = rng.normal(size=4)
        nxt = vertices[-1] + step / np.linalg.norm(step) * rng.uniform(2.0, 4.5) * s
        vertices.append(np.clip(nxt, lo, hi))
    points = polyline(np.array(vertices), closed=False)
    return splat(points, wavy_radii(rng, len(points), 1.1, 2.0, s))


def blob(rng, lo, hi, s=1.0):
    """A chain of 1-4 overlapping, randomly oriented ellipsoids inside [lo, hi]^4; their
    axes and offsets times `s`."""
    points = grid()
    image = np.zeros((SIDE,) * 4, bool)
    centre = rng.uniform(lo + 1, hi - 1, 4)
    for _ in range(rng.integers(1, 5)):
        axes = frame(rng)
        semi = rng.uniform(1.3, 3.5, 4) * s
        local = (points - centre) @ axes.T / semi
        image |= (local ** 2).sum(-1) <= 1
        centre = np.clip(centre + rng.normal(size=4) * 1.5 * s, lo + 1, hi - 1)
    return image & ((points >= np.ceil(lo)) & (points <= np.floor(hi))).all(-1)


def loop(rng, s=1.0):
    """A thickened closed random polygon around the middle, in a random 2-plane with jitter
    out of it; its radii and tube times `s`."""
    axes = frame(rng)
    centre = rng.uniform(6.5, 8.5, 4)
    n = rng.integers(5, 10)
    angles = np.sort(rng.uniform(0, 2 * np.pi, n))
    radius = rng.uniform(3.5, 5.8, n) * s
    plane = np.stack([radius * np.cos(angles), radius * np.sin(angles)], 1)
    off = rng.normal(scale=0.8, size=(n, 2)) * s
    vertices = centre + plane @ axes[:2] + off @ axes[2:]
    points = polyline(vertices, closed=True)
    return splat(points, wavy_radii(rng, len(points), 1.1, 1.7, s))


def fibonacci_sphere(n):
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    phi = np.pi * (1 + 5 ** 0.5) * k
    s = np.sqrt(1 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], 1)


def sphere(rng, s=1.0):
    """A bumpy, stretched 2-sphere in a random 3-space of R^4, bent into the fourth
    direction, thickened; its radius, bend and thickness times `s`."""
    axes = frame(rng)
    d = fibonacci_sphere(2500)
    bumps = rng.normal(size=(3, 3)) * 0.12
    radius = rng.uniform(3.6, 5.2) * (1 + ((d @ bumps) * d).sum(1)) * np.exp(d @ rng.normal(scale=0.1, size=3))
    surface = (d * radius[:, None]) * rng.uniform(0.85, 1.15, 3) * s
    bend = (d @ rng.normal(scale=1.2, size=3)) ** 2 * rng.choice([-1, 1]) * s
    points = rng.uniform(7.0, 8.0, 4) + surface @ axes[:3] + bend[:, None] * 0.4 * axes[3]
    return splat(points, np.full(len(points), rng.uniform(1.05, 1.5) * s))


def shell(rng, s=1.0):
    """A hollow blob: the voxels between two nested bumpy, stretched 3-spheres about a
    point, in a random frame; its radius and wall times `s`."""
    y = (grid() - rng.uniform(7.0, 8.0, 4)) @ frame(rng).T / rng.uniform(0.85, 1.15, 4)
    rho = np.sqrt((y ** 2).sum(-1)) + 1e-9
    u = y / rho[..., None]
    bumps = rng.normal(size=(4, 4)) * 0.08
    outer = rng.uniform(4.6, 6.0) * (1 + np.einsum("...i,ij,...j->...", u, bumps, u)) + u @ rng.normal(scale=0.3, size=4)
    return (rho <= outer * s) & (rho > (outer - rng.uniform(1.4, 2.2)) * s)


def candidate(rng, target, s=1.0):
    """One shape drawn for the object vector `target` (its label may still differ), its
    lengths times `s`."""
    if target == [1, 0, 0, 0]:
        return walk(rng, 1.5, 13.5, s) if rng.random() < 0.5 else blob(rng, 1, 14, s)
    if target == [2, 0, 0, 0]:
        axis, gap = rng.integers(4), rng.uniform(7.0, 8.0)
        parts = []
        for lo, hi in ((1.5, gap - 1.2), (gap + 1.2, 13.5)):
            part = walk(rng, 1.5, 13.5, s) if rng.random() < 0.5 else blob(rng, 1, 14, s)
            coordinate = np.arange(SIDE) / scale()
            keep = (coordinate >= np.ceil(lo)) & (coordinate <= np.floor(hi))
            shape = [1, 1, 1, 1]
            shape[axis] = SIDE
            parts.append(part & keep.reshape(shape))
        return parts[0] | parts[1]
    if target == [1, 1, 0, 0]:
        return loop(rng, s)
    if target == [1, 0, 1, 0]:
        return sphere(rng, s)
    if target == [1, 0, 0, 1]:
        return shell(rng, s)
    raise ValueError(target)


# As drawn, the generator's classes differ in size: its balls, pairs and loops hold 0.1-1%
# of a side-24 image, its 2-spheres 1-4%, its hollow blobs 3-8%, so the foreground count
# alone tells 3 classes in 5 apart. `independent-matched` gives every sample a foreground
# fraction to aim at, drawn log-uniformly from MATCHED whatever the class, and scales the
# drawn shape (every length by one factor, found in a few renders since a fraction grows
# about as its fourth power) until it is within 10% of the aim: every class then has the
# same sizes, and a model must see the holes.
MATCHED = (0.01, 0.03)


def aimed(seed, target, aim, renders=6):
    """A shape drawn for `target` from `seed`, scaled so that its foreground fraction is
    within 10% of `aim`; None if `renders` scalings do not get it there."""
    scale = 1.0
    for _ in range(renders):
        shape = candidate(np.random.default_rng(seed), target, scale)
        share = shape.mean()
        if abs(np.log(max(share, 1e-9) / aim)) < np.log(1.1):
            return shape
        scale = float(np.clip(scale * (aim / max(share, 1e-6)) ** 0.25, 0.4, 3.0))
    return None


def independent_samples(count, mode, seed, classes, tries=400, matched=False):
    """`count` shapes of the numpy generator, the classes in turn, each labelled by
    bettimill.betti; with `matched`, each scaled to a size drawn from MATCHED (see there).
    Returns voxels, Betti vectors and the share of candidates accepted."""
    rng = np.random.default_rng(seed)
    voxels, betti, drawn = [], [], 0
    for i in range(count):
        target = classes[i % len(classes)]
        want = target if mode == "embed" else carved(target)
        aim = float(np.exp(rng.uniform(*np.log(MATCHED)))) if matched else None
        for _ in range(tries):
            drawn += 1
            if matched:
                shape = aimed(rng.integers(2 ** 63), target, aim)
                if shape is None:
                    continue
            else:
                shape = candidate(rng, target)
            # Carve mode: the shape is a cavity of the full cube; the cube's border stays
            # solid (the generator's shapes stay at least one voxel inside it).
            image = shape if mode == "embed" else ~shape
            if mode == "carve":
                image = image.copy()
                for axis in range(4):
                    index = [slice(None)] * 4
                    index[axis] = [0, SIDE - 1]
                    image[tuple(index)] = True
            image = image.astype(np.uint8)
            label = bettimill.betti(image)
            if label == want:
                voxels.append(image)
                betti.append(label)
                break
        else:
            sys.exit(f"independent generator: no {want} in {tries} candidates")
    return np.stack(voxels), np.array(betti, dtype=np.int64), count / drawn


# ---------------------------------------------------------------- data sets


def engine():
    """bettimill's version and a digest of its compiled module: the identity of the code
    that made the samples. A build between releases keeps the version string, so a key of
    the version alone would hand it the samples of an older build."""
    with open(bettimill._bettimill.__file__, "rb") as f:
        return f"{bettimill.__version__} {hashlib.blake2b(f.read(), digest_size=8).hexdigest()}"


def cached(cache, key, make):
    if cache is None:
        return make()
    path = Path(cache) / (hashlib.blake2b(key.encode(), digest_size=10).hexdigest() + ".npz")
    if path.exists():
        data = np.load(path)
        return data["voxels"], data["betti"]
    voxels, betti = make()
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, voxels=voxels, betti=betti)
    os.replace(tmp, path)
    return voxels, betti


def bins(mode):
    """BINS as the manifest's foreground fractions: the objects' counts in embed mode, the
    full cube (one background layer on every face) less the cavities' counts in carve mode."""
    if mode == "embed":
        return BINS
    cube = ((SIDE - 2) / SIDE) ** 4
    return [[round(cube - hi, 4), round(cube - lo, 4)] for lo, hi in reversed(BINS)]


def family_samples(mode, classes, count, seed, threads):
    """`count` samples of the FAMILIES of `classes`, with BINS and CHAIN: one plan per object
    class (its families balanced within it), interleaved so the classes take turns."""
    per = -(-count // len(classes))
    parts = []
    for c in classes:
        bodies = []
        for body in FAMILIES[tuple(c)]:
            text = manifest(None, mode, 1, 1, False, [], bins(mode)) + f"\n[[classes]]\n{body}\n"
            try:
                bettimill.Plan(text)
                bodies.append(body)
            except ValueError as err:
                log(f"families: {body.splitlines()[0]} of {c} left out: {str(err).splitlines()[-1]}")
        classes_text = "".join(f"\n[[classes]]\n{body}\n" for body in bodies)
        text = manifest(CHAIN, mode, per, seed, False, [], bins(mode)) + classes_text
        if SMALL_BIN and mode == "embed":
            small = manifest(CHAIN, mode, per, seed, False, [], [SMALL_BIN] + BINS) + classes_text
            try:
                bettimill.Plan(small)
                text = small
            except ValueError as err:
                log(f"families: {c} keeps BINS: {str(err).splitlines()[-1][:120]}")
        parts.append(plan_samples(text, per, threads))
    voxels = np.stack([parts[i % len(parts)][0][i // len(parts)] for i in range(count)])
    betti = np.stack([parts[i % len(parts)][1][i // len(parts)] for i in range(count)])
    return voxels, betti


def kind_recipes(mode):
    """{kind: how bettimill makes it} for the kinds the installed bettimill knows, the
    feasible classes, and whether its `[deform]` is one table."""
    classes = feasible(mode)
    deforms, single = deformations(mode, classes)
    kinds = {"canonical": (None, None), **{name: (steps, None) for name, steps in deforms.items()}}
    if not single:
        kinds["binned"] = (None, bins(mode))
        kinds["binned-chain"] = (CHAIN, bins(mode))
        kinds["families"] = None
    kinds["independent"] = None
    kinds["independent-matched"] = None
    return kinds, classes, list(deforms), single


def kind_samples(name, recipe, args, classes, single, count, seed):
    """`count` samples of kind `name` made from `seed` (cached), voxels and Betti vectors."""
    start = time.perf_counter()
    # Keys of side-16 runs stay as they were, so their caches stay valid.
    side = "" if SIDE == 16 else f" side {SIDE}"
    accepted = []
    if name == "families":
        key = f"families {engine()} {args.mode} {count} {seed} {classes} {FAMILIES} {CHAIN} {BINS}{side}"
        if CLEARANCE is not None:
            key += f" clearance {CLEARANCE}"
        if INNER_GAP is not None:
            key += f" inner_gap {INNER_GAP}"
        if SURVIVES is not None:
            key += f" survives_dilations {SURVIVES}"
        if SMALL_BIN:
            key += f" small_bin {SMALL_BIN}"
        voxels, betti = cached(args.cache, key,
                               lambda: family_samples(args.mode, classes, count, seed, args.threads))
    elif name in ("independent", "independent-matched"):
        matched = name == "independent-matched"

        def make():
            voxels, betti, share = independent_samples(count, args.mode, seed, classes, matched=matched)
            accepted.append(share)
            return voxels, betti

        key = f"independent v1 {args.mode} {count} {seed} {classes}{side}"
        if matched:
            key += f" matched {MATCHED}"
        voxels, betti = cached(args.cache, key, make)
    else:
        deform, kind_bins = recipe
        text = manifest(deform, args.mode, count, seed, single, classes, kind_bins)
        voxels, betti = cached(args.cache, f"{engine()}\n{text}",
                               lambda: plan_samples(text, count, args.threads))
    log(f"{name}: {count} samples in {time.perf_counter() - start:.1f} s"
        + (f", {accepted[0]:.0%} of the candidates accepted" if accepted else ""))
    return voxels, betti


def datasets(args):
    """{kind: (train voxels, train betti, test voxels, test betti)}, the deformation kinds,
    whether the installed bettimill's `[deform]` is one table, and a maker of more samples
    of a kind (`make(name, count, seed)`)."""
    kinds, classes, deforms, single = kind_recipes(args.mode)

    def make(name, count, seed):
        return kind_samples(name, kinds[name], args, classes, single, count, seed)

    data = {}
    for name in kinds:
        if args.kinds and name not in args.kinds.split(","):
            continue
        voxels, betti = make(name, args.train + args.test, args.seed)
        data[name] = (voxels[:args.train], betti[:args.train], voxels[args.train:], betti[args.train:])
    return data, deforms, single, make


def mix(data, kinds, size):
    """`size` training samples, in equal shares from each kind's training set (its first
    ones, which go through the classes in turn)."""
    share = size // len(kinds)
    voxels = np.concatenate([data[k][0][:share] for k in kinds])
    betti = np.concatenate([data[k][1][:share] for k in kinds])
    return voxels, betti


# ---------------------------------------------------------------- training


def train(voxels, betti, args, seed):
    torch.manual_seed(seed)
    model = BettiNet4d(dimension=4, max_betti=MAX_BETTI, width=args.width)
    optimiser = torch.optim.Adam(model.parameters(), lr=args.lr)
    x = torch.from_numpy(voxels)
    y = torch.from_numpy(betti).clamp(max=MAX_BETTI)
    order_rng = torch.Generator().manual_seed(seed)
    symmetry_rng = np.random.default_rng(seed)
    # The learning rate falls to zero along a cosine: the last epochs settle the weights,
    # so the score does not depend on where the last step happened to land.
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, args.epochs * -(-len(x) // args.batch))
    model.train()
    for _ in range(args.epochs):
        order = torch.randperm(len(x), generator=order_rng)
        for start in range(0, len(x), args.batch):
            pick = order[start:start + args.batch]
            batch = x[pick]
            if args.augment:
                # One of the 384 symmetries of the 4D cube per batch (a permutation of the
                # axes and flips of some): the Betti numbers do not change, the picture does.
                batch = batch.permute(0, *(1 + symmetry_rng.permutation(4)).tolist())
                flips = [1 + axis for axis in range(4) if symmetry_rng.random() < 0.5]
                if flips:
                    batch = batch.flip(flips)
            logits = model(batch.unsqueeze(1).float())
            loss = torch.nn.functional.cross_entropy(logits.reshape(-1, MAX_BETTI + 1), y[pick].reshape(-1))
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            schedule.step()
    model.eval()
    return model


def predict(model, voxels):
    with torch.no_grad():
        return torch.cat([model(torch.from_numpy(voxels[s:s + 32]).unsqueeze(1).float()).argmax(dim=2)
                          for s in range(0, len(voxels), 32)])


def exact_accuracy(model, voxels, betti):
    truth = torch.from_numpy(betti).clamp(max=MAX_BETTI)
    return (predict(model, voxels) == truth).all(dim=1).float().mean().item()


def confusion(model, voxels, betti):
    """Per true Betti vector: its share answered right and its most common wrong answer."""
    predicted = predict(model, voxels).tolist()
    truth = np.minimum(betti, MAX_BETTI).tolist()
    lines = []
    for label in sorted({tuple(t) for t in truth}):
        answers = [tuple(p) for p, t in zip(predicted, truth) if tuple(t) == label]
        wrong = [a for a in answers if a != label]
        common = max(set(wrong), key=wrong.count) if wrong else None
        lines.append(f"{list(label)} {1 - len(wrong) / len(answers):.2f}"
                     + (f" (else mostly {list(common)}, {wrong.count(common)})" if wrong else ""))
    return "; ".join(lines)


def chebyshev_step(image, grow):
    """`image` dilated (grow) or eroded by one voxel in the Chebyshev metric (the 3^4 cube),
    outside the image counting as background."""
    out = image.copy()
    for axis in range(4):
        step = out.copy()
        for shift in (1, -1):
            moved = np.roll(out, shift, axis=axis)
            edge = [slice(None)] * 4
            edge[axis] = 0 if shift == 1 else -1
            moved[tuple(edge)] = False
            step = (step | moved) if grow else (step & moved)
        out = step
    return out


def feature_scales(image, most=6):
    """(closing, opening): the fewest Chebyshev dilations of the foreground after which one
    of its Betti numbers is smaller (its narrowest hole or gap has closed: parts merged, a
    hole filled; new holes that rough surfaces make do not count), and the fewest erosions
    after which its Betti numbers differ (its thinnest part has broken or vanished); `most`
    + 1 when none up to `most` does. Closing 1 means a hole or gap at most two voxels
    wide."""
    shape = image.astype(bool)
    label = bettimill.betti(shape.astype(np.uint8))
    return steps_to_change(shape, label, True, most), steps_to_change(shape, label, False, most)


def steps_to_change(shape, label, grow, most):
    """The fewest Chebyshev dilations (`grow`) or erosions of `shape`, at most `most`, after
    which its Betti numbers (`label`) have one smaller (dilations) or differ (erosions);
    `most` + 1 when none does."""
    current = shape
    for k in range(1, most + 1):
        current = chebyshev_step(current, grow)
        now = bettimill.betti(current.astype(np.uint8))
        if (any(n < o for n, o in zip(now, label)) if grow else now != label):
            return k
    return most + 1


def closing_at_least(image, label, least):
    """Whether the narrowest hole or gap of `image` survives `least` - 1 Chebyshev
    dilations (`feature_scales`' closing scale is at least `least`)."""
    return steps_to_change(image.astype(bool), label, True, least - 1) >= least


def wide_training(name, voxels, betti, make, args):
    """The training set of kind `name` with only samples whose closing scale is at least
    --min-closing: from its own samples, then from --extra more made from another seed,
    the first of each class in turn, classes balanced."""
    # The classes in the order the training set takes them in turn.
    classes = [list(c) for c in dict.fromkeys(tuple(int(x) for x in b) for b in betti)]
    extra_voxels, extra_betti = make(name, args.extra, args.seed + 99)
    pool_voxels = np.concatenate([voxels, extra_voxels])
    pool_betti = np.concatenate([betti, extra_betti])
    wide = np.array([closing_at_least(v, list(b), args.min_closing) for v, b in zip(pool_voxels, pool_betti)])
    share = len(voxels) // len(classes)
    picks = []
    for c in classes:
        found = np.flatnonzero((pool_betti == c).all(axis=1) & wide)
        log(f"{name}: {len(found)} of {int((pool_betti == c).all(axis=1).sum())} samples of {c} "
            f"have a closing scale of at least {args.min_closing}")
        if len(found) < share:
            sys.exit(f"--min-closing {args.min_closing}: {name} has {len(found)} wide samples of {c}, "
                     f"the training needs {share}; make more with a larger --extra")
        picks.append(found[:share])
    order = np.array([picks[k][i] for i in range(share) for k in range(len(classes))])
    return pool_voxels[order], pool_betti[order]


def scales_table(data, count):
    """Per kind and class of the held-out samples: how many have closing (opening) scale
    1, 2, 3, 4 and more: the widths of their holes and gaps (and of their parts)."""
    print(f"Feature scales of the first {count} held-out samples of each kind, 4D side {SIDE}: per "
          "class, the number of samples whose closing scale (fewest Chebyshev dilations after which a "
          "Betti number is smaller: how wide the narrowest hole or gap is) and opening scale "
          "(fewest erosions that change them: how thick the thinnest part is) is 1, 2, 3, 4+.\n")
    print("| kind | class | samples | closing 1 / 2 / 3 / 4+ | opening 1 / 2 / 3 / 4+ |")
    print("|---|---|---|---|---|")
    for kind, (_, _, voxels, betti) in data.items():
        found = {}
        for image, label in zip(voxels[:count], betti[:count]):
            found.setdefault(tuple(int(b) for b in label), []).append(feature_scales(image))
        for label in sorted(found):
            pairs = np.array(found[label])
            cells = []
            for column in (0, 1):
                hist = np.bincount(np.minimum(pairs[:, column], 4), minlength=5)[1:]
                cells.append(" / ".join(str(n) for n in hist))
            print(f"| {kind} | {list(label)} | {len(pairs)} | {cells[0]} | {cells[1]} |")


def count_alone(data, bins=10):
    """A kind's held-out accuracy of a guess from the foreground count alone: the commonest
    training class in each of `bins` bins (equal shares of the training samples) of its
    training samples' counts. Above chance, the count tells classes apart; a model may
    score without seeing a hole."""
    train_voxels, train_betti, test_voxels, test_betti = data
    counts = train_voxels.reshape(len(train_voxels), -1).sum(1)
    edges = np.quantile(counts, np.linspace(0, 1, bins + 1))[1:-1]
    keys = [tuple(b) for b in train_betti.tolist()]
    guess = {}
    for k, key in zip(np.searchsorted(edges, counts, side="right"), keys):
        guess.setdefault(int(k), []).append(key)
    guess = {k: max(set(v), key=v.count) for k, v in guess.items()}
    test_counts = test_voxels.reshape(len(test_voxels), -1).sum(1)
    picks = [guess.get(int(k)) for k in np.searchsorted(edges, test_counts, side="right")]
    return float(np.mean([p == tuple(b) for p, b in zip(picks, test_betti.tolist())]))


def chance(betti):
    _, counts = np.unique(betti, axis=0, return_counts=True)
    return counts.max() / len(betti)


def log(message):
    print(message, file=sys.stderr, flush=True)


def machine():
    cpu = platform.processor() or platform.machine()
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, torch {torch.__version__}"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mode", choices=["embed", "carve"], default="embed")
    parser.add_argument("--train", type=int, default=480, help="training samples a kind")
    parser.add_argument("--test", type=int, default=250, help="held-out samples a kind")
    parser.add_argument("--mix", type=int, default=960, help="training samples of a mix")
    parser.add_argument("--epochs", type=int, default=12)
    parser.add_argument("--batch", type=int, default=8)
    parser.add_argument("--width", type=int, default=8, help="BettiNet4d's width")
    parser.add_argument("--lr", type=float, default=3e-3)
    parser.add_argument("--seed", type=int, default=20261204)
    parser.add_argument("--threads", type=int, default=2, help="threads that make the samples")
    parser.add_argument("--cache", help="directory that keeps the made samples for re-runs")
    parser.add_argument("--quick", action="store_true", help="48 samples a kind, 20 held out, 2 epochs")
    parser.add_argument("--json", help="also write the table as JSON to this file")
    parser.add_argument("--repeats", type=int, default=1,
                        help="trainings per row, each from its own seed; the table shows their mean")
    parser.add_argument("--first-repeat", type=int, default=0,
                        help="run only trainings K..N-1 of --repeats N, seeds as in the full run")
    parser.add_argument("--rows", help="comma-separated trainings to run (e.g. canonical,mix); default all")
    parser.add_argument("--kinds", help="comma-separated kinds to make (held-out columns); default all")
    parser.add_argument("--side", type=int, default=16,
                        help="the images' side (the independent generator scales its shapes with it)")
    parser.add_argument("--clearance", help="the manifests' `clearance` (e.g. '[1, 5]'): the narrowest gap "
                             "growth leaves, drawn per sample")
    parser.add_argument("--inner-gap", type=float,
                        help="the manifests' `inner_gap`: how wide constructions build their holes, "
                             "the insides of shells and the gaps between strands (voxels)")
    parser.add_argument("--survives-dilations", type=int, metavar="N",
                        help="the manifests' `survives_dilations`: bettimill makes again each sample "
                             "whose holes or gaps N dilations close (the last attempts skip the check)")
    parser.add_argument("--augment", action="store_true",
                        help="train on a random symmetry of the 4D cube of each batch")
    parser.add_argument("--fresh", action="store_true",
                        help="a single kind's training sees every sample once: --train x --epochs "
                             "distinct samples (from another seed than the held-out ones), one epoch")
    parser.add_argument("--scales", type=int, metavar="N",
                        help="print the feature scales (widths of holes, gaps and parts) of the first N "
                             "held-out samples of each kind per class, and stop without training")
    parser.add_argument("--min-closing", type=int, metavar="K",
                        help="train only on samples whose narrowest hole or gap survives K - 1 "
                             "dilations (closing scale at least K), drawn from the training set and "
                             "--extra more; held-out sets stay as made")
    parser.add_argument("--extra", type=int, default=7000,
                        help="samples made besides a kind's training set for --min-closing to draw from")
    parser.add_argument("--confusion", action="store_true",
                        help="print each training's score per true class on every held-out kind")
    args = parser.parse_args()
    if not 0 <= args.first_repeat < args.repeats:
        parser.error(f"--first-repeat {args.first_repeat} must be at least 0 and below --repeats {args.repeats}")
    if args.min_closing is not None and args.min_closing < 2:
        parser.error(f"--min-closing {args.min_closing}: every sample has a closing scale of at least 1; ask for 2 or more")
    if args.min_closing and args.fresh:
        parser.error("--min-closing picks from a kind's training set and --fresh replaces that set: use one of them")
    global SIDE, CLEARANCE, INNER_GAP, SURVIVES
    SIDE = args.side
    CLEARANCE = args.clearance
    INNER_GAP = args.inner_gap
    SURVIVES = args.survives_dilations
    if args.quick:
        args.train, args.test, args.mix, args.epochs = 50, 20, 100, 2
    if args.cache:
        os.makedirs(args.cache, exist_ok=True)
    # One intra-op thread: the same seed gives the same weights run after run.
    torch.set_num_threads(1)
    np.random.seed(args.seed)

    started = time.perf_counter()
    data, deforms, single, make = datasets(args)
    if args.scales:
        scales_table(data, args.scales)
        print(f"\nCommand: `python benches/learnability.py {' '.join(sys.argv[1:])}`; "
              f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; bettimill {bettimill.__version__}.")
        return
    columns = list(data)
    runs = [(k, [k]) for k in columns]
    # The mixes need every kind they are made of (all of them unless --kinds leaves some out).
    if {"canonical", *deforms} <= set(columns):
        runs.append(("mix", ["canonical", *deforms]))
        for left in deforms:
            runs.append((f"mix-no-{left}", ["canonical", *[d for d in deforms if d != left]]))
    ours = [k for k in columns if not k.startswith("independent")]
    if len(ours) > 1 + len(deforms):
        runs.append(("all", ours))

    if args.rows:
        wanted = args.rows.split(",")
        unknown = sorted(set(wanted) - {name for name, _ in runs})
        if unknown:
            sys.exit(f"--rows: no training {unknown}; there are {[name for name, _ in runs]}")
        runs = [(name, kinds) for name, kinds in runs if name in wanted]

    # The first forward and backward pass sets up torch's kernels (seconds); not a
    # training's time.
    warm = BettiNet4d(dimension=4, max_betti=MAX_BETTI, width=args.width)
    warm(torch.zeros(2, 1, SIDE, SIDE, SIDE, SIDE)).sum().backward()

    rows = []
    for name, kinds in runs:
        # A training's seed depends on its name only, so --rows gives the full run's rows;
        # repeat r adds r * 1000 (repeat 0 is the single run's training).
        number = int.from_bytes(hashlib.blake2b(name.encode(), digest_size=4).digest(), "little")
        voxels, betti = (data[name][0], data[name][1]) if len(kinds) == 1 else mix(data, kinds, args.mix)
        if args.min_closing and len(kinds) == 1:
            voxels, betti = wide_training(name, voxels, betti, make, args)
        schedule = args
        if args.fresh and len(kinds) == 1:
            voxels, betti = make(name, args.train * args.epochs, args.seed + 1)
            schedule = argparse.Namespace(**{**vars(args), "epochs": 1})
        start = time.perf_counter()
        runs_scores = []
        for repeat in range(args.first_repeat, args.repeats):
            model = train(voxels, betti, schedule, args.seed + number + 1000 * repeat)
            runs_scores.append({k: exact_accuracy(model, data[k][2], data[k][3]) for k in columns})
            if args.confusion:
                for k in columns:
                    log(f"  {name} #{repeat} on {k}: {confusion(model, data[k][2], data[k][3])}")
        seconds = (time.perf_counter() - start) / len(runs_scores)
        scores = {k: float(np.mean([r[k] for r in runs_scores])) for k in columns}
        spread = {k: (min(r[k] for r in runs_scores), max(r[k] for r in runs_scores)) for k in columns}
        rows.append({"trained_on": name, "kinds": kinds, "samples": len(voxels), "seconds": seconds,
                     "scores": scores, "spread": spread, "repeats": runs_scores})
        log(f"{name} ({len(voxels)} samples, {seconds:.0f} s a training): "
            + ", ".join(f"{k} {v:.2f}" for k, v in scores.items()))

    command = "python benches/learnability.py " + " ".join(sys.argv[1:])
    schema = "[deform] one table" if single else "[[deform]] steps with per-sample ranges"
    print(f"Learnability, {args.mode} mode, 4D side {SIDE}: exact Betti vector accuracy "
          f"(bettimill {bettimill.__version__}, {schema}; {args.train} training samples a kind, "
          f"{args.mix} in a mix, {args.test} held out a kind, {args.epochs} epochs, "
          f"BettiNet4d width {args.width}"
          + ("; a single kind's training sees each of its samples once" if args.fresh else "")
          + ("; each batch in a random symmetry of the cube" if args.augment else "")
          + (f"; bettimill's manifests with `clearance = {CLEARANCE}`" if CLEARANCE else "")
          + (f"; bettimill's manifests with `inner_gap = {INNER_GAP}`" if INNER_GAP else "")
          + (f"; bettimill's manifests with `survives_dilations = {SURVIVES}`" if SURVIVES else "")
          + (f"; a single kind's training keeps samples of closing scale {args.min_closing} and up"
             if args.min_closing else "") + ").\n")
    trainings = args.repeats - args.first_repeat
    print("| trained on | samples | " + " | ".join(f"held-out {k}" for k in columns) + " | training s |")
    print("|---|---|" + "---|" * len(columns) + "---|")
    for row in rows:
        cells = []
        for k in columns:
            cell = f"{row['scores'][k]:.2f}"
            if trainings > 1:
                low, high = row["spread"][k]
                cell += f" ({low:.2f}-{high:.2f})"
            cells.append(cell if k in row["kinds"] else f"*{cell}*")
        print(f"| {row['trained_on']} | {row['samples']} | " + " | ".join(cells) + f" | {row['seconds']:.0f} |")
    print("| chance (most common class) | | " + " | ".join(f"{chance(data[k][3]):.2f}" for k in columns) + " | |")
    print("| foreground count alone | | " + " | ".join(f"{count_alone(data[k]):.2f}" for k in columns) + " | |")
    repeats = f"trainings {args.first_repeat} to {args.repeats - 1} of {args.repeats}" if args.first_repeat else \
        f"{args.repeats} trainings"
    print("\nItalic: a kind the model never saw in training."
          + (f" Each row is the mean of {repeats} from different seeds (range in brackets)."
             if trainings > 1 else (f" Training {args.first_repeat} of {args.repeats}." if args.first_repeat else "")))
    for name, deform in [(k, None if k == "canonical" else (DEFORMS_SINGLE if single else DEFORMS)[k]) for k in columns if k in DEFORMS or k in DEFORMS_SINGLE]:
        if deform is not None:
            print(f"- {name}: `{json.dumps(deform)}`")
    if not single:
        print(f"- binned: hypervolume bins `{json.dumps(bins(args.mode))}` (fractions of the image)")
        print(f"- binned-chain: binned, and `{json.dumps(CHAIN)}`")
        print("- families: binned-chain over " + "; ".join(
            f"{list(c)}: " + ", ".join(" ".join(b.split()) for b in bodies) for c, bodies in FAMILIES.items())
            + (f"; in embed mode also the bin `{json.dumps(SMALL_BIN)}` for the classes that reach it"
               if SMALL_BIN else ""))
    print(f"\nCommand: `{command.strip()}`; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; "
          f"{machine()}; total {time.perf_counter() - started:.0f} s.")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"args": vars(args), "rows": rows, "chance": {k: chance(data[k][3]) for k in columns},
                       "bettimill": bettimill.__version__, "machine": machine()}, f, indent=1)


if __name__ == "__main__":
    main()
