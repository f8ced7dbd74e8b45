#!/usr/bin/env bash
# Starts a local S3-compatible server for the tests: moto_server (moto's S3 service, from
# PyPI, pinned in ci/s3-requirements.txt) on loopback only, with request signing enforced,
# one bucket, and one access key. Stopped by ci/s3-down.sh, by its PID.
#
# Idempotent: when the server of the PID file is running and answers, it does nothing.
# Fails loudly (message, non-zero exit) when a step does not work.
#
# What the tests need is written to $S3_CI_DIR/env as KEY=VALUE lines: AWS_ENDPOINT_URL,
# AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY, AWS_REGION and BETTIMILL_S3_CI_BUCKET (the
# bucket, empty when the server starts). The key is real: the server checks every request's
# signature against it (INITIAL_NO_AUTH_ACTION_COUNT), so wrong credentials are refused as
# by a real S3.
#
# With S3_CI_KEEP=1 the server keeps its objects across a restart, as a server with a disk
# does (moto keeps them in memory): its recorder appends every request after the set-up to
# $S3_CI_DIR/recording, and a start that finds a recording replays it. The set-up is seeded
# (moto's /moto-api/seed), so a restart makes the same key and the requests' signatures
# still hold. ci/s3-down.sh leaves the recording; a new directory starts empty.
#
# Environment:
#   S3_CI_DIR    PID file, log, env file, recording (default /tmp/bettimill-s3)
#   S3_CI_PORT   port on 127.0.0.1 (default 29768, below the kernel's ephemeral ports)
#   S3_CI_KEEP   1: keep the objects across a restart (default 0)
#   S3_CI_VENV   the server's venv (default $REPO/.venv-s3; a venv of its own, see
#                ci/s3-requirements.txt)
#   PYTHON       the Python that makes the venv (default python3, >= 3.10)
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
S3_CI_DIR=${S3_CI_DIR:-/tmp/bettimill-s3}
PORT=${S3_CI_PORT:-29768}
VENV=${S3_CI_VENV:-$REPO/.venv-s3}
PYTHON=${PYTHON:-python3}
REQUIREMENTS="$REPO/ci/s3-requirements.txt"
UV_VERSION="0.13.8"
PIDFILE=$S3_CI_DIR/moto.pid
LOG=$S3_CI_DIR/moto.log
ENVFILE=$S3_CI_DIR/env
RECORDING=$S3_CI_DIR/recording
KEEP=${S3_CI_KEEP:-0}
BUCKET=bettimill-ci
ENDPOINT=http://127.0.0.1:$PORT

log() { printf '[s3-up +%ss] %s\n' "$SECONDS" "$*" >&2; }
die() {
    printf '[s3-up] ERROR: %s\n' "$*" >&2
    if [[ -f $LOG ]]; then
        printf '[s3-up] --- last lines of %s ---\n' "$LOG" >&2
        tail -n 30 "$LOG" >&2 || true
    fi
    exit 1
}

[[ $PORT =~ ^[1-9][0-9]*$ ]] || die "bad S3_CI_PORT '$PORT'"
[[ $KEEP == 0 || $KEEP == 1 ]] || die "bad S3_CI_KEEP '$KEEP' (0 or 1)"
mkdir -p "$S3_CI_DIR"
# Serialise concurrent callers (two test binaries starting at once). The server is started
# with `9>&-`, or it would hold the lock for its whole life.
exec 9>"$S3_CI_DIR/lock"
flock -w 300 9 || die "could not take $S3_CI_DIR/lock within 300 s"

# running PID: the process exists and is not a zombie.
running() {
    local st
    st=$(sed -n 's/^.*) \(.\) .*/\1/p' "/proc/$1/stat" 2>/dev/null) || return 1
    [[ -n $st && $st != Z && $st != X ]]
}
# answers: something accepts connections on the port (a TCP connect, not a request, which
# would use up one of the server's unauthenticated actions).
answers() { (exec 3<>"/dev/tcp/127.0.0.1/$PORT") 2>/dev/null; }

if [[ -s $PIDFILE && -s $ENVFILE ]]; then
    pid=$(<"$PIDFILE")
    if [[ $pid =~ ^[0-9]+$ ]] && running "$pid" && answers; then
        log "moto_server (pid $pid) already serves $ENDPOINT; nothing to do"
        exit 0
    fi
    log "stale PID file $PIDFILE (${pid:-empty}); starting again"
    rm -f "$PIDFILE" "$ENVFILE"
fi
if answers; then
    die "something else listens on 127.0.0.1:$PORT (set S3_CI_PORT)"
fi

# ---------------------------------------------------------------- 1. the server's venv
if [[ ! -x $VENV/bin/python ]]; then
    "$PYTHON" -c 'import sys; sys.exit(sys.version_info < (3, 10))' ||
        die "$PYTHON is $("$PYTHON" --version 2>&1); Python >= 3.10 is needed"
    log "creating $VENV"
    "$PYTHON" -m venv "$VENV" || die "python3 -m venv $VENV failed"
fi
if [[ "$("$VENV/bin/uv" --version 2>/dev/null || true)" != "uv $UV_VERSION"* ]]; then
    log "installing uv $UV_VERSION into $VENV (pip)"
    "$VENV/bin/python" -m pip --version >/dev/null 2>&1 || "$VENV/bin/python" -m ensurepip --upgrade >&2
    "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps "uv==$UV_VERSION" >&2 ||
        die "pip could not install uv $UV_VERSION"
fi
log "installing ci/s3-requirements.txt into $VENV (uv pip sync: exact versions)"
"$VENV/bin/uv" pip sync --quiet --python "$VENV/bin/python" "$REQUIREMENTS" >&2 ||
    die "uv pip sync of $REQUIREMENTS failed"

# ---------------------------------------------------------------- 2. the server
# The first three requests go without signatures (they make the user, its key and its
# policy); every later one is checked against IAM, signature included.
log "starting moto_server on $ENDPOINT"
: >"$LOG"
INITIAL_NO_AUTH_ACTION_COUNT=3 MOTO_ALLOW_NONEXISTENT_REGION=false MOTO_RECORDER_FILEPATH="$RECORDING" \
    setsid "$VENV/bin/moto_server" -H 127.0.0.1 -p "$PORT" </dev/null >>"$LOG" 2>&1 9>&- &
pid=$!
echo "$pid" >"$PIDFILE"
for _ in $(seq 150); do
    answers && break
    running "$pid" || die "moto_server (pid $pid) exited at start"
    sleep 0.2
done
answers || die "moto_server (pid $pid) does not accept connections on port $PORT after 30 s"

# ---------------------------------------------------------------- 3. key, policy, bucket
# With S3_CI_KEEP=1: the seed first (the same key at every start), and after the set-up the
# recording's requests replayed, then recorded on. A request cut off by a stop (its line
# without its newline) was never answered, and goes.
if [[ $KEEP == 1 && -s $RECORDING && -n $(tail -c 1 "$RECORDING") ]]; then
    head -c "$(($(wc -c <"$RECORDING") - $(tail -n 1 "$RECORDING" | wc -c)))" "$RECORDING" >"$RECORDING.tmp"
    mv "$RECORDING.tmp" "$RECORDING"
fi
"$VENV/bin/python" - "$ENDPOINT" "$BUCKET" "$ENVFILE.tmp" "$KEEP" "$RECORDING" <<'PY' || die "setting up the key and the bucket failed"
import json, os, sys
import urllib.request
import boto3
from botocore.config import Config

endpoint, bucket, envfile, keep, recording = sys.argv[1:]
keep = keep == "1"
region = "us-east-1"
config = Config(retries={"max_attempts": 1})
def moto_api(path):
    with urllib.request.urlopen(urllib.request.Request(endpoint + "/moto-api/" + path, method="POST")) as answer:
        if answer.status != 200:
            sys.exit(f"/moto-api/{path}: HTTP {answer.status}")
if keep:
    moto_api("seed?a=44")
iam = boto3.client("iam", endpoint_url=endpoint, region_name=region,
                   aws_access_key_id="setup", aws_secret_access_key="setup", config=config)
iam.create_user(UserName="bettimill-ci")
key = iam.create_access_key(UserName="bettimill-ci")["AccessKey"]
iam.put_user_policy(UserName="bettimill-ci", PolicyName="s3", PolicyDocument=json.dumps({
    "Version": "2012-10-17",
    "Statement": [{"Effect": "Allow", "Action": "s3:*", "Resource": "*"}],
}))
s3 = boto3.client("s3", endpoint_url=endpoint, region_name=region, config=config,
                  aws_access_key_id=key["AccessKeyId"], aws_secret_access_key=key["SecretAccessKey"])
s3.create_bucket(Bucket=bucket)
# Signatures are checked: a wrong secret is refused.
wrong = boto3.client("s3", endpoint_url=endpoint, region_name=region, config=config,
                     aws_access_key_id=key["AccessKeyId"], aws_secret_access_key="wrong")
try:
    wrong.head_bucket(Bucket=bucket)
except Exception:
    pass
else:
    sys.exit("the server accepted a wrong secret key")
if keep:
    replayed = 0
    if os.path.exists(recording):
        with open(recording) as f:
            replayed = sum(1 for _ in f)
        moto_api("recorder/replay-recording")
    moto_api("recorder/start-recording")
    print(f"[s3-up] keeping the objects: replayed {replayed} recorded requests, recording on",
          file=sys.stderr)
with open(envfile, "w") as f:
    f.write(f"AWS_ENDPOINT_URL={endpoint}\n")
    f.write(f"AWS_ACCESS_KEY_ID={key['AccessKeyId']}\n")
    f.write(f"AWS_SECRET_ACCESS_KEY={key['SecretAccessKey']}\n")
    f.write(f"AWS_REGION={region}\n")
    f.write(f"BETTIMILL_S3_CI_BUCKET={bucket}\n")
PY
mv "$ENVFILE.tmp" "$ENVFILE"
log "moto_server (pid $pid) serves s3://$BUCKET at $ENDPOINT; credentials in $ENVFILE"
