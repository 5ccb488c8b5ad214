#!/usr/bin/env bash
# Frame time of the viewer page (`furfit view`, 32 shells, 128^2 texels) in headless
# Chromium with software GL (SwiftShader through ANGLE: no GPU), at 640x480 and 1280x720.
# The page measures itself (`#bench=N`: N frames after the first, each waited for with a
# one-pixel readPixels; window.furfitBench), Chromium's --dump-dom hands the figure back.
# Appends one row per size to reports/viewer/frame_time.csv with the machine's load.
#
#   bench/view/frame_time.sh            # FRAMES=10 per size
#   FRAMES=30 SIZES="640x480" bench/view/frame_time.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
FURFIT=${FURFIT:-target/release/furfit}
CHROMIUM=${FURFIT_CHROMIUM:-chromium}
FRAMES=${FRAMES:-10}
SIZES=${SIZES:-"640x480 1280x720"}
CSV=${CSV:-reports/viewer/frame_time.csv}
[ -x "$FURFIT" ] || cargo build --release
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$FURFIT" view --params fits/red-fox.json --shells 32 --out "$work/page" >/dev/null
mkdir -p "$(dirname "$CSV")"
[ -s "$CSV" ] || echo "date,width,height,shells,res,frames,first_ms,mean_ms,median_ms,min_ms,max_ms,cpu_lighting_ms,nproc,load1_before,load1_after,chromium,renderer" >"$CSV"
for size in $SIZES; do
  w=${size%x*}
  h=${size#*x}
  load0=$(cut -d' ' -f1 /proc/loadavg)
  "$CHROMIUM" --headless=new --no-sandbox --use-angle=swiftshader --enable-unsafe-swiftshader \
    --hide-scrollbars --no-first-run --user-data-dir="$work/profile-$size" \
    --window-size="$w,$h" --dump-dom "file://$work/page/index.html#w=$w&h=$h&bench=$FRAMES" \
    2>/dev/null >"$work/dom-$size.html"
  load1=$(cut -d' ' -f1 /proc/loadavg)
  json=$(grep -o 'bench {"[^<]*}' "$work/dom-$size.html" | head -1 | sed 's/^bench //' || true)
  if [ -z "$json" ]; then
    echo "no bench result at $size (page status: $(grep -o 'id="status">[^<]*' "$work/dom-$size.html"))" >&2
    exit 1
  fi
  python3 - "$json" "$load0" "$load1" "$("$CHROMIUM" --version 2>/dev/null | head -1)" "$(nproc)" >>"$CSV" <<'PY'
import json, sys, datetime
b = json.loads(sys.argv[1])
row = [datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
       b["width"], b["height"], b["shells"], b["res"], b["frames"]]
row += ["%.1f" % b[k] for k in ("first_ms", "mean_ms", "median_ms", "min_ms", "max_ms")]
row += ["%.3f" % b["cpu_ms"], sys.argv[5], sys.argv[2], sys.argv[3], sys.argv[4].replace(",", " "),
        b["renderer"].replace(",", " ")]
print(",".join(str(v) for v in row))
PY
  tail -1 "$CSV"
done
