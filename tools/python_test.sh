#!/usr/bin/env bash
# The Python package (pyproject.toml, src/python/): installs the Debian packages, builds the
# programs (a no-op after tools/test.sh), renders a 24-frame rotating sequence with exact
# ground truth (and a 16-frame walk), replays it with omnipose-replay (writing FFTW wisdom) and
# runs the daemon on it into an LCM log (the tests compare the package with all three),
# installs the package with `pip install .` into a venv under build-python/ and runs its
# pytest suite (tests/python).
# Usage: tools/python_test.sh [pytest arguments]
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/install_deps.sh
bash tools/build.sh --target omnipose-synth omnipose-replay omniposed

data=build-python/data
rm -rf "$data"
mkdir -p "$data"
build/bin/omnipose-synth --texture tests/data/equirect/indoor_1024x512.jpg --out "$data/mixed" \
  --preset mixed --frames 24 --seed 1 --noise 3 >/dev/null
# A 16-frame walk of 5-15 cm steps in the box room: driven there and back by the loop-closure
# test, whose return meets the places of the way out.
build/bin/omnipose-synth --texture tests/data/equirect/indoor_1024x512.jpg --out "$data/walk" \
  --preset translate --frames 16 --seed 1 --noise 3 >/dev/null
# FFTW wisdom shared by the C++ replay and the tests: the same FFT algorithms, so the same
# last bits (FFTW_MEASURE alone may pick other algorithms in another process).
echo "pipeline: {fftw_wisdom: fftw_wisdom.txt}" > "$data/replay.yaml"
build/bin/omnipose-replay "$data/mixed" --config "$data/replay.yaml" \
  --out "$data/mixed_replay.tum" >/dev/null
# The daemon on the same frames, every frame (realtime: false), recording its LCM messages
# (poses, window diagnostics, status, panorama pictures) in a log: omnipose-mcap's other
# source, and what omnipose-view plays.
cat > "$data/daemon.yaml" <<YAML
source: {type: file, path: mixed, realtime: false}
calibration: mixed/calibration.yaml
pipeline: {fftw_wisdom: fftw_wisdom.txt}
lcm: {url: "file://$PWD/$data/daemon.lcm?mode=w", fit_channel: OMNI_FIT, status_hz: 10,
      panorama_channel: OMNI_PANORAMA, panorama_hz: 10}
YAML
build/bin/omniposed --config "$data/daemon.yaml" >/dev/null 2>"$data/daemon.log"

# shellcheck source=tools/common/python_venv.sh
source tools/common/python_venv.sh
python_venv foxglove,figure,test

export OMNIPOSE_TEST_DATASET="$PWD/$data/mixed"
export OMNIPOSE_TEST_WALK_DATASET="$PWD/$data/walk"
export OMNIPOSE_TEST_REPLAY_TUM="$PWD/$data/mixed_replay.tum"
export OMNIPOSE_TEST_WISDOM="$PWD/$data/fftw_wisdom.txt"
export OMNIPOSE_TEST_DAEMON_LOG="$PWD/$data/daemon.lcm"
# From outside the source tree, so `import omnipose` is the installed package.
cd build-python
"$VENV_PYTHON" -m pytest -q -p no:cacheprovider ../tests/python "$@"
