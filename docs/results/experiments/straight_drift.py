#!/usr/bin/env python3
"""Where on the rectangle the odometry's heading drifts, and whether the fit knows it
(docs/results/ANALYSIS.md, "Loop closure: the map pose held by places seen before"; issue 54).

Replays a render of the drift benchmark's rectangle (tools/drift/rectangle.yaml: per lap a
100-frame straight, a 30-frame turn in place, 70, 30, 100, 30, 70, 30) with the Python
package's Odometry (the defaults) and prints, per straight and turn of every lap:
- the odometry's yaw drift over it: the change of the chained pose's yaw error against the
  ground truth (both relative to the first frame), degrees;
- the fit's own yaw sigma over it: the square root of the sum of the pairs' yaw variances
  (FrameResult.covariance[2, 2]), degrees, and per pair;
- the median number of windows the fits used.
With --direct A-B,...: frame B registered against frame A directly (a fresh Odometry given the
two frames), its yaw error and sigma, beside the chain's drift from A to B.
Run, after `LAPS=2 ROOMS=office_m180 tools/loop_benchmark.sh build/loops2` and with the package
installed (tools/python_test.sh makes build-python/venv):
  build-python/venv/bin/python docs/results/experiments/straight_drift.py \\
      build/loops2/office_m180/dataset --laps 2
"""
import argparse
import math

import numpy as np

import omnipose

SEGMENTS = [("straight 1", 100), ("turn 1", 30), ("straight 2", 70), ("turn 2", 30),
            ("straight 3", 100), ("turn 3", 30), ("straight 4", 70), ("turn 4", 30)]


def yaw_deg(rotation: np.ndarray) -> float:
    return math.degrees(math.atan2(rotation[1, 0], rotation[0, 0]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", help="a render of tools/drift/rectangle*.yaml")
    parser.add_argument("--laps", type=int, default=2, help="laps to replay (default 2)")
    parser.add_argument("--direct", default="",
                        help="pairs A-B separated by commas: B registered against A directly")
    args = parser.parse_args()
    pairs = [tuple(int(x) for x in p.split("-")) for p in args.direct.split(",") if p]
    dataset = omnipose.open_dataset(args.dataset)
    if dataset.groundtruth is None:
        raise SystemExit(f"{args.dataset}: no groundtruth.tum")
    truth = dataset.groundtruth["poses"]
    ends = np.cumsum([n for _, n in SEGMENTS] * args.laps)
    if ends[-1] >= min(len(dataset.frames), len(truth)):
        raise SystemExit(f"{args.dataset}: {len(dataset.frames)} frames, "
                         f"{args.laps} laps need {ends[-1] + 1}")
    odometry = omnipose.Odometry(dataset.calibration)
    error = np.zeros(ends[-1] + 1)  # yaw error of the chained pose, degrees
    variance = np.zeros(ends[-1] + 1)  # the pair's yaw variance, rad^2
    windows = np.zeros(ends[-1] + 1)
    for k in range(ends[-1] + 1):
        r = odometry.process(omnipose.read_frame(dataset.frames[k]), dataset.timestamps[k])
        if not r.ok:
            raise SystemExit(f"frame {k}: {r.message}")
        true_relative = np.linalg.inv(truth[0]) @ truth[k]
        error[k] = yaw_deg(true_relative[:3, :3].T @ r.pose[:3, :3])
        if r.has_motion:
            variance[k] = r.covariance[2, 2]
            windows[k] = r.windows_used
    print("lap segment     frames    drift [deg]  fit sigma [deg]  per pair  windows")
    start = 0
    for i, end in enumerate(ends):
        name = SEGMENTS[i % len(SEGMENTS)][0]
        span = slice(start + 1, end + 1)
        print(f"{i // len(SEGMENTS) + 1:3d} {name:11s} {start:4d}-{end:4d} {error[end] - error[start]:+11.3f}"
              f"  {math.degrees(math.sqrt(variance[span].sum())):15.4f}"
              f"  {math.degrees(math.sqrt(variance[span].mean())):8.5f}"
              f"  {np.median(windows[span]):7.1f}")
        start = end
    for a, b in pairs:
        direct(dataset, truth, a, b, error[b] - error[a])


def direct(dataset, truth, a: int, b: int, chain_drift: float) -> None:
    odometry = omnipose.Odometry(dataset.calibration)
    odometry.process(omnipose.read_frame(dataset.frames[a]), 0.0)
    r = odometry.process(omnipose.read_frame(dataset.frames[b]), dataset.timestamps[1])
    move = np.linalg.inv(truth[a]) @ truth[b]
    text = (f"direct {a}-{b}: moved {np.linalg.norm(move[:3, 3]):.2f} m, the chain drifted "
            f"{chain_drift:+.3f} deg; registered: {r.status}")
    if r.has_motion and r.status != "lost":
        text += (f", {r.windows_used} windows, yaw error {yaw_deg(move[:3, :3].T @ r.rotation):+.3f}"
                 f" deg, sigma {math.degrees(math.sqrt(r.covariance[2, 2])):.3f}")
    print(text)


if __name__ == "__main__":
    main()
