#!/usr/bin/env bash
# The experiments of EXPERIMENTS.md, on generated data, at a CPU scale.
#
#   scripts/experiments.sh [STAGE...]      (default: every stage, in order)
#
# Stages: backbone data heads size egocentric quality ycb summary.
#
# No ImageNet weights can be downloaded here, so the paper's frozen backbone
# is replaced by one MobileNetV2 trained from scratch once, on the main job's
# data (stage `backbone`: configs/main-small.toml, 4 sequences per pair at 10
# frames/s); the heads of the paper's experiments are then trained on its
# frozen features, three seeds each, as in the paper, on separate data
# (configs/experiments.toml: other seeds, 5 frames/s). The egocentric
# comparison trains both cameras from scratch (the backbone saw only wrist
# views).
#
# Everything goes under $OUT (default runs/experiments) and every command is
# appended to $OUT/commands.log. Re-running resumes: finished renders are kept
# (--resume), finished trainings and evaluations are skipped.
# Knobs (environment): OUT, BIN, SEEDS (3), WIDTH (0.35), INPUT (64),
# BACKBONE_EPOCHS (20), SCRATCH_EPOCHS (10), SCRATCH_LR (3e-3), TRAIN_SEQ
# (16 sequences per pair), TEST_SEQ (2), EGO_SEQ (4), QUALITY_SEQ (2).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-runs/experiments}
BIN=${BIN:-target/release}
SEEDS=${SEEDS:-3}
WIDTH=${WIDTH:-0.35}
INPUT=${INPUT:-64}
BACKBONE_EPOCHS=${BACKBONE_EPOCHS:-20}
SCRATCH_EPOCHS=${SCRATCH_EPOCHS:-10}
# From scratch, the paper's 5e-4 (tuned for a head on frozen features) learns
# several times slower: 8 epochs reach 53 % train accuracy where 3e-3 reaches
# 67 % in 6 (EXPERIMENTS.md).
SCRATCH_LR=${SCRATCH_LR:-3e-3}
TRAIN_SEQ=${TRAIN_SEQ:-16}
TEST_SEQ=${TEST_SEQ:-2}
EGO_SEQ=${EGO_SEQ:-4}
QUALITY_SEQ=${QUALITY_SEQ:-2}
BASE=configs/experiments.toml
CONDITIONS=(default fast from_ground seated background)
mkdir -p "$OUT"
LOG="$OUT/commands.log"

# Logs and runs one command; EXPERIMENTS.md quotes these lines.
run() {
  echo "+ $*" | tee -a "$LOG" >&2
  "$@"
}

# A render config: BASE with the seed, sequences per pair and conditions
# replaced (and, when set, RENDER_RES pixels square, RENDER_SAMPLES Cycles
# samples instead of Workbench), plus any extra TOML appended.
derived_config() { # out seed per_pair conditions [extra toml]
  local out=$1 seed=$2 per_pair=$3 conditions=$4 extra=${5:-}
  local edits=(-e "s/^seed = .*/seed = $seed/" -e "s/^sequences_per_pair = .*/sequences_per_pair = $per_pair/"
    -e "s/^conditions = .*/conditions = [$conditions]/")
  [ -z "${RENDER_RES:-}" ] || edits+=(-e "s/^resolution = .*/resolution = [$RENDER_RES, $RENDER_RES]/")
  [ -z "${RENDER_SAMPLES:-}" ] ||
    edits+=(-e "s/^engine = .*/engine = \"cycles\"\nsamples = $RENDER_SAMPLES/")
  sed "${edits[@]}" "${RENDER_BASE:-$BASE}" >"$out"
  [ -z "$extra" ] || printf '%s\n' "$extra" >>"$out"
}

render() { # dir name seed per_pair condition [extra toml]
  local dir=$1 name=$2 seed=$3 per_pair=$4 condition=$5 extra=${6:-}
  shift 6 || shift $#
  mkdir -p "$dir"
  derived_config "$dir/$name.toml" "$seed" "$per_pair" "\"$condition\"" "$extra"
  run "$BIN/grasp-gen" render --config "$dir/$name.toml" --out "$dir/$name" --resume --no-progress "$@"
}

# Train (seed 1), val (seed 2) and test sets (seed 3) into DIR.
render_sets() { # dir train_per_pair val_per_pair test_per_pair extra "conditions"
  local dir=$1 per_pair=$2 val_per_pair=$3 test_per_pair=$4 extra=$5 conds=$6 c
  shift 6
  render "$dir" train 1 "$per_pair" default "$extra" "$@"
  render "$dir" val 2 "$val_per_pair" default "$extra" "$@"
  for c in $conds; do render "$dir" "test-$c" 3 "$test_per_pair" "$c" "$extra" "$@"; done
}

# Trains into RUNS/seed-SEED unless it finished before.
train() { # data runs seed flags...
  local data=$1 runs=$2 seed=$3
  shift 3
  [ -f "$runs/seed-$seed/.done" ] && return 0
  run "$BIN/grasp-train" train --data "$data/train" --val-data "$data/val" \
    --seed "$seed" --out "$runs" --cache-dir "$OUT/cache" "$@"
  touch "$runs/seed-$seed/.done"
}

scratch() { # data runs seed epochs flags...
  local data=$1 runs=$2 seed=$3 epochs=$4
  shift 4
  train "$data" "$runs" "$seed" --mode from-scratch --head fc \
    --width-mult "$WIDTH" --input-size "$INPUT" --max-epochs "$epochs" --lr "$SCRATCH_LR" "$@"
}

# Heads on the frozen backbone, seeds 0..SEEDS-1.
frozen_heads() { # data runs head flags...
  local data=$1 runs=$2 head=$3
  shift 3
  local s
  for s in $(seq 0 $((SEEDS - 1))); do
    train "$data" "$runs" "$s" --mode frozen-pretrained --weights "$OUT/backbone/seed-0" \
      --head "$head" "$@"
  done
}

# Evaluates all seeds of RUNS on each test condition into RUNS/report/C.
evaluate() { # data runs "conditions" [flags...]
  local data=$1 runs=$2 conds=$3
  shift 3
  local ckpts=() ckpt c
  for ckpt in "$runs"/seed-*; do ckpts+=(-c "$ckpt"); done
  for c in $conds; do
    [ -f "$runs/report/$c/report.json" ] ||
      run "$BIN/grasp-train" eval "${ckpts[@]}" --data "$data/test-$c" \
        --out "$runs/report/$c" --cache-dir "$OUT/cache" "$@"
  done
}

# The frozen backbone: the whole network trained from scratch once, on the
# main job's data. Its own test results are Table 3's "end to end" row.
stage_backbone() {
  RENDER_BASE=configs/main-small.toml render_sets "$OUT/backbone-data" 4 1 1 "" "${CONDITIONS[*]}"
  scratch "$OUT/backbone-data" "$OUT/backbone" 0 "$BACKBONE_EPOCHS"
  evaluate "$OUT/backbone-data" "$OUT/backbone" "${CONDITIONS[*]}"
}

stage_data() {
  render_sets "$OUT/data" "$TRAIN_SEQ" 2 "$TEST_SEQ" "" "${CONDITIONS[*]}"
}

# Table 3 and Table 2's rows: FC and LSTM heads on the frozen backbone.
stage_heads() {
  for head in fc lstm; do
    frozen_heads "$OUT/data" "$OUT/heads-$head" "$head"
    evaluate "$OUT/data" "$OUT/heads-$head" "${CONDITIONS[*]}"
  done
}

# Error against the number of training sequences per object-part pair.
stage_size() {
  for n in 1 2 4 8; do
    frozen_heads "$OUT/data" "$OUT/size-$n" fc --sequences-per-pair "$n"
    evaluate "$OUT/data" "$OUT/size-$n" "default background"
  done
}

# Table 2's cameras: the same plans seen by the wrist and the head camera,
# each trained from scratch.
stage_egocentric() {
  render_sets "$OUT/ego-data" "$EGO_SEQ" 1 "$TEST_SEQ" \
    "$(printf '[plan.head_camera]\nenabled = true')" "default background"
  for camera in Wrist_d435 Head_d435; do
    scratch "$OUT/ego-data" "$OUT/ego-$camera" 0 "$SCRATCH_EPOCHS" --camera "$camera"
    evaluate "$OUT/ego-data" "$OUT/ego-$camera" "default background"
  done
}

# Error against render cost: the same plans rendered by Workbench and by
# Cycles at 1, 4 and 16 samples (denoised), heads trained on each; one test
# set rendered by Cycles at 16 samples. 64 x 64 pixels, the network's input.
stage_quality() {
  local q="$OUT/quality"
  export RENDER_RES=64
  RENDER_SAMPLES=16 render "$q" test-default 3 "$TEST_SEQ" default
  for level in workbench cycles-1 cycles-4 cycles-16; do
    local d="$q/$level" samples=''
    [ "$level" = workbench ] || samples=${level#cycles-}
    RENDER_SAMPLES=$samples render "$d" train 1 "$QUALITY_SEQ" default
    RENDER_SAMPLES=$samples render "$d" val 2 1 default
    ln -sfn ../test-default "$d/test-default"
    frozen_heads "$d" "$d/heads-fc" fc
    evaluate "$d" "$d/heads-fc" default
    run "$BIN/grasp-gen" dataset stats "$d/train" --json >"$d/train-stats.json"
  done
  unset RENDER_RES
}

# The real YCB meshes (when ../shared/ycb is present): the same protocol.
stage_ycb() {
  local ycb=../shared/ycb
  if [ ! -d "$ycb" ]; then
    echo "skipping the YCB stage: $ycb is absent"
    return 0
  fi
  [ -d "$OUT/ycb-objects" ] || run "$BIN/grasp-gen" objects import-ycb --ycb "$ycb" --out "$OUT/ycb-objects"
  GRASP_OBJECTS="$OUT/ycb-objects" render_sets "$OUT/ycb-data" "$TRAIN_SEQ" 2 "$TEST_SEQ" "" \
    "${CONDITIONS[*]}"
  frozen_heads "$OUT/ycb-data" "$OUT/ycb-heads-fc" fc
  evaluate "$OUT/ycb-data" "$OUT/ycb-heads-fc" "${CONDITIONS[*]}"
}

stage_summary() {
  local s="$OUT/summary" reports=()
  for model in backbone heads-fc heads-lstm ycb-heads-fc; do
    for c in "${CONDITIONS[@]}"; do
      [ -f "$OUT/$model/report/$c/report.json" ] && reports+=(--report "$model/$c:$OUT/$model/report/$c")
    done
  done
  run "$BIN/grasp-train" summarize --by-condition --title "Per-video accuracy by test condition" \
    --out "$s/table3" "${reports[@]}"
  reports=()
  for camera in Wrist_d435 Head_d435; do
    for c in default background; do
      [ -f "$OUT/ego-$camera/report/$c/report.json" ] &&
        reports+=(--report "$camera/$c:$OUT/ego-$camera/report/$c")
    done
  done
  [ ${#reports[@]} -eq 0 ] ||
    run "$BIN/grasp-train" summarize --by-condition --title "Eye-in-hand against egocentric" \
      --out "$s/egocentric" "${reports[@]}"
  reports=()
  for c in default background; do
    for n in 1 2 4 8; do reports+=(--report "$c/$n=$n:$OUT/size-$n/report/$c"); done
    reports+=(--report "$c/$TRAIN_SEQ=$TRAIN_SEQ:$OUT/heads-fc/report/$c")
  done
  run "$BIN/grasp-train" summarize --x-label "training sequences per pair" --log-x \
    --title "Error against training set size (FC head, frozen backbone)" --out "$s/size" "${reports[@]}"
  reports=()
  for level in workbench cycles-1 cycles-4 cycles-16; do
    local d="$OUT/quality/$level" x
    # render seconds per frame, the object swap and appearance included
    x=$(python3 -c 'import json,sys; s = json.load(open(sys.argv[1])); print(s["cameras"]["Wrist_d435"]["seconds_per_frame"] + s["setup_seconds_per_frame"])' \
      "$d/train-stats.json")
    reports+=(--report "default/$level=$x:$d/heads-fc/report/default")
  done
  run "$BIN/grasp-train" summarize --x-label "render seconds per training frame" --log-x \
    --title "Error against render cost (FC head, frozen backbone)" --out "$s/quality" "${reports[@]}"
}

stages=("$@")
[ ${#stages[@]} -gt 0 ] || stages=(backbone data heads size egocentric quality ycb summary)
for stage in "${stages[@]}"; do
  echo "== $stage"
  "stage_$stage"
done
