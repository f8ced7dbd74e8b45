#!/usr/bin/env python3
"""Builds to a local S3 server against builds to local disk, in one run, interleaved.

For each dataset (demo-4d, and a 3D side-128 one made from demo-3d), builds it REPEAT times
to a fresh local directory and REPEAT times to a fresh prefix of a local S3 server
(moto_server, started here by ci/s3-up.sh on a port of its own and stopped by its PID at the
end), alternating which goes first, and reports for each: the best and median wall time,
the CPU seconds and peak resident set of the bettimill process (GNU time), and the local
disk in use at peak, polled every 20 ms: the output directory for a local build, the staging
directory (TMPDIR) for a build to the bucket. The throughput ratio is the local build's best
wall time over the bucket build's (1.0: as fast). Each bucket build's index.json must equal
the local build's, byte for byte, or the script fails.

The server runs on the same machine, so its CPU (moto is Python) is taken from the build's
cores: a server elsewhere costs the build less.

    cargo build -p bettimill-cli
    python3 benches/s3_vs_local.py --bettimill target/debug/bettimill --repeat 3
"""

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
TIME = "/usr/bin/time"


def tree_bytes(root):
    """Bytes of the regular files under root (0 when it does not exist)."""
    total = 0
    for dirpath, _, files in os.walk(root):
        for name in files:
            try:
                total += os.lstat(os.path.join(dirpath, name)).st_size
            except FileNotFoundError:
                pass
    return total


class Poller:
    """The peak of tree_bytes(root), sampled every 20 ms while running."""

    def __init__(self, root):
        self.root = root
        self.peak = 0
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self.run, daemon=True)

    def run(self):
        while not self.stop.is_set():
            self.peak = max(self.peak, tree_bytes(self.root))
            time.sleep(0.02)

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.stop.set()
        self.thread.join()
        self.peak = max(self.peak, tree_bytes(self.root))


def timed(args, env, watch):
    """Runs args under GNU time; returns wall s, CPU s, peak RSS KiB, peak bytes under watch."""
    report = tempfile.NamedTemporaryFile(delete=False)
    report.close()
    start = time.monotonic()
    with Poller(watch) as poller:
        out = subprocess.run([TIME, "-f", "%U %S %M", "-o", report.name] + args, env=env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.monotonic() - start
    if out.returncode != 0:
        sys.exit(f"{' '.join(args)} exited {out.returncode}:\n{out.stderr}")
    user, system, kib = Path(report.name).read_text().split()[-3:]
    os.unlink(report.name)
    return wall, float(user) + float(system), int(kib), poller.peak


def server_up(work, port):
    env = dict(os.environ, S3_CI_DIR=str(work / "s3"), S3_CI_PORT=str(port), S3_CI_KEEP="0")
    subprocess.run(["bash", str(REPO / "ci/s3-up.sh")], env=env, check=True)
    values = dict(line.split("=", 1) for line in (work / "s3/env").read_text().splitlines())
    return values


def server_down(work):
    env = dict(os.environ, S3_CI_DIR=str(work / "s3"))
    subprocess.run(["bash", str(REPO / "ci/s3-down.sh")], env=env, check=False)


def datasets(work):
    """(name, manifest path): demo-4d as it is, and demo-3d at side 128."""
    three = (REPO / "manifests/demo-3d.toml").read_text()
    for old, new in [('name = "demo-3d"', 'name = "bench-3d-128"'), ("side = 24", "side = 128"),
                     ("samples = 240", "samples = 48"), ("shard_size = 40", "shard_size = 8")]:
        assert old in three, old
        three = three.replace(old, new)
    path = work / "bench-3d-128.toml"
    path.write_text(three)
    return [("demo-4d", REPO / "manifests/demo-4d.toml"), ("3D side 128", path)]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--bettimill", default=str(REPO / "target/debug/bettimill"))
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--port", type=int, default=39790)
    args = parser.parse_args()
    if not Path(TIME).exists():
        sys.exit(f"{TIME} (GNU time) is needed")
    work = Path(tempfile.mkdtemp(prefix="bettimill-s3-bench-"))
    try:
        values = server_up(work, args.port)
        env = dict(os.environ)
        for key in ["AWS_ENDPOINT_URL", "AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY", "AWS_REGION"]:
            env[key] = values[key]
        bucket = values["BETTIMILL_S3_CI_BUCKET"]
        results = {}
        for name, manifest in datasets(work):
            for r in range(args.repeat):
                order = ["local", "s3"] if r % 2 == 0 else ["s3", "local"]
                index = {}
                for target in order:
                    if target == "local":
                        out = work / f"local-{r}"
                        measured = timed([args.bettimill, "build", str(manifest), "--out", str(out),
                                          "--quiet"], env, out)
                        index[target] = (out / "index.json").read_bytes()
                        shutil.rmtree(out)
                    else:
                        staging = work / f"tmp-{r}"
                        staging.mkdir()
                        url = f"s3://{bucket}/bench/{name.replace(' ', '-')}-{r}"
                        measured = timed([args.bettimill, "build", str(manifest), "--out", url,
                                          "--quiet"], dict(env, TMPDIR=str(staging)), staging)
                        index[target] = subprocess.run(
                            [args.bettimill, "cat", f"{url}/index.json"], env=env,
                            capture_output=True, check=True).stdout
                        shutil.rmtree(staging)
                    results.setdefault((name, target), []).append(measured)
                    wall, cpu, kib, disk = measured
                    print(f"{name} {target} run {r}: {wall:.2f} s wall, {cpu:.2f} CPU-s, "
                          f"{kib / 1024:.0f} MiB peak, {disk / 2**20:.1f} MiB on disk at peak",
                          file=sys.stderr)
                if index["local"] != index["s3"]:
                    sys.exit(f"{name}: the bucket's index.json differs from the local one")
        print("| dataset | target | wall best / median (s) | CPU-s | peak RSS (MiB) "
              "| local disk at peak (MiB) | throughput vs local |")
        print("|---|---|---|---|---|---|---|")
        for name, _ in datasets(work):
            best_local = min(m[0] for m in results[(name, "local")])
            for target in ["local", "s3"]:
                runs = results[(name, target)]
                walls = [m[0] for m in runs]
                print(f"| {name} | {'disk' if target == 'local' else 'S3 (local moto)'} "
                      f"| {min(walls):.2f} / {statistics.median(walls):.2f} "
                      f"| {statistics.median(m[1] for m in runs):.1f} "
                      f"| {max(m[2] for m in runs) / 1024:.0f} "
                      f"| {max(m[3] for m in runs) / 2**20:.1f} "
                      f"| {best_local / min(walls):.2f} |")
    finally:
        server_down(work)
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
