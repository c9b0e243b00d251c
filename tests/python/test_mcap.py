"""omnipose-mcap: a dataset replayed and the daemon's LCM log, written as MCAP with Foxglove's
schemas and read back with the mcap library; every pose is compared with omnipose-replay's."""

import os
import pathlib
import shutil

import numpy as np
import pytest

import omnipose
from omnipose import foxglove_topics as ft
from omnipose.mcap_export import main, read_run

pytest.importorskip("mcap.reader")
pytest.importorskip("mcap_protobuf.decoder")


def read_tum(path):
    rows = np.loadtxt(path, comments="#")
    return rows[:, 0], rows[:, 1:4], rows[:, 4:8]  # t, position, quaternion x y z w


def pose_matrix(msg):
    q = msg.pose.orientation
    m = np.eye(4)
    m[:3, :3] = ft.quaternion_matrix(q.w, q.x, q.y, q.z)
    p = msg.pose.position
    m[:3, 3] = (p.x, p.y, p.z)
    return m


def assert_poses_match_tum(messages, tum_path):
    t, position, quaternion = read_tum(tum_path)
    assert len(messages) == len(t)
    for (log_time, schema, msg), ti, pi, qi in zip(messages, t, position, quaternion):
        assert schema == "foxglove.PoseInFrame"
        assert msg.frame_id == ft.FRAME_ORIGIN
        stamp = msg.timestamp.seconds + msg.timestamp.nanos * 1e-9
        assert abs(stamp - ti) < 1e-6 and abs(log_time * 1e-9 - ti) < 1e-6
        m = pose_matrix(msg)
        assert np.allclose(m[:3, 3], pi, atol=1e-8)
        r_tum = ft.quaternion_matrix(qi[3], qi[0], qi[1], qi[2])
        angle = np.arccos(np.clip((np.trace(m[:3, :3].T @ r_tum) - 1) / 2, -1, 1))
        assert angle < 1e-7


@pytest.fixture(scope="module")
def dataset_mcap(tmp_path_factory, dataset_dir, wisdom):
    out_dir = tmp_path_factory.mktemp("mcap")
    # The replay's options, the wisdom named relative to the config file.
    shutil.copy(wisdom, out_dir / "wisdom.txt")
    (out_dir / "replay.yaml").write_text("pipeline: {fftw_wisdom: wisdom.txt}\n")
    out = out_dir / "run.mcap"
    assert main([str(dataset_dir), str(out), "--config", str(out_dir / "replay.yaml")]) == 0
    return read_run(out)


def test_a_dataset_s_poses_are_omnipose_replay_s(dataset_mcap, replay_tum):
    assert_poses_match_tum(dataset_mcap[ft.TOPIC_POSE], replay_tum)
    tf = dataset_mcap[ft.TOPIC_TF]
    assert len(tf) == len(dataset_mcap[ft.TOPIC_POSE])
    assert all(m.parent_frame_id == ft.FRAME_ORIGIN and m.child_frame_id == ft.FRAME_CAMERA
               for _, _, m in tf)


def test_relative_motion_is_the_chained_poses_step(dataset_mcap):
    poses = [pose_matrix(m) for _, _, m in dataset_mcap[ft.TOPIC_POSE]]
    relative = dataset_mcap[ft.TOPIC_RELATIVE]
    assert len(relative) == len(poses) - 1  # the first frame starts the segment
    for k, (_, _, msg) in enumerate(relative, start=1):
        assert msg.frame_id == ft.FRAME_REFERENCE
        step = np.linalg.inv(poses[k - 1]) @ poses[k]  # P_{k-1} = R P_k + t
        assert np.allclose(pose_matrix(msg)[:3, :3], step[:3, :3], atol=1e-7)


def test_windows_carry_the_measured_shifts_and_the_fitted_sinusoid(dataset_mcap):
    windows = dataset_mcap[ft.TOPIC_WINDOWS]
    motion = dataset_mcap[ft.TOPIC_MOTION]
    assert len(windows) == 23 and len(motion) == 24
    by_sequence = {m["sequence"]: m for _, _, m in motion}
    for _, _, w in windows:
        n = len(w["du"])
        assert n == by_sequence[w["sequence"]]["windows_total"] > 10
        assert all(len(w[k]) == n for k in ft.WINDOW_FIELDS + ft.WINDOW_FLAGS)
        valid = np.array(w["valid"])
        residual = np.abs(np.array(w["du"]) - np.array(w["model_du"]))[valid]
        assert np.median(residual) < 0.5  # the sinusoid fits the measured shifts
        assert np.ptp(np.array(w["model_du"])) > 0 or abs(w["model_du"][0]) > 0


def test_panorama_pictures_are_rate_limited_jpegs(dataset_mcap):
    pictures = dataset_mcap[ft.TOPIC_PANORAMA]
    times = [t for t, _, _ in pictures]
    # 24 frames at 30 fps (0.77 s) at 2 per second: the first frame's and the one 0.5 s on.
    assert len(pictures) == 2 and times[1] - times[0] >= 500_000_000
    for _, schema, msg in pictures:
        assert schema == "foxglove.CompressedImage" and msg.format == "jpeg"
        assert msg.data[:2] == b"\xff\xd8"


def test_the_replay_s_counts_close_the_file(dataset_mcap):
    (_, _, status), = dataset_mcap[ft.TOPIC_STATUS]
    assert status["final"] and status["frames"] == 24 and status["pairs"] == 23
    assert status["skipped"] == 0


@pytest.fixture(scope="module")
def daemon_log():
    value = os.environ.get("OMNIPOSE_TEST_DAEMON_LOG")
    if not value:
        pytest.skip("OMNIPOSE_TEST_DAEMON_LOG is not set (tools/python_test.sh sets it)")
    return pathlib.Path(value)


def test_the_daemon_s_log_gives_the_same_poses(tmp_path, daemon_log, replay_tum):
    out = tmp_path / "daemon.mcap"
    assert main([str(daemon_log), str(out)]) == 0
    topics = read_run(out)
    poses = topics[ft.TOPIC_POSE]
    # The daemon stamps its messages with the wall clock: compare the poses in order.
    t, position, quaternion = read_tum(replay_tum)
    assert len(poses) == len(t)
    for (_, _, msg), pi in zip(poses, position):
        assert np.allclose(pose_matrix(msg)[:3, 3], pi, atol=1e-8)
    assert len(topics[ft.TOPIC_WINDOWS]) == 23
    assert topics[ft.TOPIC_STATUS][-1][2]["final"] is True
    # lcm.panorama_hz 10: the daemon's pictures, passed through as they were published.
    pictures = topics[ft.TOPIC_PANORAMA]
    assert len(pictures) >= 1
    for _, schema, msg in pictures:
        assert schema == "foxglove.CompressedImage" and msg.format == "jpeg"
        assert msg.data[:2] == b"\xff\xd8"


def test_errors_name_the_file_and_leave_nothing(tmp_path, dataset_dir, capsys):
    out = tmp_path / "x.mcap"
    assert main([str(tmp_path / "missing"), str(out)]) == 2
    assert "missing: no such file" in capsys.readouterr().err
    bad = tmp_path / "bad.yaml"
    bad.write_text("pipeline: {window: 3}\n")
    assert main([str(dataset_dir), str(out), "--config", str(bad)]) == 1
    err = capsys.readouterr().err
    assert "bad.yaml" in err and "pipeline.window" in err
    assert not out.exists()
    out.write_bytes(b"keep")
    assert main([str(dataset_dir), str(out)]) == 2
    assert "exists" in capsys.readouterr().err and out.read_bytes() == b"keep"
    notlog = tmp_path / "notlog.lcm"
    notlog.write_bytes(b"\x00" * 64)
    assert main([str(notlog), str(tmp_path / "y.mcap")]) == 0
    assert "no pose_t message" in capsys.readouterr().err
