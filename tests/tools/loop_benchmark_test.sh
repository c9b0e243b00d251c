#!/usr/bin/env bash
# tools/loop_benchmark.sh in a quick mode (one lap of one tuning room, 1 x 1 rays): it is
# rendered, replayed and measured at the lap's end, and the table has its row, every cell a
# number, and the median and worst of its group. Then
# tools/restart_benchmark.sh on that lap: a restart finds the saved map and is measured.
# Usage: loop_benchmark_test.sh SOURCE_DIR BUILD_DIR
set -euo pipefail
src=$1
build=$(realpath "$2")
cd "$src"
bash -n tools/loop_benchmark.sh
rc=0
out=$(bash tools/loop_benchmark.sh --frobnicate 2>&1) || rc=$?
[ "$rc" = 2 ] || { echo "loop_benchmark.sh --frobnicate: exit $rc, expected 2: $out" >&2; exit 1; }
rc=0
out=$(LAPS=6 bash tools/loop_benchmark.sh 2>&1) || rc=$?
[ "$rc" = 2 ] || { echo "loop_benchmark.sh with LAPS=6: exit $rc, expected 2: $out" >&2; exit 1; }
if [ ! -f ../shared/data/equirect/park_theta_v_5376x2688.jpg ]; then
  echo "loop_benchmark.sh: syntax and usage checked (no park photo beside the repository)"
  exit 0
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
rc=0
out=$(BUILD_DIR=$build ROOMS="indoor kitchen" bash tools/loop_benchmark.sh "$tmp/bad" 2>&1) || rc=$?
[ "$rc" = 2 ] && grep -q "no room named kitchen" <<< "$out" ||
  { echo "loop_benchmark.sh with an unknown room: exit $rc: $out" >&2; exit 1; }
BUILD_DIR=$build ROOMS="indoor" LAPS=1 bash tools/loop_benchmark.sh "$tmp/loops" \
  > "$tmp/log" 2>&1 || { echo "loop_benchmark.sh failed:" >&2; tail -20 "$tmp/log" >&2; exit 1; }
table=$tmp/loops/LOOPS.md
rooms=$(grep -cE '^\| [a-z_0-9]+ \| (tuning|report-only) \|' "$table")
summaries=$(grep -cE '^\| \*\*(median|worst)\*\* \|' "$table")
[ "$rooms" = 1 ] || { echo "LOOPS.md: $rooms room rows, expected 1" >&2; cat "$table" >&2; exit 1; }
[ "$summaries" = 2 ] || { echo "LOOPS.md: $summaries summary rows, expected 2" >&2; exit 1; }
# Per room: the map's and the odometry's error after the lap, the map's worst and RMS error in
# the lap (at least its error at the lap's end), closures and places.
bad=$(grep -E '^\| [a-z_0-9]+ \| (tuning|report-only) \|' "$table" |
      awk -F'|' '{if ($4 !~ /^ [0-9]+\.[0-9]+ $/ || $5 !~ /^ [0-9]+\.[0-9]+ $/ || $6 !~ /^ [0-9]+\.[0-9]+ $/ || $7 !~ /^ [0-9]+\.[0-9]+ $/ || $8 !~ /^ [0-9]+ $/ || $9 !~ /^ [0-9]+ $/ || $6 + 0 < $4 + 0) print}' | wc -l)
[ "$bad" = 0 ] || { echo "LOOPS.md: cells that are not numbers, or a worst below the lap's end" >&2; cat "$table" >&2; exit 1; }
places=$(grep -E '^\| indoor \|' "$table" | awk -F'|' '{print $9}')
[ "$places" -gt 5 ] || { echo "LOOPS.md: $places places after a lap" >&2; cat "$table" >&2; exit 1; }
echo "loop_benchmark.sh: 1 room, 1 lap, measured"

# tools/restart_benchmark.sh on that lap: the map of its first 300 frames saved, a restart at
# frame 100 with it finds the map (after the turn at 100-129) and measures the error from there.
bash -n tools/restart_benchmark.sh
rc=0
out=$(bash tools/restart_benchmark.sh "$tmp/r" 2>&1) || rc=$?
[ "$rc" = 2 ] || { echo "restart_benchmark.sh without a room: exit $rc, expected 2: $out" >&2; exit 1; }
BUILD_DIR=$build MAP_FRAMES=300 RESTARTS=100 COUNT=80 \
  bash tools/restart_benchmark.sh "$tmp/restarts" "$tmp/loops/indoor" > "$tmp/restart.log" 2>&1 ||
  { echo "restart_benchmark.sh failed:" >&2; tail -20 "$tmp/restart.log" >&2; exit 1; }
row=$(grep -E '^\| indoor \| 100 \|' "$tmp/restarts/RESTARTS.md") ||
  { echo "RESTARTS.md: no row for the restart at 100" >&2; cat "$tmp/restarts/RESTARTS.md" >&2; exit 1; }
found=$(awk -F'|' '{split($4, f, " "); print f[1]}' <<< "$row")
error=$(awk -F'|' '{split($5, e, " "); print e[1]}' <<< "$row")
[[ "$found" =~ ^[0-9]+$ ]] && [ "$found" -ge 100 ] && [ "$found" -le 180 ] &&
  [[ "$error" =~ ^[0-9]+\.[0-9]+$ ]] && awk -v e="$error" 'BEGIN {exit !(e < 1.0)}' ||
  { echo "RESTARTS.md: the restart at 100 did not find the map within 80 frames, or its error is not a number below 1 deg: $row" >&2; exit 1; }
echo "restart_benchmark.sh: a restart found the map: $row"
