#!/usr/bin/env python3
"""Error of the motion bridged across an outage (tools/drift/bridge_sweep.sh).
Usage: bridge_error.py GROUNDTRUTH.tum ESTIMATE.tum FIRST_MISSING COUNT
Frames FIRST_MISSING .. FIRST_MISSING + COUNT - 1 (indices into the ground truth) were
removed. Compares the estimated rotation from the last frame before the outage to the first
after it with the true one, and prints one line:
  first=F count=N true_deg=A est_yaw_deg=Y true_yaw_deg=T error_deg=E
or, when the estimate has no pose at either end (a new segment was started),
  first=F count=N true_deg=A lost
Exit code 1 with a message on unreadable input.
"""
import math
import sys

import tum_rotations
from tum_rotations import conj, mul


def read_tum(path):
    """The rotations of a TUM file by timestamp (rounded to 0.1 ms)."""
    return {round(t, 4): q for t, q in tum_rotations.read_tum(path)}


def angle_deg(q):
    return math.degrees(2.0 * math.acos(min(1.0, abs(q[0]))))


def yaw_deg(q):
    w, x, y, z = q
    return math.degrees(math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


def main():
    if len(sys.argv) != 5:
        sys.exit(__doc__.strip().splitlines()[1])
    truth, estimate = read_tum(sys.argv[1]), read_tum(sys.argv[2])
    first, count = int(sys.argv[3]), int(sys.argv[4])
    stamps = sorted(truth)
    if first < 1 or first + count >= len(stamps):
        sys.exit(f"frames {first}..{first + count - 1}: no frame on both sides of the outage")
    a, b = stamps[first - 1], stamps[first + count]
    rel_true = mul(conj(truth[a]), truth[b])
    head = f"first={first} count={count} true_deg={angle_deg(rel_true):.2f}"
    if a not in estimate or b not in estimate:
        print(head + " lost")
        return
    rel_est = mul(conj(estimate[a]), estimate[b])
    print(f"{head} est_yaw_deg={yaw_deg(rel_est):.3f} true_yaw_deg={yaw_deg(rel_true):.3f} "
          f"error_deg={angle_deg(mul(conj(rel_true), rel_est)):.3f}")


if __name__ == "__main__":
    main()
