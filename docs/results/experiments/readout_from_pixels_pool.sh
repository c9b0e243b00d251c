#!/usr/bin/env bash
# The readout, the clock and the mounting from the pixels over a pool of calibration recordings
# (docs/results/ANALYSIS.md, "The readout, the clock and the mounting from the pixels"): the
# real-camera benchmark's calibration motion (`calib_turns`: 90 frames turning in place at
# changing rates, 1 deg of vibration) rendered from the park and indoor photos with other seeds,
# readouts (both signs), gyro rates and clock offsets, and in the 6 x 5 m box room turning in
# place and driving an arc (the same turns while driving forward 1 cm per frame, 0.3 m/s).
# Each is measured as a user would: `omnipose-calibrate --readout-from`, then `--imu-from` from
# it (where --readout-from refuses, from the readout 3 % short, as a datasheet might give it).
# Printed per recording: the readout's error after --readout-from and after --imu-from (per
# cent, with --imu-from's 1 sigma, or "kept" where the pixels could not tell), the clock
# offset's error (ms, with its 1 sigma) and the mounting's (deg).
#
# Usage: [CASES=REGEX] docs/results/experiments/readout_from_pixels_pool.sh RCB_OUT [BUILD_DIR]
#   RCB_OUT    the output directory of tools/real_camera_benchmark.sh (its calib_turns motion
#              and photo are reused)
#   BUILD_DIR  [build] where bin/omnipose-synth and -calibrate are
#   CASES      only the recordings whose name matches (grep -E), default all
# Takes about 8 minutes on two cores.
set -euo pipefail
out=${1:?usage: readout_from_pixels_pool.sh RCB_OUT [BUILD_DIR]}
bin=${2:-build}/bin
here=$(cd "$(dirname "$0")/../../.." && pwd)
park=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["settings"]["photo"])' \
       "$out/report/real_camera.json")
indoor=$here/tests/data/equirect/indoor_1024x512.jpg
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# The arc: every turn of calib_turns with a forward step of 1 cm.
sed 's/^\(  *\)rotation: \(.*\)$/\1rotation: \2\n\1translation: {step_m: 0.01, direction: [1, 0, 0]}/' \
  "$out/motions/calib_turns.yaml" > "$work/calib_arc.yaml"
# The benchmark's gyro mounting (camera from IMU, w x y z).
mounting=0.939692621,0.228013429,-0.228013429,0.114006714
# name | photo | scene | motion | seed | readout s | gyro Hz | clock offset s
turns=$out/motions/calib_turns.yaml
cases=(
  "park_202|$park|sphere|$turns|202|0.0267|200|0.0123"
  "indoor_202|$indoor|sphere|$turns|202|0.0267|200|0.0123"
  "park_303|$park|sphere|$turns|303|0.015|200|-0.031"
  "indoor_303|$indoor|sphere|$turns|303|-0.02|1000|0.0123"
  "park_505|$park|sphere|$turns|505|-0.03|200|0.005"
  "indoor_606|$indoor|sphere|$turns|606|0.010|200|0.05"
  "box_turns|$indoor|box|$turns|202|0.0267|200|0.0123"
  "box_arc|$indoor|box|$work/calib_arc.yaml|202|0.0267|200|0.0123"
)
printf '%-11s %14s %24s %22s %10s\n' recording "--readout-from" "--imu-from readout" "clock offset" mounting
for c in "${cases[@]}"; do
  IFS='|' read -r name photo scene motion seed readout hz offset <<< "$c"
  [[ "$name" =~ ${CASES:-.} ]] || continue
  d=$work/$name
  mkdir -p "$d/measured"
  "$bin/omnipose-synth" --texture "$photo" --out "$d/dataset" --scene "$scene" \
    --motion "$motion" --frames 90 --seed "$seed" --supersample 2 \
    --noise 3 --jpeg 90 --readout "$readout" --between-frames smooth --gyro-rate "$hz" \
    --gyro-noise 8.7e-5 --gyro-bias 0.0087 --gyro-time-offset "$offset" \
    --gyro-rotation "$mounting" --quiet > "$d/synth.log" 2>&1
  for f in frames timestamps.txt imu.csv; do ln -s "../dataset/$f" "$d/measured/$f"; done
  first=measured
  if ! "$bin/omnipose-calibrate" --readout-from "$d/dataset" --out "$d/measured/calibration.yaml" \
         > "$d/readout.log" 2>&1; then
    first=given
    python3 -c 'import re, sys; t = open(sys.argv[1]).read(); print(re.sub(r"(readout_s:\s*)(\S+)",
      lambda m: m.group(1) + repr(0.97 * float(m.group(2))), t), end="")' \
      "$d/dataset/calibration.yaml" > "$d/measured/calibration.yaml"
  fi
  if ! "$bin/omnipose-calibrate" --imu-from "$d/measured" --out "$d/estimated.yaml" > "$d/imu.log" 2>&1; then
    echo "$name: refused: $(grep -h cannot "$d/imu.log" | head -n 1)"
    continue
  fi
  python3 - "$name" "$readout" "$offset" "$mounting" "$d/measured/calibration.yaml" \
    "$d/estimated.yaml" "$d/imu.log" "$first" <<'PY'
import math, re, sys
name, readout, offset, mounting, first_yaml, estimated_yaml, log, first_kind = sys.argv[1:]
readout, offset = float(readout), float(offset)
def value(path, key):
    return re.search(r"^\s+" + key + r":\s*(.+?)(\s+#.*)?$", open(path).read(), re.M).group(1)
first = float(value(first_yaml, "readout_s"))
estimated = float(value(estimated_yaml, "readout_s"))
measured_offset = float(value(estimated_yaml, "time_offset_s"))
q = [float(v) for v in value(estimated_yaml, "rotation").strip("[]").split(",")]
t = [float(v) for v in mounting.split(",")]
dot = abs(sum(a * b for a, b in zip(q, t))) / math.sqrt(sum(a * a for a in q))
text = open(log).read()
sigmas = re.search(r"from the pixels: readout [-0-9.]+ s \+-([0-9.]+) .*time offset [-+0-9.]+ s "
                   r"\+-([0-9.]+)", text)
kept = "not measured from the pixels" in text
readout_sigma = float(sigmas.group(1)) if sigmas else float("nan")
offset_sigma = float(sigmas.group(2)) if sigmas else float("nan")
print("%-11s %13s %15s %8s %+12.4f %8s %8.3f deg"
      % (name, ("%.2f%%" % (100 * (first / readout - 1))) + ("" if first_kind == "measured" else " given"),
         "kept" if kept else "%+.3f%%" % (100 * (estimated / readout - 1)),
         "" if kept else "+-%.3f" % (100 * readout_sigma / abs(readout)),
         1e3 * (measured_offset - offset), "" if kept else "+-%.4f" % (1e3 * offset_sigma),
         2 * math.degrees(math.acos(min(1.0, dot)))))
PY
done
