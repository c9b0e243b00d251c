#!/usr/bin/env bash
# The people benchmark's renders with the robot's gyro, replayed with the gyro combined with the
# images (pipeline.gyro_fusion, the default) and without (the images' rotation alone, the gyro
# still tracking its bias): one line per render, SCENE/SITUATION, eps without and with, mrad
# (the RMS of omnipose-eval's per-pair eps), and their ratio (docs/results/ANALYSIS.md, "The
# gyro in each pair").
#
# Usage: gyro_fusion_people.sh DIR
#   DIR from `GYRO=1 tools/people_benchmark.sh DIR` (its renders carry imu.csv)
# Environment: BUILD_DIR [build] (omnipose-replay and omnipose-eval in BUILD_DIR/bin).
# Writes only under ${TMPDIR:-/tmp}; nothing is sent on the network.
set -euo pipefail
[ $# -eq 1 ] || { sed -n '8,11p' "$0" >&2; exit 2; }
dir=${1%/}
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../../.." && pwd)
bin=${BUILD_DIR:-$repo/build}/bin
work=$(mktemp -d "${TMPDIR:-/tmp}/gyro_fusion_people.XXXXXX")
trap 'rm -rf "$work"' EXIT
[ -f "$dir/default.yaml" ] || { echo "gyro_fusion_people: $dir/default.yaml missing" >&2; exit 1; }
{ cat "$dir/default.yaml"; echo "  gyro_fusion: false"; } > "$work/fusion_off.yaml"

# eps_of GROUNDTRUTH TUM: omnipose-eval's RMS of the per-pair eps, mrad.
eps_of() {
  "$bin/omnipose-eval" "$1" "$2" --json "$work/eval.json" > /dev/null
  python3 -c 'import json, sys
print("%.5f" % (1e3 * json.load(open(sys.argv[1]))[0]["eps"]["rmse"]))' "$work/eval.json"
}

found=0
for render in "$dir"/*/*/; do
  render=${render%/}
  [ -f "$render/dataset/imu.csv" ] || continue
  found=$((found + 1))
  for config in fusion_off default; do
    source_config=$dir/default.yaml
    [ "$config" = fusion_off ] && source_config=$work/fusion_off.yaml
    "$bin/omnipose-replay" "$render/dataset" --config "$source_config" --quiet \
      --out "$work/$config.tum" > /dev/null 2> "$work/$config.log" ||
      { echo "gyro_fusion_people: omnipose-replay failed on $render" >&2
        cat "$work/$config.log" >&2; exit 1; }
  done
  off=$(eps_of "$render/dataset/groundtruth.tum" "$work/fusion_off.tum")
  on=$(eps_of "$render/dataset/groundtruth.tum" "$work/default.tum")
  ratio=$(python3 -c 'import sys; print(float(sys.argv[2]) / float(sys.argv[1]))' "$off" "$on")
  printf '%s/%s\t%s\t%s\t%.3f\n' "$(basename "$(dirname "$render")")" "$(basename "$render")" \
    "$off" "$on" "$ratio"
done
[ "$found" -gt 0 ] ||
  { echo "gyro_fusion_people: no render with imu.csv under $dir (GYRO=1?)" >&2; exit 1; }
