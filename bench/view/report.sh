#!/usr/bin/env bash
# Regenerates reports/viewer/: the real page (`furfit view`) in headless Chromium with
# software GL (SwiftShader through ANGLE), three species under the two lights, plus a
# zoomed-out view with and without fins; and (unless SKIP_REFERENCE=1) the PRT-vs-path-
# traced errors and the packing errors (`furfit view --reference`).
#
#   bench/view/report.sh              # everything (the reference takes ~30 min on 2 cores)
#   SKIP_REFERENCE=1 bench/view/report.sh
#
# Environment: FURFIT (binary, default target/release/furfit, built if missing),
# FURFIT_CHROMIUM (default chromium), SPP (reference samples per pixel, default 128),
# REF_SIZE (default 320x240).
set -euo pipefail
cd "$(dirname "$0")/../.."
FURFIT=${FURFIT:-target/release/furfit}
CHROMIUM=${FURFIT_CHROMIUM:-chromium}
SPP=${SPP:-128}
REF_SIZE=${REF_SIZE:-320x240}
OUT=reports/viewer
SPECIES=(red-fox deer human)
FITS=(fits/red-fox.json fits/deer.json fits/human.json)
[ -x "$FURFIT" ] || cargo build --release
mkdir -p "$OUT"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$FURFIT" view --params "${FITS[@]}" --out "$work/page" | tee "$work/precompute.txt"

# shot NAME HASH [W H]: a screenshot of the page, UI shown, no console message allowed.
shot() {
  local name=$1 hash=$2 w=${3:-800} h=${4:-600}
  local prof
  prof=$(mktemp -d "$work/profile.XXXX")
  "$CHROMIUM" --headless=new --no-sandbox --use-angle=swiftshader --enable-unsafe-swiftshader \
    --hide-scrollbars --no-first-run --enable-logging=stderr --v=0 --user-data-dir="$prof" \
    --window-size="$w,$h" --screenshot="$OUT/$name.png" \
    "file://$work/page/index.html#w=$w&h=$h$hash" 2>"$work/$name.log" >/dev/null
  if grep -q ":CONSOLE" "$work/$name.log"; then
    grep ":CONSOLE" "$work/$name.log" >&2
    echo "console messages in $name" >&2
    exit 1
  fi
  echo "wrote $OUT/$name.png"
}
for i in 0 1 2; do
  for light in lobe sky; do
    shot "${SPECIES[$i]}_$light" "&species=$i&light=$light"
  done
done
# Fins: the swatch's edges seen from low down, with and without fins.
shot fins_on "&species=0&light=lobe&dist=7&cam=14,35&ui=0"
shot fins_off "&species=0&light=lobe&dist=7&cam=14,35&ui=0&fins=0"
cp "$work/precompute.txt" "$OUT/precompute.txt"

if [ "${SKIP_REFERENCE:-0}" != 1 ]; then
  "$FURFIT" view --params "${FITS[@]}" --reference --size "$REF_SIZE" --spp "$SPP" \
    --out "$OUT/reference" | tee "$work/reference.txt"
  cp "$work/reference.txt" "$OUT/reference/log.txt"
fi
