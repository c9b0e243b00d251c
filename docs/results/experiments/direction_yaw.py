#!/usr/bin/env python3
"""How much of a straight's yaw error goes with the error of the translation's direction
(docs/results/ANALYSIS.md, "The straights' yaw goes with the direction of travel"; issue 54).

Reads the per-pair CSV of `omnipose-replay DATASET --relative REL.csv` on a render of the drift
benchmark's rectangle (tools/drift/rectangle.yaml: straights at frames 1-100, 131-200, 231-330
and 361-430 of every 460-frame lap, driven along the camera's x axis, yaw 0), and prints per
straight: the measured direction's azimuth (atan2(tdir_y, tdir_x), degrees; 0 is the truth),
its mean and standard deviation; the pair's yaw (rz, mrad; 0 is the truth), its mean and
standard deviation; their correlation, and the slope of yaw on azimuth (mrad per degree). The
last line pools the straights of the file. Standard library only.
Run, on a room of `tools/drift_pool.sh OUT` (which keeps OUT/ROOM/dataset and OUT/default.yaml):
  build/bin/omnipose-replay OUT/ROOM/dataset --config OUT/default.yaml --quiet \\
      --relative rel.csv > /dev/null
  python3 docs/results/experiments/direction_yaw.py rel.csv
"""
import argparse
import csv
import math

STRAIGHTS = [(1, 100), (131, 200), (231, 330), (361, 430)]
LAP = 460


def stats(xs, ys):
    n = len(xs)
    mx, my = sum(xs) / n, sum(ys) / n
    vx = sum((x - mx) ** 2 for x in xs) / n
    vy = sum((y - my) ** 2 for y in ys) / n
    cov = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / n
    corr = cov / math.sqrt(vx * vy) if vx > 0 and vy > 0 else float("nan")
    slope = cov / vx if vx > 0 else float("nan")
    return mx, math.sqrt(vx), my, math.sqrt(vy), corr, slope


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("relative_csv", help="omnipose-replay --relative output")
    args = parser.parse_args()
    rows = [r for r in csv.DictReader(open(args.relative_csv)) if r["status"] != "lost"]
    last = max(int(r["frame"]) for r in rows)
    all_x, all_y = [], []
    print("straight       azimuth mean/sd [deg]   yaw mean/sd [mrad]   corr   slope [mrad/deg]")
    for lap in range(last // LAP + 1):
        for first, end in STRAIGHTS:
            a, b = lap * LAP + first, lap * LAP + end
            xs, ys = [], []
            for r in rows:
                if a <= int(r["frame"]) <= b:
                    xs.append(math.degrees(math.atan2(float(r["tdir_y"]), float(r["tdir_x"]))))
                    ys.append(float(r["rz"]) * 1e3)
            if len(xs) < 3:
                continue
            all_x += xs
            all_y += ys
            print("%4d-%-4d      %+6.2f / %5.2f          %+6.3f / %5.3f      %+5.2f  %+6.3f"
                  % ((a, b) + stats(xs, ys)))
    if all_x:
        print("all            %+6.2f / %5.2f          %+6.3f / %5.3f      %+5.2f  %+6.3f"
              % stats(all_x, all_y))


if __name__ == "__main__":
    main()
