#!/usr/bin/env bash
# What a wrong readout does when each row's rotation comes from the gyro: the real-camera
# benchmark's rolling-shutter sequence with its 200 Hz gyro and its calibration recording
# (exact mounting and clock in their calibration.yaml), replayed with the readout scaled by
# -6 .. +6 %. Prints, per readout, the rotation error against the ground truth (eps RMSE) and
# the two scores a readout search could minimise without ground truth: the mean squared
# horizontal translation per pair, split into its forward (x) and sideways (y) parts, and the
# mean squared residual of the fits (residual_px of --relative). docs/results/ANALYSIS.md,
# "The readout with the gyro", reads it.
#
# Usage: docs/results/experiments/readout_with_gyro.sh RCB_OUT [BUILD_DIR]
#   RCB_OUT    the output directory of tools/real_camera_benchmark.sh (run it first)
#   BUILD_DIR  [build] where bin/omnipose-replay and bin/omnipose-eval are
set -euo pipefail
out=${1:?usage: readout_with_gyro.sh RCB_OUT [BUILD_DIR]}
bin=${2:-build}/bin
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for dataset in "$out/rolling_shutter_gyro200/dataset" "$out/calib/dataset"; do
  [ -f "$dataset/imu.csv" ] || { echo "readout_with_gyro: $dataset has no imu.csv" >&2; exit 1; }
  truth=$(sed -n 's/^ *readout_s: *//p' "$dataset/calibration.yaml")
  echo "== $dataset (readout $truth s)"
  printf '%8s %10s %10s %12s %12s %12s\n' change readout_s eps_mrad tau_x2 tau_y2 residual_px2
  for change in -0.06 -0.03 -0.015 0 0.015 0.03 0.045 0.06; do
    readout=$(awk -v r="$truth" -v c="$change" 'BEGIN { printf "%.6f", r * (1 + c) }')
    sed "s/^\( *readout_s:\).*/\1 $readout/" "$dataset/calibration.yaml" > "$work/calibration.yaml"
    "$bin/omnipose-replay" "$dataset" --calibration "$work/calibration.yaml" --quiet \
      --out "$work/est.tum" --relative "$work/est.csv" > /dev/null 2>&1
    eps=$("$bin/omnipose-eval" "$dataset/groundtruth.tum" "$work/est.tum" |
          awk '/rotation angle eps/ { printf "%.3f", 1e3 * $4 }')
    # tdir_x, tdir_y (9, 10) times tau_norm (12); residual_px (13); state (17).
    awk -F, -v c="$change" -v r="$readout" -v e="$eps" 'NR > 1 && $17 == "tracked" {
        x += ($9 * $12) ^ 2; y += ($10 * $12) ^ 2; res += $13 ^ 2; n++ }
      END { printf "%+8.3f %10s %10s %12.4g %12.4g %12.4g\n", c, r, e, x / n, y / n, res / n }' \
      "$work/est.csv"
  done
done
