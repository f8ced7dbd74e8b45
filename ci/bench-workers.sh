#!/usr/bin/env bash
# Whole-tool benchmark of `bettimill build --workers N` (numbers go into BENCHMARKS.md).
#  1. samples/second with 1 and 2 workers on a 4D 32^4 dataset (32 samples, 8 shards);
#     the two outputs must be byte-identical;
#  2. the coordinator's overhead per shard: 200 one-sample 2D shards built by
#     `build --workers 1` versus the same shards built in-process by one array task
#     (`worker --task-index 0 --task-count 1 --threads 1`, no coordinator) plus `finalize`.
# Run it on an otherwise idle machine: it measures wall-clock time, and the load average
# is printed before each run. BETTIMILL=path/to/bettimill (default: a release build).
set -euo pipefail
cd "$(dirname "$0")/.."
source ci/bench-lib.sh
bench_setup release bench
cd "$work"
manifest() { # name dimension side samples shard_size
    printf 'schema_version = 1\nname = "%s"\ndimension = %s\nside = %s\nmode = ["embed", "carve"]\nsamples = %s\nshard_size = %s\nseed = 7\n\n[[classes]]\nfamily = "ball"\n\n[[classes]]\nfamily = "handle"\n' "$@" >"$1.toml"
}
manifest b4d 4 32 32 4
manifest o2d 2 16 200 1
load() { cut -d' ' -f1 /proc/loadavg; }
echo "machine: $(nproc) cores, $(uname -sr), $(date -u +%Y-%m-%dT%H:%MZ)"
for round in 1 2; do
    for w in 1 2; do
        rm -rf "b4d-$w"
        echo "== 4D 32^4, round $round, --workers $w (load $(load))"
        /usr/bin/time -f "wall %e s, user %U s, sys %S s" "$B" build b4d.toml --out "b4d-$w" --workers "$w" 2>&1 | grep -v index.json
    done
done
digest() { (cd "$1" && find . -type f ! -name .lock -exec sha256sum {} + | sort); }
cmp <(digest b4d-1) <(digest b4d-2) && echo "1 and 2 workers: byte-identical"
for round in 1 2; do
    rm -rf o-coord o-task
    echo "== coordinator overhead, 200 shards, round $round (load $(load))"
    /usr/bin/time -f "coordinator + 1 worker: wall %e s" "$B" build o2d.toml --out o-coord --workers 1 -q
    "$B" slurm o2d.toml --out o-task --tasks 1 -q
    /usr/bin/time -f "one array task, no coordinator: wall %e s" "$B" worker --dir o-task --task-index 0 --task-count 1 --threads 1 -q
    /usr/bin/time -f "finalize: wall %e s" "$B" finalize o-task -q
done
