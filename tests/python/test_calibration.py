"""Calibration.load / parse and read_frame: values and errors that name the file and field."""

import pathlib

import numpy as np
import pytest

import omnipose


def test_load_reads_the_dataset_calibration(dataset_dir):
    cal = omnipose.Calibration.load(dataset_dir / "calibration.yaml")
    assert cal.frame_shape == (720, 720)
    assert cal.panorama_shape == (110, 1100)
    assert cal.readout_s == 0.0
    assert not cal.has_imu


def test_load_of_a_missing_file_names_it(tmp_path):
    missing = tmp_path / "nowhere" / "calibration.yaml"
    with pytest.raises(omnipose.ConfigError) as error:
        omnipose.Calibration.load(missing)
    assert str(missing) in str(error.value)
    assert isinstance(error.value, ValueError)


def test_bad_field_is_named_with_the_file(tmp_path, dataset_dir):
    text = (dataset_dir / "calibration.yaml").read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("radius_outer: 300", "radius_outer: 90"))
    with pytest.raises(omnipose.ConfigError) as error:
        omnipose.Calibration.load(bad)
    message = str(error.value)
    assert str(bad) in message
    assert "radius" in message


def test_parse_names_the_origin_and_an_unknown_key():
    with pytest.raises(omnipose.ConfigError) as error:
        omnipose.Calibration.parse("omni: {image_widht: 720}\npanorama: {}\n", "mine.yaml")
    assert "mine.yaml" in str(error.value)
    assert "image_widht" in str(error.value)


def test_to_yaml_round_trips(calibration):
    again = omnipose.Calibration.parse(calibration.to_yaml())
    assert again.frame_shape == calibration.frame_shape
    assert again.to_yaml() == calibration.to_yaml()


def test_read_frame_decodes_grey_frames(dataset, frames):
    assert len(frames) == len(dataset.frames) == 24
    assert frames[0].dtype == np.uint8
    assert frames[0].shape == (720, 720)
    assert frames[0].flags["C_CONTIGUOUS"]
    assert frames[0].std() > 10  # a textured image, not a blank one


def test_read_frame_errors_name_the_file(tmp_path):
    missing = tmp_path / "missing.png"
    with pytest.raises(FileNotFoundError) as error:
        omnipose.read_frame(missing)
    assert "missing.png" in str(error.value)
    garbage = tmp_path / "garbage.png"
    garbage.write_bytes(b"not an image at all")
    with pytest.raises(ValueError) as error:
        omnipose.read_frame(garbage)
    assert "garbage.png" in str(error.value)


def test_open_dataset_reads_timestamps_and_groundtruth(dataset):
    assert dataset.timestamps_from_file
    assert dataset.timestamps.shape == (24,)
    assert np.all(np.diff(dataset.timestamps) > 0)
    assert dataset.exposures.shape == (24,) and np.all(np.isnan(dataset.exposures))  # none recorded
    gt = dataset.groundtruth
    assert gt["poses"].shape == (24, 4, 4)
    assert np.allclose(gt["poses"][0], np.eye(4))


def test_open_dataset_reads_each_frames_recorded_exposure(dataset_dir, tmp_path):
    copy = tmp_path / "d"
    copy.mkdir()
    source = pathlib.Path(dataset_dir)
    (copy / "frames").symlink_to(source / "frames")
    (copy / "calibration.yaml").write_text((source / "calibration.yaml").read_text())
    names = sorted(p.name for p in (copy / "frames").iterdir())
    (copy / "timestamps.txt").write_text(
        "".join(f"{n} {i / 30} {0.004 if i % 2 else 0.012}\n" for i, n in enumerate(names)))
    d = omnipose.open_dataset(copy)
    assert np.allclose(d.exposures, [0.004 if i % 2 else 0.012 for i in range(len(names))])


def test_open_dataset_error_names_the_path(tmp_path):
    with pytest.raises(RuntimeError) as error:
        omnipose.open_dataset(tmp_path / "no_dataset")
    assert "no_dataset" in str(error.value)
