#!/usr/bin/env python3
"""Where a chained heading error comes from: the per-pair rotation errors of a replay,
summed over the segments of the motion script that rendered the sequence.
Usage: segment_errors.py MOTION.yaml GROUNDTRUTH.tum RELATIVE.csv
MOTION.yaml: an omnipose-synth motion script whose `segments:` entries are one-line maps
with `frames: N` and a `rotation:` or `translation:` key (tools/drift/*.yaml);
GROUNDTRUTH.tum: the dataset's ground truth (frame k on line k); RELATIVE.csv:
`omnipose-replay DATASET --relative RELATIVE.csv` (frame, prev_frame, status, rx, ry, rz).
Each pair with status ok is charged to the segment that moves the camera from its previous
frame to its frame; its error is the rotation vector of true^-1 * estimated relative
rotation (camera axes: x roll, y pitch, z yaw). Prints one line per segment and one per
kind (rotation, translation): pairs and the summed roll / pitch / yaw error in degrees, so
a bias shows as a sum that grows with the pairs of one kind. Exit 1 with a message on
unreadable input.
"""
import csv
import math
import re
import sys

from tum_rotations import conj, mul, read_tum


def from_rotvec(v):
    t = math.sqrt(sum(x * x for x in v))
    if t < 1e-15:
        return (1.0, v[0] / 2, v[1] / 2, v[2] / 2)
    s = math.sin(t / 2) / t
    return (math.cos(t / 2), v[0] * s, v[1] * s, v[2] * s)


def to_rotvec(q):
    if q[0] < 0:
        q = tuple(-x for x in q)
    n = math.sqrt(q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
    if n < 1e-15:
        return [0.0, 0.0, 0.0]
    t = 2 * math.atan2(n, q[0])
    return [q[i] * t / n for i in (1, 2, 3)]


def read_segments(path):
    segments = []
    try:
        with open(path) as f:
            for n, line in enumerate(f, 1):
                m = re.match(r"\s*-\s*\{\s*frames:\s*(\d+)\s*,\s*(rotation|translation)\s*:", line)
                if m:
                    segments.append((int(m.group(1)), m.group(2), n))
    except OSError as e:
        sys.exit(f"{path}: {e.strerror}")
    if not segments:
        sys.exit(f"{path}: no one-line segments with frames and rotation or translation")
    return segments


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__.strip().splitlines()[2])
    segments = read_segments(sys.argv[1])
    truth = [q for _, q in read_tum(sys.argv[2])]
    # Segment of each step: step k moves the camera from frame k to frame k + 1.
    owner = []
    for i, (count, _, _) in enumerate(segments):
        owner += [i] * count
    sums = [[0, [0.0, 0.0, 0.0]] for _ in segments]
    try:
        with open(sys.argv[3]) as f:
            for row in csv.DictReader(f):
                if row["status"] != "ok":
                    continue
                k, p = int(row["frame"]), int(row["prev_frame"])
                if not (0 <= p < k < len(truth)) or k - 1 >= len(owner):
                    sys.exit(f"{sys.argv[3]}: frame {k} (from {p}) is outside the script or the truth")
                est = from_rotvec([float(row[c]) for c in ("rx", "ry", "rz")])
                true = mul(conj(truth[p]), truth[k])
                e = to_rotvec(mul(conj(true), est))
                s = sums[owner[k - 1]]
                s[0] += 1
                for i in range(3):
                    s[1][i] += e[i]
    except (OSError, KeyError, ValueError) as e:
        sys.exit(f"{sys.argv[3]}: {e}")

    def line(label, pairs, err):
        deg = [math.degrees(x) for x in err]
        print(f"{label:<28} pairs {pairs:4d}  error sum roll {deg[0]:+8.3f}  pitch {deg[1]:+8.3f}"
              f"  yaw {deg[2]:+8.3f} deg")

    kinds = {}
    for (count, kind, n), (pairs, err) in zip(segments, sums):
        line(f"segment (line {n}) {kind}", pairs, err)
        k = kinds.setdefault(kind, [0, [0.0, 0.0, 0.0]])
        k[0] += pairs
        k[1] = [a + b for a, b in zip(k[1], err)]
    for kind, (pairs, err) in kinds.items():
        line(f"all {kind}", pairs, err)


if __name__ == "__main__":
    main()
