#!/usr/bin/env bash
# The main job: set the machine up, then check the catalog, plan and render a
# training set, a validation set and the six test conditions (the paper's
# five and unseen_look, an appearance training never draws), verify and
# preview them, train a classifier, evaluate it on every test condition, and
# replay one test sequence through the runtime against the simulated hand.
#
#   scripts/main.sh [--paper-scale] [--ycb DIR] [--weights FILE] [OUT]
#
#   (default)       built-in objects, configs/main-small.toml: all 31 pairs,
#                   4 training sequences per pair, Workbench 96 x 96 at 10
#                   frames/s; MobileNetV2 (width 0.35, 64 px) trained from
#                   scratch for 8 epochs. About 15 minutes on 2 cores.
#   --paper-scale   the paper's size: configs/default.toml (47 sequences per
#                   pair, Cycles 224 x 224 at 30 frames/s); 2 test sequences
#                   per pair and condition; from scratch at width 1.0, 224 px
#                   (days on a CPU: use --weights, or a GPU machine).
#   --ycb DIR       the authors' real YCB meshes and annotations (DIR holds
#                   annotations.json and meshes/) instead of the built-in
#                   objects.
#   --weights FILE  torchvision's mobilenet_v2-b0353104.pth (or .safetensors):
#                   the paper's frozen-backbone protocol, only the head trains.
#   OUT             output folder (default runs/main).
#
# Re-running resumes: finished sequences are kept. Environment: SKIP_SETUP=1
# skips scripts/setup.sh, BIN (target/release), CONFIG overrides the config.
set -euo pipefail
cd "$(dirname "$0")/.."

PAPER=0 YCB='' WEIGHTS='' OUT=runs/main
while [ $# -gt 0 ]; do
  case $1 in
    --paper-scale) PAPER=1 ;;
    --ycb) YCB=${2:?--ycb needs a folder}; shift ;;
    --weights) WEIGHTS=${2:?--weights needs a file}; shift ;;
    -h | --help) sed -n '2,25p' "$0"; exit 0 ;;
    -*) echo "unknown option $1 (see --help)" >&2; exit 2 ;;
    *) OUT=$1 ;;
  esac
  shift
done

if [ "$PAPER" = 1 ]; then
  CONFIG=${CONFIG:-configs/default.toml} TRAIN_SEQ=47 TEST_SEQ=2
  TRAIN_FLAGS=(--width-mult 1.0 --input-size 224 --lr 3e-3)
else
  CONFIG=${CONFIG:-configs/main-small.toml} TRAIN_SEQ=4 TEST_SEQ=1
  TRAIN_FLAGS=(--width-mult 0.35 --input-size 64 --max-epochs 8 --lr 3e-3)
fi
if [ -n "$WEIGHTS" ]; then
  TRAIN_FLAGS=(--mode frozen-pretrained --weights "$WEIGHTS")
else
  TRAIN_FLAGS=(--mode from-scratch "${TRAIN_FLAGS[@]}")
fi
[ -n "${SKIP_SETUP:-}" ] || scripts/setup.sh
BIN=${BIN:-target/release}
mkdir -p "$OUT"
START=$(date +%s)
elapsed() { echo "   [$(($(date +%s) - START)) s]"; }

echo "== catalog"
if [ -n "$YCB" ]; then
  [ -d "$OUT/objects" ] || $BIN/grasp-gen objects import-ycb --ycb "$YCB" --out "$OUT/objects"
  export GRASP_OBJECTS="$OUT/objects" # every grasp-gen command's catalog
fi
$BIN/grasp-gen objects list | tail -6
$BIN/grasp-gen objects check
$BIN/grasp-gen objects show 025_mug --png "$OUT/025_mug.png"

echo "== render: train, validation, and the six test conditions"
derived_config() { # seed, sequences per pair, conditions, name
  sed -e "s/^seed = .*/seed = $1/" -e "s/^sequences_per_pair = .*/sequences_per_pair = $2/" \
    -e "s/^conditions = .*/conditions = [$3]/" "$CONFIG" >"$OUT/$4.toml"
}
render() { # name
  $BIN/grasp-gen render --config "$OUT/$1.toml" --out "$OUT/data/$1" --resume
}
derived_config 1 "$TRAIN_SEQ" '"default"' train
derived_config 2 1 '"default"' val
render train
render val
for condition in default fast from_ground seated background unseen_look; do
  derived_config 3 "$TEST_SEQ" "\"$condition\"" "test-$condition"
  render "test-$condition"
done
$BIN/grasp-gen dataset verify "$OUT/data/train" --config "$OUT/train.toml"
$BIN/grasp-gen preview "$OUT/data/train" --out "$OUT/preview"
$BIN/grasp-gen plan --config "$OUT/train.toml" --show "$OUT/paths.png"
elapsed

echo "== train and evaluate"
[ -f "$OUT/model/seed-0/.done" ] || {
  $BIN/grasp-train train --data "$OUT/data/train" --val-data "$OUT/data/val" --head fc \
    "${TRAIN_FLAGS[@]}" --out "$OUT/model"
  touch "$OUT/model/seed-0/.done"
}
for condition in default fast from_ground seated background unseen_look; do
  $BIN/grasp-train eval -c "$OUT/model/seed-0" --data "$OUT/data/test-$condition" \
    --out "$OUT/report/$condition"
done
REPORTS=()
for condition in default fast from_ground seated background unseen_look; do
  REPORTS+=(--report "model/$condition:$OUT/report/$condition")
done
$BIN/grasp-train summarize --by-condition --title "Per-video accuracy by test condition" \
  --out "$OUT/report" "${REPORTS[@]}"
elapsed

echo "== runtime: replay one test sequence against the simulated hand"
SEQUENCE=$(find "$OUT/data/test-default" -name sequence.json | sort | head -1 | xargs dirname)
PTY="$OUT/hand.pty"
$BIN/hannes-run simulate-hand --pty "$PTY" >"$OUT/hand-events.jsonl" 2>"$OUT/hand.log" &
HAND=$!
trap 'kill $HAND 2>/dev/null || true' EXIT
for _ in $(seq 50); do [ -e "$PTY" ] && break; sleep 0.1; done
$BIN/hannes-run run --checkpoint "$OUT/model/seed-0" --source "$SEQUENCE" --port "$PTY" \
  --trigger now --closure delay:0.5 --report "$OUT/replay.jsonl"
sleep 0.5
kill $HAND 2>/dev/null || true
wait $HAND 2>/dev/null || true
echo "the simulated hand's events ($OUT/hand-events.jsonl):"
cat "$OUT/hand-events.jsonl"
elapsed

echo "== done: $OUT/report/summary.md (per condition: $OUT/report/*/report.md),"
echo "   preview $OUT/preview, paths $OUT/paths.png, replay $OUT/replay.jsonl"
