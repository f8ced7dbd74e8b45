#!/usr/bin/env bash
# Installs the headless browser that the HTML viewer's test drives (tests/viewer.rs):
# Chromium and chromedriver from Debian's packages. Idempotent: a no-op when chromium is
# on PATH. Needs root (apt-get) or sudo. Prints the version it leaves.
set -euo pipefail

if ! command -v chromium >/dev/null 2>&1; then
    sudo=
    if [ "$(id -u)" -ne 0 ]; then
        sudo=sudo
    fi
    export DEBIAN_FRONTEND=noninteractive
    $sudo apt-get update -qq
    $sudo apt-get install -y -qq --no-install-recommends chromium chromium-driver fonts-dejavu-core
fi
chromium --version
