#!/usr/bin/env bash
# Stop the single-node Slurm started by ci/slurm-up.sh: slurmd, slurmctld, then munged,
# each by its pid file (SIGTERM, then SIGKILL after 30 s). Idempotent: daemons that are not
# running are skipped. Exits non-zero only if a daemon survives SIGKILL.
#
#   --clean   also remove $SLURM_CI_DIR (saved job state, spool, logs, jobcomp file)
#
# Environment: SLURM_CI_DIR (default /tmp/slurm), as for slurm-up.sh.
set -euo pipefail

SLURM_CI_DIR=${SLURM_CI_DIR:-/tmp/slurm}
LOCK=/tmp/slurm-ci.lock
clean=0
for arg in "$@"; do
    case $arg in
    --clean) clean=1 ;;
    *) echo "usage: $0 [--clean]" >&2; exit 2 ;;
    esac
done

log() { printf '[slurm-down] %s\n' "$*"; }
die() {
    printf '[slurm-down] ERROR: %s\n' "$*" >&2
    exit 1
}

[[ $(id -u) -eq 0 ]] || die "must run as root"
exec 9>"$LOCK"
flock -w 120 9 || die "could not take $LOCK within 120 s"

# running PID: the process exists and is not a zombie (PID 1 here reaps late, and `kill -0`
# succeeds on a zombie).
running() {
    local st
    st=$(sed -n 's/^.*) \(.\) .*/\1/p' "/proc/$1/stat" 2>/dev/null) || return 1
    [[ -n $st && $st != Z && $st != X ]]
}

# stop PIDFILE NAME: stop the process the pid file names, if it is a live NAME.
stop() {
    local pidfile=$1 name=$2 pid
    if [[ ! -s $pidfile ]]; then
        log "$name: no pid file ($pidfile), not running"
        return 0
    fi
    pid=$(<"$pidfile")
    if ! [[ $pid =~ ^[0-9]+$ ]] || ! running "$pid" ||
        [[ $(cat "/proc/$pid/comm" 2>/dev/null) != "$name" ]]; then
        log "$name: stale pid file ($pidfile: ${pid:-empty}), not running"
        rm -f "$pidfile"
        return 0
    fi
    log "$name: stopping pid $pid"
    kill -TERM "$pid" 2>/dev/null || true
    for _ in $(seq 150); do
        running "$pid" || { log "$name: stopped"; rm -f "$pidfile"; return 0; }
        sleep 0.2
    done
    log "$name: still running after 30 s, sending SIGKILL"
    kill -KILL "$pid" 2>/dev/null || true
    for _ in $(seq 25); do
        running "$pid" || { log "$name: killed"; rm -f "$pidfile"; return 0; }
        sleep 0.2
    done
    die "$name (pid $pid) survived SIGKILL"
}

stop "$SLURM_CI_DIR/slurmd.pid" slurmd
stop "$SLURM_CI_DIR/slurmctld.pid" slurmctld
stop /run/munge/munged.pid munged

if ((clean)); then
    log "removing $SLURM_CI_DIR"
    rm -rf -- "$SLURM_CI_DIR"
fi
log "done"
