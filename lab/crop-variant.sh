#!/usr/bin/env bash
# A wider crop measured across worlds (issue 41, the "crop angle"
# candidate): every set of the main job rendered again with a larger centre
# region, the FC recipe trained on a wider fixed-angle crop (3 seeds), and
# scored next to the main job's FC recipe on the same plans (same seeds).
#
#   lab/crop-variant.sh MAIN_OUT ANGLE_DEG REGION
#
#   lab/crop-variant.sh runs/main 25 0.7
#
# REGION is render.center_region: the crop needs tan(ANGLE/2) / tan(hfov/2)
# of the frame, up to 0.49 x tan(ANGLE/2) / tan(9.15 deg) under training's
# narrowest lens (0.67 for 25 degrees). Writes MAIN_OUT/lab/crop-ANGLE/ and
# its summary.md. Resumes.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:?usage: lab/crop-variant.sh MAIN_OUT ANGLE_DEG REGION}
ANGLE=${2:?angle in degrees} REGION=${3:?render.center_region}
BIN=${BIN:-target/release} SEEDS=${SEEDS:-3} TRAIN_SEQ=${TRAIN_SEQ:-24}
DIR="$OUT/lab/crop-$ANGLE"
mkdir -p "$DIR"
render() { # name, then arguments; the region is set after every config layer
  local name=$1 && shift
  $BIN/grasp-gen render --config configs/main.toml "$@" --set "render.center_region=$REGION" \
    --out "$DIR/data/$name" --resume
}
TEST=(--set dataset.seed=3 --set dataset.sequences_per_pair=2)
render train --set dataset.seed=1 --set dataset.sequences_per_pair="$TRAIN_SEQ"
render val --set dataset.seed=2 --set dataset.sequences_per_pair=1
SETS=(default fast from_ground seated background unseen_look)
for condition in "${SETS[@]}"; do
  render "test-$condition" "${TEST[@]}" --set "dataset.conditions=[\"$condition\"]"
done
render test-world_reach --config configs/test-world-reach.toml "${TEST[@]}"
SETS+=(world_reach)
if [ -d "$OUT/ycb-objects" ]; then
  GRASP_OBJECTS="$OUT/ycb-objects" render test-world_foreign_ycb_reach \
    --config configs/test-world-foreign.toml --config configs/test-world-reach.toml "${TEST[@]}"
  SETS+=(world_foreign_ycb_reach)
fi
[ -f "$DIR/model/.done" ] || {
  $BIN/grasp-train train --overwrite --recipe configs/recipes/fc.toml --set "reader.crop={ angle_deg = $ANGLE }" \
    --data "$DIR/data/train" --val-data "$DIR/data/val" --seeds "$SEEDS" \
    --cache-dir "$DIR/features" --out "$DIR/model" && touch "$DIR/model/.done"
}
CHECKPOINTS=()
for ((s = 0; s < SEEDS; s++)); do CHECKPOINTS+=(-c "$DIR/model/seed-$s"); done
REPORTS=()
for set in "${SETS[@]}"; do
  REPORT="$DIR/report/$set"
  [ -f "$REPORT/report.json" ] || $BIN/grasp-train eval "${CHECKPOINTS[@]}" \
    --data "$DIR/data/test-$set" --cache-dir "$DIR/features" --out "$REPORT"
  REPORTS+=(--report "crop-$ANGLE/$set:$REPORT")
  [ -f "$OUT/report/fc/$set/report.json" ] && REPORTS+=(--report "fc/$set:$OUT/report/fc/$set")
done
$BIN/grasp-train summarize --by-condition --ship-by-worst --title "Crop of $ANGLE degrees" \
  --out "$DIR/summary" "${REPORTS[@]}"
