#!/usr/bin/env bash
# How well the odometry bridges an outage, wherever it falls: the drift benchmark's rectangle
# in the box room (tools/drift/rectangle.yaml, steep non-linear mirror, sensor noise and
# exposure flicker) is rendered once; then, for outages of each LENGTH starting every STEP
# frames (and in the middle of every turn), those frames are removed
# (damage_frames.py --remove), the copy is replayed, and tools/drift/bridge_error.py compares
# the rotation bridged across the outage with the truth. Prints one line per outage and a
# summary: how many were bridged, the median and worst error, how many started a new segment.
# Usage: tools/drift/bridge_sweep.sh OUT_DIR [LENGTHS (default "5 20")] [STEP (default 25)]
# Environment: BUILD_DIR (default build), KEYFRAME_SLOTS (keyframes.slots of the replay;
# default: the default's).
set -euo pipefail
cd "$(dirname "$0")/../.."
out=${1:?usage: tools/drift/bridge_sweep.sh OUT_DIR [LENGTHS] [STEP]}
lengths=${2:-5 20}
step=${3:-25}
bin=${BUILD_DIR:-build}/bin
for t in omnipose-synth omnipose-replay; do
  [ -x "$bin/$t" ] || { echo "bridge_sweep: $bin/$t missing (bash tools/build.sh)" >&2; exit 1; }
done
case "$(realpath -m "$out")" in
  /|"$(pwd)"|"$HOME") echo "bridge_sweep: refusing to clear $out" >&2; exit 2 ;;
esac
rm -rf "$out"
mkdir -p "$out"
out=$(realpath "$out")
cat > "$out/calibration.yaml" <<YAML
omni:
  model: ocamcalib
  ocamcalib_file: $(pwd)/tests/data/catadioptric/steep_mirror_800_ocamcalib.txt
  azimuth_zero_deg: 0.0
  azimuth_direction: ccw
panorama: {width: 1100, height: 110, horizon_row: 54.5, forward_column: 0.0}
YAML
if [ -n "${KEYFRAME_SLOTS:-}" ]; then
  printf 'keyframes: {slots: %s}\n' "$KEYFRAME_SLOTS" > "$out/replay.yaml"
else
  : > "$out/replay.yaml"
fi
"$bin/omnipose-synth" --texture tests/data/equirect/indoor_1024x512.jpg --out "$out/rect" \
  --motion tools/drift/rectangle.yaml --scene box --calibration "$out/calibration.yaml" \
  --supersample 1 --noise 3 --exposure-jitter 0.05 --exposure-offset 3 --quiet
frames=$(grep -vc '^#' "$out/rect/groundtruth.tum")
# Turns (rectangle.yaml): frames 101-130, 201-230, 331-360, 431-460; mid-turn starts too.
starts="$(seq "$step" "$step" $((frames - 30))) 110 210 340"
: > "$out/sweep.txt"
for n in $lengths; do
  for s in $starts; do
    [ $((s + n)) -lt "$frames" ] || continue
    d=$out/gap
    rm -rf "$d"
    cp -al "$out/rect" "$d"
    python3 tools/drift/damage_frames.py "$d" --remove "$s-$((s + n - 1))" > /dev/null
    "$bin/omnipose-replay" "$d" --config "$out/replay.yaml" --quiet --out "$d/est.tum" \
      > /dev/null 2> "$d/replay.log" || { echo "bridge_sweep: replay failed" >&2; cat "$d/replay.log" >&2; exit 1; }
    python3 tools/drift/bridge_error.py "$d/groundtruth.tum" "$d/est.tum" "$s" "$n" | tee -a "$out/sweep.txt"
  done
done
rm -rf "$out/gap"
python3 - "$out/sweep.txt" <<'PY'
import re, sys
rows = [l for l in open(sys.argv[1]) if l.strip()]
for n in sorted({int(re.search(r"count=(\d+)", l).group(1)) for l in rows}):
    mine = [l for l in rows if f"count={n} " in l]
    errs = sorted(float(re.search(r"error_deg=([\d.]+)", l).group(1)) for l in mine if "error_deg" in l)
    lost = sum("lost" in l for l in mine)
    med = errs[len(errs) // 2] if errs else float("nan")
    worst = errs[-1] if errs else float("nan")
    print(f"bridge_sweep: outages of {n} frames: {len(errs)} of {len(mine)} bridged, error median "
          f"{med:.3f} deg, worst {worst:.3f} deg; {lost} started a new segment")
PY
