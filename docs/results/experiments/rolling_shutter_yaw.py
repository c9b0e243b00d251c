#!/usr/bin/env python3
"""Rolling-shutter yaw: how well can the heading at each timestamp be had from yaws measured
between the windows' mean capture times? (docs/results/ANALYSIS.md, issue 26)

A rolling-shutter pair registers yaw over [t_k + c, t_(k+1) + c], c the windows' mean capture
time after the timestamp (0.4 of a frame for the real-camera benchmark's 0.8-frame readout
through the default lens). What tells early rows from late ones, du's first harmonic, a
horizontal translation also makes, so only these samples of the heading at t_k + c are known.
This script takes the real-camera benchmark's yaw ramps (tools/real_camera_benchmark.sh,
`ramps`), the heading between frames as the renderer draws it (`--between-frames smooth`:
cubic Hermite with each frame's velocity from the parabola through its neighbours, or
`constant`), and compares ways to get the yaw between timestamps from the samples:
  - the velocity extrapolated linearly through the previous pair's estimate (the pipeline
    until ReadoutYaw),
  - the parabola (or line, cubic) through the last samples, 0, 1 or 2 frames late
    (0 frames late, parabola: ReadoutYaw, src/pipeline/readout_yaw.hpp).
Only yaw, noise-free: the floor each way leaves on this motion.
Run: python3 docs/results/experiments/rolling_shutter_yaw.py [--check]
(--check: exit 1 unless ReadoutYaw's way beats the old one on both motions; ctest runs it.)
"""
import math
import sys

FRAMES = 60
OFFSET = 0.4  # c in frames


def ramp_steps(frames):
    """Per-frame yaw steps (deg) of the benchmark's `ramps` script."""
    peaks, v, steps, p = [3, -4, 2, -3.5, 4, -2.5], 0.0, [], 0
    while len(steps) < frames - 1:
        target, start = peaks[p % len(peaks)], v
        p += 1
        for i in range(1, 11):
            if len(steps) >= frames - 1:
                break
            v = start + (target - start) * i / 6 if i <= 6 else target
            steps.append(v if abs(v) >= 0.01 else math.copysign(0.01, v))
    return steps


def heading_function(steps, smooth):
    th = [0.0]
    for s in steps:
        th.append(th[-1] + s)
    n = len(th)

    def vel(k):
        if k == 0:
            return th[1] - th[0]
        if k == n - 1:
            return th[-1] - th[-2]
        return (th[k + 1] - th[k - 1]) / 2

    def heading(t):
        k = min(max(int(math.floor(t)), 0), n - 2)
        u = t - k
        if not smooth:
            return th[k] + u * (th[k + 1] - th[k])
        return ((2 * u**3 - 3 * u**2 + 1) * th[k] + (u**3 - 2 * u**2 + u) * vel(k)
                + (-2 * u**3 + 3 * u**2) * th[k + 1] + (u**3 - u**2) * vel(k + 1))
    return th, heading


def lagrange(nodes, values, x):
    total = 0.0
    for a, (xa, ya) in enumerate(zip(nodes, values)):
        w = 1.0
        for b, xb in enumerate(nodes):
            if b != a:
                w *= (x - xb) / (xa - xb)
        total += w * ya
    return total


def rms_mrad(errors_deg):
    return math.sqrt(sum(e * e for e in errors_deg) / len(errors_deg)) * math.pi / 180 * 1e3


def main():
    steps = ramp_steps(FRAMES)
    print("yaw RMS per pair [mrad] over pairs 4..%d of `ramps` (%d frames), c = %.1f frame"
          % (FRAMES - 5, FRAMES, OFFSET))
    print("%-64s %8s %8s" % ("way", "smooth", "constant"))
    rows = {}
    for smooth in (True, False):
        th, heading = heading_function(steps, smooth)
        n = len(th)
        samples = [heading(j + OFFSET) for j in range(n - 1)]  # heading at t_j + c
        truth = [th[k + 1] - th[k] for k in range(n - 1)]
        pairs = range(4, n - 5)
        # The velocity linear through the previous pair's estimate (the old model).
        estimate, previous, errors = [], None, []
        for k in range(n - 1):
            measured = heading(k + 1 + OFFSET) - heading(k + OFFSET)
            x = measured if previous is None else (measured + OFFSET * previous) / (1 + OFFSET)
            previous = x
            estimate.append(x)
        rows.setdefault("velocity through the previous pair's estimate (old)", []).append(
            rms_mrad([estimate[k] - truth[k] for k in pairs]))

        def at(k, lag, order):
            top = min(k + lag, len(samples) - 1)
            js = list(range(top - order, top + 1))
            return lagrange([j + OFFSET for j in js], [samples[j] for j in js], k)

        for lag in (0, 1, 2):
            for order, name in ((1, "line"), (2, "parabola"), (3, "cubic")):
                if lag > 0 and order == 1:
                    continue  # the two latest samples no longer bracket the timestamp
                label = "%s through the last samples, %d frame%s late%s" % (
                    name, lag, "" if lag == 1 else "s",
                    " (ReadoutYaw)" if (lag, order) == (0, 2) else "")
                e = [(at(k + 1, lag, order) - at(k, lag, order)) - truth[k] for k in pairs]
                rows.setdefault(label, []).append(rms_mrad(e))
    for label, (a, b) in rows.items():
        print("%-64s %8.3f %8.3f" % (label, a, b))
    return rows


if __name__ == "__main__":
    table = main()
    if "--check" in sys.argv[1:]:
        old = table["velocity through the previous pair's estimate (old)"]
        new = table["parabola through the last samples, 0 frames late (ReadoutYaw)"]
        if not all(n < 0.9 * o for n, o in zip(new, old)):
            sys.exit("ReadoutYaw's way is not 10 % better than the old one: %s vs %s" % (new, old))
