#!/usr/bin/env python3
"""Time bettimill's exact Betti numbers against CubicalRipser and GUDHI on the same images.

Images: "blob" (uniform noise smoothed by three passes of a periodic box blur of radius 2,
thresholded at its median, so about half the voxels are foreground), "smooth" (the same
at four times the feature size, for big images) and "random" (each voxel foreground with
probability 0.5), generated with a fixed seed and saved as .npy.

Peers are set up to match bettimill's model (labels.md), and CubicalRipser is timed on both
of its routes; a case is compared against the faster one:
- `cripser-T`: `computePH_T` (T-construction: voxels are top cells, so corner contacts
  connect) of f = 0 on foreground, 1 on background, padded with one background layer;
  b_k = intervals of dimension k born at 0 that die after 0.
- `cripser-V`: `computePH` (V-construction: voxels are vertices, face neighbours joined) of
  the padded complement g = 1 on foreground, 0 on background, padded with 0: that is the
  background in the construction dual to ours, and Alexander duality gives the object's
  numbers: b_0 = b_{d-1}(bg), b_k = b_{d-1-k}(bg), b_{d-1} = b_0(bg) - 1.
  `--self-check` (run first, unless `--no-self-check`) checks V against T on small random
  and blob images in 2D, 3D and 4D.
- `gudhi` (optional, about 10x slower than CubicalRipser): `CubicalComplex(
  top_dimensional_cells=f)` with `homology_coeff_field=2`.
Every tool's Betti numbers must agree or the script exits non-zero.

Each peer runs in a child Python process of its own (the image read before the timer
starts), so that its peak RSS is its own; the time is that of the call only (in-process).
Our side is the whole process: `bettimill betti IMAGE.npy --json` when --bettimill is given,
otherwise the `betti` example of bettimill-homology (start-up and file read included, so the
comparison does not flatter us), started straight from this script and timed from its start
to its exit. Peak RSS of every process comes from GNU time (/usr/bin/time), in runs of its
own for our side (time's own start would add 0.7-1.7 ms to a 25 ms run); a peer's includes
its Python interpreter, NumPy and the image (about 40 MB). With --repeat N every tool runs N
times on each image and keeps its best wall and best CPU time (the usual minimum-of-repeats:
noise only ever adds time); the ratio is the peer's best wall time (faster route) over ours.
--ours-repeat M times our side M times instead (at least N): a run of 30 ms on a shared
machine needs more tries than a run of 3 s to dodge a busy moment (on the test VM the same
binary's best of 3 ranged from 24 to 37 ms within minutes). Our timed runs are spread over
the peers' (a chunk before each peer run, one after the last), so both sides sample the same
minutes.

Usage:
  python benches/compare_peers.py [--cases 4:32:blob,4:32:random,...] [--skip-gudhi]
      [--skip-cripser] [--routes T,V] [--bettimill PATH | --example PATH] [--workdir DIR]
      [--json OUT.json] [--repeat N] [--ours-repeat M]   (prints a Markdown table)

Needs numpy, cripser and gudhi (pip install numpy cripser gudhi; not in the CI
requirements).
"""

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np

TIME = "/usr/bin/time"  # GNU time, for peak RSS


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
    """Each voxel foreground with probability 0.5: the same bytes as
    `rng.random((side,) * dim) < 0.5`, drawn one hyperplane at a time so that 128^4 needs
    no 2 GB of doubles."""
    rng = np.random.default_rng(seed)
    out = np.empty((side,) * dim, dtype=np.uint8)
    for i in range(side):
        out[i] = rng.random((side,) * (dim - 1)) < 0.5
    return out


def betti_from_pairs(pairs, dim):
    """pairs: iterable of (k, birth, death)."""
    betti = [0] * dim
    for k, birth, death in pairs:
        if k < dim and birth == 0 and death > 0:
            betti[int(k)] += 1
    return betti


def by_duality(background):
    """The object's Betti numbers from those of the padded background (V-construction)."""
    d = len(background)
    return [background[d - 1]] + [background[d - 1 - k] for k in range(1, d - 1)] + [background[0] - 1]


def peer_betti(route, image):
    """Runs one peer route on `image` in this process: (betti, wall seconds, cpu seconds)."""
    d = image.ndim
    if route == "T":
        import cripser

        f = np.pad(1.0 - image.astype(np.float64), 1, constant_values=1.0)
        start, cpu = time.perf_counter(), time.process_time()
        ph = cripser.computePH_T(f, maxdim=d - 1)
        seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
        return betti_from_pairs(((r[0], r[1], r[2]) for r in ph), d), seconds, cpu
    if route == "V":
        import cripser

        g = np.pad(image.astype(np.float64), 1, constant_values=0.0)
        start, cpu = time.perf_counter(), time.process_time()
        ph = cripser.computePH(g, maxdim=d - 1)
        seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
        return by_duality(betti_from_pairs(((r[0], r[1], r[2]) for r in ph), d)), seconds, cpu
    if route == "gudhi":
        import gudhi

        f = np.pad(1.0 - image.astype(np.float64), 1, constant_values=1.0)
        start, cpu = time.perf_counter(), time.process_time()
        complex_ = gudhi.CubicalComplex(top_dimensional_cells=f)
        pers = complex_.persistence(homology_coeff_field=2)
        seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
        return betti_from_pairs(((k, b, dd) for k, (b, dd) in pers), d), seconds, cpu
    raise ValueError(route)


def run_measured(command, rss=True):
    """Runs `command` as a child: (stdout, wall s, cpu s, peak RSS KB). The peak RSS is GNU
    time's (%M): a child forked straight from this Python process would report this
    process's RSS when nothing it does itself comes near it (the kernel keeps the high-water
    mark across exec). With rss=False the child is started straight, without GNU time, and
    the peak RSS is None."""
    with tempfile.TemporaryFile(mode="w+") as out, tempfile.TemporaryFile(mode="w+") as err, \
            tempfile.NamedTemporaryFile(mode="r") as peak:
        under_time = [TIME, "-f", "%M", "-o", peak.name] if rss else []
        start = time.perf_counter()
        child = subprocess.Popen(under_time + command, stdout=out, stderr=err)
        _, status, usage = os.wait4(child.pid, 0)
        seconds = time.perf_counter() - start
        code = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        if code != 0:
            sys.exit(f"{' '.join(command)} failed ({code}): {err.read().strip()}")
        max_rss_kb = int(peak.read().split()[-1]) if rss else None
        return out.read(), seconds, usage.ru_utime + usage.ru_stime, max_rss_kb


def run_peer(route, path):
    """One peer route on the image at `path`, in a child process: (betti, wall s of the call,
    cpu s of the call, peak RSS KB of the child)."""
    out, _, _, rss = run_measured([sys.executable, os.path.abspath(__file__), "--child", route, path])
    record = json.loads(out.strip().splitlines()[-1])
    return record["betti"], record["seconds"], record["cpu"], rss


def ours_command(path, args):
    if args.bettimill:
        return [args.bettimill, "betti", path, "--json"]
    return [args.example, path]


def run_ours(path, args):
    """Our whole process, started straight from here: (betti, wall s, cpu s). Its peak RSS
    comes from `run_ours_rss` instead: under GNU time the wall would include time's own
    start and its fork (0.7-1.7 ms on the test VM, 3-7% of a 25 ms run)."""
    out, seconds, cpu, _ = run_measured(ours_command(path, args), rss=False)
    return json.loads(out.strip().splitlines()[-1])["betti"], seconds, cpu


def run_ours_rss(path, args):
    """Our whole process under GNU time: (betti, peak RSS KB)."""
    out, _, _, rss = run_measured(ours_command(path, args))
    return json.loads(out.strip().splitlines()[-1])["betti"], rss


def spread(total, parts):
    """`total` runs in `parts` chunks as even as can be (taken from the end: smaller first)."""
    return [total // parts + (k < total % parts) for k in range(parts)]


def self_check(workdir):
    """CubicalRipser's V route with duality against its T route on small images."""
    rng = np.random.default_rng(7)
    checked = 0
    for dim, side in ((2, 12), (2, 30), (3, 8), (3, 16), (4, 5), (4, 8)):
        for density in (0.2, 0.5, 0.8):
            image = (rng.random((side,) * dim) < density).astype(np.uint8)
            t = peer_betti("T", image)[0]
            v = peer_betti("V", image)[0]
            if t != v:
                sys.exit(f"self-check: {dim}D {side} density {density}: T {t} V-by-duality {v}")
            checked += 1
        for seed in range(2):
            image = blob(dim, max(side, 8), seed)
            if peer_betti("T", image)[0] != peer_betti("V", image)[0]:
                sys.exit(f"self-check: {dim}D blob {side}: T and V-by-duality differ")
            checked += 1
    print(f"# self-check: CubicalRipser V route by duality = T route on {checked} images", flush=True)


def main():
    if len(sys.argv) == 4 and sys.argv[1] == "--child":
        route, path = sys.argv[2], sys.argv[3]
        image = np.load(path)
        betti, seconds, cpu = peer_betti(route, image)
        print(json.dumps({"betti": betti, "seconds": seconds, "cpu": cpu}))
        return
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cases", default="4:24:random,4:32:random,4:32:blob,4:48:blob")
    parser.add_argument("--bettimill", help="path of the bettimill CLI")
    parser.add_argument(
        "--example",
        default=os.path.join(os.path.dirname(__file__), "..", "target", "release", "examples", "betti"),
        help="path of the betti example binary",
    )
    parser.add_argument("--routes", default="T,V", help="CubicalRipser routes to time (T, V)")
    parser.add_argument("--skip-gudhi", action="store_true")
    parser.add_argument("--skip-cripser", action="store_true")
    parser.add_argument("--no-self-check", action="store_true")
    parser.add_argument("--workdir")
    parser.add_argument("--json", help="also write the results here")
    parser.add_argument("--seed", type=int, default=2024)
    parser.add_argument("--repeat", type=int, default=1,
                        help="run every tool this many times and keep its best wall and CPU times")
    parser.add_argument("--ours-repeat", type=int,
                        help="run our side this many times (at least --repeat; default --repeat)")
    args = parser.parse_args()
    ours_repeat = max(args.ours_repeat or args.repeat, args.repeat)

    workdir = args.workdir or tempfile.mkdtemp(prefix="bettimill-peers-")
    os.makedirs(workdir, exist_ok=True)
    print(f"# {platform.node()} {platform.processor() or platform.machine()} {os.cpu_count()} cpus, "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, best of {args.repeat}"
          f" (ours: best of {ours_repeat})", flush=True)
    routes = [] if args.skip_cripser else [r for r in args.routes.split(",") if r]
    if routes and not args.no_self_check:
        self_check(workdir)
    tools = [f"cripser-{r}" for r in routes] + ([] if args.skip_gudhi else ["gudhi"])
    results = []
    failed = False
    header = ["case", "betti", "ours wall/cpu s, MB"] + [f"{t} wall s, MB" for t in tools] + ["x best peer"]
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header), flush=True)
    for case in args.cases.split(","):
        dim, side, kind = case.split(":")
        dim, side = int(dim), int(side)
        image = {"blob": blob, "smooth": smooth, "random": random_image}[kind](dim, side, args.seed)
        path = os.path.join(workdir, f"{kind}_{dim}d_{side}.npy")
        np.save(path, image)
        row = {"case": case, "dim": dim, "side": side, "kind": kind,
               "foreground": int(image.sum()), "repeat": args.repeat, "ours_repeat": ours_repeat}
        del image
        # Our timed runs are spread over the peers' runs (a chunk before each, the last
        # chunk after them all), so that both sides sample the same minutes of a shared
        # machine; then our peak RSS, from runs of their own.
        chunks = spread(ours_repeat, len(tools) * args.repeat + 1)
        runs = []
        peer_runs = {}
        for tool in tools:
            peer_runs[tool] = []
            for _ in range(args.repeat):
                runs += [run_ours(path, args) for _ in range(chunks.pop())]
                peer_runs[tool].append(run_peer(tool.split("-")[-1], path))
        runs += [run_ours(path, args) for _ in range(chunks.pop())]
        rss_runs = [run_ours_rss(path, args) for _ in range(args.repeat)]
        ours = runs[0][0]
        for theirs in [r[0] for r in runs] + [r[0] for r in rss_runs]:
            if theirs != ours:
                print(f"MISMATCH {case}: ours {ours} and {theirs} in another run", file=sys.stderr)
                failed = True
        row["betti"] = ours
        row["ours_seconds"] = min(r[1] for r in runs)
        row["ours_cpu_seconds"] = min(r[2] for r in runs)
        row["ours_max_rss_kb"] = max(r[1] for r in rss_runs)
        cells = [case, str(ours),
                 f"{row['ours_seconds']:.3f}/{row['ours_cpu_seconds']:.3f}, {row['ours_max_rss_kb'] / 1024:.0f}"]
        best = None
        for tool in tools:
            runs = peer_runs[tool]
            row[f"{tool}_seconds"] = min(r[1] for r in runs)
            row[f"{tool}_cpu_seconds"] = min(r[2] for r in runs)
            row[f"{tool}_max_rss_kb"] = max(r[3] for r in runs)
            for theirs, _, _, _ in runs:
                if theirs != ours:
                    print(f"MISMATCH {case}: ours {ours} {tool} {theirs}", file=sys.stderr)
                    failed = True
            cells.append(f"{row[f'{tool}_seconds']:.3f}, {row[f'{tool}_max_rss_kb'] / 1024:.0f}")
            if tool.startswith("cripser") and (best is None or row[f"{tool}_seconds"] < row[f"{best}_seconds"]):
                best = tool
        if best:
            row["best_peer"] = best
            row["ratio"] = row[f"{best}_seconds"] / max(row["ours_seconds"], 1e-9)
            row["memory_fraction"] = row["ours_max_rss_kb"] / row[f"{best}_max_rss_kb"]
            cells.append(f"{row['ratio']:.1f}x ({best}), memory {100 * row['memory_fraction']:.0f}%")
        else:
            cells.append("-")
        print("| " + " | ".join(cells) + " |", flush=True)
        results.append(row)
        if args.json:
            with open(args.json, "w") as out:
                json.dump(results, out, indent=1)
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
