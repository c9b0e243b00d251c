#!/usr/bin/env bash
# Soak run with faults: omniposed on a looping file source, paced in realtime, for at least
# FRAMES received frames, with a file:// LCM log. The recording (60 rendered frames at 30 fps)
# is made hostile by tools/common/hostile_dataset.py: bad frames between the good ones
# (decompression bombs that declare 60000 x 60000 pixels, a complete 32000 x 32000 PNG,
# truncated and garbage PNG, JPEG, PGM and BMP files, an empty file), a timestamp step
# backwards and a forward jump of 1e6 s, glitch frames that decode (flipped, repeated, torn,
# noise; each crossed on every loop); a quarter of the way one frame file becomes a FIFO
# without a writer, half way the dataset directory vanishes for VANISH seconds. Every SAMPLE seconds it sends SIGHUP (the
# daemon logs its counters) and samples the daemon's resident set size (VmRSS). Then SIGTERM,
# and the checks:
#   - the daemon stops with exit code 0;
#   - every frame is counted once: received = processed + skipped + bad + lost upstream, from
#     the final status in the LCM log, and the log holds exactly `processed` poses;
#   - the faults were met and reported: bad frames, implausible frames and a source failure
#     counted, the bombs, the resynchronised jump, the re-opened source, an implausible frame
#     and the FIFO in the daemon's log (fault lines are rate-limited, so not every one is
#     printed);
#   - memory is flat: after the warm-up (the first max(1000, FRAMES/10) frames), no RSS
#     sample exceeds the first post-warm-up sample by more than RSS_TOLERANCE_KB.
# With DATASET set, that recording (a dataset directory, e.g. the loop benchmark's five laps:
# build/loops/indoor/dataset after `ROOMS=indoor tools/loop_benchmark.sh`) is looped as it is,
# with no faults: the accounting and memory checks stay (the RSS while places are made and
# loops close), and the places kept and the loops closed are reported.
# Usage: tools/soak.sh [FRAMES]   (default 10000: about 6 minutes)
# Environment: BUILD_DIR (default build; built with tools/build.sh when omniposed is missing),
# SAMPLE (seconds between samples, default 5), RSS_TOLERANCE_KB (default 512), NICE (default 10),
# VANISH (seconds the directory is away, default 2), STALL (seconds without a new frame that
# fail the run, default 60), KEEP=1 keeps the working directory, DATASET (see above).
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=tools/common/final_status.sh
source tools/common/final_status.sh
frames=${1:-10000}
if ! [[ "$frames" =~ ^[0-9]+$ ]] || [ "$frames" -lt 1 ]; then
  echo "usage: tools/soak.sh [FRAMES]" >&2
  exit 2
fi
build=${BUILD_DIR:-build}
bin=$build/bin
sample=${SAMPLE:-5}
tolerance_kb=${RSS_TOLERANCE_KB:-512}
nice_level=${NICE:-10}
vanish=${VANISH:-2}
stall=${STALL:-60}
dataset=${DATASET:-}
if [ -n "$dataset" ] && [ ! -f "$dataset/calibration.yaml" ]; then
  echo "soak: DATASET=$dataset is not a dataset directory (no calibration.yaml)" >&2
  exit 2
fi
if [ ! -x "$bin/omniposed" ] || [ ! -x "$bin/omnipose-synth" ] || [ ! -x "$bin/omnipose-listen" ]; then
  bash tools/build.sh
fi

work=$(mktemp -d "${TMPDIR:-/tmp}/omnipose-soak-XXXXXX")
pid=""
cleanup() {
  if [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null; then kill -KILL "$pid" 2>/dev/null || true; fi
  if [ "${KEEP:-0}" = 1 ]; then echo "soak: kept $work"; else rm -rf "$work"; fi
}
trap cleanup EXIT

if [ -n "$dataset" ]; then
  ln -s "$(realpath "$dataset")" "$work/data"
else
  echo "soak: rendering the recording"
  "$bin/omnipose-synth" --texture tests/data/equirect/indoor_1024x512.jpg --out "$work/data" \
    --preset mixed --frames 60 --seed 7 --supersample 1 >"$work/synth.log" 2>&1
  python3 tools/common/hostile_dataset.py "$work/data" --seed 7
fi
fifo_frame=000035.png  # far (> 200 ms) from the other faults: its line is not rate-limited away
cat >"$work/daemon.yaml" <<YAML
source: {type: file, path: data, realtime: true, loop: true}
calibration: data/calibration.yaml
lcm: {url: "file://$work/soak.lcm?mode=w", status_hz: 1}
YAML

nice -n "$nice_level" "$bin/omniposed" --config "$work/daemon.yaml" 2>"$work/daemon.err" &
pid=$!
start=$(date +%s.%N)
warmup=$(( frames / 10 > 1000 ? frames / 10 : 1000 ))
baseline_kb=""
max_after_kb=0
last_kb=0
received=0
last_received=0
last_progress=$start
vanished=0
fifo_made=0
samples=0
printf 'soak: %8s %10s %10s\n' seconds received rss_kB
while :; do
  sleep "$sample"
  if ! kill -0 "$pid" 2>/dev/null; then
    echo "soak: FAIL: omniposed died:" >&2
    tail -20 "$work/daemon.err" >&2
    exit 1
  fi
  rss_kb=$(awk '/^VmRSS:/ {print $2}' "/proc/$pid/status")
  hups=$(grep -c 'SIGHUP received' "$work/daemon.err" || true)
  kill -HUP "$pid"
  for _ in $(seq 100); do
    [ "$(grep -c 'SIGHUP received' "$work/daemon.err" || true)" -gt "$hups" ] && break
    sleep 0.05
  done
  # "SIGHUP received: ...; received N, processed N, ..."
  received=$(sed -n 's/.*SIGHUP received.* received \([0-9]*\),.*/\1/p' "$work/daemon.err" | tail -1)
  received=${received:-0}
  now=$(date +%s.%N)
  if [ "$received" -gt "$last_received" ]; then
    last_received=$received
    last_progress=$now
  elif awk -v a="$now" -v b="$last_progress" -v s="$stall" 'BEGIN {exit !(a - b > s)}'; then
    echo "soak: FAIL: no frame received for $stall s (stuck at $received)" >&2
    tail -5 "$work/daemon.err" >&2
    exit 1
  fi
  printf 'soak: %8.0f %10d %10d\n' "$(awk -v a="$now" -v b="$start" 'BEGIN {print a - b}')" "$received" "$rss_kb"
  if [ -z "$dataset" ] && [ "$vanished" -eq 0 ] && [ "$received" -ge $((frames / 2)) ]; then
    mv "$work/data" "$work/data.away"
    sleep "$vanish"
    mv "$work/data.away" "$work/data"
    vanished=1
  fi
  # A quarter of the way, while the source streams (it listed the frames when it opened):
  # a FIFO without a writer where a frame file was, read without blocking and refused.
  if [ -z "$dataset" ] && [ "$fifo_made" -eq 0 ] && [ "$received" -ge $((frames / 4)) ]; then
    rm "$work/data/frames/$fifo_frame"
    mkfifo "$work/data/frames/$fifo_frame"
    fifo_made=1
  fi
  samples=$((samples + 1))
  last_kb=$rss_kb
  if [ "$received" -ge "$warmup" ]; then
    if [ -z "$baseline_kb" ]; then
      baseline_kb=$rss_kb
    elif [ "$rss_kb" -gt "$max_after_kb" ]; then
      max_after_kb=$rss_kb
    fi
  fi
  if [ "$received" -ge "$frames" ]; then break; fi
done

kill -TERM "$pid"
rc=0
wait "$pid" || rc=$?
pid=""
end=$(date +%s.%N)
if [ "$rc" -ne 0 ]; then
  echo "soak: FAIL: omniposed exited with $rc" >&2
  tail -20 "$work/daemon.err" >&2
  exit 1
fi

read_final_status "$bin" "$work/soak.lcm" "$work/listen.txt" soak || exit 1
final=$FINAL_STATUS
received=$(status_count received)
f_processed=$(status_count processed)
skipped=$(status_count "skipped (stale)")
bad=$(status_count bad)
implausible=$(status_count implausible)
lost=$(status_count upstream)
failures=$(sed -n 's/.* source failures \([0-9]*\).*/\1/p' <<<"$final")
poses=$(grep -c '^pose seq ' "$work/listen.txt" || true)
seconds=$(awk -v a="$end" -v b="$start" 'BEGIN {print a - b}')

fail=0
echo "soak: final status: $final"
if [ "$received" -ne $((f_processed + skipped + bad + lost)) ]; then
  echo "soak: FAIL: received $received != processed $f_processed + skipped $skipped + bad $bad + lost $lost" >&2
  fail=1
fi
if [ -z "$dataset" ]; then
  if [ "$bad" -eq 0 ] || [ "${failures:-0}" -eq 0 ] || [ "${implausible:-0}" -eq 0 ]; then
    echo "soak: FAIL: the faults were not all met: bad frames $bad, implausible ${implausible:-?}, source failures ${failures:-?}" >&2
    fail=1
  fi
  for fault in "60000x60000" "resynchronised" "source re-opened" "implausible frame" "not a regular file (a FIFO)"; do
    if ! grep -q "$fault" "$work/daemon.err"; then
      echo "soak: FAIL: the daemon's log never mentions '$fault'" >&2
      fail=1
    fi
  done
fi
if [ "$poses" -ne "$f_processed" ]; then
  echo "soak: FAIL: the log holds $poses poses, the final status says $f_processed processed" >&2
  fail=1
fi
if [ "$received" -lt "$frames" ]; then
  echo "soak: FAIL: only $received frames received, wanted $frames" >&2
  fail=1
fi
if [ -z "$baseline_kb" ] || [ "$max_after_kb" -eq 0 ]; then
  echo "soak: FAIL: fewer than two RSS samples after the warm-up ($warmup frames); run longer" >&2
  fail=1
else
  growth=$((max_after_kb - baseline_kb))
  if [ "$growth" -gt "$tolerance_kb" ]; then
    echo "soak: FAIL: RSS grew by $growth kB after the warm-up (tolerance $tolerance_kb kB)" >&2
    fail=1
  fi
fi
printf 'soak: %d frames in %.0f s (%.1f frames/s); received %d = processed %d + skipped %d + bad %d (%s implausible) + lost upstream %d; source failures %s; %d poses in the log; RSS after warm-up (%d frames) %s kB, max later %s kB, last %s kB (growth %s kB, tolerance %d kB); %d samples\n' \
  "$f_processed" "$seconds" "$(awk -v n="$f_processed" -v s="$seconds" 'BEGIN {print n / s}')" "$received" "$f_processed" \
  "$skipped" "$bad" "${implausible:-?}" "$lost" "${failures:-?}" "$poses" "$warmup" "${baseline_kb:-?}" "$max_after_kb" "$last_kb" \
  "${growth:-?}" "$tolerance_kb" "$samples"
# The map: "..., loops closed N, ..., places N, source ..." (the daemon's last log line).
summary_line=$(grep -E 'stopped: received|SIGHUP received' "$work/daemon.err" | tail -1)
echo "soak: map: loops closed $(sed -n 's/.* loops closed \([0-9]*\).*/\1/p' <<<"$summary_line"), places $(sed -n 's/.* places \([0-9]*\).*/\1/p' <<<"$summary_line")"
if [ "$fail" -ne 0 ]; then exit 1; fi
echo "soak: PASS"
