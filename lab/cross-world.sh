#!/usr/bin/env bash
# The lab's cross-world table (issue 41, EXPERIMENTS.md "Across worlds"):
# the shipped recipes and variants of the FC recipe, each without one of
# its levers, trained on a finished main job's training set (3 seeds) and
# scored on every test set, with the choice by worst world. Besides the
# main job's test sets it renders the ones the main job leaves out for
# time: looks B-D and the foreign scene alone, with the built-in objects
# (world_foreign) and with the real meshes (world_foreign_ycb, when the
# main job imported them), and two more draws of the stacked world
# (world_foreign_ycb_reach_s5, _s7: its 62 videos hold two per part, and
# one draw moves its multi-grasp score by up to 17 points).
#
#   lab/cross-world.sh MAIN_OUT [VARIANT...]
#
# MAIN_OUT is a finished `scripts/main.sh` output (its data/, features/ and
# model-*/ are reused; a recipe it did not train, such as fc-tuned, is
# trained here). Variants: fc-no-damping, fc-no-views, fc-plain (no
# pooled blocks either), fc-no-denoise, fc-crop-fraction, fc-style-0.6
# (stronger style views), fc-views-8 (twice the views) (default: the first
# three). Writes MAIN_OUT/data/test-*, MAIN_OUT/lab/VARIANT and
# MAIN_OUT/cross-world/summary.md. CONFIG: the main job's render config.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:?usage: lab/cross-world.sh MAIN_OUT [VARIANT...]} && shift
VARIANTS=("${@:-fc-no-damping fc-no-views fc-plain}")
read -r -a VARIANTS <<<"${VARIANTS[*]}"
BIN=${BIN:-target/release} SEEDS=${SEEDS:-3}
NO_VIEWS=(--set views.count=0 --set views.style=0 --set view_damping=0)
declare -A SETS=(
  [fc-no-damping]="--set view_damping=0"
  [fc-no-views]="${NO_VIEWS[*]}"
  [fc-plain]="${NO_VIEWS[*]} --set pooled_blocks=[]"
  [fc-no-denoise]="--set reader.denoise=false"
  [fc-crop-fraction]="--set reader.crop={fraction=0.42}"
  [fc-style-0.6]="--set views.style=0.6"
  [fc-views-8]="--set views.count=8"
)
# The lab's test sets, drawn as the main job draws its own (scripts/main.sh).
TEST=(--set dataset.seed=3 --set "dataset.sequences_per_pair=${TEST_SEQ:-2}")
lab_render() { # name, then config arguments over the main job's config
  local name=$1 && shift
  $BIN/grasp-gen render --config "${CONFIG:-configs/main.toml}" "${TEST[@]}" "$@" \
    --out "$OUT/data/test-$name" --resume --no-progress
}
for look in look_b look_c look_d; do lab_render "$look" --config "configs/test-${look/_/-}.toml"; done
lab_render world_foreign --config configs/test-world-foreign.toml
if [ -d "$OUT/ycb-objects" ]; then
  GRASP_OBJECTS="$OUT/ycb-objects" lab_render world_foreign_ycb --config configs/test-world-foreign.toml
  for seed in 5 7; do
    GRASP_OBJECTS="$OUT/ycb-objects" lab_render "world_foreign_ycb_reach_s$seed" \
      --config configs/test-world-foreign.toml --config configs/test-world-reach.toml \
      --set dataset.seed=$seed
  done
fi
TEST_SETS=()
for dir in "$OUT"/data/test-*; do TEST_SETS+=("${dir##*/test-}"); done
REPORTS=()
for model in fc fc-tuned lstm "${VARIANTS[@]}"; do
  RUNS="$OUT/model-$model"
  if [ ! -d "$RUNS" ]; then
    # A recipe the main job did not train (fc-tuned), or a variant of fc.
    RUNS="$OUT/lab/$model" RECIPE=configs/recipes/$model.toml FLAGS=''
    [ -f "$RECIPE" ] || RECIPE=configs/recipes/fc.toml FLAGS=${SETS[$model]:?unknown variant $model}
    # shellcheck disable=SC2086 # the variant's flags are words
    [ -f "$RUNS/.done" ] || { $BIN/grasp-train train --overwrite --recipe "$RECIPE" $FLAGS \
      --data "$OUT/data/train" --val-data "$OUT/data/val" \
      --seeds "$SEEDS" --cache-dir "$OUT/features" --out "$RUNS" && touch "$RUNS/.done"; }
  fi
  CHECKPOINTS=()
  for ((s = 0; s < SEEDS; s++)); do CHECKPOINTS+=(-c "$RUNS/seed-$s"); done
  for set in "${TEST_SETS[@]}"; do
    REPORT="$OUT/report/$model/$set"
    [ -f "$REPORT/report.json" ] || $BIN/grasp-train eval "${CHECKPOINTS[@]}" \
      --data "$OUT/data/test-$set" --cache-dir "$OUT/features" --out "$REPORT"
    REPORTS+=(--report "$model/$set:$REPORT")
  done
done
$BIN/grasp-train summarize --by-condition --ship-by-worst --title "Across worlds" \
  --out "$OUT/cross-world" "${REPORTS[@]}"
