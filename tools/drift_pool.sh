#!/usr/bin/env bash
# Room pool: the heading drift of driving, judged over rooms instead of one. The drift
# benchmark's rectangle (tools/drift/rectangle.yaml: 2.0 x 1.4 m, four 90-degree turns in
# place, one lap, 461 frames at 30 fps) is rendered by omnipose-synth in box rooms (6 x 5 m)
# whose walls carry different photos, through the drift benchmark's steep OCamCalib mirror,
# with its sensor noise and exposure flicker, then replayed by omnipose-replay with the default
# pipeline and with each variant, and scored by `omnipose-eval --drift` (end-point and ATE of
# the chained attitude: the odometry's pose, --out-odometry, which a loop closure never
# corrects; per-pair eps). The rooms are photos turned about the vertical and
# mirrored (omnipose-synth --texture-turn, --texture-mirror; tools/common/pool_rooms.sh): seven
# tuning rooms and two report-only rooms, never used to choose a setting: a change is judged
# on the tuning rooms and these tell whether it holds on rooms it was not chosen on.
# Writes OUTDIR/DRIFT_POOL.md (command, date, version, the table with each group's median and
# worst) and every room's dataset, trajectories and scores.
#
# Usage: tools/drift_pool.sh [--publish] [OUTDIR]    (default OUTDIR build/drift_pool)
#   --publish   also copy OUTDIR/DRIFT_POOL.md to docs/results/DRIFT_POOL.md
# Environment (defaults in brackets):
#   BUILD_DIR   [build]  binaries in BUILD_DIR/bin; built first when missing
#   DATA_DIR    [../shared/data/equirect]  where the park photo is
#   SUPERSAMPLE [1]      renderer anti-aliasing: K x K rays per pixel
#   FRAMES      [the lap's 461]  render only the first FRAMES frames (a quick check of the
#               script; a part of the lap does not end where it began)
#   VARIANTS    ["keyframes.slots: 0|plane_depth_prior: false"]  the settings to compare with
#               the defaults, '|' between variants, each "key: value" entries separated by ';'
#               of daemon.yaml's `pipeline:` section, or of its `keyframes:` section as
#               "keyframes.key: value", e.g. "plane_depth_prior: false|keyframes.anchor_gain: 0.3"
# Nothing is sent on the network; everything is seeded (the same build gives the same table).
# shellcheck source=tools/common/benchmark.sh
source "$(dirname "$0")/common/benchmark.sh"
# shellcheck source=tools/common/pool_rooms.sh
source "$(dirname "$0")/common/pool_rooms.sh"
bench_args drift_pool drift_pool -- "$@"
supersample=${SUPERSAMPLE:-1}
variants=${VARIANTS-"keyframes.slots: 0|plane_depth_prior: false"}
bin=$build/bin
frames_option=()
[ -n "${FRAMES:-}" ] && frames_option=(--frames "$FRAMES")
bench_command_line tools/drift_pool.sh "$@" -- BUILD_DIR DATA_DIR SUPERSAMPLE FRAMES VARIANTS
bench_tools "$build" omnipose-synth omnipose-replay omnipose-eval omnipose-equirect

lens=$root/tests/data/catadioptric/steep_mirror_800_ocamcalib.txt
for f in "$lens" tools/drift/rectangle.yaml; do
  [ -f "$f" ] || { echo "drift_pool: missing $f" >&2; exit 1; }
done

bench_fresh_out drift_pool lenses
out=$(realpath "$out")
wisdom=$out/pool.wisdom

bench_ocamcalib_calibration "$out/calibration.yaml" "$lens"
pool_rooms "$out"
# The drift benchmark's sensor: noise sigma 3 grey levels, per-frame gain 1 + N(0, 0.05) and
# offset N(0, 3) grey levels; PNG frames.
sensor="--noise 3 --exposure-jitter 0.05 --exposure-offset 3"

# replay_yaml ENTRIES: a replay configuration, the defaults but for ENTRIES (VARIANTS' form).
replay_yaml() {
  local entry pipeline_entries="" keyframe_entries=""
  local -a entries=()
  IFS=';' read -ra entries <<< "$1"
  for entry in "${entries[@]}"; do
    case "$(sed 's/^[[:space:]]*//' <<< "$entry")" in
      keyframes.*) keyframe_entries+="$(sed 's/^[[:space:]]*keyframes\.//' <<< "$entry");" ;;
      *) pipeline_entries+="$entry;" ;;
    esac
  done
  printf 'pipeline:\n  fftw_wisdom: "%s"\n' "$wisdom"
  bench_pipeline_lines "$pipeline_entries"
  if [ -n "$keyframe_entries" ]; then
    printf 'keyframes:\n'
    bench_pipeline_lines "$keyframe_entries"
  fi
}

# Replay configurations: the defaults, then one per variant.
config_names=(default)
replay_yaml "" > "$out/default.yaml"
IFS='|' read -ra variant_list <<< "$variants"
for i in "${!variant_list[@]}"; do
  name=variant$((i + 1))
  config_names+=("$name")
  replay_yaml "${variant_list[$i]}" > "$out/$name.yaml"
done

echo "== drift pool: ${#rooms[@]} rooms x ${#config_names[@]} settings, output $out"
for entry in "${rooms[@]}"; do
  IFS='|' read -r name group photo options <<< "$entry"
  dir=$out/$name
  mkdir -p "$dir"
  t0=$(date +%s)
  # shellcheck disable=SC2086  # options and sensor hold whitespace-separated options
  "$bin/omnipose-synth" --texture "$photo" $options --out "$dir/dataset" \
    --motion tools/drift/rectangle.yaml --scene box --calibration "$out/calibration.yaml" \
    --supersample "$supersample" "${frames_option[@]}" $sensor --quiet > "$dir/synth.log" || {
    echo "   $name: omnipose-synth failed, see $dir/synth.log" >&2; exit 1; }
  for config in "${config_names[@]}"; do
    "$bin/omnipose-replay" "$dir/dataset" --config "$out/$config.yaml" --quiet \
      --out-odometry "$dir/$config.tum" > /dev/null 2> "$dir/$config.log" || {
      echo "   $name: omnipose-replay ($config) failed, see $dir/$config.log" >&2; exit 1; }
    "$bin/omnipose-eval" --drift "$dir/dataset/groundtruth.tum" "$dir/$config.tum" \
      --json "$dir/$config.json" > "$dir/$config.txt"
  done
  printf '%s\n' "$group" > "$dir/group"
  printf '== %-12s %3ds\n' "$name" $(( $(date +%s) - t0 ))
done

elapsed=$(( $(date +%s) - start ))
bench_version "$bin"
names=()
for entry in "${rooms[@]}"; do names+=("${entry%%|*}"); done
python3 - "$out" "${#config_names[@]}" "${config_names[@]}" "${names[@]}" > "$out/table.md" <<'PY'
import json, math, statistics, sys
out, count = sys.argv[1], int(sys.argv[2])
configs, names = sys.argv[3:3 + count], sys.argv[3 + count:]
deg = 180 / math.pi
def score(name, config):
    d = json.load(open("%s/%s/%s.json" % (out, name, config)))[0]
    return d["end_error"] * deg, d["eps"]["rmse"] * 1e3
head = ["room", "group"]
for c in configs:
    head += ["%s end-point [deg]" % c, "%s per-pair eps [mrad]" % c]
print("| " + " | ".join(head) + " |")
print("|---|---|" + "---:|" * (2 * len(configs)))
scores = {n: [score(n, c) for c in configs] for n in names}
groups = {n: open("%s/%s/group" % (out, n)).read().strip() for n in names}
for n in names:
    cells = [n, groups[n]]
    for end, eps in scores[n]:
        cells += ["%.3f" % end, "%.3f" % eps]
    print("| " + " | ".join(cells) + " |")
for group in ("tuning", "report-only"):
    members = [n for n in names if groups[n] == group]
    for label, f in (("median", statistics.median), ("worst", max)):
        cells = ["**%s**" % label, group]
        for i in range(len(configs)):
            cells += ["%.3f" % f(scores[n][i][0] for n in members),
                      "%.3f" % f(scores[n][i][1] for n in members)]
        print("| " + " | ".join(cells) + " |")
PY

{
  echo "## Heading drift of driving over a pool of rooms"
  echo
  echo "Generated by \`$command_line\` on $(date -u '+%Y-%m-%d %H:%M UTC') with $version"
  echo "in $((elapsed / 60)) min $((elapsed % 60)) s."
  echo
  echo "One lap of the drift benchmark's rectangle (\`tools/drift/rectangle.yaml\`) in box rooms"
  echo "whose walls carry the indoor photo, the park photo and the office texture, turned and"
  echo "mirrored (\`omnipose-synth --texture-turn --texture-mirror\`; $supersample x $supersample rays per"
  echo "pixel), through the steep OCamCalib mirror, sensor noise sigma 3 and exposure flicker."
  echo "End-point: the chained attitude's error after the lap (it ends as it began); per-pair eps:"
  echo "RMSE of the relative rotation (\`omnipose-eval --drift\`). default: the default pipeline;"
  for i in "${!variant_list[@]}"; do
    echo "variant$((i + 1)): \`${variant_list[$i]}\`."
  done
  echo "The report-only rooms are never used to choose a setting."
  echo
  cat "$out/table.md"
} > "$out/DRIFT_POOL.md"
cat "$out/table.md"
if [ "$publish" = 1 ]; then
  cp "$out/DRIFT_POOL.md" "$root/docs/results/DRIFT_POOL.md"
  echo "== published docs/results/DRIFT_POOL.md"
fi
