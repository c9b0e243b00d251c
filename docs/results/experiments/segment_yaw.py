#!/usr/bin/env python3
"""The yaw error summed over each straight and each turn of a render (docs/results/ANALYSIS.md,
"The straights' yaw is in the windows' shifts"; issue 54).

The segments come from the ground truth: a run of pairs whose camera moves is a straight (S), a
run whose camera only turns is a turn (T). For each source given, the per-pair yaw errors
(camera frame, the z component of the relative rotation error, as `omnipose-eval` takes it) are
summed over each segment, in degrees: what that segment adds to the chained heading.
Sources:
  --tum EST.tum        a trajectory (the odometry's: `omnipose-replay --out-odometry`, or the
                       per-room TUM `tools/drift_pool.sh` keeps as OUT/ROOM/default.tum)
  --window-flow OUT    the output of `omnipose-experiment-window-flow` (its per-pair lines; the
                       columns measured, exact-uv, exact-all, exact-phi are summed alike, and
                       those of NAMED_COLUMNS where the tool printed them)
Standard library only. Run, on a room of `tools/drift_pool.sh OUT`:
  build/bin/omnipose-experiment-window-flow OUT/park_m240/dataset 1 460 > wf.txt
  python3 docs/results/experiments/segment_yaw.py OUT/park_m240/dataset/groundtruth.tum \\
      --tum OUT/park_m240/default.tum --window-flow wf.txt
"""
import argparse
import math


def load_tum(path):
    """Timestamp -> (position, quaternion x, y, z, w), in file order."""
    poses = []
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            v = [float(x) for x in line.split()]
            poses.append((v[0], v[1:4], v[4:8]))
    return poses


def qmul(a, b):
    x1, y1, z1, w1 = a
    x2, y2, z2, w2 = b
    return (w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2, w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2)


def qinv(q):
    return (-q[0], -q[1], -q[2], q[3])


def rotation_vector(q):
    x, y, z, w = q
    if w < 0:
        x, y, z, w = -x, -y, -z, -w
    s = math.sqrt(x * x + y * y + z * z)
    if s < 1e-15:
        return (0.0, 0.0, 0.0)
    angle = 2.0 * math.atan2(s, w)
    return (x / s * angle, y / s * angle, z / s * angle)


def segments(truth):
    """[(kind, first pair, last pair)], pair k being frames k-1 -> k."""
    out = []
    for k in range(1, len(truth)):
        moved = math.dist(truth[k - 1][1], truth[k][1]) > 1e-9
        kind = "S" if moved else "T"
        if out and out[-1][0] == kind:
            out[-1][2] = k
        else:
            out.append([kind, k, k])
    return out


def tum_yaw_errors(truth, estimate):
    """Pair k -> yaw error (rad) for the pairs both trajectories have."""
    by_time = {round(t, 6): q for t, _, q in estimate}
    errors = {}
    for k in range(1, len(truth)):
        a, b = round(truth[k - 1][0], 6), round(truth[k][0], 6)
        if a not in by_time or b not in by_time:
            continue
        true_rel = qmul(qinv(truth[k - 1][2]), truth[k][2])
        est_rel = qmul(qinv(by_time[a]), by_time[b])
        errors[k] = rotation_vector(qmul(qinv(true_rel), est_rel))[2]
    return errors


# The columns the tool names after its fixed ones (--energy, --synthetic, --preshift).
NAMED_COLUMNS = ("energy", "warp", "affine", "similarity", "sim-uv", "sim-rs", "sim-known",
                 "rigid", "rigid-uv", "preshift", "fraction")


def window_flow_yaw_errors(path):
    """Column name -> {pair k -> yaw error (rad)} from the tool's per-pair lines."""
    names = ("measured", "exact-uv", "exact-all", "exact-phi")
    columns = {name: {} for name in names}
    with open(path) as f:
        for line in f:
            fields = line.split()
            if line.startswith("#") or len(fields) < 6 or fields[5] != "|":
                continue
            for name, value in zip(names, fields[1:5]):
                columns[name][int(fields[0])] = float(value) * 1e-3
            # Named columns after the fixed ones (--energy: "energy X"; --synthetic:
            # "warp X affine Y ..."; --preshift: "preshift X fraction Y").
            for i, field in enumerate(fields[6:-1], start=6):
                if field in NAMED_COLUMNS:
                    columns.setdefault(field, {})[int(fields[0])] = float(fields[i + 1]) * 1e-3
    return columns


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("groundtruth", help="groundtruth.tum of the render")
    parser.add_argument("--tum", action="append", default=[], help="a trajectory (repeatable)")
    parser.add_argument("--window-flow", help="omnipose-experiment-window-flow output")
    args = parser.parse_args()

    truth = load_tum(args.groundtruth)
    sources = [(path, tum_yaw_errors(truth, load_tum(path))) for path in args.tum]
    if args.window_flow:
        sources += list(window_flow_yaw_errors(args.window_flow).items())
    if not sources:
        parser.error("give --tum and/or --window-flow")
    parts = segments(truth)
    print("source | " + " | ".join(f"{kind}{a}-{b}" for kind, a, b in parts) + " | sum (deg)")
    for name, errors in sources:
        sums = []
        for _, a, b in parts:
            pairs = [errors[k] for k in range(a, b + 1) if k in errors]
            sums.append(math.degrees(sum(pairs)) if pairs else float("nan"))
        known = [s for s in sums if not math.isnan(s)]
        print(f"{name} | " + " | ".join(f"{s:+.3f}" for s in sums) + f" | {sum(known):+.3f}")


if __name__ == "__main__":
    main()
