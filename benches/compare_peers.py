#!/usr/bin/env python3
"""Time bettimill's exact Betti numbers against CubicalRipser and GUDHI on the same images.

Images: "blob" (uniform noise smoothed by three passes of a periodic box blur of radius 2,
thresholded at its median, so about half the voxels are foreground), "smooth" (the same
at four times the feature size, for big images) and "random" (each voxel foreground with
probability 0.5), generated with a fixed seed and saved as .npy.

Peers are set up to match bettimill's model (labels.md): f = 0 on foreground, 1 on
background, padded with one background layer; CubicalRipser's T-construction
(`computePH_T`) and GUDHI's `CubicalComplex(top_dimensional_cells=f)` with
`homology_coeff_field=2`; b_k = intervals of dimension k born at 0 that die after 0.
Every tool's Betti numbers must agree or the script exits non-zero.

Our side runs `bettimill betti IMAGE.npy --json` when --bettimill is given, otherwise the
`betti` example of bettimill-homology (build it first:
`cargo build --release -p bettimill-homology --example betti`). Our times are those of the
whole process (start-up and file read included), so the comparison does not flatter us.
Both wall and CPU seconds are recorded; on a shared machine compare CPU seconds. With
--repeat N every tool runs N times on each image, interleaved by image, and keeps its best
wall and best CPU time (the usual minimum-of-repeats: noise only ever adds time).

Usage:
  python benches/compare_peers.py [--cases 3:64:blob,4:32:blob,...] [--skip-gudhi]
      [--bettimill PATH | --example PATH] [--workdir DIR] [--json OUT.json] [--repeat N]

Needs numpy, cripser and gudhi (pip install numpy cripser gudhi).
"""

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np


def blob(dim, side, seed):
    rng = np.random.default_rng(seed)
    f = rng.random((side,) * dim)
    for _ in range(3):
        for axis in range(dim):
            f = sum(np.roll(f, s, axis=axis) for s in range(-2, 3)) / 5.0
    return (f > np.median(f)).astype(np.uint8)


def smooth(dim, side, seed):
    """A blob with four times the feature size: a blob field at 1/4 resolution, repeated
    4x along every axis and box-blurred once more. Memory-frugal (float32, in place), so
    it also serves for 96^4 and 128^4."""
    rng = np.random.default_rng(seed)
    coarse_side = side // 4
    f = rng.random((coarse_side,) * dim, dtype=np.float32)
    for _ in range(3):
        for axis in range(dim):
            f = sum(np.roll(f, s, axis=axis) for s in range(-2, 3)) / 5.0
    for axis in range(dim):
        f = np.repeat(f, 4, axis=axis)
    for axis in range(dim):
        out = f.copy()
        for s in (1, 2):
            lo = [slice(None)] * dim
            hi = [slice(None)] * dim
            lo[axis], hi[axis] = slice(s, None), slice(None, -s)
            out[tuple(lo)] += f[tuple(hi)]
            out[tuple(hi)] += f[tuple(lo)]
        f = out
        del out
    threshold = np.median(f[(slice(None, None, 3),) * dim])
    return (f > threshold).astype(np.uint8)


def random_image(dim, side, seed):
    rng = np.random.default_rng(seed)
    return (rng.random((side,) * dim) < 0.5).astype(np.uint8)


def betti_from_pairs(pairs, dim):
    """pairs: iterable of (k, birth, death)."""
    betti = [0] * dim
    for k, birth, death in pairs:
        if k < dim and birth == 0 and death > 0:
            betti[int(k)] += 1
    return betti


def peer_input(image):
    return np.pad(1.0 - image.astype(np.float64), 1, constant_values=1.0)


def run_cripser(image):
    import cripser

    f = peer_input(image)
    start, cpu = time.perf_counter(), time.process_time()
    ph = cripser.computePH_T(f, maxdim=image.ndim - 1)
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    return betti_from_pairs(((row[0], row[1], row[2]) for row in ph), image.ndim), seconds, cpu


def run_gudhi(image):
    import gudhi

    f = peer_input(image)
    start, cpu = time.perf_counter(), time.process_time()
    complex_ = gudhi.CubicalComplex(top_dimensional_cells=f)
    pers = complex_.persistence(homology_coeff_field=2)
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    return betti_from_pairs(((k, b, d) for k, (b, d) in pers), image.ndim), seconds, cpu


def run_ours(path, args):
    if args.bettimill:
        command = [args.bettimill, "betti", path, "--json"]
    else:
        command = [args.example, path]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    out = subprocess.run(command, check=True, capture_output=True, text=True).stdout
    seconds = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    record = json.loads(out.strip().splitlines()[-1])
    return record["betti"], seconds, cpu, after.ru_maxrss


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cases", default="3:64:blob,3:64:random,4:16:blob,4:32:blob,4:32:random,4:48:blob")
    parser.add_argument("--bettimill", help="path of the bettimill CLI")
    parser.add_argument(
        "--example",
        default=os.path.join(os.path.dirname(__file__), "..", "target", "release", "examples", "betti"),
        help="path of the betti example binary",
    )
    parser.add_argument("--skip-gudhi", action="store_true")
    parser.add_argument("--skip-cripser", action="store_true")
    parser.add_argument("--workdir")
    parser.add_argument("--json", help="also write the results here")
    parser.add_argument("--seed", type=int, default=2024)
    parser.add_argument("--repeat", type=int, default=1,
                        help="run every tool this many times and keep its best wall and CPU times")
    args = parser.parse_args()

    workdir = args.workdir or tempfile.mkdtemp(prefix="bettimill-peers-")
    os.makedirs(workdir, exist_ok=True)
    results = []
    failed = False
    print(f"# {platform.node()} {platform.processor() or platform.machine()} {os.cpu_count()} cpus, "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}", flush=True)
    # Wall times suffer when the machine is shared; CPU times (user + system) are the fairer
    # comparison then, and both are recorded. Ours include process start and file read.
    print(f"{'case':16} {'betti':22} {'ours wall/cpu s':>16} {'cripser wall/cpu s':>19} "
          f"{'gudhi wall/cpu s':>17} {'x cripser wall/cpu':>18}", flush=True)
    for case in args.cases.split(","):
        dim, side, kind = case.split(":")
        dim, side = int(dim), int(side)
        image = {"blob": blob, "smooth": smooth, "random": random_image}[kind](dim, side, args.seed)
        path = os.path.join(workdir, f"{kind}_{dim}d_{side}.npy")
        np.save(path, image)
        row = {"case": case, "dim": dim, "side": side, "kind": kind,
               "foreground": int(image.sum())}
        row["repeat"] = args.repeat
        runs = [run_ours(path, args) for _ in range(args.repeat)]
        ours = runs[0][0]
        row["ours_seconds"] = min(r[1] for r in runs)
        row["ours_cpu_seconds"] = min(r[2] for r in runs)
        row["children_max_rss_kb"] = max(r[3] for r in runs)
        row["betti"] = ours
        nan = float("nan")
        for name, run, skip in (("cripser", run_cripser, args.skip_cripser),
                                ("gudhi", run_gudhi, args.skip_gudhi)):
            if skip:
                continue
            runs = [run(image) for _ in range(args.repeat)]
            row[f"{name}_seconds"] = min(r[1] for r in runs)
            row[f"{name}_cpu_seconds"] = min(r[2] for r in runs)
            for theirs, _, _ in runs:
                if theirs != ours:
                    print(f"MISMATCH {case}: ours {ours} {name} {theirs}", file=sys.stderr)
                    failed = True
        speedup = row.get("cripser_cpu_seconds", nan) / max(row["ours_cpu_seconds"], 1e-9)
        wall_speedup = row.get("cripser_seconds", nan) / max(row["ours_seconds"], 1e-9)
        print(f"{case:16} {str(ours):22} {row['ours_seconds']:7.3f}/{row['ours_cpu_seconds']:<8.3f} "
              f"{row.get('cripser_seconds', nan):9.3f}/{row.get('cripser_cpu_seconds', nan):<9.3f} "
              f"{row.get('gudhi_seconds', nan):8.3f}/{row.get('gudhi_cpu_seconds', nan):<8.3f} "
              f"{wall_speedup:10.1f}/{speedup:<7.1f}", flush=True)
        results.append(row)
    if args.json:
        with open(args.json, "w") as out:
            json.dump(results, out, indent=1)
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
