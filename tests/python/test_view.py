"""omnipose-view's bridge: the daemon's LCM messages (on an in-process memq:// LCM, nothing on
the network) served over the Foxglove WebSocket protocol (subprotocol foxglove.sdk.v1 in
foxglove-sdk 0.30) on 127.0.0.1; a WebSocket client subscribes to the pose topic and receives
the poses published, decoded with the schema the server advertised."""

import base64
import json
import os
import pathlib
import re
import signal
import struct
import subprocess
import sys
import time

import numpy as np
import pytest

import omnipose
from omnipose import foxglove_topics as ft

foxglove = pytest.importorskip("foxglove")
lcm = pytest.importorskip("lcm")
ws_client = pytest.importorskip("websockets.sync.client")
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory  # noqa: E402

from omnipose.view import LcmBridge, main  # noqa: E402


def message_class(channel):
    """The protobuf class of an advertised channel, from its base64 FileDescriptorSet."""
    fds = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(channel["schema"]))
    pool = descriptor_pool.DescriptorPool()
    for fd in fds.file:
        pool.Add(fd)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(channel["schemaName"]))


def a_pose(sequence):
    p = omnipose.pose_t()
    p.utime = 1_700_000_000_000_000 + sequence * 33_333
    p.sequence = sequence
    p.reference_sequence = sequence - 1
    p.track_state = 1
    p.status = 0
    yaw = 0.01 * sequence
    p.orientation = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]  # w x y z
    p.position = [0.1 * sequence, -0.02 * sequence, 0.0]
    p.rotation_vector = [0.0, 0.0, 0.01]
    p.translation_direction = [1.0, 0.0, 0.0]
    p.tau_norm = 0.1
    p.windows_total = 55
    p.windows_used = 50
    return p


@pytest.fixture
def served():
    lc = lcm.LCM("memq://")
    context = foxglove.Context()
    server = foxglove.start_server(name="omnipose-test", host="127.0.0.1", port=0,
                                   context=context)
    bridge = LcmBridge(lc, ft.RunTopics(context))
    yield lc, server, bridge
    bridge.close()
    server.stop()


def test_a_client_subscribes_and_receives_the_daemons_poses(served):
    lc, server, bridge = served
    with ws_client.connect(f"ws://127.0.0.1:{server.port}",
                           subprotocols=["foxglove.sdk.v1"], open_timeout=10) as ws:
        channels = {}
        deadline = time.monotonic() + 10
        while ft.TOPIC_POSE not in channels and time.monotonic() < deadline:
            msg = json.loads(ws.recv(timeout=10))
            if msg["op"] == "advertise":
                channels.update({c["topic"]: c for c in msg["channels"]})
        pose_channel = channels[ft.TOPIC_POSE]
        assert pose_channel["schemaName"] == "foxglove.PoseInFrame"
        assert {ft.TOPIC_TF, ft.TOPIC_MOTION, ft.TOPIC_WINDOWS, ft.TOPIC_PANORAMA} <= set(channels)
        ws.send(json.dumps({"op": "subscribe",
                            "subscriptions": [{"id": 7, "channelId": pose_channel["id"]}]}))
        PoseInFrame = message_class(pose_channel)
        published, received = {}, []
        sequence = 0
        while len(received) < 3 and time.monotonic() < deadline:
            sequence += 1
            pose = a_pose(sequence)
            published[pose.utime * 1000] = pose
            lc.publish("OMNI_POSE", pose.encode())
            lc.handle_timeout(50)
            try:
                while True:
                    frame = ws.recv(timeout=0.05)
                    if isinstance(frame, bytes) and frame[0] == 1:
                        received.append(frame)
            except TimeoutError:
                pass
        assert len(received) >= 3, "no pose reached the client"
        for frame in received:
            subscription, log_time = struct.unpack_from("<IQ", frame, 1)
            assert subscription == 7
            msg = PoseInFrame.FromString(frame[13:])
            pose = published[log_time]
            assert msg.frame_id == ft.FRAME_ORIGIN
            assert msg.pose.position.x == pytest.approx(pose.position[0], abs=1e-12)
            assert msg.pose.position.y == pytest.approx(pose.position[1], abs=1e-12)
            w, x, y, z = pose.orientation
            q = msg.pose.orientation
            assert abs(q.w * w + q.x * x + q.y * y + q.z * z) == pytest.approx(1.0, abs=1e-12)
    assert bridge.counts["pose"] == sequence


def test_other_and_broken_messages_are_counted_not_served(served, capsys):
    lc, _, bridge = served
    lc.publish("SOMETHING_ELSE", b"\x01\x02\x03")
    lc.publish("OMNI_POSE", a_pose(1).encode()[:20])  # the fingerprint, then cut short
    lc.publish("OMNI_IMU", omnipose.imu_t().encode())
    picture = omnipose.panorama_image_t()
    picture.format, picture.data = "jpeg", b"\xff\xd8\xff\xd9"
    picture.size, picture.width, picture.height = 4, 2, 1
    lc.publish("OMNI_PANORAMA", picture.encode())
    for _ in range(4):
        lc.handle_timeout(50)
    assert bridge.counts["other"] == 2 and bridge.counts["bad"] == 1
    assert bridge.counts["panorama"] == 1
    assert "OMNI_POSE" in capsys.readouterr().err


def test_a_bad_port_is_refused(capsys):
    assert main(["--port", "70000"]) == 2
    assert "--port 70000" in capsys.readouterr().err


def advertised(ws, topic, deadline):
    channels = {}
    while topic not in channels and time.monotonic() < deadline:
        msg = json.loads(ws.recv(timeout=max(deadline - time.monotonic(), 0.1)))
        if msg["op"] == "advertise":
            channels.update({c["topic"]: c for c in msg["channels"]})
    return channels[topic]


def test_the_program_serves_a_recorded_daemon_log_until_stopped():
    log = os.environ.get("OMNIPOSE_TEST_DAEMON_LOG")
    if not log:
        pytest.skip("OMNIPOSE_TEST_DAEMON_LOG is not set (tools/python_test.sh sets it)")
    # The daemon's log played at a fifth of its speed (24 frames in about 4 s) as if live.
    url = f"file://{pathlib.Path(log)}?speed=0.2"
    view = subprocess.Popen(
        [sys.executable, "-m", "omnipose.view", "--lcm-url", url, "--host", "127.0.0.1",
         "--port", "0"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = view.stdout.readline()
        port = int(re.search(r"ws://127\.0\.0\.1:(\d+)", line).group(1))
        deadline = time.monotonic() + 20
        with ws_client.connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"],
                               open_timeout=10) as ws:
            channel = advertised(ws, ft.TOPIC_POSE, deadline)
            ws.send(json.dumps({"op": "subscribe",
                                "subscriptions": [{"id": 1, "channelId": channel["id"]}]}))
            PoseInFrame = message_class(channel)
            poses = []
            while not poses and time.monotonic() < deadline:
                frame = ws.recv(timeout=max(deadline - time.monotonic(), 0.1))
                if isinstance(frame, bytes) and frame[0] == 1:
                    poses.append(PoseInFrame.FromString(frame[13:]))
            assert poses and poses[0].frame_id == ft.FRAME_ORIGIN
    finally:
        view.send_signal(signal.SIGTERM)
        out, err = view.communicate(timeout=20)
    assert view.returncode == 0, err
    assert re.search(r"\d+ poses", out) and " 0 undecodable" in out, out
