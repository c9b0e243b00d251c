#!/usr/bin/env python3
"""docs/results/experiments/direction_yaw.py on a made-up --relative CSV: on the straights the
yaw is 0.1 mrad per degree of the direction's azimuth, in the turns it is far off (and must be
left out), and one lost pair must be skipped. Usage: direction_yaw_test.py SOURCE_DIR"""
import math
import os
import subprocess
import sys
import tempfile

script = os.path.join(sys.argv[1], "docs/results/experiments/direction_yaw.py")
straights = [(1, 100), (131, 200), (231, 330), (361, 430)]
with tempfile.TemporaryDirectory() as tmp:
    path = os.path.join(tmp, "rel.csv")
    with open(path, "w") as f:
        f.write("frame,status,rz,tdir_x,tdir_y,tdir_z\n")
        for frame in range(1, 461):
            on_straight = any(a <= frame <= b for a, b in straights)
            azimuth = math.sin(frame * 0.37) * 3.0  # degrees
            rz = 0.1e-3 * azimuth if on_straight else 0.05
            status = "lost" if frame == 50 else "ok"
            if frame == 50:
                rz = 1.0  # a lost pair's numbers must not count
            f.write("%d,%s,%.12g,%.12g,%.12g,0\n" % (frame, status, rz,
                                                      math.cos(math.radians(azimuth)),
                                                      math.sin(math.radians(azimuth))))
    out = subprocess.run([sys.executable, script, path], check=True, capture_output=True,
                         text=True).stdout
lines = out.strip().splitlines()
rows = [line.split() for line in lines[1:]]
assert len(rows) == 5, out  # four straights and the pooled line
assert rows[-1][0] == "all", out
for row in rows:
    corr, slope = float(row[-2]), float(row[-1])
    assert abs(corr - 1.0) < 1e-6, out
    assert abs(slope - 0.1) < 1e-6, out
print("direction_yaw: 4 straights, correlation 1, slope 0.1 mrad/deg")
