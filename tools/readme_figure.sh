#!/usr/bin/env bash
# The README's picture of a run: the demo (tools/demo.sh: the bundled sample sequence
# rendered and replayed), written as MCAP by omnipose-mcap and drawn by omnipose-figure with
# the ground truth's heading, into docs/images/demo_run.png.
# Usage: tools/readme_figure.sh [OUT.png]   (default docs/images/demo_run.png)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-docs/images/demo_run.png}
bash tools/demo.sh build/demo
# shellcheck source=tools/common/python_venv.sh
source tools/common/python_venv.sh
python_venv foxglove,figure
bin=$(dirname "$VENV_PYTHON")
"$bin/omnipose-mcap" build/demo/dataset build/demo/demo.mcap --overwrite
"$bin/omnipose-figure" build/demo/demo.mcap "$out" \
  --groundtruth build/demo/dataset/groundtruth.tum \
  --title "tools/demo.sh: 60 frames in a 6 x 5 m room (yaw, roll, pitch, then 10 cm steps)"
