#!/usr/bin/env bash
# Installs the Debian packages, configures and builds omnipose (Release) into build/.
# Usage: tools/build.sh [extra cmake --build arguments]
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/install_deps.sh
jobs=$(nproc 2>/dev/null || echo 2)
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$jobs" "$@"
