"""A run of omnipose as Foxglove topics (foxglove-sdk), for an MCAP file or a live viewer.

One frame's outcome, from the library (a FrameResult) or from the daemon's LCM messages
(pose_t, fit_diagnostics_t, status_t), is written on these topics (docs/DESIGN.md section 9):

- ``/omnipose/pose``      foxglove.PoseInFrame: the chained pose, camera in ``omnipose_origin``
- ``/tf``                 foxglove.FrameTransform ``omnipose_origin`` -> ``omnipose_camera``
- ``/omnipose/relative``  foxglove.PoseInFrame: the frame's motion, camera in
  ``omnipose_reference`` (the frame it was registered against): rotation R, position tau = t/rho
- ``/omnipose/motion``    JSON: state, status, roll/pitch/yaw of the pair and the chained
  heading (degrees), omega, tau, residual, windows used
- ``/omnipose/windows``   JSON: each window's centre column, du, dv, confidence, validity, its
  weight in the fit and the share of it judged moving on its own (a person), and the fitted
  sinusoids at the same windows (model_du, model_dv), pixels; gamma and
  forward_column give each window's azimuth, gamma * (center_u - forward_column)
- ``/omnipose/status``    JSON: the daemon's status_t fields, or a replay's counts
- ``/omnipose/panorama``  foxglove.CompressedImage (JPEG): a small panorama; from a dataset
  with the windows' measured shifts (dots) and the fitted sinusoid (line) drawn in a strip
  below it, from the daemon its panorama_image_t as published (lcm.panorama_channel)

Positions are in scene distances (the translation is known up to scale); every segment starts
again at the identity in ``omnipose_origin``. Camera frame: x forward, y left, z up.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import Any, Dict, Mapping, Optional

import numpy as np

import foxglove
from foxglove import messages as fm

FRAME_ORIGIN = "omnipose_origin"
FRAME_CAMERA = "omnipose_camera"
FRAME_REFERENCE = "omnipose_reference"

TOPIC_POSE = "/omnipose/pose"
TOPIC_TF = "/tf"
TOPIC_RELATIVE = "/omnipose/relative"
TOPIC_MOTION = "/omnipose/motion"
TOPIC_WINDOWS = "/omnipose/windows"
TOPIC_STATUS = "/omnipose/status"
TOPIC_PANORAMA = "/omnipose/panorama"

WINDOW_FIELDS = ("center_u", "du", "dv", "rotation", "scale", "confidence", "model_du",
                 "model_dv", "weight", "moving_fraction")
WINDOW_FLAGS = ("valid", "masked")

_STATUS_NAMES = {0: "ok", 1: "degraded", 2: "lost"}
_TRACK_NAMES = {0: "start", 1: "tracked", 2: "bridged", 3: "lost", 4: "gyro"}


@dataclass
class FrameRecord:
    """One frame's outcome, whatever it came from. time_ns: the frame's capture time (the
    message's log time), nanoseconds; pose: (4, 4) camera to segment origin; rotation (3, 3)
    and tau (3,): the relative motion (P_ref = R P + t, tau = t / rho) when has_motion."""

    time_ns: int
    sequence: int
    reference_sequence: int
    segment: int
    state: str
    status: str
    has_motion: bool
    pose: np.ndarray
    rotation: np.ndarray
    rotation_vector: np.ndarray
    tau: np.ndarray
    residual_px: float
    windows_used: int
    windows_total: int
    seconds: float


@dataclass
class WindowRecord:
    """The windows of the pass that made a frame's estimate (fit_diagnostics_t's arrays); a
    window's azimuth is gamma * (center_u - forward_column), radians."""

    time_ns: int
    sequence: int
    refined: bool
    arrays: Dict[str, np.ndarray]
    gamma: float
    forward_column: float


def record_from_result(result: Any, sequence: int) -> FrameRecord:
    """A FrameResult (Odometry.process, replay's on_frame) of frame `sequence`."""
    return FrameRecord(
        time_ns=int(round(result.time_s * 1e9)), sequence=int(sequence),
        reference_sequence=int(result.reference_sequence), segment=int(result.segment),
        state=str(result.state), status=str(result.status), has_motion=bool(result.has_motion),
        pose=np.array(result.pose), rotation=np.array(result.rotation),
        rotation_vector=np.array(result.rotation_vector), tau=np.array(result.tau),
        residual_px=float(result.residual_rms_px), windows_used=int(result.windows_used),
        windows_total=int(result.windows_total), seconds=float(result.seconds))


def windows_from_result(result: Any, sequence: int) -> Optional[WindowRecord]:
    """A FrameResult's windows; None for a frame without them."""
    w = result.windows
    if len(w) == 0:
        return None
    arrays = {name: np.array(getattr(w, name), dtype=float) for name in WINDOW_FIELDS}
    arrays.update({name: np.array(getattr(w, name), dtype=bool) for name in WINDOW_FLAGS})
    return WindowRecord(int(round(result.time_s * 1e9)), int(sequence), bool(w.refined), arrays,
                        float(w.gamma), float(w.forward_column))


def quaternion_matrix(w: float, x: float, y: float, z: float) -> np.ndarray:
    """The rotation matrix of a quaternion (normalised first)."""
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def matrix_quaternion(r: np.ndarray) -> np.ndarray:
    """(w, x, y, z), w >= 0, of a rotation matrix (Shepperd's method: stable for any angle)."""
    t = np.trace(r)
    if t > max(r[0, 0], r[1, 1], r[2, 2]):
        s = 2.0 * math.sqrt(1.0 + t)
        q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    elif r[0, 0] >= r[1, 1] and r[0, 0] >= r[2, 2]:
        s = 2.0 * math.sqrt(max(1.0 + r[0, 0] - r[1, 1] - r[2, 2], 0.0))
        q = [(r[2, 1] - r[1, 2]) / s, 0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s]
    elif r[1, 1] >= r[2, 2]:
        s = 2.0 * math.sqrt(max(1.0 + r[1, 1] - r[0, 0] - r[2, 2], 0.0))
        q = [(r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s]
    else:
        s = 2.0 * math.sqrt(max(1.0 + r[2, 2] - r[0, 0] - r[1, 1], 0.0))
        q = [(r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return -q if q[0] < 0 else q


def rotation_vector_matrix(omega: np.ndarray) -> np.ndarray:
    """exp([omega]x) (Rodrigues)."""
    angle = float(np.linalg.norm(omega))
    if angle < 1e-12:
        return np.eye(3)
    k = np.asarray(omega, dtype=float) / angle
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx


def roll_pitch_yaw_deg(r: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw (Z-Y-X: R = Rz(yaw) Ry(pitch) Rx(roll)) of a rotation, degrees."""
    yaw = math.atan2(r[1, 0], r[0, 0])
    pitch = math.asin(max(-1.0, min(1.0, -r[2, 0])))
    roll = math.atan2(r[2, 1], r[2, 2])
    return np.degrees([roll, pitch, yaw])


def record_from_lcm_pose(msg: Any) -> FrameRecord:
    """A pose_t of the daemon."""
    omega = np.array(msg.rotation_vector, dtype=float)
    pose = np.eye(4)
    pose[:3, :3] = quaternion_matrix(*msg.orientation)
    pose[:3, 3] = msg.position
    return FrameRecord(
        time_ns=int(msg.utime) * 1000, sequence=int(msg.sequence),
        reference_sequence=int(msg.reference_sequence), segment=int(msg.segment),
        state=_TRACK_NAMES.get(int(msg.track_state), str(msg.track_state)),
        status=_STATUS_NAMES.get(int(msg.status), str(msg.status)),
        has_motion=int(msg.reference_sequence) >= 0 and int(msg.status) != 2,
        pose=pose, rotation=rotation_vector_matrix(omega), rotation_vector=omega,
        tau=np.array(msg.translation_direction, dtype=float) * float(msg.tau_norm),
        residual_px=float(msg.residual_px), windows_used=int(msg.windows_used),
        windows_total=int(msg.windows_total), seconds=float(msg.processing_time_s))


def windows_from_lcm(msg: Any) -> Optional[WindowRecord]:
    """A fit_diagnostics_t of the daemon; None without windows."""
    if msg.num_windows <= 0:
        return None
    arrays = {name: np.array(getattr(msg, name), dtype=float) for name in WINDOW_FIELDS}
    arrays.update({name: np.array(getattr(msg, name), dtype=bool) for name in WINDOW_FLAGS})
    return WindowRecord(int(msg.utime) * 1000, int(msg.sequence), bool(msg.refined), arrays,
                        float(msg.gamma), float(msg.forward_column))


def status_from_lcm(msg: Any) -> Dict[str, Any]:
    """A status_t as a JSON object (its fields, lists for arrays)."""
    out: Dict[str, Any] = {}
    for name in msg.__slots__:
        value = getattr(msg, name)
        if isinstance(value, (list, tuple)):
            value = [float(v) for v in value]
        elif isinstance(value, float) and not math.isfinite(value):
            value = None  # JSON has no infinity
        out[name] = value
    return out


class LcmDispatcher:
    """Writes the daemon's LCM messages to a RunTopics: pose_t, fit_diagnostics_t, status_t and
    panorama_image_t, recognised by their LCM fingerprint on whatever channel they come.
    counts: messages of each kind written, "other" (another type, skipped) and "bad" (the
    fingerprint of one of them but not decodable; last_error says why)."""

    def __init__(self, topics: "RunTopics") -> None:
        import omnipose

        self.topics = topics
        self.counts = {"pose": 0, "fit": 0, "status": 0, "panorama": 0, "other": 0, "bad": 0}
        self.last_error = ""
        self._kinds = {
            omnipose.pose_t._get_packed_fingerprint(): ("pose", omnipose.pose_t, self._pose),
            omnipose.fit_diagnostics_t._get_packed_fingerprint():
                ("fit", omnipose.fit_diagnostics_t, self._fit),
            omnipose.status_t._get_packed_fingerprint(): ("status", omnipose.status_t, self._status),
            omnipose.panorama_image_t._get_packed_fingerprint():
                ("panorama", omnipose.panorama_image_t, self._panorama),
        }

    def handle(self, channel: str, data: bytes) -> str:
        """Writes one message; returns its kind ("pose", ..., "other" or "bad")."""
        entry = self._kinds.get(bytes(data[:8]))
        if entry is None:
            self.counts["other"] += 1
            return "other"
        kind, message_type, write = entry
        try:
            msg = message_type.decode(data)
        except (ValueError, IndexError, struct.error, UnicodeDecodeError) as e:
            self.counts["bad"] += 1
            self.last_error = f"a message on {channel} has {kind}'s fingerprint but does not " \
                              f"decode: {e}"
            return "bad"
        write(msg)
        self.counts[kind] += 1
        return kind

    def _pose(self, msg: Any) -> None:
        self.topics.frame(record_from_lcm_pose(msg))

    def _fit(self, msg: Any) -> None:
        windows = windows_from_lcm(msg)
        if windows is not None:
            self.topics.windows(windows)

    def _status(self, msg: Any) -> None:
        self.topics.status(int(msg.utime) * 1000, status_from_lcm(msg))

    def _panorama(self, msg: Any) -> None:
        if msg.format == "jpeg":
            self.topics.panorama(int(msg.utime) * 1000, bytes(msg.data))


def _timestamp(time_ns: int) -> fm.Timestamp:
    return fm.Timestamp(sec=time_ns // 1_000_000_000, nsec=time_ns % 1_000_000_000)


def _pose(r: np.ndarray, p: np.ndarray) -> fm.Pose:
    w, x, y, z = matrix_quaternion(r)
    return fm.Pose(position=fm.Vector3(x=float(p[0]), y=float(p[1]), z=float(p[2])),
                   orientation=fm.Quaternion(x=float(x), y=float(y), z=float(z), w=float(w)))


def _array_schema(item: str) -> Dict[str, Any]:
    return {"type": "array", "items": {"type": item}}


_MOTION_SCHEMA = {
    "type": "object",
    "title": "omnipose.Motion",
    "properties": {
        "sequence": {"type": "integer"}, "reference_sequence": {"type": "integer"},
        "segment": {"type": "integer"}, "state": {"type": "string"},
        "status": {"type": "string"}, "has_motion": {"type": "boolean"},
        "roll_deg": {"type": "number"}, "pitch_deg": {"type": "number"},
        "yaw_deg": {"type": "number"}, "heading_deg": {"type": "number"},
        "omega": _array_schema("number"), "tau": _array_schema("number"),
        "tau_norm": {"type": "number"}, "residual_px": {"type": "number"},
        "windows_used": {"type": "integer"}, "windows_total": {"type": "integer"},
        "processing_ms": {"type": "number"},
    },
}

_WINDOWS_SCHEMA = {
    "type": "object",
    "title": "omnipose.Windows",
    "properties": dict(
        {"sequence": {"type": "integer"}, "refined": {"type": "boolean"},
         "gamma": {"type": "number"}, "forward_column": {"type": "number"}},
        **{name: _array_schema("number") for name in WINDOW_FIELDS},
        **{name: _array_schema("boolean") for name in WINDOW_FLAGS}),
}

_STATUS_SCHEMA = {"type": "object", "title": "omnipose.Status"}


class RunTopics:
    """The channels of a run in a foxglove Context (an MCAP writer's or a server's)."""

    def __init__(self, context: Optional[foxglove.Context] = None) -> None:
        kw = {} if context is None else {"context": context}
        self._pose = foxglove.channels.PoseInFrameChannel(TOPIC_POSE, **kw)
        self._tf = foxglove.channels.FrameTransformChannel(TOPIC_TF, **kw)
        self._relative = foxglove.channels.PoseInFrameChannel(TOPIC_RELATIVE, **kw)
        self._image = foxglove.channels.CompressedImageChannel(TOPIC_PANORAMA, **kw)
        self._motion = foxglove.Channel(TOPIC_MOTION, schema=_MOTION_SCHEMA, **kw)
        self._windows = foxglove.Channel(TOPIC_WINDOWS, schema=_WINDOWS_SCHEMA, **kw)
        self._status = foxglove.Channel(TOPIC_STATUS, schema=_STATUS_SCHEMA, **kw)

    def frame(self, rec: FrameRecord) -> None:
        """The chained pose, its transform, the relative motion (when there is one) and the
        motion's numbers."""
        t = rec.time_ns
        stamp = _timestamp(t)
        self._pose.log(fm.PoseInFrame(timestamp=stamp, frame_id=FRAME_ORIGIN,
                                      pose=_pose(rec.pose[:3, :3], rec.pose[:3, 3])), log_time=t)
        w, x, y, z = matrix_quaternion(rec.pose[:3, :3])
        p = rec.pose[:3, 3]
        self._tf.log(fm.FrameTransform(
            timestamp=stamp, parent_frame_id=FRAME_ORIGIN, child_frame_id=FRAME_CAMERA,
            translation=fm.Vector3(x=float(p[0]), y=float(p[1]), z=float(p[2])),
            rotation=fm.Quaternion(x=float(x), y=float(y), z=float(z), w=float(w))), log_time=t)
        if rec.has_motion:
            self._relative.log(fm.PoseInFrame(timestamp=stamp, frame_id=FRAME_REFERENCE,
                                              pose=_pose(rec.rotation, rec.tau)), log_time=t)
        roll, pitch, yaw = roll_pitch_yaw_deg(rec.rotation) if rec.has_motion else (0.0, 0.0, 0.0)
        self._motion.log({
            "sequence": rec.sequence, "reference_sequence": rec.reference_sequence,
            "segment": rec.segment, "state": rec.state, "status": rec.status,
            "has_motion": rec.has_motion, "roll_deg": float(roll), "pitch_deg": float(pitch),
            "yaw_deg": float(yaw), "heading_deg": float(roll_pitch_yaw_deg(rec.pose[:3, :3])[2]),
            "omega": [float(v) for v in rec.rotation_vector], "tau": [float(v) for v in rec.tau],
            "tau_norm": float(np.linalg.norm(rec.tau)), "residual_px": rec.residual_px,
            "windows_used": rec.windows_used, "windows_total": rec.windows_total,
            "processing_ms": rec.seconds * 1e3}, log_time=t)

    def windows(self, rec: WindowRecord) -> None:
        out: Dict[str, Any] = {"sequence": rec.sequence, "refined": rec.refined,
                               "gamma": rec.gamma, "forward_column": rec.forward_column}
        for name, values in rec.arrays.items():
            out[name] = [bool(v) for v in values] if values.dtype == bool else \
                [float(v) for v in values]
        self._windows.log(out, log_time=rec.time_ns)

    def status(self, time_ns: int, fields: Mapping[str, Any]) -> None:
        self._status.log(dict(fields), log_time=time_ns)

    def panorama(self, time_ns: int, jpeg: bytes) -> None:
        self._image.log(fm.CompressedImage(timestamp=_timestamp(time_ns), frame_id=FRAME_CAMERA,
                                           data=jpeg, format="jpeg"), log_time=time_ns)


def panorama_picture(panorama: np.ndarray, windows: Optional[WindowRecord],
                     width: int = 640, strip: int = 64) -> np.ndarray:
    """A BGR uint8 picture of a panorama (float grey levels, (H, W)), shrunk to at most `width`
    columns, with a strip of `strip` rows below it: each window's measured du (a dot at its
    column, BGR: green used by the fit, orange judged moving on its own (a person), red left out
    otherwise, grey masked) and the fitted sinusoid model_du (a white line)
    on one scale (the sinusoid's amplitude or the 90th percentile of the valid shifts, whichever
    is larger), zero in the middle row."""
    h, w = panorama.shape
    f = max(1, -(-w // width))
    small = panorama[: h // f * f, : w // f * f].reshape(h // f, f, w // f, f).mean(axis=(1, 3))
    grey = np.clip(small, 0, 255).astype(np.uint8)
    rows, cols = grey.shape
    out = np.zeros((rows + strip, cols, 3), dtype=np.uint8)
    out[:rows] = grey[:, :, None]
    mid = rows + strip // 2
    out[mid, :] = (60, 60, 60)
    if windows is None:
        return out
    a = windows.arrays
    x = np.clip((a["center_u"] / f).astype(int), 0, cols - 1)
    measured = np.abs(a["du"][a["valid"]])
    # One scale for the sinusoid and most windows; an outlier beyond it sits on the strip's edge.
    peak = max(float(np.max(np.abs(a["model_du"]))),
               float(np.percentile(measured, 90)) if measured.size else 0.0, 1e-9) * 1.25
    gain = (strip // 2 - 3) / peak

    def row(v: np.ndarray) -> np.ndarray:
        return np.clip(mid - np.round(v * gain).astype(int), rows + 1, rows + strip - 2)

    model_rows = row(a["model_du"])
    order = np.argsort(x)
    for i, j in zip(order[:-1], order[1:]):  # the fitted sinusoid, joined window to window
        n = max(abs(int(x[j]) - int(x[i])), abs(int(model_rows[j]) - int(model_rows[i])), 1)
        for s in np.linspace(0.0, 1.0, n + 1):
            out[int(round(model_rows[i] + s * (model_rows[j] - model_rows[i]))),
                int(round(x[i] + s * (x[j] - x[i])))] = (255, 255, 255)
    used = a["weight"] > 0
    moving = a["moving_fraction"] >= 0.06  # MovingContentCheck::kDropFraction: left out
    colours = np.where(a["masked"][:, None], (128, 128, 128),
                       np.where(moving[:, None], (0, 140, 255),
                                np.where(used[:, None], (0, 200, 0), (0, 0, 230))))
    for k, (c, r) in enumerate(zip(x, row(a["du"]))):
        out[max(r - 1, rows):r + 2, max(c - 1, 0):c + 2] = colours[k]
        out[0:4, c] = colours[k]  # the window's centre, marked on the panorama's top edge
    return out
