#!/usr/bin/env bash
# Proves that the datasets bettimill writes are read by the real Python clients
# (webdataset + torch DataLoader, HF datasets, GNU tar + numpy, wids): see
# tests/python/test_clients.py for what is checked.
#
# With BETTIMILL_DATASET set, runs the client tests on that one directory. Otherwise builds
# small datasets in a temporary directory and runs the tests on each:
#   - with the real CLI (`bettimill build`), one per member compression (none, gzip, zstd)
#     and dimension (2, 3, 4), after `bettimill verify` accepts it;
#   - with the bettimill-format demo_shards example, the same three compressions, which
#     also writes wids shard indexes.
# The Python environment comes from ci/python-env.sh (idempotent). Progress on stderr.
set -euo pipefail
cd "$(dirname "$0")/.."
REPO="$(pwd)"
# The one venv both Python suites use (ci/python-env.sh makes it; BETTIMILL_VENV moves it).
VENV="${BETTIMILL_VENV:-$REPO/.venv}"

bash ci/python-env.sh
PYTEST=("$VENV/bin/python" -m pytest -q -rs -p no:cacheprovider tests/python)

if [[ -n "${BETTIMILL_DATASET:-}" ]]; then
    echo "python-clients: testing BETTIMILL_DATASET=$BETTIMILL_DATASET" >&2
    exec "${PYTEST[@]}"
fi

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

echo "python-clients: building the bettimill CLI and the demo_shards example" >&2
cargo build --quiet --locked -p bettimill-cli -p bettimill-format --bins --examples
target="${CARGO_TARGET_DIR:-$REPO/target}/debug"

datasets=()
for spec in "none 2 20" "gzip 3 18" "zstd 4 18"; do
    read -r compression dimension side <<<"$spec"
    manifest="$work/cli-$compression.toml"
    cat >"$manifest" <<TOML
schema_version = 1
name = "pyclients${dimension}d${compression}"
dimension = $dimension
side = $side
mode = ["embed", "carve"]
samples = 12
shard_size = 5
seed = 7
compression = "$compression"

[[classes]]
family = "ball"

[[classes]]
family = "handle"
TOML
    out="$work/cli-$compression-${dimension}d"
    echo "python-clients: bettimill build ($compression, ${dimension}D) -> $out" >&2
    "$target/bettimill" build "$manifest" --quiet --out "$out"
    "$target/bettimill" verify "$out" >&2
    datasets+=("$out")
done
for spec in "none 2" "gzip 3" "zstd 4"; do
    read -r compression dimension <<<"$spec"
    out="$work/demo-$compression-${dimension}d"
    "$target/examples/demo_shards" "$out" --compression "$compression" --dim "$dimension"
    datasets+=("$out")
done

for dataset in "${datasets[@]}"; do
    echo "python-clients: testing $dataset" >&2
    BETTIMILL_DATASET="$dataset" "${PYTEST[@]}"
done
echo "python-clients: ${#datasets[@]} datasets read by every client" >&2
