#!/usr/bin/env bash
# Bring up a single-node Slurm (munge + slurmctld + slurmd) on this machine for tests.
#
# Idempotent: if munged, slurmctld and slurmd are running from their pid files, the
# config is unchanged and the node is usable in `sinfo`, it does nothing and exits 0.
# Fails loudly (message + non-zero exit) when any step does not work.
#
# Environment:
#   SLURM_CI_DIR         state/spool/log/pid directory (default /tmp/slurm)
#   SLURM_CI_WAIT        seconds to wait for the node to become idle (default 60)
#   SLURM_CI_PARTITION   partition name (default debug)
#   SLURM_CI_MIN_JOB_AGE MinJobAge: seconds a finished job stays visible to scontrol and
#                        sbatch --wait (default 3600; see the note at MinJobAge below)
#
# Needs root (apt-get, daemons run as root; munged as user munge).
# See docs/cluster.md.
set -euo pipefail

SLURM_CI_DIR=${SLURM_CI_DIR:-/tmp/slurm}
WAIT_SECS=${SLURM_CI_WAIT:-60}
PARTITION=${SLURM_CI_PARTITION:-debug}
MIN_JOB_AGE=${SLURM_CI_MIN_JOB_AGE:-3600}
CONF=/etc/slurm/slurm.conf
MUNGE_PID=/run/munge/munged.pid
CTLD_PID=$SLURM_CI_DIR/slurmctld.pid
SLURMD_PID=$SLURM_CI_DIR/slurmd.pid
LOCK=/tmp/slurm-ci.lock

log() { printf '[slurm-up +%ss] %s\n' "$SECONDS" "$*"; }
die() {
    printf '[slurm-up] ERROR: %s\n' "$*" >&2
    exit 1
}
show_log() { # file: dump the tail of a daemon log to stderr to explain a failure
    if [[ -f $1 ]]; then
        printf '[slurm-up] --- last lines of %s ---\n' "$1" >&2
        tail -n 30 "$1" >&2 || true
    fi
}

[[ $PARTITION =~ ^[A-Za-z0-9_-]+$ ]] || die "bad SLURM_CI_PARTITION '$PARTITION'"
[[ $MIN_JOB_AGE =~ ^[0-9]+$ ]] || die "bad SLURM_CI_MIN_JOB_AGE '$MIN_JOB_AGE'"
[[ $WAIT_SECS =~ ^[1-9][0-9]*$ ]] || die "bad SLURM_CI_WAIT '$WAIT_SECS'"
[[ $(id -u) -eq 0 ]] || die "must run as root (installs packages, starts daemons)"

# Serialize concurrent callers (e.g. two test suites starting at once). Every daemon below is
# started with `9>&-`: a daemon that inherits fd 9 holds the lock for its whole life.
exec 9>"$LOCK"
flock -w 120 9 || die "could not take $LOCK within 120 s (another slurm-up/down running?)"

# running PID: the process exists and is not a zombie. PID 1 here is not an init that reaps
# promptly, so a killed daemon can linger as a zombie that `kill -0` still reports.
running() {
    local st
    st=$(sed -n 's/^.*) \(.\) .*/\1/p' "/proc/$1/stat" 2>/dev/null) || return 1
    [[ -n $st && $st != Z && $st != X ]]
}
# pid_alive PIDFILE NAME: the pid file names a running process whose command is NAME.
pid_alive() {
    local pidfile=$1 name=$2 pid
    [[ -s $pidfile ]] || return 1
    pid=$(<"$pidfile")
    [[ $pid =~ ^[0-9]+$ ]] || return 1
    running "$pid" || return 1
    [[ $(cat "/proc/$pid/comm" 2>/dev/null) == "$name" ]]
}

HOST=$(hostname -s)
[[ -n $HOST ]] || die "hostname -s returned nothing"

# node_state: compact state of our node as sinfo prints it (idle, mix, alloc, down*, drain...)
node_state() { sinfo -h -N -n "$HOST" -o '%t' 2>/dev/null | head -n1; }
node_usable() {
    local s
    s=$(node_state) || return 1
    [[ $s == idle || $s == mix || $s == alloc || $s == comp ]]
}

# ---------------------------------------------------------------- 1. packages
need_install=()
for bin in /usr/sbin/slurmctld /usr/sbin/slurmd /usr/bin/sinfo /usr/bin/sbatch /usr/sbin/munged /usr/bin/munge; do
    [[ -x $bin ]] || need_install+=("$bin")
done
if ((${#need_install[@]})); then
    log "missing ${need_install[*]}: installing slurmctld slurmd slurm-client munge"
    export DEBIAN_FRONTEND=noninteractive
    apt-get -o DPkg::Lock::Timeout=300 update -q ||
        die "apt-get update failed"
    apt-get -o DPkg::Lock::Timeout=300 install -y -q --no-install-recommends \
        slurmctld slurmd slurm-client munge ||
        die "apt-get install slurmctld slurmd slurm-client munge failed"
    for bin in "${need_install[@]}"; do
        [[ -x $bin ]] || die "$bin still missing after apt-get install"
    done
else
    log "packages present ($(dpkg-query -W -f='${Version}' slurmctld 2>/dev/null || echo '?'))"
fi

# ---------------------------------------------------------------- 2. munge
if [[ ! -s /etc/munge/munge.key ]]; then
    log "creating /etc/munge/munge.key"
    if command -v mungekey >/dev/null; then
        runuser -u munge -- mungekey --create --keyfile=/etc/munge/munge.key ||
            die "mungekey --create failed"
    else
        dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none
        chown munge:munge /etc/munge/munge.key
    fi
    chmod 0400 /etc/munge/munge.key
fi
for d in /run/munge /var/lib/munge /var/log/munge; do
    install -d -o munge -g munge -m 0755 "$d"
done
chmod 0700 /var/lib/munge /var/log/munge
if pid_alive "$MUNGE_PID" munged; then
    log "munged already running (pid $(<"$MUNGE_PID"))"
else
    log "starting munged"
    # --force: take over a stale socket left by a munged that died without cleanup.
    runuser -u munge -- /usr/sbin/munged --force 9>&- ||
        { show_log /var/log/munge/munged.log; die "munged failed to start"; }
    for _ in $(seq 50); do pid_alive "$MUNGE_PID" munged && break; sleep 0.1; done
    pid_alive "$MUNGE_PID" munged || { show_log /var/log/munge/munged.log; die "munged not running after start"; }
fi
munge -n | unmunge >/dev/null 2>&1 || { show_log /var/log/munge/munged.log; die "munge -n | unmunge failed"; }
log "munge ok (munge -n | unmunge)"

# ---------------------------------------------------------------- 3. slurm.conf
mkdir -p "$SLURM_CI_DIR"/{state,spool,log} /etc/slurm
chmod 0755 "$SLURM_CI_DIR"

# NodeName line from `slurmd -C` (first line), RealMemory lowered to 90 % so the node is not
# drained for "Low RealMemory" if free memory moves a little; UpTime line dropped.
detected=$(/usr/sbin/slurmd -C 2>/dev/null | grep -m1 '^NodeName=') ||
    die "slurmd -C printed no NodeName line"
mem=$(sed -n 's/.*RealMemory=\([0-9]*\).*/\1/p' <<<"$detected")
[[ $mem =~ ^[0-9]+$ ]] || die "no RealMemory in slurmd -C output: $detected"
low=$((mem * 90 / 100))
((low >= 1)) || low=1
nodeline=$(sed -e "s/RealMemory=[0-9]*/RealMemory=$low/" -e "s/^NodeName=[^ ]*/NodeName=$HOST/" <<<"$detected")
nodeline="$nodeline NodeAddr=127.0.0.1 State=UNKNOWN"

# MinJobAge: `sbatch --wait` takes the worst exit code over the task records slurmctld still
# holds, and a finished task's record is purged MinJobAge seconds after it ends. Measured here:
# with MinJobAge=5, an array whose task 0 exits 3 while tasks 2-3 run 150 s more makes
# `sbatch --wait` exit 0. So keep MinJobAge longer than any array a test waits on. (sbatch
# polls after 2, 8, then every 32 s, so --wait returns up to ~30 s after the job ends anyway.)
newconf=$(
    cat <<EOF
# Written by ci/slurm-up.sh: single-node Slurm for tests. Do not edit; rerun the script.
ClusterName=bettimill-ci
SlurmctldHost=$HOST(127.0.0.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc=$SLURM_CI_DIR/jobcomp.log
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
StateSaveLocation=$SLURM_CI_DIR/state
SlurmdSpoolDir=$SLURM_CI_DIR/spool
SlurmctldPidFile=$CTLD_PID
SlurmdPidFile=$SLURMD_PID
SlurmctldLogFile=$SLURM_CI_DIR/log/slurmctld.log
SlurmdLogFile=$SLURM_CI_DIR/log/slurmd.log
SlurmctldPort=6817
SlurmdPort=6818
SlurmctldTimeout=30
SlurmdTimeout=60
InactiveLimit=0
MinJobAge=$MIN_JOB_AGE
KillWait=5
Waittime=0
$nodeline
PartitionName=$PARTITION Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
EOF
)

conf_changed=0
if [[ -f $CONF ]] && [[ "$(<"$CONF")" == "$newconf" ]]; then
    log "$CONF unchanged"
else
    conf_changed=1
    log "writing $CONF ($nodeline)"
    printf '%s\n' "$newconf" >"$CONF.tmp.$$"
    chmod 0644 "$CONF.tmp.$$"
    mv -f "$CONF.tmp.$$" "$CONF"
fi

# ---------------------------------------------------------------- 4. daemons
# wait_pid PIDFILE NAME LOG: after starting a daemon, wait (10 s) until its pid file names it.
# The daemons fork and write the pid file a moment after the parent returns.
wait_pid() {
    local pidfile=$1 name=$2 logfile=$3
    for _ in $(seq 100); do
        pid_alive "$pidfile" "$name" && return 0
        sleep 0.1
    done
    show_log "$logfile"
    die "$name not running 10 s after start (pid file $pidfile)"
}
stop_pid() { # pidfile name
    local pidfile=$1 name=$2 pid
    pid_alive "$pidfile" "$name" || return 0
    pid=$(<"$pidfile")
    log "stopping $name (pid $pid) to apply the new config"
    kill -TERM "$pid" 2>/dev/null || true
    for _ in $(seq 150); do running "$pid" || return 0; sleep 0.2; done
    log "$name still running after 30 s, sending SIGKILL"
    kill -KILL "$pid" 2>/dev/null || true
    for _ in $(seq 25); do running "$pid" || return 0; sleep 0.2; done
    die "$name (pid $pid) survived SIGKILL"
}
if ((conf_changed)); then
    stop_pid "$SLURMD_PID" slurmd
    stop_pid "$CTLD_PID" slurmctld
fi

if pid_alive "$CTLD_PID" slurmctld; then
    log "slurmctld already running (pid $(<"$CTLD_PID"))"
else
    log "starting slurmctld"
    /usr/sbin/slurmctld 9>&- || { show_log "$SLURM_CI_DIR/log/slurmctld.log"; die "slurmctld failed to start"; }
    wait_pid "$CTLD_PID" slurmctld "$SLURM_CI_DIR/log/slurmctld.log"
fi
ok=0
for _ in $(seq $((WAIT_SECS * 2))); do
    if scontrol ping 2>/dev/null | grep -q 'is UP'; then ok=1; break; fi
    pid_alive "$CTLD_PID" slurmctld || break
    sleep 0.5
done
((ok)) || { show_log "$SLURM_CI_DIR/log/slurmctld.log"; die "slurmctld did not answer scontrol ping"; }
log "slurmctld answers (scontrol ping)"

if pid_alive "$SLURMD_PID" slurmd; then
    log "slurmd already running (pid $(<"$SLURMD_PID"))"
else
    log "starting slurmd"
    /usr/sbin/slurmd 9>&- || { show_log "$SLURM_CI_DIR/log/slurmd.log"; die "slurmd failed to start"; }
    wait_pid "$SLURMD_PID" slurmd "$SLURM_CI_DIR/log/slurmd.log"
fi

# ---------------------------------------------------------------- 5. wait for the node
log "waiting up to ${WAIT_SECS}s for node $HOST to be idle"
start=$SECONDS
state=
resumed=0
while ((SECONDS - start < WAIT_SECS)); do
    pid_alive "$SLURMD_PID" slurmd || { show_log "$SLURM_CI_DIR/log/slurmd.log"; die "slurmd is not running"; }
    pid_alive "$CTLD_PID" slurmctld || { show_log "$SLURM_CI_DIR/log/slurmctld.log"; die "slurmctld is not running"; }
    state=$(node_state || true)
    if node_usable; then
        log "node $HOST is $state after $((SECONDS - start))s; partition $PARTITION ready"
        sinfo
        exit 0
    fi
    # A node left down/drained (e.g. by an earlier run, or "Low RealMemory") is resumed once
    # slurmd has registered; "down*" (not responding yet) needs slurmd to check in first.
    case $state in
    down | drain | drng | drain* | down~ | fail | maint)
        if ((resumed < 3)); then
            reason=$(sinfo -h -N -n "$HOST" -o '%E' 2>/dev/null || true)
            log "node $HOST is $state (reason: ${reason:-none}): scontrol update state=resume"
            scontrol update nodename="$HOST" state=resume || log "resume did not take (will retry)"
            resumed=$((resumed + 1))
        fi
        ;;
    esac
    sleep 1
done
sinfo -N -l >&2 || true
show_log "$SLURM_CI_DIR/log/slurmd.log"
show_log "$SLURM_CI_DIR/log/slurmctld.log"
die "node $HOST not idle after ${WAIT_SECS}s (state: ${state:-unknown})"
