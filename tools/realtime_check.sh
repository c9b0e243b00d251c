#!/usr/bin/env bash
# Realtime check: omniposed replays a rendered recording with `realtime: true` at FPS frames
# per second (the file source paces frames by their timestamps, as a camera would deliver
# them) with a file:// LCM log, and the final status must show that no frame was dropped:
# received = FRAMES, skipped (stale) = 0, lost upstream (not read in time) = 0, bad = 0.
# Prints the final status (processing and latency percentiles, the load fields). The verdict is
# about this machine at the moment of the run (idle, or with --load), so it is not a test.
# Usage: tools/realtime_check.sh [--load N] [--nice K | --fifo P] [FPS] [FRAMES]
#        (default 60 fps, 180 frames)
#   --load N   N busy processes (`while :; do :; done` at normal priority) run for the duration:
#              the robot's controller and camera stack sharing the cores
#   --nice K   omniposed runs at niceness K, -20..19 (a lower priority than the load when K > 0;
#              K < 0, as the systemd unit's Nice=-5, needs root or an RLIMIT_NICE that permits it)
#   --fifo P   daemon.yaml asks for SCHED_FIFO at priority P (scheduling.fifo_priority, 1-99:
#              needs root or CAP_SYS_NICE; omniposed refuses to start without)
# Environment: BUILD_DIR (default build; built with tools/build.sh when a program is missing),
# THREADS (pipeline.threads, default 0 = all online cores), PICTURES=HZ (the daemon also makes
# panorama pictures for a viewer at HZ: lcm.panorama_channel), KEEP=1 keeps the working directory.
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=tools/common/final_status.sh
source tools/common/final_status.sh
usage() {
  echo "usage: tools/realtime_check.sh [--load N] [--nice K | --fifo P] [FPS] [FRAMES]" >&2
  exit 2
}
load=0
nice_level=0
fifo=0
while [ $# -gt 0 ]; do
  case "$1" in
    --load) [ $# -ge 2 ] || usage; load=$2; shift 2 ;;
    --nice) [ $# -ge 2 ] || usage; nice_level=$2; shift 2 ;;
    --fifo) [ $# -ge 2 ] || usage; fifo=$2; shift 2 ;;
    -*) usage ;;
    *) break ;;
  esac
done
fps=${1:-60}
frames=${2:-180}
if ! [[ "$fps" =~ ^[0-9]+$ && "$frames" =~ ^[0-9]+$ && "$load" =~ ^[0-9]+$ &&
        "$nice_level" =~ ^-?[0-9]+$ && "$fifo" =~ ^[0-9]+$ ]] || [ "$fps" -lt 1 ] ||
   [ "$frames" -lt 2 ] || [ "$fifo" -gt 99 ] || [ "$nice_level" -lt -20 ] || [ "$nice_level" -gt 19 ] ||
   { [ "$fifo" -gt 0 ] && [ "$nice_level" -ne 0 ]; }; then
  usage
fi
# nice(1) runs the command at its own niceness when it may not lower it: refuse instead.
if [ "$nice_level" -lt 0 ] && [ -n "$(nice -n "$nice_level" true 2>&1)" ]; then
  echo "realtime_check: --nice $nice_level: not permitted here (needs root, CAP_SYS_NICE or an" \
    "RLIMIT_NICE of at least $((20 - nice_level)))" >&2
  exit 2
fi
bin=${BUILD_DIR:-build}/bin
threads=${THREADS:-0}
pictures=${PICTURES:-0}
if ! [[ "$pictures" =~ ^[0-9]+([.][0-9]+)?$ ]]; then
  echo "realtime_check: PICTURES=$pictures: expected a rate in Hz (0: none)" >&2
  exit 2
fi
lcm_pictures=""
if [ "$pictures" != 0 ]; then lcm_pictures=", panorama_channel: OMNI_PANORAMA, panorama_hz: $pictures"; fi
if [ ! -x "$bin/omniposed" ] || [ ! -x "$bin/omnipose-synth" ] || [ ! -x "$bin/omnipose-listen" ]; then
  bash tools/build.sh
fi

work=$(mktemp -d "${TMPDIR:-/tmp}/omnipose-realtime-XXXXXX")
busy=()
stop_load() {
  if [ ${#busy[@]} -gt 0 ]; then kill "${busy[@]}" 2>/dev/null || true; fi
  busy=()
}
cleanup() {
  stop_load
  if [ "${KEEP:-0}" = 1 ]; then echo "realtime_check: kept $work"; else rm -rf "$work"; fi
}
trap cleanup EXIT

"$bin/omnipose-synth" --texture tests/data/equirect/indoor_1024x512.jpg --out "$work/data" \
  --preset mixed --frames "$frames" --seed 11 --supersample 1 --quiet >"$work/synth.log" 2>&1
# The renderer stamps frames at its script's rate; re-stamp them at FPS.
awk -v fps="$fps" '{ printf "%s %.6f\n", $1, (NR - 1) / fps }' "$work/data/timestamps.txt" \
  >"$work/timestamps.txt"
mv "$work/timestamps.txt" "$work/data/timestamps.txt"
cat >"$work/daemon.yaml" <<YAML
source: {type: file, path: data, realtime: true, loop: false}
calibration: data/calibration.yaml
pipeline: {threads: $threads}
scheduling: {fifo_priority: $fifo}
lcm: {url: "file://$work/run.lcm?mode=w", status_hz: 1$lcm_pictures}
YAML

for ((i = 0; i < load; ++i)); do
  bash -c 'while :; do :; done' &
  busy+=($!)
done
echo "realtime_check: $frames frames at $fps fps, pipeline.threads $threads, pictures $pictures Hz, $load busy processes," \
  "niceness $nice_level, SCHED_FIFO priority $fifo (0: not), load average" \
  "$(cut -d' ' -f1-3 /proc/loadavg)"
rc=0
nice -n "$nice_level" "$bin/omniposed" --config "$work/daemon.yaml" 2>"$work/daemon.err" || rc=$?
stop_load
if [ "$rc" -ne 0 ]; then
  echo "realtime_check: FAIL: omniposed exited with $rc" >&2
  tail -20 "$work/daemon.err" >&2
  exit 1
fi
read_final_status "$bin" "$work/run.lcm" "$work/listen.txt" realtime_check || exit 1
echo "realtime_check: $FINAL_STATUS"
received=$(status_count received)
skipped=$(status_count "skipped (stale)")
bad=$(status_count bad)
lost=$(status_count upstream)
if [ "$received" -eq "$frames" ] && [ "$skipped" -eq 0 ] && [ "$bad" -eq 0 ] && [ "$lost" -eq 0 ]; then
  echo "realtime_check: PASS: all $frames frames processed at $fps fps, none dropped"
else
  echo "realtime_check: FAIL: received $received of $frames, skipped $skipped, lost upstream $lost, bad $bad" >&2
  exit 1
fi
