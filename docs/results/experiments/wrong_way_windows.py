#!/usr/bin/env python3
"""The windows that move towards the direction of travel while the robot drives
(docs/results/ANALYSIS.md, "A depth per side of the axis, and the axis from the previous
pairs"; issue 50).

Under a translation no static point moves towards the direction of travel in azimuth: a
window's du less the yaw has the sign of the translation's part at its azimuth, whatever its
depth. This replays a dataset with a daemon.yaml's options (`omnipose.replay_with_config`)
and lists, in each processed frame's final pass, the valid windows more than MIN_AXIS_DEG from
the translation's axis whose du less the fit's yaw has the wrong sign by more than MIN_PX,
in fits whose translation moves the windows by more than MIN_PX. Per window: frame, index,
azimuth, the side (sine of its angle to the axis), du, the fit's yaw and translation
amplitude in pixels, the fitted motion's du there, its final weight and peak confidence.
Run, after tools/drift_pool.sh and with the package installed (tools/python_test.sh makes
build-python/venv):
  build-python/venv/bin/python docs/results/experiments/wrong_way_windows.py \\
      POOL/indoor_t90/dataset POOL/default.yaml
"""
import argparse
import collections
import math

import numpy as np

import omnipose


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", help="a dataset directory (frames/, calibration.yaml)")
    parser.add_argument("config", help="a daemon.yaml whose pipeline options the replay takes")
    parser.add_argument("--min-px", type=float, default=0.5, help="pixels (default 0.5)")
    parser.add_argument("--min-axis-deg", type=float, default=10.0,
                        help="degrees from the axis (default 10)")
    args = parser.parse_args()
    min_side = math.sin(math.radians(args.min_axis_deg))
    rows = []

    def on_frame(index, _path, r) -> None:
        if not r.ok or not r.has_motion:
            return
        w = r.windows
        theta = w.gamma * (np.asarray(w.center_u) - w.forward_column)
        tau, omega = np.asarray(r.tau), np.asarray(r.rotation_vector)
        # du's translation part is proportional to -tau_x sin(theta) + tau_y cos(theta)
        # (motion_model.hpp), its amplitude |tau_xy| / gamma pixels up to the window's kappa.
        amplitude = math.hypot(tau[0], tau[1]) / w.gamma
        if amplitude < args.min_px:
            return
        side = (-np.sin(theta) * tau[0] + np.cos(theta) * tau[1]) / math.hypot(tau[0], tau[1])
        yaw = omega[2] / w.gamma
        du = np.asarray(w.du)
        for k in range(len(du)):
            e = du[k] - yaw
            if w.valid[k] and e * side[k] < 0 and abs(e) > args.min_px and abs(side[k]) > min_side:
                rows.append((index, k, math.degrees(theta[k]) % 360, side[k], du[k], yaw, amplitude,
                             w.model_du[k], w.weight[k], w.confidence[k]))

    omnipose.replay_with_config(args.dataset, args.config, on_frame=on_frame)
    print(f"{len(rows)} windows move towards the direction of travel")
    weighed = sum(1 for r in rows if r[8] > 0)
    print(f"of them with a weight above 0 in the final pass: {weighed}")
    by_window = collections.Counter(r[1] for r in rows)
    print("most frequent windows (index: frames):", by_window.most_common(6))
    for r in rows:
        print("frame %d window %d azimuth %.0f deg side %.2f du %.2f yaw %.2f amplitude %.2f "
              "model %.2f weight %.2f confidence %.2f" % r)


if __name__ == "__main__":
    main()
