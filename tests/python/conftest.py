"""Shared fixtures of the Python package's tests (tools/python_test.sh runs them).

The dataset: OMNIPOSE_TEST_DATASET, a directory omnipose-synth rendered (tools/python_test.sh
renders a 24-frame rotating sequence with exact ground truth); OMNIPOSE_TEST_REPLAY_TUM, what
the C++ omnipose-replay wrote for it (--out); OMNIPOSE_TEST_WALK_DATASET, a 16-frame walk in
the box room. Tests that need them are skipped without them."""

import os
import pathlib

import numpy as np
import pytest

import omnipose


def _env_path(name):
    value = os.environ.get(name)
    if not value:
        pytest.skip(f"{name} is not set (tools/python_test.sh sets it)")
    path = pathlib.Path(value)
    if not path.exists():
        pytest.fail(f"{name}={value} does not exist")
    return path


@pytest.fixture(scope="session")
def dataset_dir():
    return _env_path("OMNIPOSE_TEST_DATASET")


@pytest.fixture(scope="session")
def walk_dataset_dir():
    """A 16-frame walk of 5-15 cm steps in omnipose-synth's box room (tools/python_test.sh)."""
    return _env_path("OMNIPOSE_TEST_WALK_DATASET")


@pytest.fixture(scope="session")
def replay_tum():
    return _env_path("OMNIPOSE_TEST_REPLAY_TUM")


@pytest.fixture(scope="session")
def wisdom():
    return _env_path("OMNIPOSE_TEST_WISDOM")


@pytest.fixture(scope="session", autouse=True)
def _wisdom_first():
    """The C++ replay's FFTW wisdom into this process before any plan is made."""
    path = os.environ.get("OMNIPOSE_TEST_WISDOM")
    dataset = os.environ.get("OMNIPOSE_TEST_DATASET")
    if path and dataset:
        cal = omnipose.Calibration.load(pathlib.Path(dataset) / "calibration.yaml")
        assert omnipose.Odometry(cal, threads=1, fftw_wisdom=path).wisdom_loaded, path


@pytest.fixture(scope="session")
def dataset(dataset_dir):
    return omnipose.open_dataset(dataset_dir)


@pytest.fixture(scope="session")
def frames(dataset):
    """Every frame of the dataset, decoded by the library, as uint8 arrays."""
    return [omnipose.read_frame(p) for p in dataset.frames]


@pytest.fixture(scope="session")
def calibration(dataset):
    return dataset.calibration


def rotation_angle(r):
    """Angle of a rotation matrix, radians (atan2 of sin and cos: exact near 0 too)."""
    sin = np.linalg.norm([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / 2.0
    return float(np.arctan2(sin, (np.trace(r) - 1.0) / 2.0))
