#!/usr/bin/env bash
# What each effect of the real-camera benchmark's "all at once" row costs when the rows'
# rotations come from the gyro: its rolling-shutter sequence with a 200 Hz gyro, rendered
# again with one more effect at a time (the three walkers; the exposure steps and
# vignetting; the motion blur), each replayed with the gyro and scored against the ground
# truth. docs/results/ANALYSIS.md, "All at once with the gyro", reads it.
#
# Usage: docs/results/experiments/all_at_once_with_gyro.sh RCB_OUT [BUILD_DIR]
#   RCB_OUT    the output directory of tools/real_camera_benchmark.sh (run it first: its
#              motions, replay configuration and photo are reused)
#   BUILD_DIR  [build] where bin/omnipose-synth, -replay and -eval are
set -euo pipefail
out=${1:?usage: all_at_once_with_gyro.sh RCB_OUT [BUILD_DIR]}
bin=${2:-build}/bin
photo=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["settings"]["photo"])' \
        "$out/report/real_camera.json")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# The benchmark's flags (tools/real_camera_benchmark.sh).
base="--noise 3 --jpeg 90 --readout 0.0267 --between-frames smooth --gyro-rate 200"
base+=" --gyro-noise 8.7e-5 --gyro-bias 0.0087 --gyro-time-offset 0.0123"
base+=" --gyro-rotation 0.939692621,0.228013429,-0.228013429,0.114006714"
walkers="--walkers 3,0.5,1.8,1.2 --walker-distance 1.2,1.6 --walker-seed 5"
exposure="--exposure-step 0.25 --exposure-step-every 10 --vignetting 0.3"
blur="--exposure-time 0.01"
printf '%-34s %10s %8s %8s %8s\n' "effects on the rolling shutter" eps_mrad roll pitch yaw
for entry in "none|" "walkers|$walkers" "exposure steps, vignetting|$exposure" "motion blur|$blur" \
             "all of them|$walkers $exposure $blur"; do
  IFS='|' read -r label flags <<< "$entry"
  # shellcheck disable=SC2086  # base and flags hold whitespace-separated options
  "$bin/omnipose-synth" --texture "$photo" --out "$work/dataset" --scene sphere \
    --motion "$out/motions/ramps_vib.yaml" --frames 60 --seed 101 --supersample 2 \
    $base $flags --quiet > /dev/null
  "$bin/omnipose-replay" "$work/dataset" --config "$out/replay.yaml" --quiet \
    --out "$work/est.tum" > /dev/null 2>&1
  "$bin/omnipose-eval" "$work/dataset/groundtruth.tum" "$work/est.tum" |
    awk -v l="$label" '/roll \(x\)/ { r = $3 } /pitch \(y\)/ { p = $3 } /yaw \(z\)/ { y = $3 }
      /rotation angle eps/ { e = $4 }
      END { printf "%-34s %10.3f %8.3f %8.3f %8.3f\n", l, 1e3 * e, 1e3 * r, 1e3 * p, 1e3 * y }'
  rm -rf "$work/dataset"
done
