#!/usr/bin/env bash
# When the windows' yaw was captured, over a pool of renders (docs/results/ANALYSIS.md, "When
# the windows' yaw was captured"): the real-camera benchmark's shaking yaw ramps (`ramps_vib`)
# with a rolling shutter of 0.8 frame and its 200 Hz gyro, on the park and indoor photos and
# seeds, "all at once" (walkers, exposure steps, vignetting, 10 ms blur) on both, 300-frame
# runs, and renders held back from the choice of the regression's constants (photos mirrored or
# turned, other seeds). Each is replayed with the defaults and with `pipeline.yaw_capture_time:
# false`; printed: eps and yaw RMSE per pair (mrad) off -> on, and the offset found (ms, from
# omnipose-replay's gyro line). With READOUT_SCAN=1 the park and indoor seed-101 renders are also
# replayed with the calibration's readout 1 % long and short (yaw_capture_time off): the yaw
# columns show which readout the images' yaw was captured with.
#
# Usage: docs/results/experiments/yaw_capture_time_pool.sh RCB_OUT [BUILD_DIR]
#   RCB_OUT    the output directory of tools/real_camera_benchmark.sh (its motions, replay
#              configuration and photo are reused)
#   BUILD_DIR  [build] where bin/omnipose-synth, -replay and -eval are
# Takes about 6 minutes on two cores (the "all at once" renders are the slow ones).
set -euo pipefail
out=${1:?usage: yaw_capture_time_pool.sh RCB_OUT [BUILD_DIR]}
bin=${2:-build}/bin
here=$(cd "$(dirname "$0")/../../.." && pwd)
park=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["settings"]["photo"])' \
       "$out/report/real_camera.json")
indoor=$here/tests/data/equirect/indoor_1024x512.jpg
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
gyro="--gyro-rate 200 --gyro-noise 8.7e-5 --gyro-bias 0.0087 --gyro-time-offset 0.0123"
gyro+=" --gyro-rotation 0.939692621,0.228013429,-0.228013429,0.114006714"
rolling="--readout 0.0267 --between-frames smooth"
all="--walkers 3,0.5,1.8,1.2 --walker-distance 1.2,1.6 --exposure-step 0.25"
all+=" --exposure-step-every 10 --vignetting 0.3 --exposure-time 0.01"
# The benchmark's replay configuration (its pipeline section, with its FFTW wisdom), and the
# same with the offset off.
cp "$out/replay.yaml" "$work/on.yaml"
{ cat "$out/replay.yaml"; printf '  yaw_capture_time: false\n'; } > "$work/off.yaml"

# name | photo | seed | frames | extra omnipose-synth flags
renders=(
  "park_101|$park|101|60|"
  "park_202|$park|202|60|"
  "park_303|$park|303|60|"
  "park_404|$park|404|60|"
  "indoor_101|$indoor|101|60|"
  "indoor_202|$indoor|202|60|"
  "indoor_303|$indoor|303|60|"
  "indoor_404|$indoor|404|60|"
  "park_all_101|$park|101|60|$all --walker-seed 5"
  "park_all_303|$park|303|60|$all --walker-seed 6"
  "indoor_all_101|$indoor|101|60|$all --walker-seed 5"
  "park_300_505|$park|505|300|"
  "indoor_300_505|$indoor|505|300|"
  "held_back_park_mirrored_505|$park|505|60|--texture-mirror"
  "held_back_indoor_turned_606|$indoor|606|60|--texture-turn 270"
  "held_back_park_turned_707|$park|707|60|--texture-turn 120"
  "held_back_park_turned_all_707|$park|707|60|--texture-turn 120 $all --walker-seed 7"
  "held_back_indoor_mirrored_all_808|$indoor|808|60|--texture-mirror $all --walker-seed 8"
)

score() {  # GT.tum EST.tum: eps and yaw RMSE, mrad
  "$bin/omnipose-eval" "$1" "$2" --json "$2.json" > /dev/null
  python3 -c 'import json, sys; j = json.load(open(sys.argv[1]))[0]
print("%.4f %.4f" % (1e3 * j["eps"]["rmse"], 1e3 * j["yaw"]["rmse"]))' "$2.json"
}

printf '%-36s %-18s %-18s %s\n' render "eps off -> on" "yaw off -> on" "offset [ms]"
for entry in "${renders[@]}"; do
  IFS='|' read -r name photo seed frames flags <<< "$entry"
  d=$work/$name
  # shellcheck disable=SC2086  # the flags hold whitespace-separated options
  "$bin/omnipose-synth" --texture "$photo" --out "$d" --scene sphere \
    --motion "$out/motions/ramps_vib.yaml" --frames "$frames" --seed "$seed" --supersample 2 \
    --noise 3 --jpeg 90 $rolling $flags $gyro --quiet > "$work/synth.log" 2>&1
  "$bin/omnipose-replay" "$d" --config "$work/off.yaml" --quiet --out "$d/off.tum" > /dev/null 2>&1
  "$bin/omnipose-replay" "$d" --config "$work/on.yaml" --quiet --out "$d/on.tum" > /dev/null \
    2> "$d/on.log"
  read -r eps_off yaw_off <<< "$(score "$d/groundtruth.tum" "$d/off.tum")"
  read -r eps_on yaw_on <<< "$(score "$d/groundtruth.tum" "$d/on.tum")"
  offset=$(grep -o "windows' yaw read [-+0-9.]* ms" "$d/on.log" | awk '{ print $4 }')
  printf '%-36s %-18s %-18s %s\n' "$name" "$eps_off -> $eps_on" "$yaw_off -> $yaw_on" "$offset"
  if [ "${READOUT_SCAN:-0}" = 1 ] && [[ "$name" == park_101 || "$name" == indoor_101 ]]; then
    for scale in 1.01 0.99; do
      awk -v s="$scale" '/^  readout_s:/ { printf "  readout_s: %.6f\n", $2 * s; next } { print }' \
        "$d/calibration.yaml" > "$work/readout.yaml"
      "$bin/omnipose-replay" "$d" --config "$work/off.yaml" --calibration "$work/readout.yaml" \
        --quiet --out "$d/readout.tum" > /dev/null 2>&1
      read -r eps yaw <<< "$(score "$d/groundtruth.tum" "$d/readout.tum")"
      printf '%-36s %-18s %-18s\n' "  readout x $scale, off" "$eps" "$yaw"
    done
  fi
  rm -rf "$d/frames"
done
