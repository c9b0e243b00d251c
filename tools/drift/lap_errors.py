#!/usr/bin/env python3
"""The chained attitude's error at given frames (the end of each lap of a loop driven several
times): what a controller integrating the pose has drifted by when the robot is back where it
started, and how far off it was on the way there. Usage: lap_errors.py GROUNDTRUTH.tum EST.tum FRAME...
GROUNDTRUTH.tum: the dataset's ground truth (frame k on line k); EST.tum: a replay's poses
(omnipose-replay --out or --out-odometry), matched to the ground truth by timestamp; both
taken relative to their first pose. Prints one line per FRAME: the frame, the rotation
error angle and its yaw part at that frame, then the largest and the RMS rotation error
angle over the frames since the previous FRAME (from frame 1 for the first), degrees ("nan"
where the estimate has no pose at that frame's timestamp, or none in the span). Exit 1 with
a message on unreadable input.
"""
import math
import sys

from tum_rotations import conj, mul, read_tum


def angle_deg(q):
    w = min(1.0, abs(q[0]))
    return math.degrees(2.0 * math.acos(w))


def yaw_deg(q):
    """The yaw part of the rotation q (about z), degrees, in (-180, 180]."""
    w, x, y, z = q
    return math.degrees(math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


def main(argv):
    if len(argv) < 4:
        sys.exit(__doc__.strip().splitlines()[2])
    truth = read_tum(argv[1])
    estimate = read_tum(argv[2])
    if not truth or not estimate:
        sys.exit(f"{argv[1] if not truth else argv[2]}: no poses")
    by_time = {round(t, 6): q for t, q in estimate}
    t0, q0_true = truth[0]
    q0_est = by_time.get(round(t0, 6))
    if q0_est is None:
        sys.exit(f"{argv[2]}: no pose at the first frame's timestamp {t0}")
    def error_at(k):
        """truth^-1 * estimate at frame k, both relative to their first pose; None without one."""
        t, q_true = truth[k]
        q_est = by_time.get(round(t, 6))
        if q_est is None:
            return None
        return mul(conj(mul(conj(q0_true), q_true)), mul(conj(q0_est), q_est))

    previous = 0
    for text in argv[3:]:
        k = int(text)
        if not 0 <= k < len(truth):
            sys.exit(f"frame {k} is outside the ground truth's {len(truth)} poses")
        span = [e for e in (error_at(j) for j in range(previous + 1, k + 1)) if e is not None]
        angles = [angle_deg(e) for e in span]
        spread = (f"{max(angles):.4f} {math.sqrt(sum(a * a for a in angles) / len(angles)):.4f}"
                  if angles else "nan nan")
        previous = k
        error = error_at(k)
        if error is None:
            print(f"{k} nan nan {spread}")
            continue
        print(f"{k} {angle_deg(error):.4f} {yaw_deg(error):.4f} {spread}")


if __name__ == "__main__":
    main(sys.argv)
