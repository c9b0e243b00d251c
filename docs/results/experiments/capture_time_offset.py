#!/usr/bin/env python3
"""The images' effective capture time, measured against the gyro offline (docs/results/ANALYSIS.md,
"When the windows' yaw was captured"; issue 49): the prototype of `pipeline.yaw_capture_time`.

With a rolling shutter and a gyro each window's rotation within its frame is read at one
capture time, its taper-weighted mean. The correlation weighs the window's pixels by their
texture, so the pair's rotation is measured between instants that are delta seconds off the
timestamps: the images' yaw is then off by delta times the change of the yaw rate over the
pair. This replays nothing: it takes an estimate already written (`omnipose-replay DATASET
--out EST.tum` with `pipeline.yaw_capture_time: false`, which the pipeline would otherwise
correct itself), the dataset's imu.csv and calibration (its imu section), and
- per pair, what the images say beyond the gyro, r = log(G^T R) (G the gyro's rotation
  between the timestamps, integrated at the camera's clock in the camera's axes; R the
  images'), and the rate change w(t_cur) - w(t_ref) from the gyro;
- online, with only the pairs before: the gyro's bias (the mean of r, the first 30 pairs, then
  an exponential average over 30) and delta by a regression of r less the bias on the rate
  change, forgetting with FORGET per pair, shrunk towards 0 by RIDGE ((rad/s)^2);
- each pair's rotation corrected by exp(-delta * rate change) (yaw only unless --all-axes).
Prints the per-pair rotation error (RMSE of eps and of roll / pitch / yaw against
groundtruth.tum, mrad) before and after, and the last delta. Needs numpy (the package's venv
has it: tools/python_test.sh makes build-python/venv):
  build-python/venv/bin/python docs/results/experiments/capture_time_offset.py DATASET EST.tum
"""
import argparse
import re

import numpy as np


def quat_to_matrix(x, y, z, w):
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def so3_exp(v):
    angle = np.linalg.norm(v)
    if angle < 1e-12:
        return np.eye(3)
    k = v / angle
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def so3_log(R):
    angle = np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return v * (0.5 if angle < 1e-9 else angle / (2 * np.sin(angle)))


def load_tum(path):
    poses = {}
    for line in open(path):
        if line.startswith("#") or not line.strip():
            continue
        f = line.split()
        poses[round(float(f[0]), 4)] = quat_to_matrix(*(float(x) for x in f[4:8]))
    return poses


def rms(errors):
    e = np.array(errors) * 1e3
    return "eps %.4f r/p/y %.4f %.4f %.4f" % (
        np.sqrt((np.linalg.norm(e, axis=1) ** 2).mean()), *np.sqrt((e ** 2).mean(0)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", help="a dataset with groundtruth.tum, imu.csv, calibration.yaml")
    parser.add_argument("estimate", help="the estimate's TUM file (omnipose-replay --out)")
    parser.add_argument("--forget", type=float, default=0.995, help="per pair (default 0.995)")
    parser.add_argument("--ridge", type=float, default=0.3, help="(rad/s)^2 (default 0.3)")
    parser.add_argument("--all-axes", action="store_true", help="a delta per axis")
    parser.add_argument("--score-from", type=int, default=0,
                        help="score the pairs from this one on (the estimate starts at the first)")
    args = parser.parse_args()

    calibration = open(args.dataset + "/calibration.yaml").read()
    w, x, y, z = (float(v) for v in
                  re.search(r"rotation: \[([^\]]*)\]", calibration).group(1).split(","))
    offset = float(re.search(r"time_offset_s: ([-0-9.e+]+)", calibration).group(1))
    camera_from_imu = quat_to_matrix(x, y, z, w)
    imu = np.loadtxt(args.dataset + "/imu.csv", delimiter=",", skiprows=1, usecols=(0, 1, 2, 3))
    times = imu[:, 0] + offset
    rates = (camera_from_imu @ imu[:, 1:4].T).T

    def rate(t):
        return np.array([np.interp(t, times, rates[:, i]) for i in range(3)])

    def integrate(a, b, pieces=40):
        R = np.eye(3)
        edges = np.linspace(a, b, pieces + 1)
        for u, v in zip(edges, edges[1:]):
            R = R @ so3_exp(rate(0.5 * (u + v)) * (v - u))
        return R

    truth, estimate = load_tum(args.dataset + "/groundtruth.tum"), load_tum(args.estimate)
    stamps = sorted(truth)
    bias, readings = np.zeros(3), 0
    sxy, sxx = np.zeros(3), np.zeros(3)
    delta = np.zeros(3)
    before, after = [], []
    for a, b in zip(stamps, stamps[1:]):
        if a not in estimate or b not in estimate:
            continue
        true_pair = truth[a].T @ truth[b]
        images = estimate[a].T @ estimate[b]
        change = rate(b) - rate(a)
        delta = sxy / (sxx + args.ridge)
        if not args.all_axes:
            delta[:2] = 0.0
        corrected = images @ so3_exp(-delta * change)
        if readings >= args.score_from:
            before.append(so3_log(true_pair.T @ images))
            after.append(so3_log(true_pair.T @ corrected))
        beyond = so3_log(integrate(a, b).T @ images)
        readings += 1
        bias += (beyond - bias) / min(readings, 30)
        sxy = args.forget * sxy + (beyond - bias) * change
        sxx = args.forget * sxx + change * change
    print("before %s | after %s | delta [ms] %s" % (rms(before), rms(after),
                                                    np.round(delta * 1e3, 3)))


if __name__ == "__main__":
    main()
