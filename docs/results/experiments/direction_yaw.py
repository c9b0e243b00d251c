#!/usr/bin/env python3
"""How much of a straight's yaw error goes with the error of the translation's direction
(docs/results/ANALYSIS.md, "The straights' yaw goes with the direction of travel"; issue 54).

Reads the per-pair CSV of `omnipose-replay DATASET --relative REL.csv` on a render of the drift
benchmark's rectangle (--motion, default tools/drift/rectangle.yaml: its translation segments are
the straights, driven along the camera's x axis with yaw 0, and its segments make one lap; the
lap repeats to the CSV's last frame), and prints per
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
import os
import re

RECTANGLE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "tools",
                         "drift", "rectangle.yaml")


def straights(motion_path):
    """The straights of one lap as (first, last) pair numbers (the pair ending at frame f is f),
    and the lap's length in frames, from the motion file's `- {frames: N, translation: ...}` and
    `- {frames: N, rotation: ...}` segment lines."""
    ranges, step = [], 0
    for line in open(motion_path):
        m = re.match(r"\s*-\s*\{\s*frames:\s*(\d+)\s*,\s*(translation|rotation)\b", line)
        if not m:
            continue
        frames = int(m.group(1))
        if m.group(2) == "translation":
            ranges.append((step + 1, step + frames))
        step += frames
    if not ranges:
        raise SystemExit("%s: no `- {frames: N, translation: ...}` segment" % motion_path)
    return ranges, step


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
    parser.add_argument("--motion", default=RECTANGLE,
                        help="the omnipose-synth motion file rendered (default: %(default)s)")
    args = parser.parse_args()
    lap_straights, lap_frames = straights(args.motion)
    rows = [r for r in csv.DictReader(open(args.relative_csv)) if r["status"] != "lost"]
    last = max(int(r["frame"]) for r in rows)
    all_x, all_y = [], []
    print("straight       azimuth mean/sd [deg]   yaw mean/sd [mrad]   corr   slope [mrad/deg]")
    for lap in range(last // lap_frames + 1):
        for first, end in lap_straights:
            a, b = lap * lap_frames + first, lap * lap_frames + end
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
