#!/usr/bin/env bash
# The drift benchmark's parts that CI can afford (the benchmark itself takes minutes): the
# script parses and prints its usage, tools/drift/damage_frames.py damages a small
# dataset exactly as documented without touching a hard-linked copy, and
# tools/drift/bridge_error.py (tools/drift/bridge_sweep.sh) measures a bridged rotation and
# tools/drift/segment_errors.py charges each pair's error to its motion segment.
# Usage: drift_benchmark_test.sh SOURCE_DIR
set -euo pipefail
src=$1
# shellcheck source=tests/tools/benchmark_script_checks.sh
source "$src/tests/tools/benchmark_script_checks.sh"

check_script_usage "$src/tools/drift_benchmark.sh" \
  'Usage: tools/drift_benchmark.sh \[--publish\] \[--evo\] \[OUTDIR\]'

work=$(mktemp -d "${TMPDIR:-/tmp}/omnipose-drift-test-XXXXXX")
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/a/frames"
# A real 8-bit grey PNG: the all-zero image hostile_dataset.py builds, 4 x 3 pixels.
python3 -c "
import sys; sys.path.insert(0, '$src/tools/common')
from hostile_dataset import zero_png
open('$work/frame.png', 'wb').write(zero_png(4, 3) + b'x' * 100)"
for i in $(seq 0 11); do
  name=$(printf '%06d.png' "$i")
  cp "$work/frame.png" "$work/a/frames/$name"
  awk -v n="$name" -v i="$i" 'BEGIN { printf "%s %.6f\n", n, i / 30 }' >> "$work/a/timestamps.txt"
done
cp -al "$work/a" "$work/b"
python3 "$src/tools/drift/damage_frames.py" "$work/b" --corrupt 1 --corrupt 3-6 --remove 8-9 > "$work/log"
grep -q 'corrupted frames 3-6 (000003.png .. 000006.png)' "$work/log" || fail "log: $(cat "$work/log")"
grep -q 'removed frames 8-9' "$work/log" || fail "log: $(cat "$work/log")"
# The copy is untouched.
[ "$(ls "$work/a/frames" | wc -l)" = 12 ] || fail "the original lost frames"
[ "$(wc -l < "$work/a/timestamps.txt")" = 12 ] || fail "the original lost timestamps"
for i in 1 3 4 5 6; do
  cmp -s "$work/frame.png" "$work/a/frames/$(printf '%06d.png' "$i")" || fail "original frame $i changed"
done
# Damaged: five files differ from the good one (cycling truncated, empty, random, black PNG).
for i in 1 3 4 5 6; do
  f=$work/b/frames/$(printf '%06d.png' "$i")
  cmp -s "$work/frame.png" "$f" && fail "frame $i not corrupted"
done
[ "$(stat -c %s "$work/b/frames/000003.png")" = 0 ] || fail "frame 3 should be the empty file"
[ "$(stat -c %s "$work/b/frames/000001.png")" = $(( $(stat -c %s "$work/frame.png") / 2 )) ] ||
  fail "frame 1 should be the truncated half"
[ "$(stat -c %s "$work/b/frames/000004.png")" = 4096 ] || fail "frame 4 should be 4096 random bytes"
# Removed: files and timestamps, nothing else.
[ ! -e "$work/b/frames/000008.png" ] && [ ! -e "$work/b/frames/000009.png" ] || fail "frames 8-9 remain"
[ "$(ls "$work/b/frames" | wc -l)" = 10 ] || fail "frames left: $(ls "$work/b/frames")"
grep -q '^000008.png\|^000009.png' "$work/b/timestamps.txt" && fail "timestamps of 8-9 remain"
[ "$(wc -l < "$work/b/timestamps.txt")" = 10 ] || fail "timestamps left: $(cat "$work/b/timestamps.txt")"
# Bad input is named.
out=$(python3 "$src/tools/drift/damage_frames.py" "$work/b" --corrupt 40 2>&1) && fail "range past the end accepted"
grep -q 'range 40-40 is past the last frame' <<< "$out" || fail "message: $out"
out=$(python3 "$src/tools/drift/damage_frames.py" "$work/b" --remove 5-2 2>&1) && fail "5-2 accepted"
grep -q "need 0 <= A <= B" <<< "$out" || fail "message: $out"
out=$(python3 "$src/tools/drift/damage_frames.py" "$work/none" --remove 1 2>&1) && fail "missing dataset accepted"
grep -q "$work/none/frames: no such directory" <<< "$out" || fail "message: $out"

# The bridge sweep parses; its error measure: truth turning 10 deg about z from frame 0 to 3
# (frames 1-2 removed), the estimate 9 deg: 1 deg of error; no estimate at frame 3: lost.
bash -n "$src/tools/drift/bridge_sweep.sh" || fail "tools/drift/bridge_sweep.sh: syntax"
python3 - "$work" <<'PY'
import math, sys
def line(t, deg):
    h = math.radians(deg) / 2
    return f"{t:.6f} 0 0 0 0 0 {math.sin(h):.9f} {math.cos(h):.9f}\n"
open(sys.argv[1] + "/gt.tum", "w").write("# t x y z qx qy qz qw\n" + "".join(line(i / 30, 5 + 10 * (i == 3)) for i in range(5)))
open(sys.argv[1] + "/est.tum", "w").write("".join(line(i / 30, 5 + 9 * (i == 3)) for i in (0, 3, 4)))
open(sys.argv[1] + "/lost.tum", "w").write("".join(line(i / 30, 5) for i in (0, 4)))
PY
out=$(python3 "$src/tools/drift/bridge_error.py" "$work/gt.tum" "$work/est.tum" 1 2)
grep -q '^first=1 count=2 true_deg=10.00 est_yaw_deg=9.000 true_yaw_deg=10.000 error_deg=1.000$' <<< "$out" ||
  fail "bridge_error: $out"
out=$(python3 "$src/tools/drift/bridge_error.py" "$work/gt.tum" "$work/lost.tum" 1 2)
[ "$out" = "first=1 count=2 true_deg=10.00 lost" ] || fail "bridge_error without a pose: $out"
out=$(python3 "$src/tools/drift/bridge_error.py" "$work/gt.tum" "$work/est.tum" 3 2 2>&1) &&
  fail "an outage reaching the last frame accepted"
grep -q "no frame on both sides" <<< "$out" || fail "message: $out"

# segment_errors.py: a turn of 3 steps of 2 deg, then a drive of 2 steps; the estimate is
# 0.5 deg short in yaw on each drive pair and right on the turn, one turn pair is lost.
cat > "$work/motion.yaml" <<'YAML'
segments:
  - {frames: 3, rotation: {axis: z, step_deg: 2, sign: positive}}
  - {frames: 2, translation: {step_m: 0.02, direction: [1, 0, 0]}}
YAML
python3 - "$work" <<'PY'
import math, sys
yaw = [0, 2, 4, 6, 6, 6]
def q(deg):
    h = math.radians(deg) / 2
    return f"0 0 0 0 0 {math.sin(h):.12f} {math.cos(h):.12f}"
open(sys.argv[1] + "/seg_gt.tum", "w").write("".join(f"{k / 30:.6f} {q(d)}\n" for k, d in enumerate(yaw)))
rows = ["frame,timestamp,file,prev_frame,status,rx,ry,rz"]
for k in range(1, 6):
    step = math.radians(yaw[k] - yaw[k - 1] - 0.5 * (k > 3))
    rows.append(f"{k},{k / 30},{k:06d}.png,{k - 1},{'lost' if k == 2 else 'ok'},0,0,{step!r}")
open(sys.argv[1] + "/seg.csv", "w").write("\n".join(rows) + "\n")
PY
out=$(python3 "$src/tools/drift/segment_errors.py" "$work/motion.yaml" "$work/seg_gt.tum" "$work/seg.csv")
grep -q '^all rotation  *pairs    2  error sum roll   +0.000  pitch   +0.000  yaw   +0.000 deg$' <<< "$out" &&
  grep -q '^all translation  *pairs    2  error sum roll   +0.000  pitch   +0.000  yaw   -1.000 deg$' <<< "$out" &&
  [ "$(grep -c '^segment' <<< "$out")" = 2 ] || fail "segment_errors: $out"
out=$(python3 "$src/tools/drift/segment_errors.py" "$work/motion.yaml" "$work/seg_gt.tum" "$work/none.csv" 2>&1) &&
  fail "a missing CSV accepted"
grep -q "none.csv" <<< "$out" || fail "segment_errors message: $out"
echo "drift_benchmark_test: PASS"
