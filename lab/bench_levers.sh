#!/usr/bin/env bash
# Render cost of each training lever: the same 4 mug sequences (15 frames,
# Cycles 224 x 224, 1 sample + denoiser, one worker; configs/bench-levers.toml)
# rendered with every lever off, with one lever on at a time, with all on
# (the defaults) and as the unseen_look condition. Prints a Markdown table of
# the worker's seconds per frame, wall-clock (render + effects + setup) and
# CPU (every thread: steadier when other jobs share the machine), each with
# its ratio to "none"; the "none" run is repeated last to show the spread.
#
#   lab/bench_levers.sh [OUT]        (default: runs/bench-levers)
#
# About 10 minutes on 2 cores. Environment: BIN (target/release);
# TABLE_ONLY=1 prints the table of an earlier run without rendering.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-runs/bench-levers}
BIN=${BIN:-target/release}
BASE=configs/bench-levers.toml
LEVERS=(fov principal_point sensor_noise motion_blur white_balance jpeg world_light
  object_color distractors standoff aim approach_ends)
mkdir -p "$OUT"

# BASE plus a [randomize] section with only the given levers on (at their
# defaults; world light and JPEG always drawn, three distractors).
config() { # name, condition, levers...
  local name=$1 condition=$2 lever l on
  shift 2
  {
    sed -e "s/^conditions = .*/conditions = [\"$condition\"]/" "$BASE"
    printf '\n[randomize]\nenabled = true\n'
    for lever in "${LEVERS[@]}"; do
      on=false
      for l in "$@"; do [ "$l" = "$lever" ] && on=true; done
      printf '\n[randomize.%s]\nenabled = %s\n' "$lever" "$on"
      case $lever in
        world_light | jpeg) echo "probability = 1.0" ;;
        distractors) echo "count = [3, 3]" ;;
      esac
    done
  } >"$OUT/$name.toml"
}

run() { # name
  rm -rf "$OUT/$1"
  "$BIN/grasp-gen" render --config "$OUT/$1.toml" --out "$OUT/$1" --no-progress >/dev/null
  "$BIN/grasp-gen" dataset stats "$OUT/$1" --json >"$OUT/$1.json"
}

per_frame() { # name -> seconds per frame (wrist camera + setup), effects ms
  python3 -c '
import json, sys
s = json.load(open(sys.argv[1]))
total = s["cameras"]["Wrist_d435"]["seconds_per_frame"] + s["setup_seconds_per_frame"]
print("%.3f %.3f %.1f" % (total, s["cpu_seconds_per_frame"], s["effects_seconds_per_frame"] * 1000))
' "$OUT/$1.json"
}

names=(none)
config none default
for lever in "${LEVERS[@]}"; do
  config "$lever" default "$lever"
  names+=("$lever")
done
config all default "${LEVERS[@]}"
config unseen_look unseen_look "${LEVERS[@]}"
config none-again default
names+=(all unseen_look none-again)
if [ -z "${TABLE_ONLY:-}" ]; then
  for n in "${names[@]}"; do
    echo "rendering $n" >&2
    run "$n"
  done
fi
read -r base cpu_base _ < <(per_frame none)
echo "| levers on | wall s/frame | vs none | CPU s/frame | vs none | of which effects (ms/frame) |"
echo "|---|---|---|---|---|---|"
for n in "${names[@]}"; do
  read -r s c e < <(per_frame "$n")
  ratio=$(python3 -c "print('%.2f' % ($s / $base))")
  cpu_ratio=$(python3 -c "print('%.2f' % ($c / $cpu_base))")
  echo "| $n | $s | $ratio | $c | $cpu_ratio | $e |"
done
