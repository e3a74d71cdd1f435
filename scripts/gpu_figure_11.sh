#!/bin/sh
# ASLOD Figure 11 in the paper's setting: the aerobic class (three dancers, P = 5,000) and a
# crowd (100 dancers, P = 100,000), each rendered with LOD and without, interleaved, and the
# reports written to one folder:
#
#   OUT/class/WxH/   frames.csv, frame_time.png, allocation.png, screenshots, summary.json
#   OUT/crowd/WxH/   the same for the crowd
#   OUT/*/summary.json   every size's summary
#
# Usage: scripts/gpu_figure_11.sh [OUT]           (default out/figure_11)
# Settings (environment): SIZES (default 1920x1080; several as WxH,WxH), CROWD_SIZES (default
# SIZES), REPEAT (default 5; the crowd uses CROWD_REPEAT, default 3), FRAMES (default 120).
# Runs on any Vulkan driver, lavapipe included (`make figure-11` runs it there at the sizes
# where a software rasteriser shows the geometry).
set -eu

OUT=${1:-out/figure_11}
SIZES=${SIZES:-1920x1080}
CROWD_SIZES=${CROWD_SIZES:-$SIZES}
REPEAT=${REPEAT:-5}
CROWD_REPEAT=${CROWD_REPEAT:-3}
FRAMES=${FRAMES:-120}
CARGO=${CARGO:-cargo}

cd "$(dirname "$0")/.."
"$CARGO" build --release --example aerobic_class
run() {
	"$CARGO" run --release --quiet --example aerobic_class -- --headless --frames "$FRAMES" "$@"
}
echo "== the aerobic class: 3 dancers, P = 5000, $REPEAT runs each, $SIZES"
run --repeat "$REPEAT" --sizes "$SIZES" --report "$OUT/class"
echo "== a crowd: 100 dancers, P = 100000, $CROWD_REPEAT runs each, $CROWD_SIZES"
run --repeat "$CROWD_REPEAT" --count 100 --budget 100000 --sizes "$CROWD_SIZES" --report "$OUT/crowd"
echo "reports in $OUT"
