#!/usr/bin/env bash
# Regenerates every preview picture the README shows (docs/figures/previews/*.png,
# docs/figures/families-{3d,4d}.png and the viewer's screenshot docs/figures/viewer.png)
# with the commands written next to them in README.md. The screenshot needs Chromium
# (ci/browser.sh installs it). Usage, from the repository root:
#   docs/figures/previews.sh [path/to/bettimill]    (default: bettimill on PATH)
# The datasets are built in a temporary directory and removed afterwards.
set -euo pipefail
bin=${1:-bettimill}
root=$(cd "$(dirname "$0")/../.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
out="$root/docs/figures"
for d in 2d 3d 4d; do
  "$bin" build "$root/manifests/demo-$d.toml" --out "$work/demo-$d" --quiet
done
"$bin" preview "$work/demo-2d" --key s000000 --out "$out/previews/demo-2d-s000000.png" --quiet
"$bin" preview "$work/demo-3d" --key s000006 --out "$out/previews/demo-3d-s000006.png" --quiet
"$bin" preview "$work/demo-4d" --key s000004 --out "$out/previews/demo-4d-s000004.png" --quiet
for d in 2d 3d 4d; do
  "$bin" preview "$work/demo-$d" --n 12 --out "$out/previews/demo-$d-sheet.png" --quiet
done
# The same samples before deformation (each one's construction, remade from the manifest):
# the "before" of the sheets above.
for d in 2d 3d 4d; do
  "$bin" preview "$work/demo-$d" --n 12 --undeformed \
    --out "$out/previews/demo-$d-undeformed-sheet.png" --quiet
done
"$bin" stats "$work/demo-3d" --plot "$out/previews/demo-3d-stats.png" --quiet > /dev/null
"$bin" build "$out/families-3d.toml" --out "$work/f3" --quiet
"$bin" preview "$work/f3" --n 31 --out "$out/families-3d.png" --quiet
"$bin" build "$out/families-4d.toml" --out "$work/f4" --quiet
"$bin" preview "$work/f4" --n 21 --out "$out/families-4d.png" --quiet
"$bin" build "$out/viewer-4d.toml" --out "$work/v4" --quiet
"$bin" preview "$work/v4" --key s000003 --html "$work/viewer.html" --quiet
chromium --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
  --disable-background-networking --disable-component-update --disable-sync \
  --user-data-dir="$work/profile" --hide-scrollbars --force-device-scale-factor=1 \
  --window-size=1300,720 --screenshot="$out/viewer.png" \
  "file://$work/viewer.html#copy=full&k=13&l=9" 2> /dev/null
