#!/usr/bin/env bash
# Calibrates the cost model of `bettimill plan` (crates/bettimill-plan/src/estimate.rs):
# builds small datasets of one family, side and mode each with one worker
# under /usr/bin/time and prints, per case, CPU seconds (user + system: the machine is
# shared, wall time is not a measure) per sample, nanoseconds per voxel, and the
# compressed bytes per sample and ratio to the uncompressed bound, beside what
# `plan --json` estimates for the same manifest. Also the demo manifests as they are.
# BETTIMILL=path/to/bettimill (default: the dev build); CASES=quick skips the larger sides,
# CASES=extra runs only the factor cases (bins, deformation, copies, parts, resolutions),
# CASES=all runs everything.
set -euo pipefail
cd "$(dirname "$0")/.."
source ci/bench-lib.sh
bench_setup dev calibrate
echo "machine: $(nproc) cores, $(uname -sr), $(date -u +%Y-%m-%dT%H:%MZ), load $(cut -d' ' -f1 /proc/loadavg)"
printf '%-34s %7s %9s %9s %11s %8s %9s %11s\n' case samples cpu-s/smp ns/voxel bytes/smp ratio model-s model-bytes

# measure NAME MANIFEST: one build, one line of figures.
measure() {
    local name=$1 manifest=$2
    rm -rf "$work/ds"
    /usr/bin/time -f "%U %S" -o "$work/time.txt" \
        "$B" build "$manifest" --out "$work/ds" --workers 1 --quiet >/dev/null
    read -r user sys <"$work/time.txt"
    "$B" plan "$manifest" --json >"$work/plan.json"
    python3 - "$name" "$work/plan.json" "$work/ds" "$user" "$sys" <<'PY'
import json, os, sys
name, plan_path, ds, user, sys_s = sys.argv[1:6]
plan = json.load(open(plan_path))
n = plan["samples"]
cpu = (float(user) + float(sys_s)) / n
voxels = plan["side"] ** plan["dimension"]
shards = os.path.join(ds, "shards")
size = sum(os.path.getsize(os.path.join(shards, f)) for f in os.listdir(shards)) / n
bound = plan["estimated_bytes"] / n
# The model's whole build (samples, the fixed costs, one worker's tables) per sample, as measured.
model_s = plan.get("estimated_cpu_seconds", float("nan")) / n
model_b = plan.get("estimated_compressed_bytes", float("nan")) / n
print(f"{name:<34} {n:>7} {cpu:>9.4f} {cpu / voxels * 1e9:>9.1f} {size:>11.0f} {bound / size:>8.1f} {model_s:>9.4f} {model_b:>11.0f}")
PY
}

# case NAME DIM SIDE MODE SAMPLES COMPRESSION FAMILY [EXTRA TOML] [CLASS TOML]
case_() {
    local name=$1 dim=$2 side=$3 mode=$4 samples=$5 compression=$6 family=$7 extra=${8:-}
    local class=${9:-}
    cat >"$work/m.toml" <<TOML
schema_version = 1
name = "cal"
dimension = $dim
side = $side
mode = "$mode"
samples = $samples
shard_size = 20
seed = 7
compression = "$compression"
$extra

[[classes]]
family = "$family"
$class
TOML
    measure "$name" "$work/m.toml"
}

if [[ ${CASES:-} == extra ]]; then
    set -- extra
else
    set -- base
fi
if [[ $1 == base ]]; then
for m in demo-2d demo-3d demo-4d; do measure "$m (as shipped)" "manifests/$m.toml"; done
case_ "2D 16 embed ball (fixed cost)" 2 16 embed 1 none ball
case_ "2D 128 embed ball" 2 128 embed 60 none ball
case_ "2D 128 carve handle" 2 128 carve 60 none handle
case_ "2D 128 carve handle gzip" 2 128 carve 60 gzip handle
case_ "2D 128 embed ball zstd" 2 128 embed 60 zstd ball
case_ "3D 64 embed handle" 3 64 embed 20 gzip handle
case_ "3D 64 carve ball" 3 64 carve 20 gzip ball
case_ "3D 64 carve ball zstd" 3 64 carve 20 zstd ball
case_ "4D 32 embed t2_x_b2" 4 32 embed 16 gzip t2_x_b2
case_ "4D 32 carve s2_x_b2" 4 32 carve 16 gzip s2_x_b2
case_ "4D 48 carve handle zstd" 4 48 carve 4 zstd handle
if [[ ${CASES:-} != quick ]]; then
    case_ "4D 64 carve ball zstd" 4 64 carve 2 zstd ball
    case_ "4D 64 carve ball zstd binned" 4 64 carve 2 zstd ball \
        $'[hypervolume]\nunit = "fraction"\nbins = [[0.55, 0.65]]'
fi
fi
if [[ $1 == extra || ${CASES:-} == all ]]; then
    case_ "3D 64 carve ball binned" 3 64 carve 20 gzip ball \
        $'[hypervolume]\nunit = "fraction"\nbins = [[0.55, 0.65]]'
    case_ "3D 64 embed ball deform 200" 3 64 embed 20 gzip ball \
        $'[deform]\nmethod = "moves"\nsteps = 200'
    case_ "4D 48 carve handle x2 zstd" 4 48 carve 4 zstd handle 'components = [2]'
    case_ "4D 64 carve CS(1,1,1,1) zstd" 4 64 carve 2 zstd connected_sum '' \
        $'g = 1\nh = 1\ni = 1\nj = 1'
    case_ "4D 48 carve handle r24 r12 zstd" 4 48 carve 4 zstd handle 'resolutions = [24, 12]'
    # The 4D mixed 128 preset at side 64 (its first class, its deformations), cavities
    # about 6% of the cube: the bytes follow the cavities' boundary, not the cube's.
    sed -e 's/^side = 128$/side = 64/' -e 's/^samples = 9600$/samples = 24/' \
        -e 's/^train = 8000$/train = 16/' -e 's/^val = 800$/val = 4/' -e 's/^test = 800$/test = 4/' \
        -e 's/^resolutions = \[64, 32\]$/resolutions = [32, 16]/' \
        -e 's/^bins = .*/bins = [[0.820, 0.822], [0.822, 0.824], [0.824, 0.826], [0.826, 0.828]]/' \
        manifests/4d-mixed-128.toml | awk '/^\[\[classes\]\]/ { n++ } n < 2' >"$work/m64.toml"
    measure "4D 64 mixed binned 6% deformed" "$work/m64.toml"
fi
