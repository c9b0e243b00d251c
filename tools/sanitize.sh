#!/usr/bin/env bash
# Sanitizer runs, each in a build directory of its own (the Release build/ is untouched).
#
#   tools/sanitize.sh [asan]   AddressSanitizer + UndefinedBehaviorSanitizer (build-asan/):
#                              the whole ctest suite, except the tests labelled
#                              "allocation" (they replace or interpose the malloc family to
#                              count allocations; under ASan the sanitizer owns the allocator,
#                              so they would bypass it and count its bookkeeping) and "long"
#                              (tests/long_tests.txt says which and why).
#   tools/sanitize.sh tsan     ThreadSanitizer (build-tsan/): the daemon and driver tests
#                              (the two-thread daemon, its mailbox and status board, the
#                              V4L2 / libcamera sources). Uninstrumented third-party code
#                              that TSan misreads is suppressed in tests/sanitizers/tsan.supp
#                              (GDAL, GLib, LCM's memq hand-over); OpenCV runs its loops on
#                              the calling thread there (tests/sanitizers/opencv_serial.cpp).
#
# Any sanitizer report fails the run (halt_on_error, -fno-sanitize-recover=all).
# UBSan's vptr check is off (-fno-sanitize=vptr): LCM 1.3.1's C++ subscription callbacks
# trip GCC 12's check through a benign cast in lcm-cpp-impl.hpp. Its null and alignment checks
# are off as well (CMakeLists.txt says why; the fuzzers keep them).
# Environment: JOBS (build jobs, default nproc), NICE (niceness, default 10),
# CTEST_ARGS (extra ctest arguments, e.g. "-R io_test").
set -euo pipefail
cd "$(dirname "$0")/.."
mode=${1:-asan}
jobs=${JOBS:-$(nproc 2>/dev/null || echo 2)}
nice_level=${NICE:-10}
bash tools/install_deps.sh

case "$mode" in
  asan)
    dir=build-asan
    sanitize=address
    # Under ASan every test is slower (3-5x). The "long" ones (tests/long_tests.txt: the
    # statistics over pools of renders) are left to the Release suite.
    select=(-LE '^(allocation|long)$')
    timeout=3600
    export ASAN_OPTIONS="halt_on_error=1:abort_on_error=0:detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=0:check_initialization_order=1"
    export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
    ;;
  tsan)
    dir=build-tsan
    sanitize=thread
    select=(-L '^(daemon|drivers)$' -LE allocation)
    timeout=1800
    export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$PWD/tests/sanitizers/tsan.supp"
    ;;
  *)
    echo "usage: tools/sanitize.sh [asan|tsan]" >&2
    exit 2
    ;;
esac

start=$(date +%s)
# -g1: line tables only, enough for the sanitizers' stack traces; full -g costs a third more
# compile time (Eigen and GoogleTest instantiate much) and CI has 90 minutes for everything.
nice -n "$nice_level" cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" \
  -DOMNIPOSE_SANITIZE="$sanitize" -DOMNIPOSE_BUILD_BENCHMARKS=OFF >/dev/null
if [ "$mode" = tsan ]; then
  # Only what the selected tests need.
  targets=(daemon_test daemon_config_test daemon_process_test daemon_check_test omniposed
           omnipose-listen omnipose-synth driver_common_test v4l2_test daemon_v4l2_test)
  [ -n "$(grep -l 'libcamera_test' "$dir/build.ninja" 2>/dev/null)" ] && targets+=(libcamera_test)
  nice -n "$nice_level" cmake --build "$dir" -j"$jobs" --target "${targets[@]}"
else
  nice -n "$nice_level" cmake --build "$dir" -j"$jobs"
fi
built=$(date +%s)
echo "sanitize.sh $mode: build took $((built - start)) s"

# Every name in tests/long_tests.txt must still name a test: a renamed test would otherwise
# drop out of the "long" label and quietly cost the sanitizer run its time again.
if [ "$mode" = asan ]; then
  labelled=$(ctest --test-dir "$dir" -N -L '^long$' | sed -n 's/^ *Test *#[0-9]*: //p')
  missing=0
  while read -r name; do
    case "$name" in ''|'#'*) continue ;; esac
    if ! grep -qxF "$name" <<<"$labelled"; then
      echo "sanitize.sh: tests/long_tests.txt names '$name', which is no test" >&2
      missing=1
    fi
  done < tests/long_tests.txt
  [ "$missing" = 0 ] || exit 1
  echo "sanitize.sh $mode: $(grep -c . <<<"$labelled") long tests left to the Release suite"
fi

# shellcheck disable=SC2086
nice -n "$nice_level" ctest --test-dir "$dir" --output-on-failure -j"$jobs" --timeout "$timeout" \
  "${select[@]}" ${CTEST_ARGS:-}
end=$(date +%s)
echo "sanitize.sh $mode: clean. build $((built - start)) s, tests $((end - built)) s, total $((end - start)) s"
