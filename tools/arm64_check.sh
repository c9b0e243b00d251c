#!/usr/bin/env bash
# Cross-builds omnipose for arm64 (AArch64) with Debian 12's cross toolchain and runs the
# registration, fit, pipeline, unwrap, calibration and io test binaries under qemu-user.
# Also checks that the NEON branch of src/runtime/simd.hpp is the one compiled.
#
# Too slow for CI (first run: ~400 MB of arm64 packages, a full cross build, tests under
# emulation: 20-40 min on the 2-core development VM). Run as root (or with sudo):
#     bash tools/arm64_check.sh            # everything
#     bash tools/arm64_check.sh --no-tests # sysroot + build + NEON check only
#     bash tools/arm64_check.sh --instructions  # build + NEON check + arm64 instructions per
#                                               # frame (no tests)
#
# How: the host gets g++-aarch64-linux-gnu and qemu-user-static (apt-get). The arm64
# libraries (OpenCV, FFTW, yaml-cpp, GoogleTest, LCM, ...) are NOT installed into the host
# through dpkg multiarch: on Debian 12 libopencv-dev:arm64 conflicts with the host's
# libopencv-dev and apt would remove it. Instead apt-get, pointed at a private state
# directory with APT::Architecture=arm64, downloads them and they are unpacked into a
# sysroot (build-arm64/sysroot, dpkg-deb -x, no maintainer scripts) that the compiler
# (--sysroot), CMake (toolchain file) and qemu (-L) use.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
OUT=$ROOT/build-arm64
SYSROOT=$OUT/sysroot
RUN_TESTS=1
SYSROOT_ONLY=0
INSTRUCTIONS=0
[ "${1:-}" = "--no-tests" ] && RUN_TESTS=0
[ "${1:-}" = "--sysroot-only" ] && SYSROOT_ONLY=1
[ "${1:-}" = "--instructions" ] && { INSTRUCTIONS=1; RUN_TESTS=0; }

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive

# 1. Host tools.
need=()
for p in g++-aarch64-linux-gnu qemu-user-static liblcm-bin cmake ninja-build pkg-config; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || need+=("$p")
done
if [ ${#need[@]} -gt 0 ]; then
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
fi

# 2. arm64 sysroot from Debian 12 packages (once per package list; delete build-arm64/sysroot
# to refresh).
ARM_PACKAGES=(libc6-dev libstdc++-12-dev libopencv-core-dev libopencv-imgproc-dev
  libopencv-imgcodecs-dev libopencv-features2d-dev libopencv-calib3d-dev libopencv-dev
  libeigen3-dev libfftw3-dev libyaml-cpp-dev libgtest-dev libgmock-dev libbenchmark-dev
  liblcm-dev libglib2.0-dev libsystemd-dev libopengv-dev libcli11-dev)
# .complete records the package list it was made from: a changed list fetches again.
if [ "$(cat "$SYSROOT/.complete" 2>/dev/null)" != "${ARM_PACKAGES[*]}" ]; then
  APTDIR=$OUT/apt
  mkdir -p "$APTDIR/etc/apt/sources.list.d" "$APTDIR/etc/apt/preferences.d" \
    "$APTDIR/var/lib/dpkg" "$APTDIR/var/cache/apt/archives/partial" \
    "$APTDIR/var/lib/apt/lists/partial" "$SYSROOT"
  cp /etc/apt/sources.list.d/debian.sources "$APTDIR/etc/apt/sources.list.d/" 2>/dev/null ||
    cp /etc/apt/sources.list "$APTDIR/etc/apt/"
  touch "$APTDIR/var/lib/dpkg/status"
  APT_OPTS=(-o "Dir=$APTDIR" -o "Dir::State::status=$APTDIR/var/lib/dpkg/status"
    -o "Dir::Etc::trusted=/etc/apt/trusted.gpg" -o "Dir::Etc::trustedparts=/etc/apt/trusted.gpg.d"
    -o APT::Architecture=arm64 -o APT::Architectures=arm64
    -o APT::Install-Recommends=false -o Debug::NoLocking=true)
  apt-get "${APT_OPTS[@]}" update -qq
  apt-get "${APT_OPTS[@]}" install -y -qq --download-only "${ARM_PACKAGES[@]}" >/dev/null
  for deb in "$APTDIR"/var/cache/apt/archives/*.deb; do dpkg-deb -x "$deb" "$SYSROOT"; done
  # usr-merge links the packages expect (the loader is /lib/ld-linux-aarch64.so.1).
  for d in lib bin sbin; do
    if [ ! -e "$SYSROOT/$d" ]; then ln -s "usr/$d" "$SYSROOT/$d"; fi
  done
  # Absolute symlinks inside the sysroot (e.g. libfoo.so -> /lib/...) made relative to it.
  find "$SYSROOT" -type l -lname '/*' | while read -r link; do
    target=$(readlink "$link")
    ln -sfn "$(realpath -m --relative-to="$(dirname "$link")" "$SYSROOT$target")" "$link"
  done
  echo "${ARM_PACKAGES[*]}" > "$SYSROOT/.complete"
fi
# Alternatives that maintainer scripts would have set (update-alternatives): BLAS / LAPACK.
MA=$SYSROOT/usr/lib/aarch64-linux-gnu
for lib in blas/libblas.so.3 lapack/liblapack.so.3; do
  if [ -e "$MA/$lib" ] && [ ! -e "$MA/$(basename "$lib")" ]; then ln -s "$lib" "$MA/$(basename "$lib")"; fi
done

[ "$SYSROOT_ONLY" = 1 ] && { echo "arm64_check: sysroot ready in $SYSROOT"; exit 0; }

# 3. Cross build (Release, like the host build). lcm-gen runs on the host.
cat > "$OUT/toolchain.cmake" <<EOF
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
set(CMAKE_SYSROOT $SYSROOT)
set(CMAKE_FIND_ROOT_PATH $SYSROOT)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
set(CMAKE_CROSSCOMPILING_EMULATOR qemu-aarch64-static;-L;$SYSROOT)
EOF
export PKG_CONFIG_SYSROOT_DIR=$SYSROOT
export PKG_CONFIG_LIBDIR=$SYSROOT/usr/lib/aarch64-linux-gnu/pkgconfig:$SYSROOT/usr/share/pkgconfig
cmake -S . -B "$OUT/build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_TOOLCHAIN_FILE="$OUT/toolchain.cmake" -DOMNIPOSE_WITH_LIBCAMERA=OFF \
  -DOMNIPOSE_WITH_SYSTEMD=OFF -DOMNIPOSE_BUILD_BENCHMARKS=ON >/dev/null
TESTS=(registration_test registration_alloc_test simd_check_test fft_plan_test noise_weighting_test
  column_spectra_test worker_pool_test worker_count_tuner_test fit_test pipeline_test
  pipeline_alloc_test calibration_test io_test)
jobs=$(nproc 2>/dev/null || echo 2)
nice -n 10 cmake --build "$OUT/build" -j"$jobs" --target "${TESTS[@]}" omnipose-bench-pipeline \
  omnipose-bench-instructions

# 4. The NEON branch is the one compiled: simd.hpp defines OMNIPOSE_SIMD_BACKEND, the object
# file of the registration records it (.comment-free: a string in .rodata), and the
# simd_check_test binary asserts it at run time.
file "$OUT/build/tests/registration_test" | grep "ARM aarch64" >/dev/null || { echo "arm64_check: not an aarch64 binary"; exit 1; }
if ! strings "$OUT/build/tests/simd_check_test" | grep "omnipose-simd-backend=neon" >/dev/null; then
  echo "arm64_check: FAIL: simd.hpp did not compile its NEON branch"
  exit 1
fi
echo "arm64_check: simd.hpp backend: neon (omnipose-simd-backend=neon found in simd_check_test)"

# 5. Tests under qemu-user.
if [ "$RUN_TESTS" = 1 ]; then
  export QEMU_LD_PREFIX=$SYSROOT
  failed=0
  for t in "${TESTS[@]}"; do
    start=$(date +%s)
    if (cd "$ROOT" && qemu-aarch64-static -L "$SYSROOT" "$OUT/build/tests/$t" --gtest_brief=1 > "$OUT/$t.log" 2>&1); then
      echo "arm64_check: PASS $t ($(( $(date +%s) - start )) s: $(grep -E '^\[  PASSED  \]' "$OUT/$t.log" | tail -1))"
    else
      echo "arm64_check: FAIL $t (log: $OUT/$t.log)"
      tail -20 "$OUT/$t.log"
      failed=1
    fi
  done
  [ "$failed" = 0 ] || exit 1
fi

# 6. (--instructions) Guest instructions per frame, paper setting, one thread. Debian's qemu
# 7.2 has no TCG plugins; instead qemu runs the benchmark in single-step mode (one guest
# instruction per translation block) with -d exec,nochain, which logs one line per executed
# instruction into a pipe that wc counts. Runs of 1 and 3 measured frames (same start-up,
# one warm-up frame) differ by exactly two frames of work.
if [ "$INSTRUCTIONS" = 1 ]; then
  bench=$OUT/build/bin/omnipose-bench-instructions
  frames_dir=$OUT/bench-frames
  wisdom=$OUT/bench.wisdom
  mkdir -p "$frames_dir"
  # Render the two frames and write the arm64 FFTW wisdom (normal emulation, no logging).
  qemu-aarch64-static -L "$SYSROOT" "$bench" --threads 1 --warmup 0 --frames 1 \
    --wisdom "$wisdom" --save "$frames_dir" > /dev/null
  count_run() {  # measured frames -> executed guest instructions of the whole run
    local fifo=$OUT/qemu-exec.fifo rc=0
    rm -f "$fifo"
    mkfifo "$fifo"
    wc -l < "$fifo" > "$OUT/qemu-exec.count" &
    local counter=$!
    qemu-aarch64-static -L "$SYSROOT" -singlestep -d exec,nochain -D "$fifo" "$bench" \
      --threads 1 --warmup 1 --frames "$1" --wisdom "$wisdom" --load "$frames_dir" \
      > /dev/null || rc=$?
    # Open and close the pipe once more (read-write: never blocks), so that the counter sees
    # an end of file even when qemu failed before opening its log.
    : 1<>"$fifo"
    wait "$counter"
    rm -f "$fifo"
    if [ "$rc" -ne 0 ]; then
      echo "arm64_check: FAIL: the counted run of $1 frame(s) exited with $rc" >&2
      return 1
    fi
    cat "$OUT/qemu-exec.count"
  }
  one=$(count_run 1) || exit 1
  three=$(count_run 3) || exit 1
  per_frame=$(( (three - one) / 2 ))
  echo "arm64_check: instructions per frame (arm64, 1 thread, refine 1): $per_frame" \
    "(runs of 1 and 3 frames: $one, $three)"
fi
echo "arm64_check: OK"
