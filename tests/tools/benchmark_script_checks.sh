# shellcheck shell=bash
# What the tests of the benchmark scripts (tools/*_benchmark.sh, their common command line
# tools/common/benchmark.sh) check the same way. Sourced after `set -euo pipefail`.

fail() { echo "FAIL: $*" >&2; exit 1; }

# check_script_usage SCRIPT USAGE_PATTERN: the script parses, --help shows the usage line
# (a grep pattern), an unknown option and a second OUTDIR exit 2.
check_script_usage() {
  local script=$1 usage=$2 help rc
  bash -n "$script" || fail "$script: syntax"
  help=$(bash "$script" --help)
  grep -q "$usage" <<< "$help" || fail "--help does not show the usage: $help"
  rc=0
  bash "$script" --bogus 2> /dev/null || rc=$?
  [ "$rc" = 2 ] || fail "an unknown option exits with $rc, not 2"
  rc=0
  bash "$script" /tmp/a /tmp/b 2> /dev/null || rc=$?
  [ "$rc" = 2 ] || fail "two OUTDIRs exit with $rc, not 2"
}

# check_refuses_home SCRIPT WORK: OUTDIR = $HOME is refused (exit 2, "refusing to clear") and
# left as it was. A stand-in home under WORK, so a broken guard clears only the stand-in.
check_refuses_home() {
  local script=$1 work=$2 msg rc=0
  mkdir -p "$work/home"
  touch "$work/home/keep"
  msg=$(HOME=$work/home bash "$script" "$work/home" 2>&1) || rc=$?
  [ "$rc" = 2 ] && grep -q "refusing to clear" <<< "$msg" || fail "OUTDIR = HOME: exit $rc: $msg"
  [ -f "$work/home/keep" ] || fail "OUTDIR = HOME was cleared"
}
