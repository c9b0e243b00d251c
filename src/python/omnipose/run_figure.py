"""omnipose-figure RUN.mcap OUT.png: one picture of a run from its MCAP file (omnipose-mcap).

Three panels: a panorama picture of the run (/omnipose/panorama) at a frame; that frame's
windows, the shifts each measured (du and dv, pixels, dots; invalid windows hollow) against
their azimuth with the sinusoids the fit found (model_du, model_dv, lines; hollow dots: windows
the fit left out); and the chained
heading over the run (/omnipose/motion), with the ground truth's when --groundtruth gives a
TUM file. The frame is --sequence, or by default the pictured frame whose fitted du varies
most around the ring (the clearest sinusoid). Needs matplotlib and mcap
(``pip install 'omnipose[figure]'``).
"""

from __future__ import annotations

import argparse
import io
import math
import sys
from typing import Any, Dict, List, Optional

import numpy as np

from . import foxglove_topics as ft
from .mcap_export import read_run


def _tum_heading(path: str) -> tuple:
    """Times and headings (degrees, relative to the first pose) of a TUM trajectory."""
    rows = np.loadtxt(path, comments="#", ndmin=2)
    t = rows[:, 0]
    first = ft.quaternion_matrix(rows[0, 7], rows[0, 4], rows[0, 5], rows[0, 6])
    heading = []
    for r in rows:
        m = first.T @ ft.quaternion_matrix(r[7], r[4], r[5], r[6])
        heading.append(math.degrees(math.atan2(m[1, 0], m[0, 0])))
    return t, np.unwrap(np.radians(heading)) * 180 / math.pi


def choose_frame(windows: List[Dict[str, Any]], pictured: set) -> Optional[Dict[str, Any]]:
    """The windows message to show: of the pictured frames, the one whose fitted du varies
    most around the ring (all frames when none is pictured)."""
    candidates = [w for w in windows if w["sequence"] in pictured] or windows
    if not candidates:
        return None
    return max(candidates, key=lambda w: float(np.ptp(w["model_du"])))


def make_figure(run: Dict[str, List[Any]], sequence: Optional[int] = None,
                groundtruth: Optional[str] = None, title: str = ""):
    """The figure (matplotlib) of a run read by read_run()."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt

    motion = [m for _, _, m in run.get(ft.TOPIC_MOTION, [])]
    motion_times = np.array([t for t, _, _ in run.get(ft.TOPIC_MOTION, [])]) * 1e-9
    pictures = [(t, m) for t, _, m in run.get(ft.TOPIC_PANORAMA, [])]
    time_of = {m["sequence"]: t for t, m in zip(motion_times, motion)}
    pictured = {m["sequence"] for t, m in zip(motion_times, motion)
                if any(abs(t - p * 1e-9) < 1e-6 for p, _ in pictures)}
    windows = [w for _, _, w in run.get(ft.TOPIC_WINDOWS, [])]
    if sequence is None:
        shown = choose_frame(windows, pictured)
    else:
        shown = next((w for w in windows if w["sequence"] == sequence), None)
        if shown is None:
            raise ValueError(f"frame {sequence} has no windows in the run")

    fig, axes = plt.subplots(3, 1, figsize=(10, 8.5),
                             gridspec_kw={"height_ratios": [1.1, 1.4, 1.4]})
    ax_pano, ax_win, ax_head = axes
    # The picture of the shown frame, else the one nearest in time.
    ax_pano.axis("off")
    if pictures:
        t_shown = time_of.get(shown["sequence"], 0.0) if shown else 0.0
        _, pic = min(pictures, key=lambda p: abs(p[0] * 1e-9 - t_shown))
        ax_pano.imshow(mpimg.imread(io.BytesIO(pic.data), format="jpeg"), cmap="gray",
                       vmin=0, vmax=255)
        ax_pano.set_title("panorama; below it each window's du (dots) and the fitted sinusoid",
                          fontsize=9)
    if shown is not None:
        u = np.array(shown["center_u"])
        valid = np.array(shown["weight"]) > 0  # the windows the fit used
        azimuth = np.degrees(shown["gamma"] * (u - shown["forward_column"])) % 360.0
        order = np.argsort(azimuth)
        for name, colour in (("du", "tab:blue"), ("dv", "tab:orange")):
            values = np.array(shown[name])
            ax_win.plot(azimuth[valid], values[valid], "o", ms=4, color=colour,
                        label=f"{name} measured")
            ax_win.plot(azimuth[~valid], values[~valid], "o", ms=4, mfc="none", color=colour)
            ax_win.plot(azimuth[order], np.array(shown["model_" + name])[order], "-",
                        color=colour, label=f"{name} fitted")
        m = next((x for x in motion if x["sequence"] == shown["sequence"]), None)
        label = f"frame {shown['sequence']}"
        if m is not None:
            label += (f": roll {m['roll_deg']:.2f}, pitch {m['pitch_deg']:.2f}, yaw "
                      f"{m['yaw_deg']:.2f} deg, |tau| {m['tau_norm']:.3f}")
        ax_win.set_title(label, fontsize=9)
        ax_win.set_xlabel("window azimuth (deg; 0 = forward, 90 = left)")
        ax_win.set_ylabel("shift (px)")
        ax_win.set_xlim(0, 360)
        ax_win.legend(fontsize=8, ncol=4, loc="upper right")
        ax_win.grid(alpha=0.3)
    heading = np.unwrap(np.radians([m["heading_deg"] for m in motion])) * 180 / math.pi
    if len(motion_times):
        ax_head.plot(motion_times - motion_times[0], heading, "-", color="tab:blue",
                     label="omnipose, chained")
    if groundtruth:
        t, h = _tum_heading(groundtruth)
        t0 = motion_times[0] if len(motion_times) else t[0]
        ax_head.plot(t - t0, h, "--", color="black", label="ground truth")
    ax_head.set_xlabel("time (s)")
    ax_head.set_ylabel("heading (deg)")
    ax_head.legend(fontsize=8)
    ax_head.grid(alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return fig


def main(argv: Optional[List[str]] = None) -> int:
    p = argparse.ArgumentParser(prog="omnipose-figure", description=__doc__.splitlines()[0])
    p.add_argument("run", help="an MCAP file omnipose-mcap wrote")
    p.add_argument("out", help="the picture to write (PNG, or any format matplotlib knows)")
    p.add_argument("--sequence", type=int, help="the frame whose windows are shown")
    p.add_argument("--groundtruth", help="a TUM trajectory to draw the true heading from")
    p.add_argument("--title", default="", help="a title above the panels")
    args = p.parse_args(argv)
    try:
        from mcap.exceptions import McapError
        run = read_run(args.run)
    except ImportError as e:
        print(f"omnipose-figure: needs {e.name} (pip install 'omnipose[figure]')", file=sys.stderr)
        return 1
    except (OSError, ValueError, McapError) as e:
        print(f"omnipose-figure: {args.run}: {e}", file=sys.stderr)
        return 1
    if not run.get(ft.TOPIC_MOTION):
        print(f"omnipose-figure: {args.run}: no {ft.TOPIC_MOTION} messages (not an omnipose run?)",
              file=sys.stderr)
        return 1
    try:
        fig = make_figure(run, args.sequence, args.groundtruth, args.title)
        fig.savefig(args.out, dpi=100)
    except (OSError, ValueError) as e:
        print(f"omnipose-figure: {e}", file=sys.stderr)
        return 1
    print(f"omnipose-figure: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
