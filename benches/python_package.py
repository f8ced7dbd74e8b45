"""Benchmarks of the Python package, results in BENCHMARKS.md.

    python benches/python_package.py betti     # needs bettimill and cripser (a scratch venv)
    python benches/python_package.py loader    # needs bettimill[torch], webdataset, the CLI

betti: in-process ``bettimill.betti`` against in-process CubicalRipser at its faster route
on a 4D 32^4 smooth blob (compare_peers.py's ``smooth``): ``computePH_T`` (T-construction,
our model) and ``computePH`` (V-construction) of the padded complement, with our Betti
numbers by duality (b0 = b_{d-1}(bg), b_k = b_{d-1-k}(bg), b_{d-1} = b0(bg) - 1). Best of
--repeat runs each; every answer must agree.

loader: samples/s of a DataLoader with 2 workers over ``SyntheticDataset`` (made on the fly)
against the same samples read from the shards ``bettimill build`` wrote (webdataset).
"""

import argparse
import json
import os
import subprocess
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


def bench_loader(args):
    import torch
    import webdataset as wds

    import bettimill
    from bettimill.torch import SyntheticDataset

    manifest = Path(args.manifest)
    plan = bettimill.Plan(manifest)
    n = len(plan)

    def rate(loader):
        start = time.perf_counter()
        seen = sum(len(batch[0]) for batch in loader)
        assert seen == n, seen
        return n / (time.perf_counter() - start)

    synthetic = torch.utils.data.DataLoader(SyntheticDataset(plan), batch_size=8, num_workers=2, collate_fn=lambda b: list(zip(*b)))
    fly = max(rate(synthetic) for _ in range(args.repeat))
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "built"
        subprocess.run([args.cli, "build", manifest, "--out", out, "--quiet"], check=True)
        index = json.loads((out / "index.json").read_text())
        urls = [str(out / s["name"]) for s in index["shards"]]
        dataset = wds.WebDataset(urls, shardshuffle=False, empty_check=False).decode().to_tuple("npy;npy.gz;npy.zst", "json")
        disk = max(rate(torch.utils.data.DataLoader(dataset.batched(8, collation_fn=lambda b: list(zip(*b))), batch_size=None, num_workers=2)) for _ in range(args.repeat))
    print(json.dumps({
        "manifest": str(manifest.relative_to(HERE.parent)) if manifest.is_absolute() else str(manifest),
        "samples": n,
        "on_the_fly_samples_per_s": round(fly, 1),
        "from_shards_samples_per_s": round(disk, 1),
    }))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("part", choices=["betti", "loader"])
    parser.add_argument("--side", type=int, default=32)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--manifest", default=str(HERE.parent / "manifests" / "demo-3d.toml"))
    parser.add_argument("--cli", default=os.environ.get("BETTIMILL_CLI", "bettimill"))
    args = parser.parse_args()
    (bench_betti if args.part == "betti" else bench_loader)(args)


if __name__ == "__main__":
    main()
