#!/usr/bin/env bash
# libFuzzer runs under ASan + UBSan, one target at a time (tests/fuzz):
#   fuzz_calibration_yaml   calibration.yaml (Calibration::parse)
#   fuzz_daemon_yaml        daemon.yaml (DaemonConfig::parse)
#   fuzz_frame_pipeline     frame decode (readFrame) + Pipeline::process on arbitrary bytes
#   fuzz_timestamps_tum     DATASET/timestamps.txt and groundtruth.tum (Dataset::open, readTum)
#   fuzz_ocamcalib          OCamCalib calib_results.txt (OcamCalibModel::parse + the lens model)
# Usage: tools/fuzz.sh [SECONDS] [TARGET...]   (default 600 s each, every target)
# Installs clang-16 and its libFuzzer runtime (Debian 12 packages) when missing; builds into
# build-fuzz/ with clang; seeds each corpus from the repository's own files (the example
# configurations, a dataset rendered by omnipose-synth: calibration.yaml, timestamps.txt,
# groundtruth.tum, PNG frames, the bundled JPEG photo). Corpora grow in build-fuzz/corpus/,
# crashes land in build-fuzz/artifacts/ and fail the run; each crash found so far is a
# regression test in the normal suite.
# Environment: NICE (default 15), JOBS (build jobs, default nproc), KEEP_GOING=1 (fork mode:
# a crash is recorded in build-fuzz/artifacts/ and fuzzing goes on for the full time; the run
# still fails).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-600}
shift || true
all_targets=(fuzz_calibration_yaml fuzz_daemon_yaml fuzz_frame_pipeline fuzz_timestamps_tum fuzz_ocamcalib)
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
# src/registration/simd.hpp uses GCC's __builtin_shuffle: tests/fuzz/clang_compat.hpp gives
# clang the same (element-wise) shuffle.
flags="$flags -include $PWD/tests/fuzz/clang_compat.hpp"
flags="$flags -fsanitize=fuzzer-no-link,address,undefined -fno-sanitize=vptr -fno-sanitize-recover=all -fno-omit-frame-pointer -g"
nice -n "$nice_level" cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_COMPILER=clang-16 -DCMAKE_CXX_COMPILER=clang++-16 \
  -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" \
  -DOMNIPOSE_BUILD_FUZZERS=ON -DOMNIPOSE_BUILD_BENCHMARKS=OFF >/dev/null
nice -n "$nice_level" cmake --build "$dir" -j"$jobs" --target "${targets[@]}"

# Seeds from the repository's own files.
seeds=$dir/seeds
if [ ! -d "$seeds/done" ]; then
  rm -rf "$seeds"
  mkdir -p "$seeds"/{fuzz_calibration_yaml,fuzz_daemon_yaml,fuzz_frame_pipeline,fuzz_timestamps_tum,fuzz_ocamcalib}
  cp tests/data/catadioptric/*_ocamcalib.txt "$seeds/fuzz_ocamcalib/"
  synth=""
  for b in build/bin/omnipose-synth build-asan/bin/omnipose-synth; do [ -x "$b" ] && synth=$b && break; done
  if [ -z "$synth" ]; then bash tools/build.sh omnipose-synth; synth=build/bin/omnipose-synth; fi
  "$synth" --texture tests/data/equirect/indoor_1024x512.jpg --out "$seeds/dataset" --preset mixed \
    --frames 3 --seed 1 --supersample 1 >/dev/null
  cp "$seeds/dataset/calibration.yaml" "$seeds/fuzz_calibration_yaml/"
  cp tools/omniposed/daemon.example.yaml "$seeds/fuzz_daemon_yaml/"
  # timestamps target: the first half of an input is timestamps.txt, the second half
  # groundtruth.tum (read when the first byte is odd: '#' is).
  ds=$seeds/dataset
  cat "$ds/timestamps.txt" "$ds/timestamps.txt" >"$seeds/fuzz_timestamps_tum/timestamps"
  { printf '#\n'; cat "$ds/timestamps.txt" "$ds/groundtruth.tum"; } >"$seeds/fuzz_timestamps_tum/with-tum"
  # frame target: first byte odd = an image file follows, even = raw pixels.
  first=$(find "$ds/frames" -type f | sort | head -1)
  { printf '\x01'; cat "$first"; } >"$seeds/fuzz_frame_pipeline/png"
  { printf '\x01'; cat tests/data/equirect/indoor_1024x512.jpg; } >"$seeds/fuzz_frame_pipeline/jpg"
  { printf '\x00'; tail -c 4096 "$first"; } >"$seeds/fuzz_frame_pipeline/raw"
  for y in tools/synth/examples/*.yaml; do cp "$y" "$seeds/fuzz_daemon_yaml/$(basename "$y").seed"; done
  touch "$seeds/done"
fi

mkdir -p "$dir/artifacts" "$dir/logs"
failed=0
summary=$dir/logs/summary.txt
: >"$summary"
for t in "${targets[@]}"; do
  mkdir -p "$dir/corpus/$t"
  log=$dir/logs/$t.log
  echo "fuzz.sh: $t for $seconds s"
  rc=0
  keep=()
  [ "${KEEP_GOING:-0}" = 1 ] && keep=(-fork=1 -ignore_crashes=1 -ignore_ooms=1 -ignore_timeouts=1)
  before=$(find "$dir/artifacts" -name "$t-*" | wc -l)
  start=$(date +%s)
  nice -n "$nice_level" "$dir/fuzz/$t" "${keep[@]}" -max_total_time="$seconds" -timeout=30 \
    -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$dir/artifacts/$t-" \
    "$dir/corpus/$t" "$seeds/$t" >"$log" 2>&1 || rc=$?
  secs=$(( $(date +%s) - start ))
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  # fork mode prints no final stats: the last status line "#RUNS: cov: ..." has the count.
  [ -z "$runs" ] && runs=$(grep -oE '^#[0-9]+' "$log" | tail -1 | tr -d '#')
  found=$(( $(find "$dir/artifacts" -name "$t-*" | wc -l) - before ))
  [ "$found" -gt 0 ] && [ "$rc" -eq 0 ] && rc=1
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | cut -d' ' -f2)
  corpus=$(find "$dir/corpus/$t" -type f | wc -l)
  if [ "$rc" -ne 0 ]; then
    failed=1
    line="$t: FAILED (exit $rc, $found new artifacts) after ${runs:-?} runs in $secs s; see $log and $dir/artifacts/"
    grep -m3 -E "ERROR|runtime error|deadly signal" "$log" || true
  else
    line="$t: ${runs:-?} runs in ${secs:-?} s, no crash (coverage ${cov:-?} edges, corpus $corpus inputs)"
  fi
  echo "fuzz.sh: $line"
  echo "$line" >>"$summary"
done
echo "fuzz.sh: $(date -u +%Y-%m-%dT%H:%MZ), $seconds s per target:"
cat "$summary"
exit "$failed"
