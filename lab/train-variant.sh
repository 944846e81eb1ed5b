#!/usr/bin/env bash
# A training-data lever measured across worlds (issue 41): render the main
# job's training and validation sets again with config layers or --set
# values over the main config, train the FC recipe on them (3 seeds) and
# score it on every test set of a finished main job.
#
#   lab/train-variant.sh MAIN_OUT NAME [grasp-gen render arguments...]
#
#   lab/train-variant.sh runs/main close --set randomize.standoff.scale=[0.45,1.25]
#
# Writes MAIN_OUT/lab/train-NAME/{data,features,model} and the reports to
# MAIN_OUT/report/train-NAME/SET, then a summary of the FC recipe against
# this variant in MAIN_OUT/lab/train-NAME/summary.md. Resumes.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:?usage: lab/train-variant.sh MAIN_OUT NAME [render arguments...]}
NAME=${2:?usage: lab/train-variant.sh MAIN_OUT NAME [render arguments...]}
shift 2
BIN=${BIN:-target/release} SEEDS=${SEEDS:-3} TRAIN_SEQ=${TRAIN_SEQ:-24}
RECIPE=${RECIPE:-configs/recipes/fc.toml}
DIR="$OUT/lab/train-$NAME"
mkdir -p "$DIR"
echo "$*" >"$DIR/arguments.txt"
render() { # name, then arguments
  local name=$1 && shift
  $BIN/grasp-gen render --config configs/main.toml "$@" --out "$DIR/data/$name" --resume
}
render train --set dataset.seed=1 --set dataset.sequences_per_pair="$TRAIN_SEQ" "$@"
render val --set dataset.seed=2 --set dataset.sequences_per_pair=1 "$@"
[ -f "$DIR/model/.done" ] || {
  $BIN/grasp-train train --overwrite --recipe "$RECIPE" --data "$DIR/data/train" --val-data "$DIR/data/val" \
    --seeds "$SEEDS" --cache-dir "$DIR/features" --out "$DIR/model" && touch "$DIR/model/.done"
}
CHECKPOINTS=()
for ((s = 0; s < SEEDS; s++)); do CHECKPOINTS+=(-c "$DIR/model/seed-$s"); done
REPORTS=()
for dir in "$OUT"/data/test-*; do
  set=${dir##*/test-}
  REPORT="$OUT/report/train-$NAME/$set"
  [ -f "$REPORT/report.json" ] || $BIN/grasp-train eval "${CHECKPOINTS[@]}" \
    --data "$dir" --cache-dir "$OUT/features" --out "$REPORT"
  REPORTS+=(--report "train-$NAME/$set:$REPORT")
  [ -f "$OUT/report/fc/$set/report.json" ] && REPORTS+=(--report "fc/$set:$OUT/report/fc/$set")
done
$BIN/grasp-train summarize --by-condition --ship-by-worst --title "Training variant $NAME" \
  --out "$DIR/summary" "${REPORTS[@]}"
