#!/usr/bin/env bash
# A head recipe measured across worlds (issue 57's levers that need no new
# render): trained on a finished main job's training and validation sets
# and cached features (3 seeds), scored on every one of its test sets, and
# summarized next to the main job's FC recipe.
#
#   lab/head-variant.sh MAIN_OUT NAME RECIPE [train arguments...]
#
#   lab/head-variant.sh runs/main trace configs/recipes/trace.toml --set trace_s=1.0
#
# Writes MAIN_OUT/lab/head-NAME/model, the reports to
# MAIN_OUT/report/head-NAME/SET and MAIN_OUT/lab/head-NAME/summary.md. Resumes.
set -euo pipefail
cd "$(dirname "$0")/.."
USAGE="usage: lab/head-variant.sh MAIN_OUT NAME RECIPE [train arguments...]"
OUT=${1:?$USAGE} NAME=${2:?$USAGE} RECIPE=${3:?$USAGE}
shift 3
BIN=${BIN:-target/release} SEEDS=${SEEDS:-3}
DIR="$OUT/lab/head-$NAME"
mkdir -p "$DIR"
echo "$RECIPE $*" >"$DIR/arguments.txt"
[ -f "$DIR/model/.done" ] || {
  $BIN/grasp-train train --overwrite --recipe "$RECIPE" "$@" --data "$OUT/data/train" \
    --val-data "$OUT/data/val" --seeds "$SEEDS" --cache-dir "$OUT/features" --out "$DIR/model"
  touch "$DIR/model/.done"
}
CHECKPOINTS=()
for ((s = 0; s < SEEDS; s++)); do CHECKPOINTS+=(-c "$DIR/model/seed-$s"); done
REPORTS=()
for dir in "$OUT"/data/test-*; do
  set=${dir##*/test-}
  REPORT="$OUT/report/head-$NAME/$set"
  [ -f "$REPORT/report.json" ] || $BIN/grasp-train eval "${CHECKPOINTS[@]}" \
    --data "$dir" --cache-dir "$OUT/features" --out "$REPORT"
  REPORTS+=(--report "head-$NAME/$set:$REPORT")
  [ -f "$OUT/report/fc/$set/report.json" ] && REPORTS+=(--report "fc/$set:$OUT/report/fc/$set")
done
$BIN/grasp-train summarize --by-condition --ship-by-worst --title "Head variant $NAME" \
  --out "$DIR/summary" "${REPORTS[@]}"
