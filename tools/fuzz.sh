#!/usr/bin/env bash
# libFuzzer runs under ASan + UBSan (tests/fuzz), twelve targets, JOBS of them at a time:
#   fuzz_calibration_yaml   calibration.yaml (Calibration::parse)
#   fuzz_daemon_yaml        daemon.yaml (DaemonConfig::parse)
#   fuzz_frame_pipeline     frame decode (readFrame) + Pipeline::process on arbitrary bytes
#   fuzz_timestamps_tum     DATASET/timestamps.txt and groundtruth.tum (Dataset::open, readTum)
#   fuzz_gyro_csv           DATASET/imu.csv, the recorded gyro (parseGyroCsv)
#   fuzz_imu_lcm            omnipose.imu_t messages, the gyro over LCM (decodeImuMessage)
#   fuzz_gyro_stream        a live gyro stream: GyroBuffer, FrameRotation, integrateGyro
#   fuzz_iio_scan           an IIO device's scan type and scans (drivers/iio/iio_scan.hpp)
#   fuzz_ocamcalib          OCamCalib calib_results.txt (OcamCalibModel::parse + the lens model)
#   fuzz_lens_mask          Calibration::load with the files it names (OCamCalib model, Mei
#                           cv::omnidir FileStorage, mask image)
#   fuzz_calibrate_frames   omnipose-calibrate's frame set (ring detector, calibrateLens,
#                           proposeMask) on 1-4 small frames
#   fuzz_map_file           the saved map of places (decodeMap, restoreSnapshot, the solve)
# Usage: tools/fuzz.sh [SECONDS] [TARGET...]   (default 600 s each, every target; .ci/run
# uses 20 s)
# Installs clang-16 and its libFuzzer runtime (Debian 12 packages) when missing; builds every
# chosen target into build-fuzz/ with clang (ccache when installed); works on a clean clone.
# Per target: first every input of tests/fuzz/regressions/<target>/ (each input that ever
# crashed it) is run once, then the target fuzzes for SECONDS on build-fuzz/corpus/<target>/
# (where the corpus grows, outside the source tree) seeded from tests/fuzz/corpus/<target>/
# (read only). A crashing regression input or a crash, leak, out-of-memory or timeout (over
# 30 s) found while fuzzing (saved in build-fuzz/artifacts/) fails the run; an input slower
# than 10 s (libFuzzer's -report_slow_units; its slow-unit-* file) is counted in the summary but
# is no failure: on a busy machine a heavy seed takes that long. One summary line per target
# at the end, also in build-fuzz/logs/summary.txt, logs in build-fuzz/logs/.
# A crash found here is minimised (fuzzer -minimize_crash=1 -runs=10000 ARTIFACT), added to
# tests/fuzz/regressions/<target>/ and becomes a regression test of the normal suite.
# Environment: NICE (default 15), JOBS (build jobs and targets fuzzed at once, default nproc),
# KEEP_GOING=1 (fork mode: a crash is recorded in build-fuzz/artifacts/ and fuzzing goes on for
# the full time; the run still fails).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-600}
shift || true
all_targets=(fuzz_calibration_yaml fuzz_daemon_yaml fuzz_frame_pipeline fuzz_timestamps_tum
             fuzz_gyro_csv fuzz_imu_lcm fuzz_gyro_stream fuzz_iio_scan fuzz_ocamcalib fuzz_lens_mask fuzz_calibrate_frames
             fuzz_map_file)
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=("${all_targets[@]}")
nice_level=${NICE:-15}
jobs=${JOBS:-$(nproc 2>/dev/null || echo 2)}

bash tools/install_deps.sh
if ! command -v clang++-16 >/dev/null || ! ls /usr/lib/llvm-16/lib/clang/16/lib/linux/libclang_rt.fuzzer-x86_64.a >/dev/null 2>&1; then
  sudo_cmd=""
  [ "$(id -u)" -ne 0 ] && sudo_cmd=sudo
  $sudo_cmd apt-get update
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y --no-install-recommends clang-16 libclang-rt-16-dev
fi

dir=build-fuzz
# clang 16 implements what libstdc++ 12's <expected> needs (conditionally trivial special
# members, P0848) but still reports __cpp_concepts 201907, which hides std::expected from it:
# the fuzz build states the level it has.
flags="-U__cpp_concepts -D__cpp_concepts=202002L -Wno-builtin-macro-redefined"
# src/runtime/simd.hpp uses GCC's __builtin_shuffle (one and two operands):
# tests/fuzz/clang_compat.hpp gives clang the same (element-wise) shuffles.
flags="$flags -include $PWD/tests/fuzz/clang_compat.hpp"
# Line tables only (-gline-tables-only, the default -g dropped from RelWithDebInfo): enough
# for the sanitizers' stack traces, and a third less compile time in CI's 90 minutes.
flags="$flags -fsanitize=fuzzer-no-link,address,undefined -fno-sanitize=vptr -fno-sanitize-recover=all -fno-omit-frame-pointer -gline-tables-only"
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
build_start=$(date +%s)
nice -n "$nice_level" cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_COMPILER=clang-16 -DCMAKE_CXX_COMPILER=clang++-16 "${launcher[@]}" \
  -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -DNDEBUG" \
  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" \
  -DOMNIPOSE_BUILD_FUZZERS=ON -DOMNIPOSE_BUILD_BENCHMARKS=OFF >/dev/null
nice -n "$nice_level" cmake --build "$dir" -j"$jobs" --target "${targets[@]}"
echo "fuzz.sh: built ${#targets[@]} target(s) in $(( $(date +%s) - build_start )) s"

# Stack traces with function names and lines (clang-16's own symbolizer, else any on PATH).
if [ -z "${ASAN_SYMBOLIZER_PATH:-}" ]; then
  for s in /usr/lib/llvm-16/bin/llvm-symbolizer "$(command -v llvm-symbolizer-16 || true)" \
           "$(command -v llvm-symbolizer || true)"; do
    if [ -n "$s" ] && [ -x "$s" ]; then export ASAN_SYMBOLIZER_PATH=$s; break; fi
  done
fi

mkdir -p "$dir/artifacts" "$dir/logs"
rm -f "$dir"/logs/*.line
summary=$dir/logs/summary.txt
: >"$summary"
# An input slower than this is listed (libFuzzer's slow-unit-* file), not failed.
slow_s=10
# One target: its regression inputs, then SECONDS of fuzzing. Its summary line, which starts
# "<target>: FAILED" when it failed, goes to $dir/logs/<target>.line.
fuzz_one() {
  local t=$1
  mkdir -p "$dir/corpus/$t"
  log=$dir/logs/$t.log
  seeds=tests/fuzz/corpus/$t
  regressions=tests/fuzz/regressions/$t

  # Every input that ever crashed this target, run once each.
  reg_total=0
  reg_failed=()
  if [ -d "$regressions" ]; then
    while IFS= read -r -d '' f; do
      reg_total=$((reg_total + 1))
      if ! nice -n "$nice_level" "$dir/fuzz/$t" -timeout=30 -rss_limit_mb=2048 "$f" \
          >"$dir/logs/$t.regression.$(basename "$f").log" 2>&1; then
        reg_failed+=("$(basename "$f")")
      fi
    done < <(find "$regressions" -type f ! -name '*.md' -print0 | sort -z)
  fi

  echo "fuzz.sh: $t for $seconds s"
  rc=0
  keep=()
  [ "${KEEP_GOING:-0}" = 1 ] && keep=(-fork=1 -ignore_crashes=1 -ignore_ooms=1 -ignore_timeouts=1)
  corpora=("$dir/corpus/$t")
  [ -d "$seeds" ] && corpora+=("$seeds")
  before=$(find "$dir/artifacts" -name "$t-*" ! -name "$t-slow-unit-*" | wc -l)
  slow_before=$(find "$dir/artifacts" -name "$t-slow-unit-*" | wc -l)
  start=$(date +%s)
  nice -n "$nice_level" "$dir/fuzz/$t" "${keep[@]}" -max_total_time="$seconds" -timeout=30 \
    -report_slow_units="$slow_s" -rss_limit_mb=2048 -print_final_stats=1 \
    -artifact_prefix="$dir/artifacts/$t-" \
    "${corpora[@]}" >"$log" 2>&1 || rc=$?
  secs=$(( $(date +%s) - start ))
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  # fork mode prints no final stats: the last status line "#RUNS: cov: ..." has the count.
  [ -z "$runs" ] && runs=$(grep -oE '^#[0-9]+' "$log" | tail -1 | tr -d '#' || true)
  found=$(( $(find "$dir/artifacts" -name "$t-*" ! -name "$t-slow-unit-*" | wc -l) - before ))
  slow=$(( $(find "$dir/artifacts" -name "$t-slow-unit-*" | wc -l) - slow_before ))
  [ "$found" -gt 0 ] && [ "$rc" -eq 0 ] && rc=1
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | cut -d' ' -f2 || true)
  corpus=$(find "$dir/corpus/$t" -type f | wc -l)
  reg="regressions $((reg_total - ${#reg_failed[@]}))/$reg_total pass"
  [ ${#reg_failed[@]} -gt 0 ] && reg="$reg (CRASHED: ${reg_failed[*]}; logs $dir/logs/$t.regression.*.log)"
  if [ "$rc" -ne 0 ]; then
    line="$t: FAILED (exit $rc, $found new artifacts) after ${runs:-?} runs in $secs s; $reg; see $log and $dir/artifacts/"
    grep -m3 -E "ERROR|runtime error|deadly signal" "$log" || true
  else
    status="no crash"
    [ ${#reg_failed[@]} -gt 0 ] && status="FAILED"
    line="$t: $status: ${runs:-?} runs in ${secs:-?} s (coverage ${cov:-?} edges, corpus $corpus inputs); $reg"
  fi
  [ "$slow" -gt 0 ] && line="$line; $slow input(s) slower than $slow_s s in $dir/artifacts/$t-slow-unit-*"
  echo "fuzz.sh: $line"
  echo "$line" >"$dir/logs/$t.line"
}

# The targets run $jobs at a time (each fuzzer is one process on one core); the summary keeps
# the targets' order.
running=0
for t in "${targets[@]}"; do
  fuzz_one "$t" &
  running=$((running + 1))
  if [ "$running" -ge "$jobs" ]; then
    wait -n || true
    running=$((running - 1))
  fi
done
wait
failed=0
for t in "${targets[@]}"; do
  if [ -s "$dir/logs/$t.line" ]; then
    cat "$dir/logs/$t.line" >>"$summary"
    if grep -q "^$t: FAILED" "$dir/logs/$t.line"; then failed=1; fi
  else
    echo "$t: FAILED (no result; see $dir/logs/$t.log)" >>"$summary"
    failed=1
  fi
done
echo "fuzz.sh: $(date -u +%Y-%m-%dT%H:%MZ), $seconds s per target:"
cat "$summary"
exit "$failed"
