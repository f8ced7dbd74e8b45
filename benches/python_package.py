"""Benchmarks of the Python package, results in BENCHMARKS.md.

    python benches/python_package.py betti     # needs bettimill and cripser (a scratch venv)
    python benches/python_package.py loader    # needs bettimill[torch] and webdataset

betti: in-process ``bettimill.betti`` against in-process CubicalRipser at its faster route
on a 4D 32^4 smooth blob (compare_peers.py's ``smooth``): ``computePH_T`` (T-construction,
our model) and ``computePH`` (V-construction) of the padded complement, with our Betti
numbers by duality (b0 = b_{d-1}(bg), b_k = b_{d-1-k}(bg), b_{d-1} = b0(bg) - 1). Best of
--repeat runs each; every answer must agree.

loader: samples per CPU-second (and per second) of a DataLoader (batch 16; 0 and 2 workers)
over ``SyntheticDataset`` (samples made on the fly) against webdataset reading the shards
``bettimill.build`` wrote for the same manifest, in one run: demo-4d and a 3D side-64
manifest. CPU time is this process's plus its ended workers' (getrusage), so spinning threads
and waiting workers count too; rounds are interleaved and the best of --repeat is kept.
"""

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))


def best(fn, repeat):
    """(result, best CPU seconds of this process, best wall seconds): on a shared machine
    CPU seconds are the fairer figure (both tools run on one thread)."""
    cpu, wall, result = [], [], None
    for _ in range(repeat):
        start, start_cpu = time.perf_counter(), time.process_time()
        result = fn()
        cpu.append(time.process_time() - start_cpu)
        wall.append(time.perf_counter() - start)
    return result, min(cpu), min(wall)


def bench_betti(args):
    import cripser
    import numpy as np

    import bettimill
    from compare_peers import betti_from_pairs, smooth

    image = smooth(4, args.side, args.seed)
    d = image.ndim
    ours, t_ours, w_ours = best(lambda: bettimill.betti(image), args.repeat)

    def t_route():
        f = np.pad(1.0 - image.astype(np.float64), 1, constant_values=1.0)
        return betti_from_pairs(((r[0], r[1], r[2]) for r in cripser.computePH_T(f, maxdim=d - 1)), d)

    def v_route():
        # The padded background as sublevel set 0 in the V-construction (2d-adjacency).
        bg = np.pad(image.astype(np.float64), 1, constant_values=0.0)
        b = betti_from_pairs(((r[0], r[1], r[2]) for r in cripser.computePH(bg, maxdim=d - 1)), d)
        return [b[d - 1]] + [b[d - 1 - k] for k in range(1, d - 1)] + [b[0] - 1]

    t_betti, t_time, t_wall = best(t_route, args.repeat)
    v_betti, v_time, v_wall = best(v_route, args.repeat)
    assert ours == t_betti == v_betti, (ours, t_betti, v_betti)
    faster = min(t_time, v_time)
    print(json.dumps({
        "image": f"4D {args.side}^4 smooth blob (seed {args.seed})",
        "betti": ours,
        "cpu_s": {"bettimill": round(t_ours, 4), "cripser_T": round(t_time, 3), "cripser_V_complement": round(v_time, 3)},
        "wall_s": {"bettimill": round(w_ours, 4), "cripser_T": round(t_wall, 3), "cripser_V_complement": round(v_wall, 3)},
        "speedup_cpu_vs_faster_route": round(faster / t_ours, 1),
        "speedup_wall_vs_faster_route": round(min(t_wall, v_wall) / w_ours, 1),
    }))


MANIFEST_3D_64 = """\
schema_version = 1
name = "bench3d64"
dimension = 3
side = 64
mode = ["embed", "carve"]
samples = 128
shard_size = 32
seed = 11

[[classes]]
family = ["ball", "handle", "shell", "torus_shell"]
"""


def cpu_seconds():
    """User + system CPU seconds of this process and of its children that have ended."""
    import resource

    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def bench_loader(args):
    import platform

    import torch
    import webdataset as wds

    import bettimill
    from bettimill.torch import SyntheticDataset

    torch.set_num_threads(1)

    def on_the_fly(voxels, label):
        return voxels, torch.tensor(label["betti"], dtype=torch.int64)

    def from_shard(sample):
        return torch.from_numpy(sample["npy"]), torch.tensor(sample["json"]["betti"], dtype=torch.int64)

    def measure(dataset, workers, n):
        """(samples per CPU-second, samples per second) of one pass over every sample."""
        loader = torch.utils.data.DataLoader(dataset, batch_size=16, num_workers=workers)
        cpu, wall = cpu_seconds(), time.perf_counter()
        seen = sum(len(voxels) for voxels, _ in loader)
        del loader  # its workers end and are reaped, so their CPU time is counted
        wall, cpu = time.perf_counter() - wall, cpu_seconds() - cpu
        assert seen == n, (seen, n)
        return seen / cpu, seen / wall

    print(f"{time.strftime('%Y-%m-%d')}, {platform.machine()}, {os.cpu_count()} cores, bettimill "
          f"{bettimill.__version__}, torch {torch.__version__}, webdataset {wds.__version__}")
    print("| manifest | workers | loader | samples / CPU-s | samples / s |")
    print("|---|---|---|---|---|")
    manifests = [(m, m) for m in args.manifests] + [("3D side 64", MANIFEST_3D_64)]
    with tempfile.TemporaryDirectory() as tmp:
        for name, manifest in manifests:
            plan = bettimill.Plan(manifest)
            out = Path(tmp) / plan.name
            bettimill.build(manifest, out)
            index = json.loads((out / "index.json").read_text())
            urls = [str(out / s["name"]) for s in index["shards"]]
            loaders = [
                ("SyntheticDataset", lambda: SyntheticDataset(plan, transform=on_the_fly)),
                (
                    "webdataset shards",
                    lambda: wds.WebDataset(urls, shardshuffle=False, empty_check=False)
                    .decode()
                    .rename(npy="npy;npy.gz;npy.zst", json="json")
                    .map(from_shard),
                ),
            ]
            for workers in args.workers:
                # Interleaved rounds, best of each: the machine's speed drifts.
                results = {label: [] for label, _ in loaders}
                for _ in range(args.repeat):
                    for label, make in loaders:
                        results[label].append(measure(make(), workers, len(plan)))
                for label, runs in results.items():
                    per_cpu, per_s = max(runs)
                    print(f"| {name} | {workers} | {label} | {per_cpu:.1f} | {per_s:.1f} |", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("part", choices=["betti", "loader"])
    parser.add_argument("--side", type=int, default=32)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--manifests", nargs="+", default=["demo-4d"], help="loader: presets or paths (a 3D side-64 manifest is added)")
    parser.add_argument("--workers", type=int, nargs="+", default=[0, 2], help="loader: DataLoader worker counts")
    args = parser.parse_args()
    (bench_betti if args.part == "betti" else bench_loader)(args)


if __name__ == "__main__":
    main()
