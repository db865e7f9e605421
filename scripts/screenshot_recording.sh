#!/usr/bin/env bash
# A PNG of the rerun viewer showing a recording (for the docs), on a virtual screen.
# Needs Debian's xvfb, x11-apps, xdotool and imagemagick (not in setup.sh: only docs need them).
# Usage: scripts/screenshot_recording.sh FILE.rrd OUT.png [SECONDS]
set -euo pipefail
rrd=$1; out=$2; wait=${3:-25}
here=$(cd "$(dirname "$0")/.." && pwd)
rerun_bin=${RERUN:-$here/.venv/bin/rerun}
display=:97
Xvfb $display -screen 0 1600x1000x24 >/dev/null 2>&1 &
xvfb=$!
trap 'kill $xvfb 2>/dev/null || true' EXIT
sleep 2
DISPLAY=$display WGPU_BACKEND=vulkan timeout $((wait + 20)) "$rerun_bin" "$rrd" >/dev/null 2>&1 &
viewer=$!
sleep "$wait"
DISPLAY=$display xdotool mousemove 1599 999  # the pointer off the views: no hover tooltips
sleep 1
DISPLAY=$display xwd -root -silent | convert xwd:- "$out"
kill $viewer 2>/dev/null || true
echo "wrote $out"
