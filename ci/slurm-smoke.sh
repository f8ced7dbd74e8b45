#!/usr/bin/env bash
# Smoke test of the single-node Slurm: runs ci/slurm-up.sh (a no-op when already up), then
#  1. `sbatch --wait --array=0-3` of a script writing its SLURM_ARRAY_TASK_ID to a file:
#     sbatch must exit 0 and all four files must appear with the right array variables;
#  2. `sbatch --wait --array=0-3` where task 2 exits 3: sbatch must exit non-zero, and the
#     jobcomp file must record that task as FAILED with ExitCode=3.
# Exits non-zero on any failure. Environment: SLURM_CI_DIR as for slurm-up.sh,
# SLURM_SMOKE_TIMEOUT (seconds per sbatch --wait, default 120).
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
SLURM_CI_DIR=${SLURM_CI_DIR:-/tmp/slurm}
TIMEOUT=${SLURM_SMOKE_TIMEOUT:-120}
JOBCOMP=$SLURM_CI_DIR/jobcomp.log

log() { printf '[slurm-smoke] %s\n' "$*"; }
fail() {
    printf '[slurm-smoke] FAIL: %s\n' "$*" >&2
    exit 1
}

"$here/slurm-up.sh" || fail "ci/slurm-up.sh failed"

work=$(mktemp -d /tmp/slurm-smoke.XXXXXX)
chmod 0755 "$work"
jobs=()
cleanup() {
    local j
    for j in "${jobs[@]}"; do scancel "$j" 2>/dev/null || true; done
    rm -rf -- "$work"
}
trap cleanup EXIT

# submit NAME SCRIPT: sbatch --wait --parsable an array 0-3 of SCRIPT with the work dir as
# its argument (SLURM_SUBMIT_DIR would be the caller's cwd); sets $jobid and $rc.
submit() {
    local name=$1 script=$2 out
    rc=0
    out=$(cd "$work" && timeout "$TIMEOUT" sbatch --wait --parsable --array=0-3 --job-name="$name" \
        --output="$work/$name-%A_%a.out" --chdir="$work" "$script" "$work") || rc=$?
    jobid=${out%%;*}
    jobid=${jobid//[!0-9]/}
    [[ -n $jobid ]] && jobs+=("$jobid")
    ((rc != 124)) || fail "$name: sbatch --wait did not return within ${TIMEOUT}s (job ${jobid:-?})"
    [[ -n $jobid ]] || fail "$name: sbatch printed no job id (exit $rc): $out"
    log "$name: job $jobid, sbatch --wait exit $rc"
}

# ---------------------------------------------------------------- 1. all tasks succeed
cat >"$work/ok.sh" <<'EOF'
#!/bin/bash
set -eu
echo "$SLURM_ARRAY_TASK_ID $SLURM_ARRAY_TASK_COUNT $SLURM_ARRAY_TASK_MIN $SLURM_ARRAY_TASK_MAX $SLURM_ARRAY_JOB_ID" \
    >"$1/task-$SLURM_ARRAY_TASK_ID.tmp"
mv "$1/task-$SLURM_ARRAY_TASK_ID.tmp" "$1/task-$SLURM_ARRAY_TASK_ID"
EOF
t0=$SECONDS
submit ok "$work/ok.sh"
((rc == 0)) || { cat "$work"/ok-*.out >&2 2>/dev/null || true; fail "ok: sbatch --wait exit $rc, expected 0"; }
for i in 0 1 2 3; do
    f=$work/task-$i
    [[ -f $f ]] || { ls -l "$work" >&2; fail "ok: $f missing"; }
    read -r id count min max ajob <"$f"
    [[ "$id $count $min $max $ajob" == "$i 4 0 3 $jobid" ]] ||
        fail "ok: $f has '$id $count $min $max $ajob', expected '$i 4 0 3 $jobid'"
done
log "ok: 4 tasks wrote task-0..3 with the right array variables ($((SECONDS - t0))s)"

# ---------------------------------------------------------------- 2. one task fails
cat >"$work/bad.sh" <<'EOF'
#!/bin/bash
if [ "$SLURM_ARRAY_TASK_ID" = 2 ]; then exit 3; fi
exit 0
EOF
t0=$SECONDS
submit bad "$work/bad.sh"
((rc != 0)) || fail "bad: sbatch --wait exit 0, expected non-zero (task 2 exits 3)"
log "bad: sbatch --wait exit $rc (non-zero, as expected) ($((SECONDS - t0))s)"

# The jobcomp file gets one line per finished task; task 2 must be FAILED with ExitCode=3.
# (Best-effort wait: the line is written when the controller processes the completion.)
line=
for _ in $(seq 20); do
    line=$(grep -E " ArrayJobId=$jobid ArrayTaskId=2 " "$JOBCOMP" 2>/dev/null | tail -n1 || true)
    [[ -n $line ]] && break
    sleep 0.5
done
if [[ -z $line ]]; then
    # Show this array job's lines (if any) so a format difference shows up clearly.
    grep -E " ArrayJobId=$jobid " "$JOBCOMP" >&2 2>/dev/null || true
    fail "bad: no jobcomp line for task 2 of job $jobid in $JOBCOMP"
fi
[[ $line == *"JobState=FAILED"* && $line == *"ExitCode=3:0"* ]] ||
    fail "bad: jobcomp line for task 2 is not FAILED/ExitCode=3:0: $line"
log "bad: jobcomp records task 2 as FAILED ExitCode=3:0"

log "PASS"
