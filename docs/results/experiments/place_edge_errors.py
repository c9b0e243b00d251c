#!/usr/bin/env python3
"""The pose-graph edges of docs/results/experiments/place_edges.patch against the ground truth.

For each new place, the yaw from the previous place by the odometry's chain and by the direct
registration, each less the true yaw, degrees, and the registration's sigma (ok 0: the
registration failed or was refused, no edge). Pure Python.
Usage: place_edge_errors.py EDGES GROUNDTRUTH_TUM
  EDGES: the PLACEEDGE lines of the patched replay's stderr
  GROUNDTRUTH_TUM: the dataset's groundtruth.tum (its rows are the frames, in sequence order)
"""
import math
import sys


def rotation(q):
    x, y, z, w = map(float, q)
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]


def transpose_times(a, b):
    return [[sum(a[k][i] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def yaw(m):
    return math.atan2(m[1][0], m[0][0])


def main():
    truth = [line.split() for line in open(sys.argv[2]) if not line.startswith("#")]
    chain_sum = direct_sum = 0.0
    for line in open(sys.argv[1]):
        f = line.split()
        a, b = int(f[1]), int(f[2])
        chain, direct, sigma, ok = float(f[4]), float(f[6]), float(f[8]), int(f[10])
        true_yaw = yaw(transpose_times(rotation(truth[a][4:8]), rotation(truth[b][4:8])))
        chain_error = math.degrees(chain - true_yaw)
        direct_error = math.degrees(direct - true_yaw)
        print("%4d-%4d true %8.4f chain error %+.4f direct error %+.4f sigma %.4f ok %d" %
              (a, b, math.degrees(true_yaw), chain_error, direct_error, math.degrees(sigma), ok))
        chain_sum += chain_error
        direct_sum += direct_error * ok
    print("sum: chain %.3f direct %.3f" % (chain_sum, direct_sum))


if __name__ == "__main__":
    main()
