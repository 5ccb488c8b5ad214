#!/usr/bin/env bash
# Screenshots of the viewer page (furfit view) in headless Chromium with software GL
# (SwiftShader through ANGLE): three species under the two lights, into reports/viewer/.
#
#   bench/view/screenshots.sh [OUT_DIR]      (default reports/viewer; run from the repo root)
#
# Env: FURFIT (binary, default target/release/furfit), CHROMIUM (default chromium),
#      SIZE (default 640x480).
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT=${1:-reports/viewer}
FURFIT=${FURFIT:-target/release/furfit}
CHROMIUM=${CHROMIUM:-chromium}
SIZE=${SIZE:-640x480}
W=${SIZE%x*}; H=${SIZE#*x}
SPECIES=(red-fox human cat)
LIGHTS=(lobe sky)

[ -x "$FURFIT" ] || { echo "no $FURFIT: cargo build --release" >&2; exit 1; }
command -v "$CHROMIUM" >/dev/null || { echo "no $CHROMIUM: apt-get install -y chromium" >&2; exit 1; }
TMP=$(mktemp -d); trap 'rm -rf "$TMP"' EXIT
PAGE=$TMP/page
FITS=(); for s in "${SPECIES[@]}"; do FITS+=("fits/$s.json"); done
"$FURFIT" view --params "${FITS[@]}" --out "$PAGE" >/dev/null
mkdir -p "$OUT"
for i in "${!SPECIES[@]}"; do
  for l in "${LIGHTS[@]}"; do
    png=$OUT/${SPECIES[$i]}_$l.png
    log=$TMP/chromium.log
    "$CHROMIUM" --headless=new --no-sandbox --use-angle=swiftshader --enable-unsafe-swiftshader \
      --hide-scrollbars --no-first-run --enable-logging=stderr --v=0 \
      --user-data-dir="$TMP/profile" --window-size="$W,$H" --screenshot="$png" \
      "file://$PAGE/index.html#w=$W&h=$H&species=$i&light=$l" 2>"$log" >/dev/null
    if grep -q ':CONSOLE' "$log"; then
      echo "console messages for $png:" >&2; grep ':CONSOLE' "$log" >&2; exit 1
    fi
    [ -s "$png" ] || { echo "no screenshot $png" >&2; cat "$log" >&2; exit 1; }
    echo "wrote $png"
  done
done
