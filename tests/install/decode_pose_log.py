#!/usr/bin/env python3
"""Reads an LCM log file (no LCM Python module: Debian 12 has no python3-lcm) and decodes its
OMNI_POSE events with the generated Python type omnipose.pose_t; checks them against what
pose_log_writer.cpp wrote. usage: decode_pose_log.py <log file>  (omnipose/ on PYTHONPATH)

LCM log event framing (all big-endian): uint32 sync word 0xEDA1DA01, int64 event number,
int64 timestamp (microseconds), int32 channel length, int32 data length, the channel name
(not NUL-terminated), the data (the encoded message, its 8-byte type fingerprint first).
"""
import math
import struct
import sys

from omnipose import pose_t, status_t

SYNC = 0xEDA1DA01
HEADER = struct.Struct(">IqqII")


def read_events(path):
    with open(path, "rb") as f:
        data = f.read()
    offset = 0
    while offset < len(data):
        if len(data) - offset < HEADER.size:
            raise ValueError(f"truncated event header at byte {offset}")
        sync, number, utime, channel_len, data_len = HEADER.unpack_from(data, offset)
        if sync != SYNC:
            raise ValueError(f"bad sync word 0x{sync:08X} at byte {offset}")
        offset += HEADER.size
        end = offset + channel_len + data_len
        if end > len(data):
            raise ValueError(f"truncated event {number} at byte {offset}")
        channel = data[offset:offset + channel_len].decode("utf-8")
        yield number, utime, channel, data[offset + channel_len:end]
        offset = end


def check(condition, what):
    if not condition:
        sys.exit(f"decode_pose_log: FAILED: {what}")


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    events = list(read_events(sys.argv[1]))
    check([e[2] for e in events] == ["OMNI_STATUS", "OMNI_POSE", "OMNI_POSE"],
          f"channels {[e[2] for e in events]}")
    check([e[0] for e in events] == [0, 1, 2], f"event numbers {[e[0] for e in events]}")

    status = status_t.decode(events[0][3])
    check(status.frames_processed == 2, f"status frames_processed {status.frames_processed}")
    check(status.source_state == status_t.SOURCE_STREAMING, f"source_state {status.source_state}")
    check(status.source == "file /data/run1 (2 frames)", f"source {status.source!r}")
    try:
        pose_t.decode(events[0][3])
        check(False, "a status_t decoded as a pose_t")
    except ValueError:
        pass  # the fingerprint tells the types apart

    axis = (1.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0)
    for k, event in enumerate(events[1:]):
        pose = pose_t.decode(event[3])
        angle = 0.1 + 0.2 * k
        check(pose.sequence == 41 + k, f"pose {k} sequence {pose.sequence}")
        check(pose.reference_sequence == 40 + k, f"pose {k} reference {pose.reference_sequence}")
        check(pose.utime == 1_700_000_000_100_000 + 33_333 * k, f"pose {k} utime {pose.utime}")
        expected_status = pose_t.STATUS_OK if k == 0 else pose_t.STATUS_DEGRADED
        check(pose.status == expected_status, f"pose {k} status {pose.status}")
        norm = math.sqrt(sum(q * q for q in pose.orientation))
        check(abs(norm - 1.0) < 1e-12, f"pose {k} quaternion norm {norm}")
        expected_q = [math.cos(angle / 2)] + [math.sin(angle / 2) * a for a in axis]
        check(all(abs(q - e) < 1e-15 for q, e in zip(pose.orientation, expected_q)),
              f"pose {k} orientation {pose.orientation}")
        check(all(abs(r - angle * a) < 1e-15 for r, a in zip(pose.rotation_vector, axis)),
              f"pose {k} rotation_vector {pose.rotation_vector}")
        check(list(pose.covariance) == [i * 1e-3 for i in range(36)], f"pose {k} covariance")
        check(pose.windows_used == 30 + k and pose.windows_total == 32,
              f"pose {k} windows {pose.windows_used}/{pose.windows_total}")
        check(pose.residual_px == 0.5, f"pose {k} residual_px {pose.residual_px}")
        check(pose.encode() == event[3], f"pose {k} does not re-encode to the logged bytes")
        print(f"decode_pose_log: {event[2]} #{event[0]}: sequence {pose.sequence}, status "
              f"{pose.status}, |q| {norm:.15f}, windows {pose.windows_used}/{pose.windows_total}")
    print(f"decode_pose_log: {len(events)} events, 2 poses decoded and checked")


if __name__ == "__main__":
    main()
