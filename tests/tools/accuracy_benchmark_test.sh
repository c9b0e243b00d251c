#!/usr/bin/env bash
# tools/accuracy_benchmark.sh in its tiny mode (the benchmark itself takes many minutes): the
# script parses, prints its usage, rejects bad options, names a missing photo, refuses to clear
# a dangerous OUTDIR, and a 3-frame run at 1 x 1 rays per pixel (ifmi and akazerot) writes a
# report with Tables I to IV, every scene and lens of Table IV, the office texture made
# by omnipose-equirect and the uncertainty calibration of both lenses.
# Usage: accuracy_benchmark_test.sh SOURCE_DIR BUILD_DIR   (BUILD_DIR/bin holds the binaries)
set -euo pipefail
src=$1 build=$2 script=$1/tools/accuracy_benchmark.sh
# shellcheck source=tests/tools/benchmark_script_checks.sh
source "$src/tests/tools/benchmark_script_checks.sh"

check_script_usage "$script" 'Usage: tools/accuracy_benchmark.sh \[--publish\] \[OUTDIR\]'

# IFMI_PIPELINE (tools/common/benchmark.sh, shared with the drift and real-camera benchmarks):
# its entries become lines of the replays' pipeline: section, the report's command line
# names it, and --publish refuses it.
(
  # shellcheck source=tools/common/benchmark.sh
  source "$src/tools/common/benchmark.sh"
  publish=0
  command_line="tools/x.sh OUT"
  IFMI_PIPELINE=" noise_weighting: true ;; refine_iterations: 2 " bench_ifmi_pipeline x
  [ "$ifmi_pipeline_yaml" = $'  noise_weighting: true\n  refine_iterations: 2\n' ] ||
    fail "IFMI_PIPELINE yaml: '$ifmi_pipeline_yaml'"
  [ "$command_line" = "IFMI_PIPELINE=' noise_weighting: true ;; refine_iterations: 2 ' tools/x.sh OUT" ] ||
    fail "IFMI_PIPELINE command line: $command_line"
  unset IFMI_PIPELINE
  bench_ifmi_pipeline x
  [ -z "$ifmi_pipeline_yaml" ] && [ "$command_line" = "IFMI_PIPELINE=' noise_weighting: true ;; refine_iterations: 2 ' tools/x.sh OUT" ] ||
    fail "unset IFMI_PIPELINE changed something"
)
# bench_command_line: the environment the report names can be pasted back into a shell, a
# value with spaces or quotes single-quoted.
(
  # shellcheck source=tools/common/benchmark.sh
  source "$src/tools/common/benchmark.sh"
  VARIANTS="ring_consensus: false|keyframes.slots: 0" FRAMES=10 ROOMS="it's" \
    bench_command_line tools/x.sh --publish OUT -- VARIANTS FRAMES ROOMS UNSET_ONE
  [ "$command_line" = "ROOMS='it'\\''s' FRAMES=10 VARIANTS='ring_consensus: false|keyframes.slots: 0' tools/x.sh --publish OUT" ] ||
    fail "bench_command_line: $command_line"
  eval "set -- $command_line"
  [ "$#" = 6 ] && [ "$1" = "ROOMS=it's" ] && [ "$3" = "VARIANTS=ring_consensus: false|keyframes.slots: 0" ] ||
    fail "bench_command_line does not read back: $*"
)
rc=0
msg=$(source "$src/tools/common/benchmark.sh"; publish=1; command_line=x
      IFMI_PIPELINE="noise_weighting: true" bench_ifmi_pipeline demo 2>&1) || rc=$?
[ "$rc" = 2 ] && grep -q "demo: --publish publishes the defaults; unset IFMI_PIPELINE" <<< "$msg" ||
  fail "--publish with IFMI_PIPELINE: exit $rc: $msg"

data=$src/../shared/data/equirect
if [ ! -f "$data/park_theta_v_5376x2688.jpg" ]; then
  echo "accuracy_benchmark_test: SKIP the tiny run: the shared park photo is not in $data"
  exit 0
fi
work=$(mktemp -d "${TMPDIR:-/tmp}/omnipose-accuracy-test-XXXXXX")
trap 'rm -rf "$work"' EXIT
export BUILD_DIR=$build WISDOM=$work/wisdom FRAMES=3 SUPERSAMPLE=1 METHODS="ifmi akazerot" DATA_DIR=$data \
  UNCERTAINTY_PAIRS=2

rc=0
msg=$(DATA_DIR=$work/none bash "$script" "$work/x" 2>&1) || rc=$?
[ "$rc" = 1 ] && grep -q "missing photo $work/none/park_theta_v_5376x2688.jpg" <<< "$msg" ||
  fail "missing photo: exit $rc: $msg"
check_refuses_home "$script" "$work"

# The tiny run.
out=$work/out
bash "$script" "$out" > "$work/run.log" 2>&1 || { cat "$work/run.log" >&2; fail "the tiny run failed"; }
md=$out/report/RESULTS.md
[ -f "$md" ] || fail "no $md"
for table in 'Table I ' 'Table II ' 'Table III' 'Table IV'; do
  grep -q "^### $table" "$md" || fail "no $table in $md"
done
grep -q '^| ifmi | ' "$md" || fail "no ifmi row in Table I"
grep -q '^| akazerot | ' "$md" || fail "no akazerot row in Table I"
for row in 'linear | park |' 'linear | park-1024 |' 'linear | indoor |' 'linear | office |' \
           'office mirror (OCamCalib) | park |' 'office mirror (OCamCalib) | indoor |' \
           'office mirror (OCamCalib) | office |'; do
  grep -qF "| $row" "$md" || fail "Table IV has no row '$row'"
done
for lens in linear mirror_office; do
  [ -s "$out/report/uncertainty_$lens.png" ] || fail "no uncertainty figure for $lens"
  for scene in park indoor office; do
    for axis in du dv; do
      grep -q "^| $scene | [0-9]* | [0-9.]* | $axis | " "$out/uncertainty_$lens.md" ||
        fail "the $lens uncertainty table has no $scene $axis row"
    done
  done
done
grep -q '^### Uncertainty of each window' "$md" || fail "no uncertainty section in $md"
grep -q 'omnipose-equirect: wrote .*, 4096 x 2048; the ring sees elevations -40.5..27.1 deg' \
  "$out/lenses/office_texture.log" || fail "office texture: $(cat "$out/lenses/office_texture.log")"
echo "accuracy_benchmark_test: PASS"
