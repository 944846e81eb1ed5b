#!/usr/bin/env bash
# The hand's policy chosen on the worlds (issue 57): every candidate setting
# of hannes-run's decision policy (window, confidence checks, fallback,
# early decision) scored by `grasp-train eval` (the one policy
# implementation, grasp-policy) on every test set of a finished main job,
# for each model of it; then, per candidate, the hand's decision on each
# model's worst set. The defaults are the candidate whose worst set is best
# for the shipped model, never one test set's best.
#
#   lab/policy-sweep.sh MAIN_OUT            # writes MAIN_OUT/lab/policy/
#   MODELS="fc" lab/policy-sweep.sh MAIN_OUT  # only the models named (default: all)
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:?usage: lab/policy-sweep.sh MAIN_OUT}
BIN=${BIN:-target/release}
LAB="$OUT/lab/policy"
# name: flags over hannes-run's defaults (window 2 s, 3 votes, share 0.5,
# mean probability 0.5, fallback power, no early decision).
CANDIDATES=(
  "default:"
  "window-1.2:--window 1.2"
  "window-1.6:--window 1.6"
  "window-all:--window 60"
  "votes-1:--min-votes 1"
  "confidence-0:--min-confidence 0"
  "checks-off:--min-votes 1 --min-share 0 --min-confidence 0"
  "checks-off-window-1.6:--min-votes 1 --min-share 0 --min-confidence 0 --window 1.6"
  "early-2:--early-margin 2"
  "fallback-none:--fallback none"
)
SETS=()
for d in "$OUT"/report/fc/*/; do SETS+=("$(basename "$d")"); done
NAMED=${MODELS:-}
MODELS=()
if [ -n "$NAMED" ]; then
  for m in $NAMED; do MODELS+=("$OUT/model-$m"); done
else
  for d in "$OUT"/model-*/; do MODELS+=("${d%/}"); done
fi
for candidate in "${CANDIDATES[@]}"; do
  name=${candidate%%:*} flags=${candidate#*:}
  ENTRIES=()
  for m in "${MODELS[@]}"; do
    model=${m##*/model-}
    CHECKPOINTS=()
    for s in "$m"/seed-*; do CHECKPOINTS+=(-c "$s"); done
    for set in "${SETS[@]}"; do
      dir="$LAB/$name/$model/$set"
      # shellcheck disable=SC2086 # the flags are words
      [ -f "$dir/report.json" ] || $BIN/grasp-train eval "${CHECKPOINTS[@]}" \
        --data "$OUT/data/test-$set" --cache-dir "$OUT/features" $flags --out "$dir" >/dev/null
      ENTRIES+=(--report "$model/$set:$dir")
    done
  done
  $BIN/grasp-train summarize --by-condition --ship-by-worst --title "policy $name: $flags" \
    --out "$LAB/$name" "${ENTRIES[@]}" >/dev/null
done
.venv/bin/python - "$LAB" "${CANDIDATES[@]}" <<'PY' | tee "$LAB/policy-sweep.md"
import json, sys
lab, candidates = sys.argv[1], sys.argv[2:]
print("| candidate | flags | model | worst set (hand) | the hand there | mean of the hand | worst vote |")
print("|---|---|---|---|---|---|---|")
for c in candidates:
    name, flags = c.split(":", 1)
    choice = json.load(open(f"{lab}/{name}/summary.json"))["choice"]
    for st in choice["standings"]:
        print(f"| {name} | `{flags or '(defaults)'}` | {st['model']} | {st['worst_set']} | "
              f"{100 * st['worst_hand_accuracy']:.1f} | {100 * st['mean_hand_accuracy']:.1f} | "
              f"{100 * st['worst_vote_accuracy']:.1f} |")
PY
