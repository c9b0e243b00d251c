# shellcheck shell=bash
# The daemon's final status from a file:// LCM log (sourced by tools/soak.sh and
# tools/realtime_check.sh, which judge a run by its counters).

# read_final_status BIN_DIR LOG LISTEN_OUT WHO: decodes LOG with omnipose-listen into
# LISTEN_OUT and sets FINAL_STATUS to its last "status (final):" line; without one, prints
# "WHO: FAIL: ..." on stderr and returns 1.
read_final_status() {
  local bin=$1 log=$2 out=$3 who=$4
  "$bin/omnipose-listen" --url "file://$log?speed=0" >"$out" 2>&1 || true
  FINAL_STATUS=$(grep '^status (final):' "$out" | tail -1)
  if [ -z "$FINAL_STATUS" ]; then
    echo "$who: FAIL: no final status in the LCM log" >&2
    return 1
  fi
}

# status_count NAME: the number after the words NAME in FINAL_STATUS ("received 180" -> 180;
# the last such, and only where a number follows: "bad 11", not "bad imu messages 0").
status_count() { sed -n "s/.* $1 \([0-9][0-9]*\).*/\1/p" <<<"$FINAL_STATUS"; }
