"""The daemon's LCM messages in the package (omnipose.pose_t, ...), as the .deb's package has them."""

import pytest

import omnipose


def test_the_message_types_are_in_the_package():
    for name in ("pose_t", "status_t", "fit_diagnostics_t", "imu_t"):
        assert name in omnipose.__all__
        assert hasattr(getattr(omnipose, name), "decode")


def test_a_pose_survives_encoding():
    pose = omnipose.pose_t()
    pose.utime = 1_700_000_000_123_456
    pose.sequence = 42
    pose.status = omnipose.pose_t.STATUS_DEGRADED
    pose.track_state = omnipose.pose_t.TRACK_GYRO
    pose.orientation = [0.5, 0.5, -0.5, 0.5]
    pose.rotation_vector = [0.01, -0.02, 0.03]
    back = omnipose.pose_t.decode(pose.encode())
    assert back.utime == pose.utime and back.sequence == 42
    assert back.status == omnipose.pose_t.STATUS_DEGRADED
    assert back.track_state == omnipose.pose_t.TRACK_GYRO
    assert list(back.orientation) == pytest.approx([0.5, 0.5, -0.5, 0.5])
    assert list(back.rotation_vector) == pytest.approx([0.01, -0.02, 0.03])


def test_another_types_bytes_are_refused():
    imu = omnipose.imu_t()
    imu.gyro = [0.1, 0.2, 0.3]
    with pytest.raises(ValueError):
        omnipose.pose_t.decode(imu.encode())
