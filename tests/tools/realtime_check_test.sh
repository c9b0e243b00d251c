#!/usr/bin/env bash
# tools/realtime_check.sh judges the machine at the moment of the run, so it is not a test: its
# syntax and its refusal of bad arguments (exit 2 with the usage, before anything is built or
# started) are checked here. Usage: realtime_check_test.sh SOURCE_DIR
set -euo pipefail
src=$1
bash -n "$src/tools/realtime_check.sh"
for args in "--load" "--load x 30" "--nice x" "--nice 1.5" "--nice 20" "--nice -21" \
            "--frobnicate" "0" "30 1" "--fifo 100" "--fifo 5 --nice 5" "--fifo 5 --nice -5" \
            "--fifo"; do
  rc=0
  # shellcheck disable=SC2086
  out=$(bash "$src/tools/realtime_check.sh" $args 2>&1) || rc=$?
  if [ "$rc" != 2 ]; then
    echo "realtime_check.sh $args: exit $rc, expected 2: $out" >&2
    exit 1
  fi
  if ! grep -qF "usage: tools/realtime_check.sh [--load N] [--nice K | --fifo P] [FPS] [FRAMES]" \
       <<<"$out"; then
    echo "realtime_check.sh $args: no usage line: $out" >&2
    exit 1
  fi
done
echo "realtime_check.sh: syntax checked, bad arguments refused with the usage"
