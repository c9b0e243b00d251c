#!/usr/bin/env bash
# A restart with a saved map, on the loop benchmark's recordings (tools/loop_benchmark.sh keeps
# each room's dataset): the first lap is replayed and its map saved (omnipose-replay --count
# MAP_FRAMES --map-out), then the replay is started again part of the way into the second lap
# with that map (--from S --count COUNT --map-in) at each of RESTARTS. For every restart: the
# frames it took to find the map, and the map pose's rotation error from then on, beside the
# error of the run that never stopped (the loop benchmark's map.tum, the same frames): a
# restart that found the map is as right as the map is there (tools/drift/restart_errors.py).
#
# Usage: tools/restart_benchmark.sh OUTDIR ROOMDIR...
#   ROOMDIR   a loop benchmark room's directory (its dataset/ and map.tum), e.g. build/loops/indoor
# Environment (defaults in brackets):
#   BUILD_DIR   [build]  binaries in BUILD_DIR/bin
#   CONFIG      [ROOMDIR/../replay.yaml]  the replay's daemon.yaml
#   MAP_FRAMES  [490]    frames replayed before the map is saved (a lap is 460, and its closure)
#   RESTARTS    [520 600 700 800]  the frames the restarts begin at
#   COUNT       [120]    frames replayed from each
# Writes OUTDIR/RESTARTS.md (a table) and each run's poses and log. Exit 1 when a replay fails.
set -euo pipefail
usage() { sed -n '12,19p' "$0" >&2; exit 2; }
[ $# -ge 2 ] || usage
case "$1" in -*) usage ;; esac
out=$1
shift
build=${BUILD_DIR:-build}
replay=$build/bin/omnipose-replay
[ -x "$replay" ] || { echo "restart_benchmark: no $replay (build first)" >&2; exit 1; }
map_frames=${MAP_FRAMES:-490}
restarts=${RESTARTS:-520 600 700 800}
count=${COUNT:-120}
here=$(dirname "$0")
mkdir -p "$out"
table=$out/RESTARTS.md
{
  echo "| room | restart at | found on | restart: error found / end / worst (deg) | yaw at end | uninterrupted: found / end / worst | yaw at end |"
  echo "|---|---:|---:|---|---:|---|---:|"
} > "$table"
for room in "$@"; do
  name=$(basename "$room")
  dataset=$room/dataset
  config=${CONFIG:-$(dirname "$room")/replay.yaml}
  for f in "$dataset/groundtruth.tum" "$room/map.tum" "$config"; do
    [ -f "$f" ] || { echo "restart_benchmark: $room: missing $f" >&2; exit 1; }
  done
  dir=$out/$name
  mkdir -p "$dir"
  "$replay" "$dataset" --config "$config" --quiet --count "$map_frames" \
    --map-out "$dir/first.map" --out "$dir/first.tum" > "$dir/first.txt" 2> "$dir/first.log" ||
    { echo "restart_benchmark: $name: the first run failed:" >&2; tail -5 "$dir/first.log" >&2; exit 1; }
  for s in $restarts; do
    "$replay" "$dataset" --config "$config" --quiet --from "$s" --count "$count" \
      --map-in "$dir/first.map" --out "$dir/restart_$s.tum" > "$dir/restart_$s.txt" \
      2> "$dir/restart_$s.log" ||
      { echo "restart_benchmark: $name: the restart at $s failed:" >&2; tail -5 "$dir/restart_$s.log" >&2; exit 1; }
    found=$(sed -n 's/.* relocalised=\(-\{0,1\}[0-9]*\).*/\1/p' "$dir/restart_$s.txt")
    if [ -z "$found" ] || [ "$found" -lt 0 ]; then
      echo "| $name | $s | never | | | | |" >> "$table"
      continue
    fi
    read -r _ r0 r1 rw ry u0 u1 uw uy < <(python3 "$here/drift/restart_errors.py" \
      "$dataset/groundtruth.tum" "$dir/first.tum" "$dir/restart_$s.tum" "$found" "$room/map.tum")
    echo "| $name | $s | $found (+$((found - s))) | $r0 / $r1 / $rw | $ry | $u0 / $u1 / $uw | $uy |" >> "$table"
  done
done
cat "$table"
