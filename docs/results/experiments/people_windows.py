#!/usr/bin/env python3
"""The windows of chosen pairs of a dataset, as the fit saw them (docs/results/ANALYSIS.md,
"People over a pool of situations"; issue 50): per window its azimuth, measured du, the fitted
motion's du, their difference, the peak's confidence, the weight in the fit and the share of
its pixels the moving-content check found moving.

Replays the dataset with the Python package's Odometry (the defaults, one thread) and prints
the windows of the pass that made each chosen frame's estimate (`FrameResult.windows`).
Run, after tools/people_benchmark.sh and with the package installed (tools/python_test.sh
makes build-python/venv; reading the frames needs Pillow, which the `figure` extra brings):
  build-python/venv/bin/python docs/results/experiments/people_windows.py \\
      build/people/office/third_of_ring/dataset 41
"""
import argparse

import numpy as np
from PIL import Image

import omnipose


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", help="a dataset directory (frames/, calibration.yaml)")
    parser.add_argument("frames", help="frame indices, separated by commas (the pair ending there)")
    args = parser.parse_args()
    wanted = {int(x) for x in args.frames.split(",")}
    dataset = omnipose.open_dataset(args.dataset)
    odometry = omnipose.Odometry(dataset.calibration, threads=1)
    for i, (path, t) in enumerate(zip(dataset.frames, dataset.timestamps)):
        result = odometry.process(np.asarray(Image.open(path).convert("L")), float(t))
        if i not in wanted:
            continue
        w = result.windows
        azimuth = np.degrees(w.gamma * (np.asarray(w.center_u) - w.forward_column)) % 360.0
        print("frame %d: %d windows, %d used in the fit, refined: %s"
              % (i, len(w), result.windows_used, w.refined))
        print("  azimuth     du  model  du-model  confidence  weight  moving")
        for k in range(len(w)):
            print("  %7.1f %6.2f %6.2f %9.2f %11.2f %7.2f %7.2f" % (
                azimuth[k], w.du[k], w.model_du[k], w.du[k] - w.model_du[k], w.confidence[k],
                w.weight[k], w.moving_fraction[k]))


if __name__ == "__main__":
    main()
