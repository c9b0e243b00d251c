#!/usr/bin/env bash
# Loop closure benchmark: the heading of a robot that drives the same rooms over and over.
# The drift benchmark's rectangle driven five times around (tools/drift/rectangle_5laps.yaml:
# 2.0 x 1.4 m, four 90-degree turns in place a lap, 2301 frames at 30 fps) is rendered by
# omnipose-synth in the box rooms of the room pool (tools/common/pool_rooms.sh: tuning and
# report-only rooms) through the drift benchmark's steep OCamCalib mirror, with its sensor
# noise and exposure flicker, and replayed by omnipose-replay with the defaults. At the end of
# every lap (the robot back where and as it started) the heading error of the map pose
# (--out: corrected by loop closures) and of the odometry's pose (--out-odometry: the chain
# a controller integrates) is measured (tools/drift/lap_errors.py), with the loop closures
# and the places kept; and, over the last lap, the map pose's largest and RMS error (the
# lap's end is where the map was last tied to the first place: the error on the way is the
# one that does not flatter). Writes OUTDIR/LOOPS.md (command, date, version, the table with each
# group's median and worst) and every room's dataset, trajectories and logs.
#
# Usage: tools/loop_benchmark.sh [--publish] [OUTDIR]    (default OUTDIR build/loops)
#   --publish   also copy OUTDIR/LOOPS.md to docs/results/LOOPS.md
# Environment (defaults in brackets):
#   BUILD_DIR   [build]  binaries in BUILD_DIR/bin; built first when missing
#   DATA_DIR    [../shared/data/equirect]  where the park photo is
#   SUPERSAMPLE [1]      renderer anti-aliasing: K x K rays per pixel
#   ROOMS       [every room of the pool]  the rooms to drive, names separated by spaces
#               (about 10 minutes a room on two cores, nearly all of it rendering)
#   LAPS        [5]      laps driven, 1..5 (fewer: a quick check)
# Nothing is sent on the network; everything is seeded (the same build gives the same table).
# shellcheck source=tools/common/benchmark.sh
source "$(dirname "$0")/common/benchmark.sh"
# shellcheck source=tools/common/pool_rooms.sh
source "$(dirname "$0")/common/pool_rooms.sh"
bench_args loop_benchmark loops -- "$@"
supersample=${SUPERSAMPLE:-1}
laps=${LAPS:-5}
case "$laps" in
  [1-5]) ;;
  *) echo "loop_benchmark: LAPS=$laps is outside 1..5" >&2; exit 2 ;;
esac
bin=$build/bin
bench_command_line tools/loop_benchmark.sh "$@" -- BUILD_DIR DATA_DIR SUPERSAMPLE ROOMS LAPS
bench_tools "$build" omnipose-synth omnipose-replay omnipose-equirect

lens=$root/tests/data/catadioptric/steep_mirror_800_ocamcalib.txt
motion=tools/drift/rectangle_5laps.yaml
for f in "$lens" "$motion" tools/drift/lap_errors.py; do
  [ -f "$f" ] || { echo "loop_benchmark: missing $f" >&2; exit 1; }
done

bench_fresh_out loop_benchmark lenses
out=$(realpath "$out")
bench_ocamcalib_calibration "$out/calibration.yaml" "$lens"
pool_rooms "$out"
bench_pick loop_benchmark room "${ROOMS:-}" "${rooms[@]}"
rooms=("${picked[@]}")
printf 'pipeline:\n  fftw_wisdom: "%s"\n' "$out/loops.wisdom" > "$out/replay.yaml"
# The drift benchmark's sensor: noise sigma 3 grey levels, per-frame gain 1 + N(0, 0.05) and
# offset N(0, 3) grey levels; PNG frames.
sensor="--noise 3 --exposure-jitter 0.05 --exposure-offset 3"
# A lap is 460 steps (tools/drift/rectangle.yaml); lap k ends at frame 460 k.
lap_frames=()
for ((k = 1; k <= laps; k++)); do lap_frames+=($((460 * k))); done

echo "== loop benchmark: ${#rooms[@]} rooms, $laps laps, output $out"
for entry in "${rooms[@]}"; do
  IFS='|' read -r name group photo options <<< "$entry"
  dir=$out/$name
  mkdir -p "$dir"
  t0=$(date +%s)
  # shellcheck disable=SC2086  # options and sensor hold whitespace-separated options
  "$bin/omnipose-synth" --texture "$photo" $options --out "$dir/dataset" --motion "$motion" \
    --frames $((460 * laps + 1)) --scene box --calibration "$out/calibration.yaml" \
    --supersample "$supersample" $sensor --quiet > "$dir/synth.log" || {
    echo "   $name: omnipose-synth failed, see $dir/synth.log" >&2; exit 1; }
  line=$("$bin/omnipose-replay" "$dir/dataset" --config "$out/replay.yaml" --quiet \
           --out "$dir/map.tum" --out-odometry "$dir/odometry.tum" 2> "$dir/replay.log" |
         tail -n 1) || {
    echo "   $name: omnipose-replay failed, see $dir/replay.log" >&2; exit 1; }
  printf '%s\n' "$line" > "$dir/replay.txt"
  for pose in map odometry; do
    python3 tools/drift/lap_errors.py "$dir/dataset/groundtruth.tum" "$dir/$pose.tum" \
      "${lap_frames[@]}" > "$dir/$pose.laps"
  done
  printf '%s\n' "$group" > "$dir/group"
  printf '== %-12s %4ds  %s\n' "$name" $(( $(date +%s) - t0 )) "$line"
done

elapsed=$(( $(date +%s) - start ))
bench_version "$bin"
names=()
for entry in "${rooms[@]}"; do names+=("${entry%%|*}"); done
python3 - "$out" "$laps" "${names[@]}" > "$out/table.md" <<'PY'
import re, statistics, sys
out, laps, names = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
def errors(name, pose):
    return [float(line.split()[1]) for line in open("%s/%s/%s.laps" % (out, name, pose))]
def last_lap_spread(name):
    """The map pose's largest and RMS error over the last lap."""
    last = open("%s/%s/map.laps" % (out, name)).read().split("\n")[laps - 1].split()
    return [float(last[3]), float(last[4])]
def counts(name):
    text = open("%s/%s/replay.txt" % (out, name)).read()
    return [int(re.search(key + r"=(\d+)", text).group(1)) for key in ("loops", "places")]
head = ["room", "group"] + ["map lap %d" % k for k in range(1, laps + 1)] + \
       ["odometry lap %d" % k for k in range(1, laps + 1)] + \
       ["map worst in lap %d" % laps, "map RMS in lap %d" % laps, "loop closures", "places"]
print("| " + " | ".join(head) + " |")
print("|---|---|" + "---:|" * (2 * laps + 4))
rows = {n: (errors(n, "map"), errors(n, "odometry"), counts(n), last_lap_spread(n)) for n in names}
groups = {n: open("%s/%s/group" % (out, n)).read().strip() for n in names}
for n in names:
    m, o, c, spread = rows[n]
    print("| " + " | ".join([n, groups[n]] + ["%.3f" % x for x in m + o + spread] +
                            [str(x) for x in c]) + " |")
for group in ("tuning", "report-only"):
    members = [n for n in names if groups[n] == group]
    if not members:
        continue
    for label, f in (("median", statistics.median), ("worst", max)):
        cells = ["**%s**" % label, group]
        for pose in (0, 1):
            cells += ["%.3f" % f(rows[n][pose][k] for n in members) for k in range(laps)]
        cells += ["%.3f" % f(rows[n][3][k] for n in members) for k in range(2)]
        cells += ["", ""]
        print("| " + " | ".join(cells) + " |")
PY

{
  echo "## Heading over five laps of the same rooms: the map pose and the odometry's"
  echo
  echo "Generated by \`$command_line\` on $(date -u '+%Y-%m-%d %H:%M UTC') with $version"
  echo "in $((elapsed / 60)) min $((elapsed % 60)) s."
  echo
  echo "The drift benchmark's rectangle (2.0 x 1.4 m, four 90-degree turns in place) driven $laps"
  echo "times around (\`$motion\`) in box rooms of the room pool (\`tools/common/pool_rooms.sh\`;"
  echo "$supersample x $supersample rays per pixel), through the steep OCamCalib mirror, sensor"
  echo "noise sigma 3 and exposure flicker, replayed with the defaults. Each cell: the rotation"
  echo "error of the pose, degrees, at the end of the lap (back where and as it started; the"
  echo "error of the pose relative to the first frame's, \`tools/drift/lap_errors.py\`). map: the"
  echo "map pose (\`--out\`, corrected by loop closures); odometry: the odometry's pose"
  echo "(\`--out-odometry\`, which a controller integrates). The lap's end is where the map pose"
  echo "was last tied to the first place; map worst / RMS in the last lap: the largest and the RMS"
  echo "rotation error of the map pose over that lap's frames, the figure that does not flatter."
  echo "Loop closures: frames that closed a loop; places: kept at the end. The report-only rooms"
  echo "are never used to choose a setting."
  echo
  cat "$out/table.md"
} > "$out/LOOPS.md"
cat "$out/table.md"
if [ "$publish" = 1 ]; then
  cp "$out/LOOPS.md" "$root/docs/results/LOOPS.md"
  echo "== published docs/results/LOOPS.md"
fi
