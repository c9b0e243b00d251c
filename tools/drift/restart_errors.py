#!/usr/bin/env python3
"""How well a run restarted with a saved map finds its heading in it (omnipose-replay --from S
--map-in MAP, the map saved by an earlier run of the same dataset with --map-out).
Usage: restart_errors.py GROUNDTRUTH.tum MAPPED.tum RESTART.tum RELOCALISED [OTHER.tum]
GROUNDTRUTH.tum: the dataset's ground truth (frame k on line k); MAPPED.tum: the run that saved
the map (--out; its first pose is the map frame's origin, the ground truth's first frame);
RESTART.tum: the restarted run's map pose (--out), matched to the ground truth by timestamp;
RELOCALISED: the frame that found the map (the replay's relocalised=F); OTHER.tum: optional,
another run's map pose in the same map frame (the run that never stopped), for comparison.
Prints one line: RELOCALISED, then for the restart, from that frame to its last: the rotation
error angle at RELOCALISED, at its last frame and the largest, and its yaw error at its last
frame, degrees; then the same four for OTHER over the same frames ("nan" without it). Exit 1
with a message on unreadable input or a restart that never found the map.
"""
import math
import sys

from lap_errors import angle_deg, yaw_deg
from tum_rotations import conj, mul, read_tum


def main(argv):
    if len(argv) not in (5, 6):
        sys.exit(__doc__.strip().splitlines()[2])
    truth = read_tum(argv[1])
    mapped = read_tum(argv[2])
    relocalised = int(argv[4])
    if not truth or not mapped:
        sys.exit(f"{argv[1] if not truth else argv[2]}: no poses")
    if not 0 <= relocalised < len(truth):
        sys.exit(f"RELOCALISED {relocalised}: the restart never found the map, or is outside "
                 f"the ground truth's {len(truth)} poses")
    t0, q0_true = truth[0]
    by_time = {round(t, 6): q for t, q in mapped}
    q0_map = by_time.get(round(t0, 6))
    if q0_map is None:
        sys.exit(f"{argv[2]}: no pose at the first frame's timestamp {t0}")
    index = {round(t, 6): k for k, (t, _) in enumerate(truth)}

    def errors(path):
        """(frame, truth^-1 * estimate) from RELOCALISED on, in the map frame."""
        out = []
        for t, q in read_tum(path):
            k = index.get(round(t, 6))
            if k is None or k < relocalised:
                continue
            q_true = mul(conj(q0_true), truth[k][1])
            out.append((k, mul(conj(q_true), mul(conj(q0_map), q))))
        return sorted(out)

    restart = errors(argv[3])
    if not restart or restart[0][0] != relocalised:
        sys.exit(f"{argv[3]}: no pose at frame {relocalised}")
    frames = {k for k, _ in restart}

    def summary(errs):
        errs = [(k, e) for k, e in errs if k in frames]
        if not errs:
            return "nan nan nan nan"
        angles = [angle_deg(e) for _, e in errs]
        return f"{angles[0]:.4f} {angles[-1]:.4f} {max(angles):.4f} {yaw_deg(errs[-1][1]):.4f}"

    other = summary(errors(argv[5])) if len(argv) == 6 else "nan nan nan nan"
    print(f"{relocalised} {summary(restart)} {other}")


if __name__ == "__main__":
    main(sys.argv)
