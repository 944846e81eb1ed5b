#!/usr/bin/env bash
# The experiments of EXPERIMENTS.md, with the paper's protocol: FC (and LSTM)
# heads on frozen, cached EfficientNet-Lite0 ImageNet features, 3 seeds each.
#
#   lab/experiments.sh [STAGE...]      (default: every stage, in order)
#
# Stages:
#   fixed     the fixed validation and test sets of the studies: 224 x 224,
#             Cycles 1 sample + denoiser, 5 frames/s; test `default` and
#             `unseen_look`, 2 sequences per pair (62 videos each).
#   study     error against render cost: training sets of the same plans
#             (seed 1, 2 sequences per pair) at several resolutions, frame
#             rates, sample counts and with/without the denoiser; heads with
#             whole frames and with the centre crop.
#   ablation  each [randomize.*] lever off in turn (and all off), at the
#             study's cheapest setting (128 px, 2.5 frames/s).
#   parts     what makes the part readable: centre crops, vote windows,
#             LSTM against FC, on the study's 224 px / 5 frames/s set.
#   egocentric  Table 2's columns: wrist against head camera, same plans.
#   main      scripts/main.sh into $OUT/main: Table 3, Table 2's rows, Fig. 5.
#   size      error against training sequences per pair: nested subsets
#             (1, 2, 4, 8, 16 of 24) of the main job's training set, every
#             test condition.
#   large     scripts/main.sh --large into $OUT/main-large (32 training
#             sequences per pair; its own training set).
#   input     the backbone's input side: the main job's FC head retrained
#             with the crop resized to 64-224 px, every test condition.
#             (Its sensor probes, eval --probe-noise/--probe-blur, are gone
#             with those flags; EXPERIMENTS-archive.md section 9 has them.)
#   draws     four more draws of the test sets (seeds 5, 7, 9, 11), pooled
#             with the main job's into one report per head and condition
#             (310 videos); default, unseen_look and looks B, C and D
#             (look_b, look_c, look_d, more held-out looks: EXPERIMENTS-archive.md
#             sections 15, 16 and 18)
#             unless DRAW_CONDITIONS.
#   inlook    how much of a held-out look's gap is transfer: each look of
#             INLOOK_CONDITIONS (unseen_look, look_b, look_d) gets a training
#             and a validation set of its own (the main job's test config of
#             that look with the training and validation seeds and sizes),
#             and the main job's frozen FC recipe, with and without its style
#             views and damping, trains on it, as on the default look's;
#             scored on the draws stage's pooled draws (that stage first).
#             EXPERIMENTS-archive.md section 19.
#   camera    the camera's view normalised: the main job's frozen FC recipe
#             with a fixed-fraction or a fixed-angle crop, denoised or not,
#             scored on the draws stage's pooled draws (that stage first).
#             EXPERIMENTS-archive.md section 21.
#   summary   the tables and plots (summary/*/summary.md, error.png).
#
# Everything goes under $OUT (default runs/experiments), and every command is
# appended to $OUT/commands.log. Re-running resumes: finished renders,
# trainings and evaluations are kept. Knobs (environment): OUT, BIN, SEEDS
# (3), CROP (0.42), INPUT_SIZE (128: the main job's input side, used by the
# size stage; the studies' heads keep the trainer's default, 224), DRAW_SEEDS
# (the draws stage's test seeds), DRAW_CONDITIONS (its test conditions),
# INLOOK_CONDITIONS (the inlook stage's looks).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-runs/experiments}
BIN=${BIN:-target/release}
SEEDS=${SEEDS:-3}
CROP=${CROP:-0.42}
INPUT_SIZE=${INPUT_SIZE:-128}
# The heads' crop as a recipe override (grasp-train train --set).
CROP_SET=(--set "reader.crop={ fraction = $CROP }")
# The main job's FC head's style views and damping (configs/recipes/fc.toml);
# words without spaces, so that they also travel in a string.
STYLE_DAMPED=(--set views.count=4 --set views.scale=0.0 --set views.shift=0.0
  --set views.color=0.0 --set views.style=0.3 --set "views.style_blocks=[2,4,7]"
  --set view_damping=1)
DRAW_SEEDS=${DRAW_SEEDS:-5 7 9 11}
DRAW_CONDITIONS=${DRAW_CONDITIONS:-default unseen_look look_b look_c look_d}
INLOOK_CONDITIONS=${INLOOK_CONDITIONS:-unseen_look look_b look_d}
LEVERS=(fov principal_point sensor_noise motion_blur white_balance jpeg world_light object_color
  distractors standoff aim approach_ends)
# name = resolution, samples, denoiser, frames/s
declare -A SETTINGS=(
  [r224-s1dn-f5]="224 1 openimagedenoise 5.0" [r224-s1dn-f2.5]="224 1 openimagedenoise 2.5"
  [r160-s1dn-f2.5]="160 1 openimagedenoise 2.5" [r128-s1dn-f2.5]="128 1 openimagedenoise 2.5"
  [r128-s1dn-f5]="128 1 openimagedenoise 5.0" [r128-s1-f2.5]="128 1 none 2.5"
  [r128-s4dn-f2.5]="128 4 openimagedenoise 2.5")
mkdir -p "$OUT"
LOG="$OUT/commands.log"

# Logs and runs one command; EXPERIMENTS-archive.md quotes these lines.
run() {
  echo "+ $*" | tee -a "$LOG" >&2
  "$@"
}

# Sets CKPTS to the -c flags of the seed checkpoints under RUNS.
checkpoints_of() { # runs
  local s
  CKPTS=()
  for ((s = 0; s < SEEDS; s++)); do CKPTS+=(-c "$1/seed-$s"); done
}

# A complete render config: the defaults plus these values.
config() { # out seed per_pair condition resolution samples denoiser fps [extra toml]
  cat >"$1" <<EOF
[dataset]
seed = $2
sequences_per_pair = $3
conditions = ["$4"]
[plan.camera]
resolution = [$5, $5]
[plan.trajectory]
fps = $8
[render]
engine = "cycles"
samples = $6
denoiser = "$7"
workers = 2
threads = 1
${9:-}
EOF
}

render() { # dir config-args...
  local dir=$1
  shift
  mkdir -p "$(dirname "$dir")"
  config "$dir.toml" "$@"
  run "$BIN/grasp-gen" render --config "$dir.toml" --out "$dir" --resume --no-progress
}

# FC heads (seeds 0..SEEDS-1) on DATA, early stopping on the fixed
# validation set, evaluated on the fixed test sets.
heads() { # data runs flags...
  local data=$1 runs=$2 t
  shift 2
  [ -f "$runs/.done" ] || {
    run "$BIN/grasp-train" train --overwrite --data "$data" --val-data "$OUT/fixed/val" --seeds "$SEEDS" \
      --out "$runs" --cache-dir "$OUT/cache" "$@"
    touch "$runs/.done"
  }
  checkpoints_of "$runs"
  for t in default unseen_look; do
    [ -f "$runs/eval-$t/report.json" ] ||
      run "$BIN/grasp-train" eval "${CKPTS[@]}" --data "$OUT/fixed/test-$t" \
        --out "$runs/eval-$t" --cache-dir "$OUT/cache"
  done
}

stage_fixed() {
  render "$OUT/fixed/val" 2 1 default 224 1 openimagedenoise 5.0
  for t in default unseen_look; do
    render "$OUT/fixed/test-$t" 3 2 "$t" 224 1 openimagedenoise 5.0
  done
}

stage_study() {
  local name
  for name in "${!SETTINGS[@]}"; do
    # shellcheck disable=SC2086 # the setting is four words
    render "$OUT/study/$name" 1 2 default ${SETTINGS[$name]}
    run "$BIN/grasp-gen" dataset stats "$OUT/study/$name" --json >"$OUT/study/$name.stats.json"
    heads "$OUT/study/$name" "$OUT/study-models/$name-whole" --set head=fc
    heads "$OUT/study/$name" "$OUT/study-models/$name-crop" --set head=fc "${CROP_SET[@]}"
  done
}

stage_ablation() {
  local lever base="128 1 openimagedenoise 2.5"
  for lever in "${LEVERS[@]}" all; do
    local extra="[randomize.$lever]"
    [ "$lever" = all ] && extra="[randomize]"
    # shellcheck disable=SC2086
    render "$OUT/ablation/no-$lever" 1 2 default $base "$(printf '%s\nenabled = false' "$extra")"
    run "$BIN/grasp-gen" dataset stats "$OUT/ablation/no-$lever" --json >"$OUT/ablation/no-$lever.stats.json"
    heads "$OUT/ablation/no-$lever" "$OUT/ablation-models/no-$lever" --set head=fc "${CROP_SET[@]}"
  done
  # every lever on, the training noise widened towards (not into) unseen_look's
  # shellcheck disable=SC2086
  render "$OUT/ablation/noise-wide" 1 2 default $base "$(printf '[randomize.sensor_noise]\nsigma = [0.0, 0.029]')"
  heads "$OUT/ablation/noise-wide" "$OUT/ablation-models/noise-wide" --set head=fc "${CROP_SET[@]}"
}

stage_parts() {
  local data="$OUT/study/r224-s1dn-f5" crop window
  for crop in 0.35 0.5 0.7; do
    heads "$data" "$OUT/parts/crop-$crop" --set head=fc --set "reader.crop={ fraction = $crop }"
  done
  heads "$data" "$OUT/parts/lstm-whole" --set head=lstm
  heads "$data" "$OUT/parts/lstm-crop" --set head=lstm "${CROP_SET[@]}"
  local runs="$OUT/study-models/r224-s1dn-f5-crop"
  checkpoints_of "$runs"
  for window in "--before-tail-s 1.0" "--before-tail-s 0.5" "--to-s 1.5" "--from-s 1.0"; do
    local name=${window// /}
    # shellcheck disable=SC2086 # the window is a flag and its value
    [ -f "$OUT/parts/window${name}/report.json" ] ||
      run "$BIN/grasp-train" eval "${CKPTS[@]}" --data "$OUT/fixed/test-default" $window \
        --out "$OUT/parts/window${name}" --cache-dir "$OUT/cache"
  done
}

# Table 2's columns: the same plans seen by the wrist and by the head camera
# (128 px, 2.5 frames/s, both cameras in one render), an FC head per camera.
stage_egocentric() {
  local ego="$OUT/egocentric" head_camera camera
  head_camera=$(printf '[plan.head_camera]\nenabled = true')
  render "$ego/train" 1 2 default 128 1 openimagedenoise 2.5 "$head_camera"
  render "$ego/val" 2 1 default 128 1 openimagedenoise 2.5 "$head_camera"
  render "$ego/test-default" 3 2 default 128 1 openimagedenoise 2.5 "$head_camera"
  for camera in Wrist_d435 Head_d435 Wrist_d435-whole Head_d435-whole; do
    local runs="$ego/$camera" crop=("${CROP_SET[@]}")
    [ "${camera%-whole}" = "$camera" ] || crop=()
    [ -f "$runs/.done" ] || {
      run "$BIN/grasp-train" train --overwrite --data "$ego/train" --val-data "$ego/val" --set head=fc \
        --seeds "$SEEDS" --set "reader.camera=${camera%-whole}" "${crop[@]}" --out "$runs" \
        --cache-dir "$OUT/cache"
      touch "$runs/.done"
    }
    checkpoints_of "$runs"
    [ -f "$runs/eval-default/report.json" ] ||
      run "$BIN/grasp-train" eval "${CKPTS[@]}" --data "$ego/test-default" \
        --out "$runs/eval-default" --cache-dir "$OUT/cache"
  done
}

stage_main() {
  SKIP_SETUP=1 run scripts/main.sh "$OUT/main"
}

# Frozen FC heads (SEEDS of them) trained on DATA/train and DATA/val with
# the main job's feature cache, unless RUNS is done. They crop the fraction
# CROP unless the flags set reader.crop.
frozen_fc() { # runs data train-flags...
  local runs=$1 data=$2 crop=("${CROP_SET[@]}")
  shift 2
  [[ " $* " != *" reader.crop="* ]] || crop=()
  [ -f "$runs/.done" ] || {
    run "$BIN/grasp-train" train --overwrite --data "$data/train" --val-data "$data/val" --set head=fc \
      --seeds "$SEEDS" --set mode=frozen-pretrained "${crop[@]}" --out "$runs" \
      --cache-dir "$OUT/main/features" "$@"
    touch "$runs/.done"
  }
}

# An FC head on the main job's data (extra train flags), evaluated on every
# test condition; the checkpoints are RUNS/seed-*.
main_fc() { # runs train-flags...
  local runs=$1 main="$OUT/main" c
  shift
  frozen_fc "$runs" "$main/data" "$@"
  checkpoints_of "$runs"
  for c in default fast from_ground seated background unseen_look; do
    [ -f "$runs/report/$c/report.json" ] ||
      run "$BIN/grasp-train" eval "${CKPTS[@]}" --data "$main/data/test-$c" --out "$runs/report/$c" \
        --cache-dir "$main/features"
  done
}

stage_large() {
  SKIP_SETUP=1 run scripts/main.sh --large "$OUT/main-large"
}

stage_size() {
  local n
  for n in 1 2 4 8 16; do
    main_fc "$OUT/size-$n" --set "sequences_per_pair=$n" --set "input_size=$INPUT_SIZE"
  done
}

# FC heads of the main job's data at other input sides.
stage_input() {
  local n
  for n in 64 96 128 160 224; do
    main_fc "$OUT/input-$n" --set "input_size=$n"
  done
}

# Renders CONDITION into OUT as the main job renders its test sets
# (configs/main.toml, one condition) and lab/cross-world.sh its held-out
# looks (configs/test-look-X.toml laid over it), with SEED and PER_PAIR
# sequences per pair.
render_condition() { # out seed per_pair condition
  local which=(--set "dataset.conditions=[\"$4\"]")
  [[ $4 != look_* ]] || which=(--config "configs/test-${4/_/-}.toml")
  run "$BIN/grasp-gen" render --config configs/main.toml "${which[@]}" --set "dataset.seed=$2" \
    --set "dataset.sequences_per_pair=$3" --out "$1" --resume --no-progress
}

# More draws of the test sets (seeds 5, 7, 9, 11; the main job's settings),
# scored with the main job's own (seed 3; rendered here for the looks the
# main job leaves to lab/cross-world.sh) as one pooled set of 310 videos per
# condition: a binomial error near 2 points, not 4.5.
stage_draws() {
  local main="$OUT/main" c h sd
  mkdir -p "$OUT/draws"
  for c in $DRAW_CONDITIONS; do
    [ -d "$main/data/test-$c" ] || render_condition "$main/data/test-$c" 3 2 "$c"
    for sd in $DRAW_SEEDS; do
      render_condition "$OUT/draws/s$sd/test-$c" "$sd" 2 "$c"
    done
    pooled_roots "$c"
    for h in fc lstm fc-tuned; do
      [ -d "$main/model-$h" ] || continue
      checkpoints_of "$main/model-$h"
      [ -f "$OUT/draws/report/$h-$c/report.json" ] ||
        run "$BIN/grasp-train" eval "${CKPTS[@]}" "${POOLED_ROOTS[@]}" --out "$OUT/draws/report/$h-$c" \
          --cache-dir "$main/features"
    done
  done
}

# The --data flags of a condition's pooled draws (the main job's and the
# draws stage's), in POOLED_ROOTS.
pooled_roots() { # condition
  local sd
  POOLED_ROOTS=(--data "$OUT/main/data/test-$1")
  for sd in $DRAW_SEEDS; do POOLED_ROOTS+=(--data "$OUT/draws/s$sd/test-$1"); done
}

# Heads trained on a held-out look's own renders, against the same heads
# trained on the default look: how much of the look's gap is transfer.
stage_inlook() {
  local main="$OUT/main" look dir
  inlook_heads "$OUT/inlook/default" "$main/data"
  for look in $INLOOK_CONDITIONS; do
    dir="$OUT/inlook/$look"
    mkdir -p "$dir/data"
    # The look's test set with the training (seed 1, 24 per pair) and the
    # validation (seed 2, 1 per pair) sets' seeds and sizes.
    render_condition "$dir/data/train" 1 24 "$look"
    render_condition "$dir/data/val" 2 1 "$look"
    inlook_heads "$dir" "$dir/data"
  done
}

# The main job's frozen FC recipe with (style-damped) and without (plain)
# its style views and damping, trained on DATA/train, scored on the pooled
# draws of every condition of the draws stage.
inlook_heads() { # dir data
  local dir=$1 data=$2 recipe c
  local -A recipes=([plain]="" [style-damped]="${STYLE_DAMPED[*]}")
  for recipe in plain style-damped; do
    # shellcheck disable=SC2086 # the recipe's flags are words
    frozen_fc "$dir/fc-$recipe" "$data" --set "input_size=$INPUT_SIZE" --set "pooled_blocks=[7,10,14,15]" \
      ${recipes[$recipe]}
    score_draws "$dir/fc-$recipe"
  done
}

# RUNS' seeds scored on the pooled draws of every condition of the draws
# stage (RUNS/draws-CONDITION).
score_draws() { # runs
  local c
  checkpoints_of "$1"
  for c in $DRAW_CONDITIONS; do
    pooled_roots "$c"
    [ -f "$1/draws-$c/report.json" ] ||
      run "$BIN/grasp-train" eval "${CKPTS[@]}" "${POOLED_ROOTS[@]}" --out "$1/draws-$c" \
        --cache-dir "$OUT/main/features"
  done
}

# The camera's view normalised: the main job's frozen FC recipe (style
# views, damping) with its crop a fixed fraction (0.42) or a fixed angle
# (18.3 degrees, 0.42 of the default lens), denoised or not, on the main
# job's data, scored on the pooled draws (the draws stage first).
# EXPERIMENTS-archive.md section 21.
stage_camera() {
  local variant
  local -A variants=([fraction]="" [fraction-denoised]="--set reader.denoise=true"
    [angle]="--set reader.crop={angle_deg=18.3}"
    [angle-denoised]="--set reader.crop={angle_deg=18.3} --set reader.denoise=true")
  for variant in fraction fraction-denoised angle angle-denoised; do
    # shellcheck disable=SC2086 # the variant's flags are words
    frozen_fc "$OUT/camera/$variant" "$OUT/main/data" --set "input_size=$INPUT_SIZE" \
      --set "pooled_blocks=[7,10,14,15]" "${STYLE_DAMPED[@]}" \
      ${variants[$variant]}
    score_draws "$OUT/camera/$variant"
  done
}

# render CPU seconds of a training set (the x of the cost plots)
cost() { python3 -c 'import json,sys; print(round(json.load(open(sys.argv[1]))["cpu_seconds"]))' "$1"; }

stage_summary() {
  local s="$OUT/summary" reports=() name lever t n
  for name in "${!SETTINGS[@]}"; do
    for t in default unseen_look; do
      reports+=(--report "$t-crop/$name=$(cost "$OUT/study/$name.stats.json"):$OUT/study-models/$name-crop/eval-$t")
      reports+=(--report "$t-whole/$name=$(cost "$OUT/study/$name.stats.json"):$OUT/study-models/$name-whole/eval-$t")
    done
  done
  run "$BIN/grasp-train" summarize --x-label "render CPU seconds per training set (62 sequences)" \
    --title "Error against render cost (FC head, frozen Lite0)" --out "$s/study" "${reports[@]}"
  reports=()
  for lever in "${LEVERS[@]}" all; do
    for t in default unseen_look; do
      reports+=(--report "$t/no-$lever=$(cost "$OUT/ablation/no-$lever.stats.json"):$OUT/ablation-models/no-$lever/eval-$t")
    done
  done
  for t in default unseen_look; do
    reports+=(--report "$t/all-on=$(cost "$OUT/study/r128-s1dn-f2.5.stats.json"):$OUT/study-models/r128-s1dn-f2.5-crop/eval-$t")
  done
  run "$BIN/grasp-train" summarize --x-label "render CPU seconds per training set" \
    --title "Randomisation ablation (FC head, centre crop)" --out "$s/ablation" "${reports[@]}"
  reports=()
  for t in default fast from_ground seated background unseen_look; do
    for n in 1 2 4 8 16; do reports+=(--report "$t/$n=$n:$OUT/size-$n/report/$t"); done
    reports+=(--report "$t/24=24:$OUT/main/report/fc/$t")
    [ ! -d "$OUT/main-large/report/fc/$t" ] || reports+=(--report "$t/32=32:$OUT/main-large/report/fc/$t")
  done
  run "$BIN/grasp-train" summarize --x-label "training sequences per pair" --log-x \
    --title "Error against training set size (FC head, frozen Lite0)" --out "$s/size" "${reports[@]}"
}

stages=("$@")
[ ${#stages[@]} -gt 0 ] || stages=(fixed study ablation parts egocentric main large size input draws inlook camera summary)
for stage in "${stages[@]}"; do
  echo "== $stage"
  "stage_$stage"
done
