#!/usr/bin/env bash
# Auto-exposure with motion blur and the robot's gyro: the real-camera benchmark's shaking
# yaw ramps rendered with every frame exposed for its own time (omnipose-synth
# --exposure-times), a 200 Hz gyro beside them, a global and a rolling shutter, two photos
# and three seeds. Each render is replayed three ways: with no exposure at all, with the
# calibration's single exposure (the frames' mean), and with each frame's own (timestamps.txt's
# third column). Then the frames with each frame's own exposure are stamped at the end of
# their first row's exposure, as a Raspberry Pi stamps them, and replayed with
# `sensor.timestamp: exposure_end`, without it, and without it but with the gyro's clock
# offset moved by the mean half exposure (what --imu-from would find). Columns: eps / roll /
# pitch / yaw RMSE per pair, mrad. docs/results/ANALYSIS.md, "Auto-exposure with motion blur",
# reads it.
#
# Usage: docs/results/experiments/auto_exposure_with_gyro.sh RCB_OUT [BUILD_DIR]
#   RCB_OUT    the output directory of tools/real_camera_benchmark.sh (run it first: its
#              motions, replay configuration and photo are reused)
#   BUILD_DIR  [build] where bin/omnipose-synth, -replay and -eval are
# Environment: SEEDS ["202 303 404"], CYCLE [0.004,0.016,0.008,0.012,0.016,0.006] (seconds,
# cycled over the frames), PHOTOS [the benchmark's photo and the indoor test photo],
# TEXTURE_FLAGS [none] (e.g. "--texture-mirror --texture-turn 240").
set -euo pipefail
out=${1:?usage: auto_exposure_with_gyro.sh RCB_OUT [BUILD_DIR]}
bin=${2:-build}/bin
here=$(cd "$(dirname "$0")/../../.." && pwd)
photos=${PHOTOS:-}
if [ -z "$photos" ]; then
  photos=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["settings"]["photo"])' \
           "$out/report/real_camera.json")
  photos+=" $here/tests/data/equirect/indoor_1024x512.jpg"
fi
seeds=${SEEDS:-"202 303 404"}
cycle=${CYCLE:-0.004,0.016,0.008,0.012,0.016,0.006}
mean=$(tr ',' '\n' <<< "$cycle" | awk '{ s += $1; n++ } END { printf "%.7f", s / n }')
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
gyro="--gyro-rate 200 --gyro-noise 8.7e-5 --gyro-bias 0.0087 --gyro-time-offset 0.0123"
gyro+=" --gyro-rotation 0.939692621,0.228013429,-0.228013429,0.114006714"

score() {  # GT.tum EST.tum: eps / roll / pitch / yaw, mrad (stamps may be off by up to 10 ms)
  "$bin/omnipose-eval" "$1" "$2" --tolerance 0.01 |
    awk '/roll \(x\)/ { r = $3 } /pitch \(y\)/ { p = $3 } /yaw \(z\)/ { y = $3 }
      /rotation angle eps/ { e = $4 }
      END { printf "%.3f / %.3f / %.3f / %.3f", 1e3 * e, 1e3 * r, 1e3 * p, 1e3 * y }'
}
replay() {  # DATASET: writes DATASET/est.tum
  "$bin/omnipose-replay" "$1" --config "$out/replay.yaml" --quiet --out "$1/est.tum" > /dev/null 2>&1
}
# variant DATASET NAME: a copy of DATASET's files beside its frames (linked).
variant() {
  local x=$1.$2
  mkdir -p "$x"
  ln -s "$1/frames" "$x/frames"
  cp "$1/calibration.yaml" "$1/imu.csv" "$1/groundtruth.tum" "$x/"
  echo "$x"
}
# sensor_line FILE LINE: LINE added to FILE's sensor section (made when there is none).
sensor_line() {
  if grep -q '^sensor:' "$1"; then sed -i "s/^sensor:/sensor:\n  $2/" "$1"
  else printf 'sensor:\n  %s\n' "$2" >> "$1"; fi
}

echo "exposures $cycle s (mean $mean)"
for photo in $photos; do
  for seed in $seeds; do
    for shutter in "global|--readout 0" "rolling 0.8 frame|--readout 0.0267 --between-frames smooth"; do
      IFS='|' read -r label flags <<< "$shutter"
      d=$work/d
      rm -rf "$d" "$d".*
      # shellcheck disable=SC2086  # the flags hold whitespace-separated options
      "$bin/omnipose-synth" --texture "$photo" ${TEXTURE_FLAGS:-} --out "$d" --scene sphere \
        --motion "$out/motions/ramps_vib.yaml" --frames 60 --seed "$seed" --supersample 2 \
        --noise 3 --jpeg 90 $flags --exposure-times "$cycle" $gyro --quiet > /dev/null
      none=$(variant "$d" none)
      awk '{ print $1, $2 }' "$d/timestamps.txt" > "$none/timestamps.txt"
      calibrated=$(variant "$d" calibrated)
      cp "$none/timestamps.txt" "$calibrated/"
      sensor_line "$calibrated/calibration.yaml" "exposure_s: $mean"
      # Stamped at the end of the first row's exposure.
      end=$(variant "$d" end)
      awk '{ printf "%s %.9f %s\n", $1, $2 + 0.5 * $3, $3 }' "$d/timestamps.txt" > "$end/timestamps.txt"
      undeclared=$(variant "$d" undeclared)
      cp "$end/timestamps.txt" "$undeclared/"
      offset=$(variant "$d" offset)
      cp "$end/timestamps.txt" "$offset/"
      sensor_line "$end/calibration.yaml" "timestamp: exposure_end"
      sed -i "s/^  time_offset_s: .*/  time_offset_s: $(awk -v m="$mean" 'BEGIN { printf "%.7f", 0.0123 + 0.5 * m }')/" \
        "$offset/calibration.yaml"
      for x in "$d" "$none" "$calibrated" "$end" "$undeclared" "$offset"; do replay "$x"; done
      gt=$d/groundtruth.tum
      echo "$(basename "$photo") seed $seed, $label | none $(score "$gt" "$none/est.tum")" \
           "| calibration's mean $(score "$gt" "$calibrated/est.tum")" \
           "| each frame's $(score "$gt" "$d/est.tum")" \
           "|| stamped at the end, declared $(score "$gt" "$end/est.tum")" \
           "| not declared $(score "$gt" "$undeclared/est.tum")" \
           "| not declared, clock offset by the mean $(score "$gt" "$offset/est.tum")"
    done
  done
done
