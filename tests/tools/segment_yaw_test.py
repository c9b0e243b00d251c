#!/usr/bin/env python3
"""docs/results/experiments/segment_yaw.py on made-up trajectories: a straight of 10 pairs and a
turn of 5 (0.02 rad a pair about z); the estimate's pairs err by +0.1 mrad of yaw on the straight
and -0.2 mrad in the turn, and one estimated pose is missing (its two pairs must not count); a
window-flow output gives +0.3 mrad a pair on the straight, and in its named columns (the tool's
--synthetic: "warp X affine Y similarity Z") -0.5 mrad a pair of warp on the straight and 0.1
of similarity in the turn. The sums per segment must be those.
Usage: segment_yaw_test.py SOURCE_DIR"""
import math
import os
import subprocess
import sys
import tempfile

script = os.path.join(sys.argv[1], "docs/results/experiments/segment_yaw.py")


def quaternion_z(angle):
    return (0.0, 0.0, math.sin(angle / 2), math.cos(angle / 2))


def tum_line(t, position, angle):
    return "%.6f %.9f %.9f %.9f %.12f %.12f %.12f %.12f\n" % (t, *position, *quaternion_z(angle))


truth, estimate = [], []
true_yaw = est_yaw = 0.0
x = 0.0
for k in range(16):
    if k > 0:
        straight = k <= 10
        if straight:
            x += 0.02
        else:
            true_yaw += 0.02
        est_yaw += (0.0 if straight else 0.02) + (1e-4 if straight else -2e-4)
    t = k / 30.0
    truth.append(tum_line(t, (x, 0.0, 0.0), true_yaw))
    if k != 4:  # pairs 4 and 5 cannot be scored
        estimate.append(tum_line(t, (x, 0.0, 0.0), est_yaw))

with tempfile.TemporaryDirectory() as tmp:
    gt, est, flow = (os.path.join(tmp, name) for name in ("gt.tum", "est.tum", "wf.txt"))
    with open(gt, "w") as f:
        f.write("# timestamp tx ty tz qx qy qz qw\n" + "".join(truth))
    with open(est, "w") as f:
        f.write("".join(estimate))
    with open(flow, "w") as f:
        f.write("# pair  yaw error [mrad]: measured  exact-uv  exact-all  exact-phi  |  x\n")
        for k in range(1, 16):
            value = 0.3 if k <= 10 else 0.0
            warp, similarity = (-0.5, 0.0) if k <= 10 else (0.0, 0.1)
            f.write("%5d  %+9.4f %+9.4f %+9.4f %+9.4f  |  0.001  -  |  warp %+9.4f affine %+9.4f"
                    " similarity %+9.4f\n" % (k, value, 0, 0, 0, warp, 0, similarity))
    out = subprocess.run([sys.executable, script, gt, "--tum", est, "--window-flow", flow],
                         check=True, capture_output=True, text=True).stdout

lines = out.strip().splitlines()
assert lines[0].split(" | ")[1:3] == ["S1-10", "T11-15"], out
cells = {line.split(" | ")[0]: [float(v) for v in line.split(" | ")[1:]] for line in lines[1:]}
straight, turn, total = cells[est]
assert abs(straight - math.degrees(8 * 1e-4)) < 1e-3, out  # 10 pairs less the 2 unscored
assert abs(turn - math.degrees(5 * -2e-4)) < 1e-3, out
assert abs(total - (straight + turn)) < 2e-3, out
assert abs(cells["measured"][0] - math.degrees(10 * 3e-4)) < 1e-3, out
assert cells["measured"][1] == 0.0 and cells["exact-uv"][0] == 0.0, out
assert abs(cells["warp"][0] - math.degrees(10 * -5e-4)) < 1e-3 and cells["warp"][1] == 0.0, out
assert abs(cells["similarity"][1] - math.degrees(5 * 1e-4)) < 1e-3, out
assert cells["affine"] == [0.0, 0.0, 0.0], out
print("segment_yaw: straight and turn summed, the missing pose's pairs left out, the named "
      "columns read")
