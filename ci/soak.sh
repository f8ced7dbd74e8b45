#!/usr/bin/env bash
# The kill soak of docs/reliability.md (not part of the default test run; about 10 minutes
# for 200 kills on 2 cores).
#
# usage: ci/soak.sh [KILLS] [BIN]     (env: SOAK_SEED, SOAK_WORKERS, SOAK_DEMOS)
#
# Builds manifests/demo-2d, demo-3d and demo-4d once cleanly, then again and again with one
# signal per run sent at a random (seeded) moment from 0 ms to the clean build's duration:
# SIGKILL, SIGTERM, SIGINT, or SIGSTOP followed after up to 0.5 s by SIGKILL, to the
# coordinator (one time in three) or to a random worker. Each killed run is rerun (and
# killed again, at random) until a run completes; the completed directory must equal the
# clean build byte for byte (timings/ and the lock aside). As root it also builds into a
# tmpfs of a random size too small for the dataset (disk full, a kill on top), grows it
# and resumes. Every exit code is checked against what the signal allows:
#   coordinator: SIGKILL or SIGSTOP+SIGKILL -> 137; SIGINT or SIGTERM -> 130 (143 only for a
#   SIGTERM before main has run); or 0 when the build had finished;
#   worker: 0, or 2 when the coordinator gave a shard up or a worker died before any
#   handshake (both documented; the rerun resumes).
# Prints one line per kill and a summary "kills: N tried, N survived"; exit 1 on any
# failure, with the run's stderr.
set -uo pipefail

KILLS=${1:-200}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BIN=${2:-${CARGO_TARGET_DIR:-$ROOT/target}/debug/bettimill}
RANDOM=${SOAK_SEED:-2026}
WORKERS=${SOAK_WORKERS:-2}
DEMOS=${SOAK_DEMOS:-"demo-2d demo-3d demo-4d"}
# 1 during a disk-full round (set for one one_run call), where exit 2 with ENOSPC is allowed.
DISK_FULL=0
[ -x "$BIN" ] || { echo "no bettimill binary at $BIN (cargo build -p bettimill-cli)"; exit 2; }

work=$(mktemp -d /tmp/bettimill-soak.XXXXXX)
mounted=""
cleanup() {
    [ -n "$mounted" ] && umount "$mounted" 2>/dev/null
    rm -rf "$work"
}
trap cleanup EXIT

now_ms() { date +%s%3N; }
rand() { echo $(( (RANDOM * 32768 + RANDOM) % $1 )); }

# Every `bettimill worker --dir OUT` process still alive.
workers_of() {
    local out=$1 pid
    for pid in $(pgrep -f -- "worker --dir $out\$" 2>/dev/null); do
        [ "$(awk '{print $3}' /proc/$pid/stat 2>/dev/null)" = "Z" ] || echo "$pid"
    done
}

same_as_clean() {
    diff -r -x timings -x .lock "$1" "$2" >/dev/null
}

tried=0; survived=0; failures=0; runs=0; rebuilds=0
declare -A by_kind

fail() {
    failures=$((failures + 1))
    echo "FAIL: $*"
    [ -f "$work/stderr" ] && sed 's/^/  | /' "$work/stderr" | tail -20
}

# One run of `build` with one random signal; sets $completed.
one_run() {
    local manifest=$1 out=$2 clean_ms=$3
    runs=$((runs + 1))
    "$BIN" build "$manifest" --out "$out" --workers "$WORKERS" --quiet 2>"$work/stderr" &
    local pid=$! delay
    # A quarter of the kills land in the first 20 ms (start-up), the rest anywhere.
    if [ "$(rand 4)" = 0 ]; then delay=$(rand 21); else delay=$(rand $((clean_ms + 1))); fi
    sleep "$(printf '0.%03d' "$delay")" 2>/dev/null || sleep "$((delay / 1000))"
    local target=coordinator victim=$pid
    if [ "$(rand 3)" != 0 ]; then
        local workers
        workers=$(pgrep -P "$pid" 2>/dev/null | tr '\n' ' ')
        if [ -n "$workers" ]; then
            local list=($workers)
            victim=${list[$(rand ${#list[@]})]}
            target=worker
        fi
    fi
    local signals=(KILL TERM INT STOP)
    local signal=${signals[$(rand 4)]}
    local sent=no
    if kill -0 "$victim" 2>/dev/null && kill -"$signal" "$victim" 2>/dev/null; then sent=yes; fi
    if [ "$signal" = STOP ]; then
        sleep "$(printf '0.%03d' "$(rand 500)")"
        kill -KILL "$victim" 2>/dev/null
    fi
    wait "$pid" 2>/dev/null
    local code=$?
    # Orphaned workers (their coordinator died) must go on their own.
    local waited=0
    while [ -n "$(workers_of "$out")" ]; do
        sleep 0.1; waited=$((waited + 1))
        if [ $waited -gt 300 ]; then fail "workers outlived their coordinator in $out"; pkill -KILL -f -- "worker --dir $out\$"; break; fi
    done
    local ok=no
    case "$target:$signal:$code" in
        *:*:0) ok=yes ;;
        coordinator:KILL:137|coordinator:STOP:137) ok=yes ;;
        coordinator:INT:130|coordinator:TERM:130|coordinator:TERM:143) ok=yes ;;
        worker:*:2)
            grep -q -e "failed 3 times" -e "exited before its handshake" "$work/stderr" && ok=yes ;;
    esac
    # On a full disk a build stops with exit 2 and says why, whatever the signal did.
    if [ $ok = no ] && [ $code = 2 ] && [ "$DISK_FULL" = 1 ] && grep -q "No space left on device" "$work/stderr"; then ok=yes; fi
    [ $ok = yes ] || fail "$target $signal after ${delay} ms: exit $code"
    if [ $sent = yes ] && [ $code != 0 ] || { [ $sent = yes ] && [ $target = worker ]; }; then
        tried=$((tried + 1))
        by_kind[$target-$signal]=$(( ${by_kind[$target-$signal]:-0} + 1 ))
        [ $ok = yes ] && survived=$((survived + 1))
        echo "kill $tried: $(basename "$out") $target SIG$signal at ${delay} ms -> exit $code"
    fi
    completed=no
    [ $code = 0 ] && [ -f "$out/index.json" ] && completed=yes
}

declare -A clean_ms
for demo in $DEMOS; do
    start=$(now_ms)
    "$BIN" build "$ROOT/manifests/$demo.toml" --out "$work/clean-$demo" --workers "$WORKERS" --quiet \
        || { echo "clean build of $demo failed"; exit 1; }
    clean_ms[$demo]=$(( $(now_ms) - start ))
    echo "clean $demo: ${clean_ms[$demo]} ms"
done

demos=($DEMOS)
round=0
while [ $tried -lt "$KILLS" ]; do
    demo=${demos[$((round % ${#demos[@]}))]}
    round=$((round + 1))
    out=$work/run-$demo
    rm -rf "$out"
    tries=0
    while :; do
        tries=$((tries + 1))
        one_run "$ROOT/manifests/$demo.toml" "$out" "${clean_ms[$demo]}"
        if [ $completed = yes ]; then
            same_as_clean "$work/clean-$demo" "$out" || fail "$demo: the completed build differs from the clean one"
            rebuilds=$((rebuilds + 1))
            break
        fi
        [ $tries -gt 100 ] && { fail "$demo: no completion in 100 runs"; break; }
    done
done

# Disk full (root only): a tmpfs too small for the dataset, a kill on top, then space back.
if [ "$(id -u)" = 0 ] && [ "${SOAK_DISK_FULL:-1}" = 1 ]; then
    demo=${demos[0]}
    need=$(du -sk "$work/clean-$demo" | cut -f1)
    for i in $(seq 1 "${SOAK_DISK_FULL_ROUNDS:-10}"); do
        mnt=$work/tmpfs; mkdir -p "$mnt"
        size=$(( 4 + $(rand "$need") ))
        mount -t tmpfs -o "size=${size}k" tmpfs "$mnt" || { echo "cannot mount a tmpfs: disk-full rounds skipped"; break; }
        mounted=$mnt
        out=$mnt/ds
        DISK_FULL=1 one_run "$ROOT/manifests/$demo.toml" "$out" "${clean_ms[$demo]}"
        full_code=$(grep -c "No space left on device" "$work/stderr")
        mount -o remount,size=256M "$mnt"
        tries=0
        while :; do
            tries=$((tries + 1))
            "$BIN" build "$ROOT/manifests/$demo.toml" --out "$out" --workers "$WORKERS" --quiet 2>"$work/stderr" && break
            [ $tries -gt 5 ] && { fail "disk full ${size} KiB: no resume"; break; }
        done
        same_as_clean "$work/clean-$demo" "$out" || fail "disk full ${size} KiB: the resumed build differs"
        echo "disk full: tmpfs of ${size} KiB (dataset ${need} KiB), 'No space left' lines: $full_code, resumed identical"
        rebuilds=$((rebuilds + 1))
        umount "$mnt"; mounted=""
    done
fi

echo "by kind: $(for k in "${!by_kind[@]}"; do printf '%s=%s ' "$k" "${by_kind[$k]}"; done)"
echo "kills: $tried tried, $survived survived; $runs runs, $rebuilds complete rebuilds byte-identical to the clean build; $failures failures"
[ $failures = 0 ]
