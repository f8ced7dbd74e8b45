#!/usr/bin/env python3
"""Scale benchmark of the dataset directory: does the index, and do `verify`,
`status`, `finalize` and a build's start-up, stay flat as a dataset grows?

Builds 2D datasets of tiny samples (side 12, one class, shard_size 1000) of 10^4, 10^5 and
10^6 samples (``--sizes``) and reports, per size:

- index.json bytes, in all and per sample;
- build wall time, and the start-up: seconds from launching ``bettimill build --workers 2``
  until the first completion record appears (the coordinator reads nothing per shard before
  its workers start: whether a shard is complete is checked when its turn comes);
- wall time and peak RSS (``/usr/bin/time``; for builds the largest of the coordinator and
  its workers) of ``verify``, ``status`` and a standalone ``finalize``;
- with ``--big N`` (default 10^7), the seconds until a plan of N samples writes its first
  shard, and the coordinator's peak RSS at that moment; the build is then stopped.

Usage: python3 benches/scale.py [--bin target/debug/bettimill] [--sizes 10000,100000,1000000]
[--work /tmp/bettimill-scale] [--big 10000000]. Prints a Markdown table. Datasets are
deleted after each size (10^6 tiny samples take about 4 GB).
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

MANIFEST = """schema_version = 1
name = "scale"
dimension = 2
side = 12
mode = ["embed"]
samples = {samples}
shard_size = {shard_size}
seed = 1
compression = "none"

[[classes]]
family = "ball"
"""


def timed(cmd, ok=(0,)):
    """Runs cmd under /usr/bin/time; returns (wall seconds, peak RSS in MiB, stdout)."""
    stats = Path("/tmp") / f"bettimill-scale-time-{os.getpid()}"
    proc = subprocess.run(
        ["/usr/bin/time", "-o", str(stats), "-f", "%e %M", *cmd],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    if proc.returncode not in ok:
        sys.exit(f"{cmd} failed ({proc.returncode}): {proc.stderr}")
    wall, rss = stats.read_text().split()[-2:]
    stats.unlink()
    return float(wall), int(rss) / 1024, proc.stdout


def first_record(records, start, proc, timeout=600):
    """Seconds from start until records/ holds a file, polling every 10 ms."""
    while time.monotonic() - start < timeout:
        try:
            with os.scandir(records) as entries:
                if any(e.name.endswith(".json") and not e.name.startswith(".") for e in entries):
                    return time.monotonic() - start
        except FileNotFoundError:
            pass
        if proc.poll() is not None:
            return time.monotonic() - start
        time.sleep(0.01)
    return float("nan")


def vm_hwm(pid):
    """Peak RSS of a running process in MiB (from /proc)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def one_size(binary, work, samples, shard_size):
    root = work / f"n{samples}"
    shutil.rmtree(root, ignore_errors=True)
    root.mkdir(parents=True)
    manifest = root / "m.toml"
    manifest.write_text(MANIFEST.format(samples=samples, shard_size=shard_size))
    out = root / "out"
    stats = root / "build-time"
    start = time.monotonic()
    proc = subprocess.Popen(
        ["/usr/bin/time", "-o", str(stats), "-f", "%e %M", binary, "build", str(manifest),
         "--out", str(out), "--quiet", "--workers", "2"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    startup = first_record(out / "records", start, proc)
    _, err = proc.communicate()
    if proc.returncode != 0:
        sys.exit(f"build of {samples} failed: {err}")
    build_wall, build_rss = stats.read_text().split()[-2:]
    row = {
        "samples": samples,
        "shards": -(-samples // shard_size),
        "index_bytes": (out / "index.json").stat().st_size,
        "build_s": float(build_wall),
        "build_rss_mib": int(build_rss) / 1024,
        "startup_s": startup,
    }
    row["index_bytes_per_sample"] = row["index_bytes"] / samples
    for command, ok in (("verify", (0,)), ("status", (0,)), ("finalize", (0,))):
        args = [binary, command, str(out)] + (["--quiet"] if command == "finalize" else [])
        wall, rss, _ = timed(args, ok)
        row[f"{command}_s"] = wall
        row[f"{command}_rss_mib"] = rss
    # A second build of the complete directory: start-up checks every shard, then finalizes.
    wall, rss, _ = timed([binary, "build", str(manifest), "--out", str(out), "--quiet", "--workers", "2"])
    row["rebuild_s"] = wall
    row["rebuild_rss_mib"] = rss
    shutil.rmtree(root)
    return row


def big_plan(binary, work, samples, shard_size):
    root = work / f"big{samples}"
    shutil.rmtree(root, ignore_errors=True)
    root.mkdir(parents=True)
    manifest = root / "m.toml"
    manifest.write_text(MANIFEST.format(samples=samples, shard_size=shard_size))
    out = root / "out"
    start = time.monotonic()
    proc = subprocess.Popen(
        [binary, "build", str(manifest), "--out", str(out), "--quiet", "--workers", "2"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    seconds = first_record(out / "records", start, proc)
    rss = vm_hwm(proc.pid)
    proc.terminate()
    proc.wait()
    shutil.rmtree(root)
    return seconds, rss


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bin", default="target/debug/bettimill")
    parser.add_argument("--sizes", default="10000,100000,1000000")
    parser.add_argument("--shard-size", type=int, default=1000)
    parser.add_argument("--work", default="/tmp/bettimill-scale")
    parser.add_argument("--big", type=int, default=10_000_000)
    parser.add_argument("--json", help="also write the rows to this file")
    args = parser.parse_args()
    binary = str(Path(args.bin).resolve())
    work = Path(args.work)
    rows = []
    for samples in [int(s) for s in args.sizes.split(",") if s]:
        row = one_size(binary, work, samples, args.shard_size)
        print(json.dumps(row), file=sys.stderr, flush=True)
        rows.append(row)
    big = big_plan(binary, work, args.big, args.shard_size) if args.big else None
    print("| samples | shards | index.json | bytes/sample | build | first record after | verify | verify RSS | status | status RSS | finalize | finalize RSS | re-build of complete dir | its RSS |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['samples']:,} | {r['shards']:,} | {r['index_bytes']:,} B | {r['index_bytes_per_sample']:.2f} "
            f"| {r['build_s']:.1f} s | {r['startup_s']:.2f} s | {r['verify_s']:.2f} s | {r['verify_rss_mib']:.1f} MiB "
            f"| {r['status_s']:.2f} s | {r['status_rss_mib']:.1f} MiB | {r['finalize_s']:.2f} s | {r['finalize_rss_mib']:.1f} MiB "
            f"| {r['rebuild_s']:.2f} s | {r['rebuild_rss_mib']:.1f} MiB |"
        )
    if big:
        print(f"\nA plan of {args.big:,} samples ({-(-args.big // args.shard_size):,} shards): first completion record after {big[0]:.2f} s, coordinator peak RSS then {big[1]:.1f} MiB.")
    if args.json:
        Path(args.json).write_text(json.dumps({"rows": rows, "big": big}, indent=2) + "\n")


if __name__ == "__main__":
    main()
