"""omnipose: how an omnidirectional camera moved between frames.

The C++ library (iFMI registration of a cylindrical panorama's windows and a robust fit of
two sinusoids, Kuang et al., IROS 2019) for Python, and the daemon's LCM messages
(``omnipose.pose_t``, ``status_t``, ``fit_diagnostics_t``, ``imu_t``, ``panorama_image_t``:
``decode(bytes)``, ``encode()``)::

    import numpy as np, omnipose
    cal = omnipose.Calibration.load("run/calibration.yaml")
    odo = omnipose.Odometry(cal, window=110, keyframes={"slots": 4})
    r = odo.process(frame, t)          # frame: uint8 (H, W) grey, (H, W, 3) BGR; t: seconds
    r.rotation, r.translation_direction, r.covariance, r.pose, r.state, r.status
    r.windows.du, r.windows.model_du   # each window's measured shift and the fitted sinusoid
    run = omnipose.replay("run", on_frame=lambda index, path, result: ...)

With the extras: ``omnipose-mcap`` (a run as MCAP for Foxglove), ``omnipose-view`` (the
daemon live over the Foxglove WebSocket protocol), ``omnipose-figure`` (a picture of a run).

Camera frame: x forward, y left, z up. A frame's relative motion is (R, t) with
P_ref = R P + t, t up to scale; the chained pose maps the camera to its segment's origin
(positions in scene distances). docs/DESIGN.md has the conventions and the formats.

Options are daemon.yaml's (tools/omniposed/daemon.example.yaml): the keys of its
``pipeline:`` section as keyword arguments, ``keyframes=`` and ``plausibility=`` dicts of
those sections' keys, ``input="omni"|"panorama"``. The daemon's own parser reads them: a bad
key or value raises ConfigError (a ValueError) with the daemon's message, named by the key.
"""

from __future__ import annotations

import math
import numbers
import os
import warnings as _warnings
from dataclasses import dataclass
from typing import Any, Callable, List, Mapping, Optional, Union

import numpy as np

from . import _omnipose
from ._omnipose import (Calibration, ConfigError, FrameResult, Panorama, Windows, encode_jpeg,
                        read_frame)
from . import _lcm_types
# The daemon's LCM messages (pose_t, status_t, fit_diagnostics_t, imu_t): encode() and
# decode(), as in the .deb's Python package of the same name.
from ._lcm_types import *  # noqa: F401,F403

__version__: str = _omnipose.__version__
__all__ = [
    "Calibration",
    "ConfigError",
    "Dataset",
    "FrameResult",
    "Odometry",
    "Panorama",
    "Replay",
    "Windows",
    "encode_jpeg",
    "open_dataset",
    "read_frame",
    "replay",
    "replay_with_config",
] + sorted(name for name in vars(_lcm_types) if name.endswith("_t"))

PathLike = Union[str, "os.PathLike[str]"]

_OPTIONS_ORIGIN = "omnipose options"


def _yaml_scalar(key: str, value: Any) -> str:
    """One option value as a YAML scalar (the daemon's parser then checks its type and range)."""
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        x = float(value)
        if math.isnan(x):
            return ".nan"
        if math.isinf(x):
            return ".inf" if x > 0 else "-.inf"
        return repr(x)
    if isinstance(value, (str, os.PathLike)):
        text = os.fspath(value)
        escaped = text.replace("\\", "\\\\").replace('"', '\\"')
        return '"' + "".join(c if c.isprintable() else "\\x%02x" % ord(c) if ord(c) < 256
                             else "\\u%04x" % ord(c) for c in escaped) + '"'
    raise TypeError(f"{key}: expected a bool, a number or a string, got {type(value).__name__}")


def _yaml_section(name: str, values: Mapping[str, Any]) -> str:
    if not isinstance(values, Mapping):
        raise TypeError(f"{name}: expected a dict of daemon.yaml's {name} keys, "
                        f"got {type(values).__name__}")
    items = []
    for key, value in values.items():
        if not isinstance(key, str):
            raise TypeError(f"{name}: keys must be strings, got {key!r}")
        items.append(_yaml_scalar(f"{name}.{key}", key) + ": " + _yaml_scalar(f"{name}.{key}", value))
    return name + ": {" + ", ".join(items) + "}\n"


def options_yaml(pipeline: Mapping[str, Any], keyframes: Optional[Mapping[str, Any]] = None,
                 plausibility: Optional[Mapping[str, Any]] = None,
                 input: Optional[str] = None,
                 loop_closure: Optional[Mapping[str, Any]] = None) -> str:
    """The daemon.yaml text that sets these options (what Odometry and replay() parse)."""
    text = _yaml_section("pipeline", pipeline) if pipeline else ""
    if keyframes is not None:
        text += _yaml_section("keyframes", keyframes)
    if plausibility is not None:
        text += _yaml_section("plausibility", plausibility)
    if loop_closure is not None:
        text += _yaml_section("loop_closure", loop_closure)
    if input is not None:
        text += "input: " + _yaml_scalar("input", input) + "\n"
    return text


def _warn(messages: List[str]) -> None:
    for message in messages:
        _warnings.warn(message, RuntimeWarning, stacklevel=3)


class Odometry(_omnipose.Odometry):
    """The odometry: frames in, per frame the motion since the previous one and the chained pose.

    ``Odometry(calibration, *, input=None, keyframes=None, plausibility=None,
    loop_closure=None, **pipeline)``:
    ``pipeline`` holds daemon.yaml's ``pipeline:`` keys (window, step, huber_delta_px,
    median, refine_iterations, use_rotation_scale, estimate_rotation_scale, min_confidence,
    inlier_sigmas, moving_content, dewarp_by_fit, yaw_capture_time, gyro_fusion,
    noise_weighting, cubic_window_sampling, plane_depth_prior, ring_consensus, vertical_scale,
    translation_shrinkage, planar_motion_deg, threads, fftw_wisdom;
    a relative fftw_wisdom path is relative to the current directory); ``keyframes``,
    ``plausibility`` and ``loop_closure`` dicts of those sections' keys. Defaults are the daemon's (threads 0: every
    core). Raises ConfigError (a ValueError) listing every bad key or value by its daemon.yaml
    key, ValueError when the options do not fit the calibration (e.g. a window taller than
    the panorama). The parser's warnings (threads clamped to the cores) are issued as
    RuntimeWarning.

    ``process(frame, t)`` reads ``frame`` in place without a copy and releases the GIL while
    the frame is processed; one caller at a time (a second thread gets RuntimeError).
    """

    def __init__(self, calibration: Calibration, *, input: Optional[str] = None,
                 keyframes: Optional[Mapping[str, Any]] = None,
                 plausibility: Optional[Mapping[str, Any]] = None,
                 loop_closure: Optional[Mapping[str, Any]] = None, **pipeline: Any) -> None:
        super().__init__(calibration,
                         options_yaml(pipeline, keyframes, plausibility, input, loop_closure),
                         _OPTIONS_ORIGIN)
        _warn(list(self.warnings))


@dataclass(frozen=True)
class Replay:
    """A dataset replayed as omnipose-replay does: the trajectory it writes (--out) and its counts.

    timestamps (N,) seconds and poses (N, 4, 4) of the frames with a pose (segment starts and
    tracked frames; a lost frame has none): the map pose, corrected by loop closures, as --out
    writes it; odometry_poses (N, 4, 4) the odometry's own (--out-odometry); sequences (N,) their frame indices, states (N) their
    TrackState names; frames, pairs, skipped (unreadable or rejected), implausible (of the
    skipped), lost, bridged, gyro_frames (rows' rotations from imu.csv); the median pipeline
    time per frame, seconds; log: omnipose-replay's lines for skipped and lost frames."""

    timestamps: np.ndarray
    poses: np.ndarray
    odometry_poses: np.ndarray
    sequences: np.ndarray
    states: List[str]
    frames: int
    pairs: int
    skipped: int
    implausible: int
    lost: int
    bridged: int
    gyro_frames: int
    median_seconds_per_frame: float
    log: List[str]


FrameCallback = Callable[[int, str, FrameResult], None]


def replay(dataset_dir: PathLike, *, calibration: Optional[PathLike] = None,
           input: Optional[str] = None, keyframes: Optional[Mapping[str, Any]] = None,
           plausibility: Optional[Mapping[str, Any]] = None,
           loop_closure: Optional[Mapping[str, Any]] = None,
           on_frame: Optional[FrameCallback] = None, **pipeline: Any) -> Replay:
    """Replays a dataset directory (calibration.yaml, frames/, timestamps.txt, imu.csv when its
    calibration has an imu section) through the odometry with Odometry's options, as
    ``omnipose-replay DATASET`` does (the same frames skipped, the same poses). ``calibration``
    replaces the dataset's calibration.yaml. ``on_frame(index, path, result)`` is called with
    every frame the odometry processed (a FrameResult, its windows included; unreadable frames
    are skipped as omnipose-replay skips them); an exception it raises ends the replay's
    callbacks and is raised by replay() at the end. The GIL is released while it runs (but
    for the callbacks). Raises RuntimeError naming the path for a dataset that cannot be
    opened, ConfigError for bad options or a bad calibration."""
    return _replay(dataset_dir,
                   options_yaml(pipeline, keyframes, plausibility, input, loop_closure),
                   _OPTIONS_ORIGIN, calibration, on_frame)


def replay_with_config(dataset_dir: PathLike, config: PathLike, *,
                       calibration: Optional[PathLike] = None,
                       on_frame: Optional[FrameCallback] = None) -> Replay:
    """replay() with the options of a daemon.yaml file (``omnipose-replay DATASET --config
    FILE``): its pipeline, keyframes, plausibility, loop_closure and input sections; relative paths in it
    (fftw_wisdom) are relative to the file. ConfigError names the file and every bad key."""
    path = os.fspath(config)
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as e:
        raise ConfigError(f"{path}: cannot read: {e.strerror}") from None
    return _replay(dataset_dir, text, path, calibration, on_frame,
                   os.path.dirname(os.path.abspath(path)))


def _replay(dataset_dir: PathLike, text: str, origin: str, calibration: Optional[PathLike],
            on_frame: Optional[FrameCallback], base_dir: Optional[str] = None) -> Replay:
    result = _omnipose._replay(os.fspath(dataset_dir), text, origin,
                               None if calibration is None else os.fspath(calibration),
                               on_frame, base_dir)
    _warn(result.pop("warnings"))
    return Replay(**result)


@dataclass(frozen=True)
class Dataset:
    """A dataset directory as the library reads it: its calibration, frame files and their
    timestamps (seconds; i / 30 s without timestamps.txt; moved to the middle of the first
    row's exposure as the calibration's sensor.timestamp says), each frame's exposure as
    recorded (timestamps.txt's third column, seconds; NaN where none), ground truth when it has
    groundtruth.tum (``groundtruth["timestamps"]`` (M,), ``groundtruth["poses"]`` (M, 4, 4),
    camera to world), the gyro file (imu.csv) when present, and the reader's warnings."""

    root: str
    calibration: Calibration
    frames: List[str]
    timestamps: np.ndarray
    exposures: np.ndarray
    timestamps_from_file: bool
    gyro_file: Optional[str]
    groundtruth: Optional[dict]
    warnings: List[str]


def open_dataset(dataset_dir: PathLike, *, calibration: Optional[PathLike] = None) -> Dataset:
    """Opens a dataset directory (include/omnipose/io/dataset.hpp). Raises RuntimeError naming
    the path when it cannot (no frames/, a bad timestamps.txt line, ...), ConfigError for a
    bad calibration."""
    d = _omnipose._open_dataset(os.fspath(dataset_dir),
                                None if calibration is None else os.fspath(calibration))
    d["root"] = os.fspath(d["root"])
    d["frames"] = [os.fspath(p) for p in d["frames"]]
    d["gyro_file"] = None if d["gyro_file"] is None else os.fspath(d["gyro_file"])
    return Dataset(**d)
