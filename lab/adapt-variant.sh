#!/usr/bin/env bash
# `grasp-train adapt` measured across worlds (issue 57): each test set of a
# finished main job split into its two draws per object-part pair; the
# shipped model's seeds adapted on one draw (its labels unread) and scored
# on the other, and the other way round, so that no video is scored by a
# model adapted on it; the shipped model scored on the same draws beside.
#
#   lab/adapt-variant.sh MAIN_OUT NAME [adapt arguments...]
#
#   lab/adapt-variant.sh runs/main copies4 --copies 4
#
# Writes MAIN_OUT/lab/adapt-NAME/ and prints (and writes to its result.md)
# the pooled hand's decision and vote per set. Resumes.
set -euo pipefail
cd "$(dirname "$0")/.."
USAGE="usage: lab/adapt-variant.sh MAIN_OUT NAME [adapt arguments...]"
OUT=${1:?$USAGE} NAME=${2:?$USAGE}
shift 2
BIN=${BIN:-target/release} SEEDS=${SEEDS:-3} PY=${PY:-.venv/bin/python}
MODEL=${MODEL:-$(cat "$OUT/report/shipped.txt")}
DIR="$OUT/lab/adapt-$NAME"
mkdir -p "$DIR"
echo "model $MODEL; $*" >"$DIR/arguments.txt"
SHIPPED=()
for ((s = 0; s < SEEDS; s++)); do SHIPPED+=(-c "$OUT/model-$MODEL/seed-$s"); done
for dir in "$OUT"/data/test-*; do
  set=${dir##*/test-}
  [ -f "$DIR/halves/$set/half-1/manifest.jsonl" ] || $PY lab/adapt_halves.py "$dir" "$DIR/halves/$set"
  for h in 0 1; do
    other=$((1 - h))
    ADAPTED="$DIR/model/$set-$h"
    [ -f "$ADAPTED/.done" ] || {
      $BIN/grasp-train adapt --overwrite "${SHIPPED[@]}" --recordings "$DIR/halves/$set/half-$h" \
        --out "$ADAPTED" "$@"
      touch "$ADAPTED/.done"
    }
    CHECKPOINTS=()
    for ((s = 0; s < SEEDS; s++)); do CHECKPOINTS+=(-c "$ADAPTED/seed-$s"); done
    score() { # report, checkpoints...
      local report=$1 && shift
      [ -f "$report/report.json" ] || $BIN/grasp-train eval "$@" \
        --data "$DIR/halves/$set/half-$other" --cache-dir "$OUT/features" --out "$report" >/dev/null
    }
    score "$DIR/reports/adapted/$set/on-$other" "${CHECKPOINTS[@]}"
    score "$DIR/reports/base/$set/on-$other" "${SHIPPED[@]}"
  done
done
$PY lab/adapt_pool.py "$DIR/reports" | tee "$DIR/result.md"
