#!/usr/bin/env bash
# Stops the local S3 server of ci/s3-up.sh by the PID in its PID file (SIGTERM, then SIGKILL
# after 10 s). Idempotent: a server that is not running is skipped. Its objects live in its
# memory and go with it. Exits non-zero only if the server survives SIGKILL.
#
# Environment: S3_CI_DIR (default /tmp/bettimill-s3), as for ci/s3-up.sh.
set -euo pipefail

S3_CI_DIR=${S3_CI_DIR:-/tmp/bettimill-s3}
PIDFILE=$S3_CI_DIR/moto.pid

log() { printf '[s3-down] %s\n' "$*" >&2; }

running() {
    local st
    st=$(sed -n 's/^.*) \(.\) .*/\1/p' "/proc/$1/stat" 2>/dev/null) || return 1
    [[ -n $st && $st != Z && $st != X ]]
}

mkdir -p "$S3_CI_DIR"
exec 9>"$S3_CI_DIR/lock"
flock -w 300 9 || { log "ERROR: could not take $S3_CI_DIR/lock within 300 s"; exit 1; }

if [[ ! -s $PIDFILE ]]; then
    log "no PID file ($PIDFILE): not running"
    rm -f "$S3_CI_DIR/env"
    exit 0
fi
pid=$(<"$PIDFILE")
# The PID file must name a moto_server (a Python process running it), or the PID was reused.
if ! [[ $pid =~ ^[0-9]+$ ]] || ! running "$pid" ||
    ! tr '\0' ' ' <"/proc/$pid/cmdline" 2>/dev/null | grep -q moto_server; then
    log "stale PID file ($PIDFILE: ${pid:-empty}): not running"
    rm -f "$PIDFILE" "$S3_CI_DIR/env"
    exit 0
fi
log "stopping moto_server (pid $pid)"
kill -TERM "$pid" 2>/dev/null || true
for _ in $(seq 50); do
    running "$pid" || { rm -f "$PIDFILE" "$S3_CI_DIR/env"; log "stopped"; exit 0; }
    sleep 0.2
done
log "still running after 10 s, sending SIGKILL"
kill -KILL "$pid" 2>/dev/null || true
for _ in $(seq 25); do
    running "$pid" || { rm -f "$PIDFILE" "$S3_CI_DIR/env"; log "killed"; exit 0; }
    sleep 0.2
done
log "ERROR: moto_server (pid $pid) survived SIGKILL"
exit 1
