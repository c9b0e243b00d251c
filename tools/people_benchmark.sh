#!/usr/bin/env bash
# People benchmark: how much people walking around the robot cost, over a pool of situations
# and scenes, each render against its TWIN (the same motion, seed, noise, JPEG and lens
# without the people). Seeded renders of omnipose-synth (the default lens, 720 x 720 omni
# frames, SUPERSAMPLE x SUPERSAMPLE rays per pixel, noise sigma 3, JPEG 90, 30 fps, global
# shutter), FRAMES frames each. The situations (omnipose-synth --walkers COUNT,WIDTH,HEIGHT,SPEED
# --walker-distance MIN,MAX; each person's circle radius, start and direction drawn by the
# walker seed, so both directions occur):
#   narrow_far     1 person 0.4 m wide at 1.8-2.0 m (11-13 deg as seen), 1.0 m/s
#   three          3 people 0.5 m wide at 1.2-1.6 m (18-24 deg), 1.2 m/s (the real-camera
#                  benchmark's walkers)
#   close_wide     1 person 0.7 m wide at 0.9-1.0 m (39-43 deg: fills whole windows), 0.4 m/s
#   along_turn     2 people 0.5 m wide at 1.3-1.5 m walking 0.35 m/s (0.45-0.5 deg/frame:
#                  about the robot's turn rate, one of them with it when its direction is)
#   fast           2 people 0.5 m wide at 1.3-1.6 m, 3.0 m/s (3.6-4.4 deg/frame)
#   third_of_ring  5 people 0.6 m wide at 1.2-1.6 m (22-28 deg each, a third of the ring)
#   driving        2 people 0.5 m wide at 1.5-2.0 m, 1.2 m/s, the robot driving straight
#                  (1 cm/frame) in the box room instead of turning in place
# Motions: `slow_turn` (yaw 0.3..0.6 deg/frame, positive, in a sphere scene), `straight`
# (translation 1 cm/frame along x in the 6 x 5 m box room). Scenes: the room pool's textures
# (tools/common/pool_rooms.sh) indoor, park and office (tuning) and indoor_t270 and
# park_m240 (report-only: reported, never used to choose a setting).
# Each people render is replayed with the defaults, with `pipeline.moving_content: false`
# (the pixel check off), with `pipeline.ring_consensus: false` (the fit's ring consensus
# off) and with `pipeline.translation_shrinkage: 0`, each twin with the defaults and with the
# shrinkage off; omnipose-eval gives the per-pair
# rotation eps (RMSE of the relative-rotation error angle, mrad). Writes OUTDIR/PEOPLE.md
# (command, date, version, one row per render with its ratios to the twin, and per group and
# situation the median and the worst) and every render's dataset, trajectories and logs.
#
# Usage: tools/people_benchmark.sh [--publish] [OUTDIR]    (default OUTDIR build/people)
#   --publish   also copy OUTDIR/PEOPLE.md to docs/results/PEOPLE.md
# Environment (defaults in brackets):
#   BUILD_DIR   [build]  binaries in BUILD_DIR/bin; built first when missing
#   DATA_DIR    [../shared/data/equirect]  where the park photo is
#   FRAMES      [60]     frames per render, at least 10
#   SUPERSAMPLE [2]      renderer anti-aliasing: K x K rays per pixel
#   SITUATIONS  [all]    situation names separated by spaces (a quick check)
#   SCENES      [all]    scene names separated by spaces
#   GYRO        [0]      1: every render carries the robot's gyro (imu.csv and the
#                        calibration's imu section, 200 Hz, bench_gyro_model; the frames the
#                        same), so the replays combine it with the images (pipeline.gyro_fusion);
#                        docs/results/experiments/gyro_fusion_people.sh compares with it off
# Nothing is sent on the network; everything is seeded (the same build gives the same table).
# shellcheck source=tools/common/benchmark.sh
source "$(dirname "$0")/common/benchmark.sh"
# shellcheck source=tools/common/pool_rooms.sh
source "$(dirname "$0")/common/pool_rooms.sh"
bench_args people_benchmark people -- "$@"
frames=${FRAMES:-60}
supersample=${SUPERSAMPLE:-2}
[[ "$frames" =~ ^[0-9]+$ ]] && [ "$frames" -ge 10 ] ||
  { echo "people_benchmark: FRAMES=$frames is not a whole number of at least 10" >&2; exit 2; }
bin=$build/bin
bench_command_line tools/people_benchmark.sh "$@" -- BUILD_DIR DATA_DIR FRAMES SUPERSAMPLE SITUATIONS SCENES
bench_tools "$build" omnipose-synth omnipose-replay omnipose-eval omnipose-equirect
bench_version "$bin"

# name|walkers|distance|motion
all_situations=(
  "narrow_far|1,0.4,1.8,1.0|1.8,2.0|slow_turn"
  "three|3,0.5,1.8,1.2|1.2,1.6|slow_turn"
  "close_wide|1,0.7,1.8,0.4|0.9,1.0|slow_turn"
  "along_turn|2,0.5,1.8,0.35|1.3,1.5|slow_turn"
  "fast|2,0.5,1.8,3.0|1.3,1.6|slow_turn"
  "third_of_ring|5,0.6,1.8,1.2|1.2,1.6|slow_turn"
  "driving|2,0.5,1.8,1.2|1.5,2.0|straight"
)
bench_pick people_benchmark situation "${SITUATIONS:-}" "${all_situations[@]}"
situations=("${picked[@]}")

bench_fresh_out people_benchmark motions
out=$(realpath "$out")
pool_rooms "$out"
scene_pool=()
for entry in "${rooms[@]}"; do
  case "${entry%%|*}" in indoor|park|office|indoor_t270|park_m240) scene_pool+=("$entry") ;; esac
done
bench_pick people_benchmark scene "${SCENES:-}" "${scene_pool[@]}"
scenes=("${picked[@]}")

bench_slow_turn_motion "$out/motions/slow_turn.yaml" "$frames"
cat > "$out/motions/straight.yaml" <<YAML
# The robot driving straight ahead at 0.3 m/s (1 cm per frame) from the room's centre.
seed: 0
frame_rate: 30
frames: $frames
segments:
  - {frames: $((frames - 1)), translation: {step_m: 0.01, direction: [1, 0, 0]}}
YAML
printf 'pipeline:\n  fftw_wisdom: "%s"\n' "$out/people.wisdom" > "$out/default.yaml"
printf 'pipeline:\n  fftw_wisdom: "%s"\n  moving_content: false\n' "$out/people.wisdom" > "$out/check_off.yaml"
printf 'pipeline:\n  fftw_wisdom: "%s"\n  ring_consensus: false\n' "$out/people.wisdom" > "$out/consensus_off.yaml"
printf 'pipeline:\n  fftw_wisdom: "%s"\n  translation_shrinkage: 0\n' "$out/people.wisdom" > "$out/shrinkage_off.yaml"

seed=301
common=(--frames "$frames" --seed "$seed" --supersample "$supersample" --noise 3 --jpeg 90
        --readout 0 --quiet)
case "${GYRO:-0}" in
  0) ;;
  1) read -r -a gyro_flags <<< "--gyro-rate 200 $bench_gyro_model"; common+=("${gyro_flags[@]}") ;;
  *) echo "people_benchmark: GYRO=$GYRO is neither 0 nor 1" >&2; exit 2 ;;
esac
# render DIR PHOTO TEXTURE_OPTIONS MOTION [WALKER OPTIONS...]: a dataset in DIR/dataset.
render() {
  local dir=$1 photo=$2 texture=$3 motion=$4 scene=sphere
  shift 4
  [ "$motion" = straight ] && scene=box
  mkdir -p "$dir"
  # shellcheck disable=SC2086  # texture holds whitespace-separated options
  "$bin/omnipose-synth" --texture "$photo" $texture --out "$dir/dataset" --scene "$scene" \
    --motion "$out/motions/$motion.yaml" "${common[@]}" "$@" > "$dir/synth.log" 2>&1 || {
    echo "people_benchmark: omnipose-synth failed for $dir, see $dir/synth.log" >&2
    cat "$dir/synth.log" >&2; exit 1; }
}
# eps DIR CONFIG NAME: replays DIR/dataset with CONFIG and prints its rotation eps, mrad.
eps() {
  local dir=$1 config=$2 name=$3
  "$bin/omnipose-replay" "$dir/dataset" --config "$config" --quiet --out "$dir/$name.tum" \
    > "$dir/$name.txt" 2> "$dir/$name.log" ||
    { echo "people_benchmark: omnipose-replay failed for $dir ($name), see $dir/$name.log" >&2; exit 1; }
  "$bin/omnipose-eval" "$dir/dataset/groundtruth.tum" "$dir/$name.tum" \
    --json "$dir/$name.eval.json" > "$dir/$name.eval.txt"
  # The JSON's eps at full precision (the table's rad column has 1e-6: 5 % of a park pair's).
  python3 - "$dir/$name.eval.json" <<'PY' ||
import json, sys
print("%.5f" % (1e3 * json.load(open(sys.argv[1]))[0]["eps"]["rmse"]))
PY
    { echo "people_benchmark: no eps in $dir/$name.eval.json" >&2; exit 1; }
}

rows=$out/rows.tsv
: > "$rows"
scene_index=0
for scene_entry in "${scenes[@]}"; do
  IFS='|' read -r scene group photo texture <<< "$scene_entry"
  scene_index=$((scene_index + 1))
  declare -A twin_eps=() twin_shrinkage_off=()
  situation_index=0
  for situation in "${situations[@]}"; do
    IFS='|' read -r name walkers distance motion <<< "$situation"
    situation_index=$((situation_index + 1))
    if [ -z "${twin_eps[$motion]:-}" ]; then
      render "$out/$scene/twin_$motion" "$photo" "$texture" "$motion"
      twin_eps[$motion]=$(eps "$out/$scene/twin_$motion" "$out/default.yaml" default)
      twin_shrinkage_off[$motion]=$(eps "$out/$scene/twin_$motion" "$out/shrinkage_off.yaml" \
        shrinkage_off)
    fi
    dir=$out/$scene/$name
    walker_seed=$((1000 + 10 * situation_index + scene_index))
    render "$dir" "$photo" "$texture" "$motion" --walkers "$walkers" \
      --walker-distance "$distance" --walker-seed "$walker_seed"
    with=$(eps "$dir" "$out/default.yaml" default)
    without=$(eps "$dir" "$out/check_off.yaml" check_off)
    no_consensus=$(eps "$dir" "$out/consensus_off.yaml" consensus_off)
    no_shrinkage=$(eps "$dir" "$out/shrinkage_off.yaml" shrinkage_off)
    printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$scene" "$group" "$name" \
      "$walker_seed" "$with" "$without" "${twin_eps[$motion]}" "$no_consensus" "$no_shrinkage" \
      "${twin_shrinkage_off[$motion]}" >> "$rows"
    printf '== %-12s %-14s eps %7s mrad (check off %7s, consensus off %7s, shrinkage off %7s), twin %7s (shrinkage off %7s)\n' \
      "$scene" "$name" "$with" "$without" "$no_consensus" "$no_shrinkage" "${twin_eps[$motion]}" \
      "${twin_shrinkage_off[$motion]}"
  done
  unset twin_eps twin_shrinkage_off
done

elapsed=$(( $(date +%s) - start ))
python3 - "$rows" "$out/PEOPLE.md" "$command_line" "$version" "$elapsed" "$frames" "$supersample" \
  "${GYRO:-0}" <<'PY'
import statistics, sys, time
rows_path, report, command, version, elapsed, frames, supersample, gyro = sys.argv[1:9]
rows = [line.rstrip("\n").split("\t") for line in open(rows_path) if line.strip()]
def ratio(a, b):
    return float(a) / float(b) if float(b) > 0 else float("inf")
lines = [
    "## People walking around the robot: each render against its twin", "",
    "Generated by `%s` on %s with %s in %d min %d s." % (
        command, time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), version,
        int(elapsed) // 60, int(elapsed) % 60), "",
    "%s frames per render, %s x %s rays per pixel, noise sigma 3, JPEG 90, global shutter, the "
    "default lens%s (tools/people_benchmark.sh names each situation). eps: the per-pair rotation "
    "error's RMSE, mrad (`omnipose-eval`); default: `omnipose-replay` with the defaults; check "
    "off: `pipeline.moving_content: false` (the pixel check); consensus off: "
    "`pipeline.ring_consensus: false` (the fit's ring consensus); shrinkage off: "
    "`pipeline.translation_shrinkage: 0` (tau as fitted); twin: the same render without the "
    "people, with the defaults (twin, shrinkage off: and with the shrinkage off). The "
    "report-only scenes are never used to choose a setting." % (
        frames, supersample, supersample,
        ", the robot's gyro beside each render (GYRO=1: 200 Hz, bias 0.5 deg/s)" if gyro == "1"
        else ""),
    "",
    "| scene | group | situation | walker seed | eps default | eps check off "
    "| eps consensus off | eps shrinkage off | eps twin | eps twin, shrinkage off "
    "| default / twin | check off / twin | consensus off / twin "
    "| default / check off | default / consensus off | default / shrinkage off "
    "| twin / twin, shrinkage off |",
    "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
]
for scene, group, name, seed, with_, without, twin, no_consensus, no_shrink, twin_ns in rows:
    lines.append("| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %.2f | %.2f | %.2f | %.2f "
                 "| %.2f | %.3f | %.3f |" % (
        scene, group, name, seed, with_, without, no_consensus, no_shrink, twin, twin_ns,
        ratio(with_, twin), ratio(without, twin), ratio(no_consensus, twin),
        ratio(with_, without), ratio(with_, no_consensus), ratio(with_, no_shrink),
        ratio(twin, twin_ns)))
lines += ["", "Over each group, and each situation over the tuning scenes (median / worst):", "",
          "| rows | renders | default / twin | check off / twin | consensus off / twin "
          "| default / check off | default / consensus off | default / shrinkage off |",
          "|---|---:|---:|---:|---:|---:|---:|---:|"]
def summary(label, subset):
    if not subset:
        return
    cols = [[ratio(r[4], r[6]) for r in subset], [ratio(r[5], r[6]) for r in subset],
            [ratio(r[7], r[6]) for r in subset], [ratio(r[4], r[5]) for r in subset],
            [ratio(r[4], r[7]) for r in subset], [ratio(r[4], r[8]) for r in subset]]
    lines.append("| %s | %d | %s |" % (label, len(subset), " | ".join(
        "%.2f / %.2f" % (statistics.median(c), max(c)) for c in cols)))
for group in ("tuning", "report-only"):
    summary("**%s**" % group, [r for r in rows if r[1] == group])
for name in dict.fromkeys(r[2] for r in rows):
    summary("%s (tuning)" % name, [r for r in rows if r[2] == name and r[1] == "tuning"])
open(report, "w").write("\n".join(lines) + "\n")
PY
echo "== report: $out/PEOPLE.md"
if [ "$publish" = 1 ]; then
  mkdir -p docs/results
  cp "$out/PEOPLE.md" docs/results/PEOPLE.md
  echo "== published docs/results/PEOPLE.md"
fi
