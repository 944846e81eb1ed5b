#!/usr/bin/env bash
# Vote rules and ensembles of a finished main job's heads on every test set
# (issue 41): dumps each frame's probabilities with the trainer's
# dump_predictions example (cached features: seconds), then tabulates
# lab/vote_rules.py.
#
#   lab/vote-rules.sh MAIN_OUT
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:?usage: lab/vote-rules.sh MAIN_OUT}
DUMPS="$OUT/lab/predictions"
cargo build --release -q -p trainer --example dump_predictions
mkdir -p "$DUMPS"
for model in fc lstm; do
  for seed in "$OUT/model-$model"/seed-*; do
    for data in "$OUT"/data/test-*; do
      file="$DUMPS/$model-${seed##*seed-}-${data##*/test-}.jsonl"
      [ -s "$file" ] && continue
      target/release/examples/dump_predictions "$seed" "$data" "$OUT/features" "$file.tmp"
      mv "$file.tmp" "$file"
    done
  done
done
.venv/bin/python lab/vote_rules.py "$DUMPS" | tee "$OUT/lab/vote-rules.md"
