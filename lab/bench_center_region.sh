#!/usr/bin/env bash
# Render cost of rendering only the centre ([render] center_region): the main
# job's settings (configs/main.toml: Cycles 1 sample + denoiser, 2.5
# frames/s, two workers) on 31 sequences (one per pair, seed 1), at 160 and
# 224 px, whole frames and the central half. Prints a Markdown table of the
# wall-clock seconds of `grasp-gen render` (the workers' start included) and
# each setting's ratio to whole 160 px frames, measured in one run; the first
# setting is rendered again last to show the spread.
#
#   lab/bench_center_region.sh [OUT]     (default: runs/bench-region)
#
# About 3 minutes on 2 idle cores. Environment: BIN (target/release).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-runs/bench-region}
BIN=${BIN:-target/release}
mkdir -p "$OUT"

config() { # name resolution region
  sed -e 's/^seed = .*/seed = 1/' -e 's/^sequences_per_pair = .*/sequences_per_pair = 1/' \
    -e 's/^conditions = .*/conditions = ["default"]/' \
    -e "s/^resolution = .*/resolution = [$2, $2]/" -e "s/^center_region = .*/center_region = $3/" \
    configs/main.toml >"$OUT/$1.toml"
}

declare -A SECONDS_OF
time_render() { # name
  rm -rf "$OUT/data-$1"
  local start end
  start=$(date +%s.%N)
  "$BIN/grasp-gen" render --config "$OUT/$1.toml" --out "$OUT/data-$1" >"$OUT/$1.log" 2>&1
  end=$(date +%s.%N)
  SECONDS_OF[$1]=$(echo "$end - $start" | bc -l)
}

NAMES=(r160-whole r160-half r224-whole r224-half)
config r160-whole 160 1.0
config r160-half 160 0.5
config r224-whole 224 1.0
config r224-half 224 0.5
for name in "${NAMES[@]}"; do time_render "$name"; done
first=${SECONDS_OF[r160-whole]}
time_render r160-whole
again=${SECONDS_OF[r160-whole]}

echo "| resolution | center_region | wall s | ratio to whole 160 px |"
echo "|---|---|---|---|"
SECONDS_OF[r160-whole]=$first
for name in "${NAMES[@]}"; do
  res=${name%-*} res=${res#r} region=1
  [ "${name#*-}" = half ] && region=0.5
  printf '| %s x %s | %s | %.1f | %.2f |\n' "$res" "$res" "$region" "${SECONDS_OF[$name]}" \
    "$(echo "${SECONDS_OF[$name]} / $first" | bc -l)"
done
printf '| 160 x 160, again | 1 | %.1f | %.2f |\n' "$again" "$(echo "$again / $first" | bc -l)"
