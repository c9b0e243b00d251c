#!/usr/bin/env bash
# Installs every Debian 12 package omnipose needs to build, test and run.
# Idempotent: packages already present are left as they are. Needs root (or sudo).
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  libopencv-dev libopencv-contrib-dev libeigen3-dev libfftw3-dev libyaml-cpp-dev
  libgtest-dev libgmock-dev libbenchmark-dev libcli11-dev
  liblcm-dev liblcm-bin libglib2.0-dev liblcm-java default-jdk-headless
  libcamera-dev libopengv-dev libsystemd-dev
  zlib1g-dev valgrind iproute2 util-linux python3
  python3-dev python3-venv   # the Python package (tools/python_test.sh)
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install_deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install_deps: done"
