#!/usr/bin/env bash
# Drift benchmark: how far the chained attitude (what a robot controller
# integrates) wanders from the truth over long sequences, for omnipose-replay and for the
# daemon omniposed on the same recordings. Renders seeded sequences at 30 fps with exact
# ground truth from the real photo tests/data/equirect/indoor_1024x512.jpg through a
# non-linear lens (tests/data/catadioptric/steep_mirror_800_ocamcalib.txt, the steep mirror
# of Table III in docs/results/RESULTS.md), with sensor noise and exposure flicker:
#   still            240 frames standing still (tools/drift/still.yaml)
#   swing            yaw +120 / -120 / 0 deg in 10 s with track vibration (tools/drift/swing.yaml)
#   loop             a 2.0 x 1.4 m rectangle in the box room, four 90-degree turns in place
#                    (tools/drift/rectangle.yaml)
#   swing + faults   the swing's frames damaged by tools/drift/damage_frames.py: one corrupt
#                    frame mid-turn, ten corrupt in a row, a 2 s outage (60 frames missing),
#                    each alone and all three together
#   swing + gyro     the swing with the robot's gyro (imu.csv, 200 Hz) beside the same frames,
#                    and its outage; the rectangle with the gyro: replayed only (omniposed
#                    takes a gyro over LCM or IIO)
# Every sequence ends with the attitude it began with. Each is replayed by omnipose-replay
# (its TUM output of the odometry's pose, --out-odometry: what the controller integrates,
# never corrected by a loop closure; tools/loop_benchmark.sh measures the map pose) and by
# omniposed (file source, realtime, LCM to a file:// log decoded by omnipose-listen --tum,
# the pose_t odometry pose), and scored by `omnipose-eval --drift` (omnipose::evaluateDrift):
# end-point rotation error, ATE rotation RMSE (first pose aligned, no scale), the maximum on
# the way, and the per-pair eps. Writes
#   OUTDIR/DRIFT.md          Markdown: command, date, version, machine, the table
# plus the datasets, trajectories, logs and omnipose-eval outputs of every sequence.
#
# Usage: tools/drift_benchmark.sh [--publish] [--evo] [OUTDIR]    (default OUTDIR build/drift)
#   --publish   also copy OUTDIR/DRIFT.md to docs/results/DRIFT.md (with KEYFRAME_SLOTS=0:
#               to docs/results/DRIFT_FRAME_TO_FRAME.md, the frame-to-frame chain's table
#               beside the defaults' one; another KEYFRAME_SLOTS is not published)
#   --evo       cross-check every ATE with evo_ape (PyPI package `evo`, installed on first use
#               into a venv BUILD_DIR/evo-venv; needs the package index)
# Environment (defaults in brackets):
#   BUILD_DIR   [build]  binaries in BUILD_DIR/bin; built first when missing
#   SUPERSAMPLE [2]      renderer anti-aliasing: K x K rays per pixel
#   KEYFRAME_SLOTS [the default, 4]  keyframes.slots of the replay's and the daemon's
#               configuration (omnipose/odometry.hpp), to measure the keyframe policy
#   WISDOM      [BUILD_DIR/drift.wisdom]  FFTW wisdom shared by every replay and daemon run
#               (made by the first run that lacks a plan, reused afterwards)
#   IFMI_PIPELINE [""]  more keys of the replay's and the daemon's `pipeline:` section
#               (daemon.yaml's), "key: value" entries separated by ';', e.g.
#               IFMI_PIPELINE="noise_weighting: true", to measure what a setting is worth
#               (not with --publish: the published results are those of the defaults)
# Nothing is sent on the network: the daemon publishes to an LCM log file. Everything is
# seeded: the same build gives the same datasets and replays; the daemon runs in real time
# (30 fps), so a loaded machine may make it skip frames (counted in the table).
# shellcheck source=tools/common/benchmark.sh
source "$(dirname "$0")/common/benchmark.sh"
# shellcheck source=tools/common/final_status.sh
source "$(dirname "$0")/common/final_status.sh"
bench_args drift_benchmark drift --evo -- "$@"
supersample=${SUPERSAMPLE:-2}
bin=$build/bin
bench_command_line tools/drift_benchmark.sh "$@" -- BUILD_DIR SUPERSAMPLE KEYFRAME_SLOTS WISDOM
bench_ifmi_pipeline drift_benchmark
if [ "$publish" = 1 ] && [ -n "${KEYFRAME_SLOTS:-}" ] && [ "$KEYFRAME_SLOTS" != 0 ]; then
  echo "drift_benchmark: --publish publishes the defaults or KEYFRAME_SLOTS=0 (frame to frame)" >&2
  exit 2
fi

bench_tools "$build" omnipose-synth omnipose-replay omnipose-eval omniposed omnipose-listen

photo=$root/tests/data/equirect/indoor_1024x512.jpg
lens=$root/tests/data/catadioptric/steep_mirror_800_ocamcalib.txt
for f in "$photo" "$lens" tools/drift/still.yaml tools/drift/swing.yaml tools/drift/rectangle.yaml; do
  [ -f "$f" ] || { echo "drift_benchmark: missing $f" >&2; exit 1; }
done

evo_ape=""
if [ "$evo" = 1 ]; then
  venv=$(realpath -m "$build/evo-venv")
  if [ ! -x "$venv/bin/evo_ape" ]; then
    echo "== installing evo into $venv"
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet evo
  fi
  evo_ape=$venv/bin/evo_ape
  [ -x "$evo_ape" ] || { echo "drift_benchmark: $evo_ape missing after installing evo" >&2; exit 1; }
fi

bench_fresh_out drift_benchmark
out=$(realpath "$out")
wisdom=$(realpath -m "${WISDOM:-$build/drift.wisdom}")

bench_ocamcalib_calibration "$out/calibration.yaml" "$lens"
keyframes_yaml="" keyframes_title=""
if [ -n "${KEYFRAME_SLOTS:-}" ]; then
  keyframes_yaml="keyframes: {slots: $KEYFRAME_SLOTS}"
  keyframes_title=", \`$keyframes_yaml\`"
fi
printf 'pipeline:\n  fftw_wisdom: "%s"\n%s%s\n' "$wisdom" "$ifmi_pipeline_yaml" "$keyframes_yaml" \
  > "$out/replay.yaml"

# ---------------------------------------------------------------------------- suite
# Sensor: noise sigma 3 grey levels, per-frame exposure gain 1 + N(0, 0.05) and offset
# N(0, 3) grey levels (flicker); lossless PNG frames.
sensor="--noise 3 --exposure-jitter 0.05 --exposure-offset 3"
# name | label | source: render:MOTION:SCENE or copy:NAME | damage_frames.py arguments
# Frames of the swing (tools/drift/swing.yaml): yaw +120 deg at frame 75, -120 deg at 225.
# Frame 37 is mid-turn (yaw +59 deg); around 110..119 the camera turns 17.6 deg from the last
# good frame to the next; the outage 150..209 is mid-turn (the yaw is +1.6 deg before it and
# -96 deg after it: 97.6 deg turned unseen).
suite=(
  "still|standing still, 240 frames|render:still:sphere|"
  "swing|yaw swing +-120 deg, 10 s, vibration +-0.5 deg up to 9 Hz|render:swing:sphere|"
  "loop|2.0 x 1.4 m rectangle, four 90-deg turns (box room)|render:rectangle:box|"
  "swing_corrupt1|swing, 1 corrupt frame mid-turn (frame 37)|copy:swing|--corrupt 37"
  "swing_corrupt10|swing, 10 corrupt frames in a row (110-119)|copy:swing|--corrupt 110-119"
  "swing_outage|swing, 2 s outage (frames 150-209 missing)|copy:swing|--remove 150-209"
  "swing_faults|swing, all three faults|copy:swing|--corrupt 37 --corrupt 110-119 --remove 150-209"
  "swing_gyro|swing, 200 Hz gyro (replay)|render:swing:sphere:gyro|"
  "swing_outage_gyro|swing, 2 s outage, 200 Hz gyro (replay)|copy:swing_gyro|--remove 150-209"
  "loop_gyro|rectangle, 200 Hz gyro (replay)|render:rectangle:box:gyro|"
)
# The robot's gyro (render:...:gyro): imu.csv at 200 Hz beside the same frames, white noise
# 0.005 deg/s/sqrt(Hz), bias 0.5 deg/s, its clock 12.3 ms behind the camera's, mounted 40 deg
# off the camera's axes, its exact calibration in calibration.yaml; the replay reads it (the
# daemon takes a gyro over LCM or IIO only, so these rows have no daemon run).
gyro="--gyro-rate 200 $bench_gyro_model"
# omniposed on $dir/dataset (file source, realtime), its poses decoded from its LCM log, its
# counts, and both runs scored.
run_daemon() {
  cat > "$dir/daemon.yaml" <<YAML
source: {type: file, path: "$dir/dataset", realtime: true}
calibration: "$dir/dataset/calibration.yaml"
pipeline:
  fftw_wisdom: "$wisdom"
$ifmi_pipeline_yaml$keyframes_yaml
lcm: {url: "file://$dir/daemon.lcm?mode=w", status_hz: 1}
YAML
  "$bin/omniposed" --config "$dir/daemon.yaml" > "$dir/daemon.out" 2> "$dir/daemon.err" || {
    echo "   $name: omniposed failed (exit $?), see $dir/daemon.err" >&2; tail -5 "$dir/daemon.err" >&2; exit 1; }
  "$bin/omnipose-listen" --url "file://$dir/daemon.lcm?speed=0" --tum "$dir/daemon.tum" \
    > "$dir/daemon.listen" 2> "$dir/daemon.listen.err" || {
    echo "   $name: omnipose-listen failed, see $dir/daemon.listen.err" >&2; exit 1; }
  final=$(grep '^status (final):' "$dir/daemon.listen" | tail -1)
  [ -n "$final" ] || { echo "   $name: no final status in $dir/daemon.lcm" >&2; exit 1; }
  FINAL_STATUS=$final
  segments=$(grep '^pose ' "$dir/daemon.listen" | awk '{print $7}' | sort -un | wc -l)
  printf '%s\t%s\t%s\t%s\t%s\t%s\n' "$(status_count processed)" "$(status_count 'skipped (stale)')" \
    "$(status_count bad)" "$(status_count poses)" "$segments" "$(status_count received)" > "$dir/daemon.counts"

  "$bin/omnipose-eval" --drift "$dir/dataset/groundtruth.tum" "$dir/replay.tum" "$dir/daemon.tum" \
    --json "$dir/drift.json" > "$dir/drift.txt"
}

echo "== drift benchmark: ${#suite[@]} sequences, output $out"

for entry in "${suite[@]}"; do
  IFS='|' read -r name label source damage <<< "$entry"
  dir=$out/$name
  mkdir -p "$dir"
  t0=$(date +%s)
  case "$source" in
    render:*)
      IFS=':' read -r _ motion scene with <<< "$source"
      extra=""
      [ "$with" = gyro ] && extra=$gyro
      # shellcheck disable=SC2086  # sensor and extra hold whitespace-separated options
      "$bin/omnipose-synth" --texture "$photo" --out "$dir/dataset" --motion "tools/drift/$motion.yaml" \
        --scene "$scene" --calibration "$out/calibration.yaml" --supersample "$supersample" \
        $sensor $extra --quiet > "$dir/synth.log"
      ;;
    copy:*)
      # Hard links: damage_frames.py replaces the files it damages, so the original stays.
      cp -al "$out/${source#copy:}/dataset" "$dir/dataset"
      # shellcheck disable=SC2086  # damage holds whitespace-separated options
      python3 tools/drift/damage_frames.py "$dir/dataset" $damage > "$dir/damage.log"
      ;;
  esac
  frames=$(find "$dir/dataset/frames" -type f | wc -l)
  gt_frames=$(grep -vc '^#' "$dir/dataset/groundtruth.tum")

  replay_line=$("$bin/omnipose-replay" "$dir/dataset" --config "$out/replay.yaml" --quiet \
                  --out-odometry "$dir/replay.tum" --relative "$dir/replay.csv" 2> "$dir/replay.log" | tail -n 1) || {
    echo "   $name: omnipose-replay failed, see $dir/replay.log" >&2; tail -5 "$dir/replay.log" >&2; exit 1; }

  if [ -f "$dir/dataset/imu.csv" ]; then
    # A render with the gyro has its twin's frames, bit for bit (swing_gyro: swing's).
    if [[ $source == render:*:gyro ]]; then
      twin=${name%_gyro}
      diff -rq "$out/$twin/dataset/frames" "$dir/dataset/frames" > /dev/null ||
        { echo "   $name: its frames differ from $twin's: the gyro changed the render" >&2; exit 1; }
    fi
    "$bin/omnipose-eval" --drift "$dir/dataset/groundtruth.tum" "$dir/replay.tum" \
      --json "$dir/drift.json" > "$dir/drift.txt"
  else
    run_daemon
  fi

  evo_rmse="-	-"
  [ -f "$dir/daemon.tum" ] || evo_rmse="-	–"
  if [ -n "$evo_ape" ]; then
    evo_of() {
      "$evo_ape" tum "$dir/dataset/groundtruth.tum" "$1" --pose_relation angle_deg --align_origin \
        > "$2" 2>&1 || { echo "   $name: evo_ape failed, see $2" >&2; cat "$2" >&2; exit 1; }
      awk '$1 == "rmse" { print $2 }' "$2"
    }
    evo_daemon="–"
    [ -f "$dir/daemon.tum" ] && evo_daemon=$(evo_of "$dir/daemon.tum" "$dir/evo_daemon.txt")
    evo_rmse="$(evo_of "$dir/replay.tum" "$dir/evo_replay.txt")	$evo_daemon"
  fi
  printf '%s\t%s\t%s\t%s\t%s\n' "$label" "$frames" "$gt_frames" "$replay_line" "$evo_rmse" > "$dir/row.tsv"

  printf '== %-16s %3ds  %s\n' "$name" $(( $(date +%s) - t0 )) "$replay_line"
  sed 's/^/   /' "$dir/drift.txt" | grep -E 'end-point|ATE|eps' | sed "s|$dir/||"
  [ -f "$dir/daemon.tum" ] && printf '   daemon: %s\n' "$(sed 's/^status (final): //; s/ | source.*//' <<< "$final")"
done

# ---------------------------------------------------------------------------- table
elapsed=$(( $(date +%s) - start ))
load_end=$(cut -d' ' -f1-3 /proc/loadavg)
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//')
bench_version "$bin"
names=()
for entry in "${suite[@]}"; do names+=("${entry%%|*}"); done

python3 - "$out" "$evo" "${names[@]}" > "$out/table.md" <<'PY'
import json, math, sys
out, evo, names = sys.argv[1], sys.argv[2] == "1", sys.argv[3:]
deg = 180 / math.pi
def f(x, digits=3):
    return ("%%.%df" % digits) % x
print("| sequence | frames | replay end-point [deg] | replay ATE [deg] | replay max [deg] "
      "| daemon end-point [deg] | daemon ATE [deg] | daemon max [deg] "
      "| per-pair eps [mrad] replay / daemon | evo ATE [deg] replay / daemon "
      "| replay pairs missing | daemon processed / bad / skipped / lost, segments |")
print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|")
for name in names:
    label, frames, gt_frames, replay_line, evo_replay, evo_daemon = \
        open("%s/%s/row.tsv" % (out, name)).read().rstrip("\n").split("\t")
    runs = json.load(open("%s/%s/drift.json" % (out, name)))
    replay, daemon = runs[0], (runs[1] if len(runs) > 1 else None)
    def end(d):
        s = f(d["end_error"] * deg)
        return s if d["end_is_last"] else s + " (at %.2f s)" % d["end_timestamp"]
    frames_cell = frames if frames == gt_frames else "%s of %s" % (frames, gt_frames)
    evo_cell = "%s / %s" % (evo_replay, evo_daemon) if evo else "–"
    if daemon:
        processed, skipped, bad, lost, segments, received = \
            open("%s/%s/daemon.counts" % (out, name)).read().split()
        daemon_cells = (end(daemon), f(daemon["ate_rmse"] * deg), f(daemon["max_error"] * deg))
        eps_cell = "%s / %s" % (f(replay["eps"]["rmse"] * 1e3), f(daemon["eps"]["rmse"] * 1e3))
        counts_cell = "%s / %s / %s / %s, %s" % (processed, bad, skipped, lost, segments)
    else:
        daemon_cells = ("–", "–", "–")
        eps_cell = "%s / –" % f(replay["eps"]["rmse"] * 1e3)
        counts_cell = "no daemon run (gyro)"
    print("| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %d | %s |" % (
        (label, frames_cell, end(replay), f(replay["ate_rmse"] * deg), f(replay["max_error"] * deg))
        + daemon_cells + (eps_cell, evo_cell, replay["pairs_missing"], counts_cell)))
PY

{
  echo "## Drift of the chained attitude$keyframes_title"
  echo
  echo "Generated by \`$command_line\` on $(date -u '+%Y-%m-%d %H:%M UTC') with $version."
  echo
  echo "Machine: $cpu, $(nproc) cores ($(uname -sr)); load average $load_start at the start and"
  echo "$load_end at the end. The whole benchmark took $((elapsed / 60)) min $((elapsed % 60)) s."
  echo
  echo "Data: seeded sequences at 30 fps rendered by \`omnipose-synth\` ($supersample x $supersample rays"
  echo "per pixel) with exact ground truth from the real photo \`tests/data/equirect/indoor_1024x512.jpg\`"
  echo "through the steep OCamCalib mirror of Table III (\`tests/data/catadioptric/steep_mirror_800_ocamcalib.txt\`,"
  echo "800 x 800 omni frames unwrapped to 1100 x 110), with sensor noise sigma 3 grey levels and"
  echo "exposure flicker (per-frame gain 1 + N(0, 0.05), offset N(0, 3) grey levels), PNG frames."
  echo "Motions: \`tools/drift/*.yaml\`; every sequence ends with the attitude it began with."
  echo "The swing's track vibration (roll and pitch, three sinusoids each of 1..9 Hz, peak 0.5 deg;"
  echo "\`synth::Vibration\`) is in its ground truth. The faulty swings are the swing's frames"
  echo "damaged by \`tools/drift/damage_frames.py\`: corrupt frames keep their names and timestamps"
  echo "(truncated, empty, random bytes, all-black PNG in turn); the outage's 60 frames and their"
  echo "timestamps are gone. Frame 37 is mid-turn (the camera turns 3.2 deg from frame 36 to 38);"
  echo "around frames 110-119 it turns 17.6 deg from the last good frame to the next; the outage"
  echo "is mid-turn (the yaw is +1.6 deg before it and -96 deg after it: 97.6 deg turned unseen)."
  echo "The gyro rows: the swing rendered again with the robot's gyro in imu.csv beside the same"
  echo "frames (checked bit for bit; 200 Hz, white noise 0.005 deg/s/sqrt(Hz), bias 0.5 deg/s, its"
  echo "clock 12.3 ms behind the camera's, mounted 40 deg off, the exact calibration in"
  echo "calibration.yaml), and its outage; the rectangle the same way; replayed only (omniposed"
  echo "takes a gyro over LCM or IIO)."
  echo
  echo "Runs: \`omnipose-replay\` (its TUM output) and \`omniposed\` (file source, \`realtime: true\`,"
  echo "publishing to an LCM \`file://\` log, decoded with \`omnipose-listen --tum\`) on the same"
  echo "directory, default pipeline settings${KEYFRAME_SLOTS:+ with keyframes.slots $KEYFRAME_SLOTS}${IFMI_PIPELINE:+ and pipeline keys $IFMI_PIPELINE}, one FFTW wisdom file. Scores: \`omnipose-eval --drift\`"
  echo "(\`omnipose::evaluateDrift\`): the estimate is aligned by its first pose (no scale); end-point ="
  echo "rotation error angle at the last pose (if the estimate lacks the last frame: at its last pose,"
  echo "time shown); ATE = RMSE of the rotation error angle over all estimated poses; max = its largest"
  echo "value on the way. Per-pair eps = RMSE of the relative-rotation error angle over the"
  echo "consecutive frame pairs both trajectories have (\`omnipose::evaluate\`). evo ATE = \`evo_ape tum"
  echo "GT EST --pose_relation angle_deg --align_origin\` RMSE (with \`--evo\`). Daemon counts from its"
  echo "final status: frames processed, bad, skipped as stale, poses published as lost; segments ="
  echo "chain segments in its poses. frames: \"N of M\" when M - N frames are missing."
  echo
  cat "$out/table.md"
  echo
  echo "Targets for the library: standing still end-point <= 0.02 deg, swing <= 0.05 deg,"
  echo "loop <= 0.3 deg, swing with a corrupt frame or the outage in the daemon <= 0.1 deg."
} > "$out/DRIFT.md"

echo
cat "$out/table.md"
echo
echo "== done in $((elapsed / 60)) min $((elapsed % 60)) s: $out/DRIFT.md"
if [ "$publish" = 1 ]; then
  published=docs/results/DRIFT.md
  [ -n "$keyframes_yaml" ] && published=docs/results/DRIFT_FRAME_TO_FRAME.md
  mkdir -p docs/results
  cp "$out/DRIFT.md" "$published"
  echo "== published to $published"
fi
