#!/usr/bin/env bash
# Installs the Debian packages, builds everything and runs the test suite.
#
#   tools/test.sh           every test except those labelled "long" (a few minutes after the build)
#   tools/test.sh --long    only the "long" ones (tests/long_tests.txt, the benchmark scripts:
#                           the statistics over pools of renders; the downstream build and the
#                           .deb packages of tests/install); CI runs both
#   tools/test.sh --all     both
set -euo pipefail
cd "$(dirname "$0")/.."
case "${1:-}" in
  "") select=(-LE '^long$') ;;
  --long) select=(-L '^long$') ;;
  --all) select=() ;;
  *) echo "usage: tools/test.sh [--long|--all]" >&2; exit 2 ;;
esac
bash tools/build.sh
jobs=$(nproc 2>/dev/null || echo 2)
ctest --test-dir build --output-on-failure -j"$jobs" --timeout 900 "${select[@]}"
