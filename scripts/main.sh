#!/usr/bin/env bash
# The main job, on the built-in objects at a small scale (configs/main-small.toml):
# check the catalog, plan and render a training set, a validation set and the
# five test conditions, verify and preview them, train a classifier (from
# scratch: no pretrained weights are needed), evaluate it on every test
# condition, and replay one test sequence through the runtime.
#
#   scripts/main.sh [OUT]        (default OUT: runs/main)
#
# Re-running resumes: finished sequences are kept.
set -euo pipefail
cd "$(dirname "$0")/.."
[ -n "${SKIP_SETUP:-}" ] || scripts/setup.sh
OUT=${1:-runs/main}
CONFIG=${CONFIG:-configs/main-small.toml}
BIN=${BIN:-target/release}
mkdir -p "$OUT"

echo "== catalog"
$BIN/grasp-gen objects list | tail -6
$BIN/grasp-gen objects check
$BIN/grasp-gen objects show 025_mug --png "$OUT/025_mug.png"

echo "== render: train, validation, and the five test conditions"
derived_config() { # seed, sequences per pair, conditions
  sed -e "s/^seed = .*/seed = $1/" -e "s/^sequences_per_pair = .*/sequences_per_pair = $2/" \
      -e "s/^conditions = .*/conditions = [$3]/" "$CONFIG" > "$OUT/$4.toml"
}
derived_config 1 4 '"default"' train
derived_config 2 1 '"default"' val
$BIN/grasp-gen render --config "$OUT/train.toml" --out "$OUT/data/train" --resume
$BIN/grasp-gen render --config "$OUT/val.toml" --out "$OUT/data/val" --resume
for condition in default fast from_ground seated background; do
  derived_config 3 1 "\"$condition\"" "test-$condition"
  $BIN/grasp-gen render --config "$OUT/test-$condition.toml" --out "$OUT/data/test-$condition" --resume
done
$BIN/grasp-gen dataset verify "$OUT/data/train" --config "$OUT/train.toml"
$BIN/grasp-gen preview "$OUT/data/train" --out "$OUT/preview"
$BIN/grasp-gen plan --config "$OUT/train.toml" --show "$OUT/paths.png"

echo "== train (from scratch) and evaluate"
$BIN/grasp-train train --data "$OUT/data/train" --val-data "$OUT/data/val" \
  --mode from-scratch --head fc --width-mult 0.35 --input-size 96 --max-epochs 10 \
  --out "$OUT/model"
for condition in default fast from_ground seated background; do
  $BIN/grasp-train eval -c "$OUT/model/seed-0" --data "$OUT/data/test-$condition" \
    --out "$OUT/report/$condition"
done

echo "== runtime: replay one test sequence"
SEQUENCE=$(find "$OUT/data/test-default" -name sequence.json | sort | head -1 | xargs dirname)
$BIN/hannes-run replay --checkpoint "$OUT/model/seed-0" --source "$SEQUENCE"

echo "== done: reports in $OUT/report/*/report.md, preview in $OUT/preview, paths in $OUT/paths.png"
