# Sourced by the benchmark scripts in ci/ (bench-workers.sh, bench-4d-mixed-128.sh,
# calibrate-plan.sh): what each needs before it measures anything.
#
# bench_setup PROFILE NAME: sets B to $BETTIMILL, or else builds the CLI with cargo in
# PROFILE (release or dev) and uses that binary; sets work to a fresh scratch directory
# /tmp/bettimill-NAME.XXXXXX, removed when the script exits.
bench_setup() {
    local profile=$1 name=$2
    if [[ -z ${BETTIMILL:-} ]]; then
        local target=${CARGO_TARGET_DIR:-$PWD/target}
        if [[ $profile == release ]]; then
            cargo build --release -p bettimill-cli
            BETTIMILL=$target/release/bettimill
        else
            cargo build -p bettimill-cli
            BETTIMILL=$target/debug/bettimill
        fi
    fi
    B=$BETTIMILL
    work=$(mktemp -d "/tmp/bettimill-$name.XXXXXX")
    trap 'rm -rf -- "$work"' EXIT
}
