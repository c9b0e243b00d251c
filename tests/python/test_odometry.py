"""Odometry.process on a rendered sequence: against the C++ replay, the ground truth, the
frame checks, the options' errors and the GIL."""

import pathlib
import threading
import time

import numpy as np
import pytest

import omnipose
from conftest import rotation_angle


def run_frames(odometry, frames, times):
    return [odometry.process(f, t, sequence=i) for i, (f, t) in enumerate(zip(frames, times))]


def test_first_frame_starts_a_segment_and_the_fields_have_their_shapes(calibration, frames):
    odometry = omnipose.Odometry(calibration, threads=1)
    first = odometry.process(frames[0], 0.0)
    assert first.ok and first.error is None
    assert first.state == "start" and not first.has_motion
    assert np.array_equal(first.pose, np.eye(4))
    second = odometry.process(frames[1], 1 / 30)
    assert second.state == "tracked" and second.has_motion and second.status == "ok"
    assert second.rotation.shape == (3, 3) and second.rotation.dtype == np.float64
    assert second.rotation_vector.shape == (3,)
    assert second.translation_direction.shape == (3,)
    assert second.covariance.shape == (6, 6)
    assert np.all(np.linalg.eigvalsh(second.covariance) > 0)
    assert second.pose.shape == (4, 4)
    assert second.sequence == 1 and second.reference_sequence == 0
    assert second.windows_used > 0 and second.windows_used <= second.windows_total
    assert 0 < second.seconds == second.timing["total"]
    # R = exp([omega]x): the matrix's angle is |omega|.
    assert rotation_angle(second.rotation) == pytest.approx(
        np.linalg.norm(second.rotation_vector), abs=1e-9)


def test_relative_rotations_match_the_ground_truth(dataset, frames):
    odometry = omnipose.Odometry(dataset.calibration)
    results = run_frames(odometry, frames, dataset.timestamps)
    gt = dataset.groundtruth["poses"]
    errors = []
    for k in range(1, len(frames)):
        r_gt = gt[k - 1][:3, :3].T @ gt[k][:3, :3]  # P_{k-1} = R P_k + t
        assert results[k].state == "tracked"
        errors.append(rotation_angle(results[k].rotation.T @ r_gt))
    assert max(errors) < 2e-3, errors  # radians
    motion = [rotation_angle(gt[k - 1][:3, :3].T @ gt[k][:3, :3]) for k in range(1, len(frames))]
    assert max(motion) > 10 * max(errors)  # the sequence does move


def test_replay_equals_process_frame_by_frame(dataset_dir, dataset, frames):
    odometry = omnipose.Odometry(dataset.calibration, threads=1)
    results = run_frames(odometry, frames, dataset.timestamps)
    replayed = omnipose.replay(dataset_dir, threads=1)
    assert replayed.frames == 24 and replayed.pairs == 23 and replayed.skipped == 0
    assert list(replayed.sequences) == list(range(24))
    assert replayed.states == [r.state for r in results]
    assert np.array_equal(replayed.timestamps, dataset.timestamps)
    assert np.array_equal(replayed.poses, np.stack([r.pose for r in results]))


def read_tum(path):
    rows = np.loadtxt(path, comments="#")
    return rows[:, 0], rows[:, 1:4], rows[:, 4:8]  # t, position, quaternion x y z w


def quaternion_matrix(q):
    x, y, z, w = q / np.linalg.norm(q)  # written with 9 digits
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def test_replay_equals_the_cpp_replay(dataset_dir, replay_tum, wisdom):
    # omnipose-replay DATASET --config (fftw_wisdom) --out replay.tum: the daemon's defaults.
    t, position, quaternion = read_tum(replay_tum)
    replayed = omnipose.replay(dataset_dir, fftw_wisdom=str(wisdom))
    assert np.allclose(replayed.timestamps, t, atol=1e-6)
    assert np.allclose(replayed.poses[:, :3, 3], position, atol=1e-8)
    for pose, q in zip(replayed.poses, quaternion):
        assert rotation_angle(pose[:3, :3].T @ quaternion_matrix(q)) < 1e-8


def test_strided_rows_and_colour_give_the_same_result(calibration, frames):
    def pair(a, b):
        odometry = omnipose.Odometry(calibration, threads=1)
        odometry.process(a, 0.0)
        return odometry.process(b, 1 / 30)

    reference = pair(frames[0], frames[1])
    # A slice of rows of a wider array: rows 800 bytes apart, read in place.
    wide = [np.zeros((720, 800), np.uint8) for _ in range(2)]
    for w, f in zip(wide, frames):
        w[:, :720] = f
    strided = pair(wide[0][:, :720], wide[1][:, :720])
    # BGR with equal channels: OpenCV's grey conversion gives the grey frame back exactly.
    colour = pair(*(np.repeat(f[:, :, None], 3, axis=2) for f in frames[:2]))
    for other in (strided, colour):
        assert np.array_equal(other.rotation, reference.rotation)
        assert np.array_equal(other.covariance, reference.covariance)


def test_frames_are_read_in_place(calibration, frames):
    # The cv::Mat header process() builds points at the array's own pixels, with its row step.
    frame = frames[0]
    address, step, channels = omnipose._omnipose._frame_view(frame, calibration)
    assert address == frame.ctypes.data and step == 720 and channels == 1
    wide = np.zeros((720, 1000, 3), np.uint8)
    view = wide[:, 100:820]
    address, step, channels = omnipose._omnipose._frame_view(view, calibration)
    assert address == view.ctypes.data and step == 3000 and channels == 3
    readonly = frame.copy()
    readonly.flags.writeable = False
    address, _, _ = omnipose._omnipose._frame_view(readonly, calibration)
    assert address == readonly.ctypes.data


@pytest.mark.parametrize("bad, error, words", [
    (np.zeros((720, 720), np.float64), TypeError, ["uint8", "(720, 720)", "got float64 (720, 720)"]),
    (np.zeros((720, 720), np.uint16), TypeError, ["uint8", "got uint16"]),
    ([[0] * 720] * 720, TypeError, ["uint8 array", "got list"]),
    (np.zeros(720 * 720, np.uint8), ValueError, ["(720, 720)", "got uint8 (518400,)"]),
    (np.zeros((480, 640), np.uint8), ValueError, ["(720, 720)", "got uint8 (480, 640)"]),
    (np.zeros((720, 720, 2), np.uint8), ValueError, ["(720, 720, 3)", "got uint8 (720, 720, 2)"]),
    (np.zeros((720, 1440), np.uint8)[:, ::2], ValueError, ["contiguous", "ascontiguousarray"]),
    (np.zeros((720, 720), np.uint8).T, ValueError, ["contiguous", "strides (1, 720)"]),
])
def test_wrong_frames_raise_naming_what_was_expected(calibration, bad, error, words):
    odometry = omnipose.Odometry(calibration, threads=1)
    with pytest.raises(error) as raised:
        odometry.process(bad, 0.0)
    for word in words:
        assert word in str(raised.value)
    assert str(raised.value).startswith("frame: expected")


def test_a_black_frame_is_rejected_not_raised(calibration, frames):
    odometry = omnipose.Odometry(calibration, threads=1)
    assert odometry.process(frames[0], 0.0).ok
    black = odometry.process(np.zeros((720, 720), np.uint8), 1 / 30)
    assert not black.ok and black.error == "bad_frame" and black.message
    assert black.state is None
    after = odometry.process(frames[2], 2 / 30)
    assert after.ok and after.state == "bridged" and after.reference_sequence == 0


@pytest.mark.parametrize("options, words", [
    ({"windw": 110}, ["pipeline.windw"]),
    ({"step": 0}, ["pipeline.step"]),
    ({"window": "large"}, ["pipeline.window"]),
    ({"threads": -1}, ["pipeline.threads"]),
    ({"window": 500}, ["pipeline.window", "panorama"]),
    ({"keyframes": {"slots": 99}}, ["keyframes.slots"]),
    ({"keyframes": {"max_tilt_deg": -1.0}}, ["keyframes.max_tilt_deg"]),
    ({"plausibility": {"max_rotation_deg_s": float("nan")}}, ["plausibility.max_rotation_deg_s"]),
    ({"plausibility": {"enable": True}}, ["plausibility.enable"]),
    ({"input": "donut"}, ["input", "donut"]),
])
def test_bad_options_raise_the_daemons_message_naming_the_key(calibration, options, words):
    with pytest.raises(omnipose.ConfigError) as raised:
        omnipose.Odometry(calibration, **options)
    assert isinstance(raised.value, ValueError)
    message = str(raised.value)
    assert message.startswith("omnipose options")
    for word in words:
        assert word in message, message


def test_every_bad_option_is_reported_at_once(calibration):
    with pytest.raises(omnipose.ConfigError) as raised:
        omnipose.Odometry(calibration, step=0, median=-3, keyframes={"slots": 99})
    message = str(raised.value)
    assert "pipeline.step" in message and "pipeline.median" in message
    assert "keyframes.slots" in message


def test_options_of_an_unsupported_type_raise_type_error(calibration):
    with pytest.raises(TypeError, match=r"pipeline\.window: expected a bool, a number or a string"):
        omnipose.Odometry(calibration, window=[110])
    with pytest.raises(TypeError, match="keyframes: expected a dict"):
        omnipose.Odometry(calibration, keyframes=4)


def test_options_change_the_pipeline(calibration, frames):
    odometry = omnipose.Odometry(calibration, threads=1, window=90, step=30,
                                 keyframes={"slots": 2}, input="omni")
    assert odometry.threads == 1 and odometry.frame_shape == (720, 720)
    default = omnipose.Odometry(calibration, threads=1)
    assert odometry.window_count < default.window_count
    odometry.process(frames[0], 0.0)
    assert odometry.process(frames[1], 1 / 30).keyframe_sequence == 0


def test_threads_beyond_the_cores_warn(calibration):
    with pytest.warns(RuntimeWarning, match="pipeline.threads"):
        odometry = omnipose.Odometry(calibration, threads=64)
    assert odometry.threads < 64


def test_the_gil_is_released_while_a_frame_is_processed(calibration, frames):
    # A Python thread counts while process() runs in another: with the GIL held it would stand
    # still for the whole call (C++ code does not give the GIL up on its own).
    odometry = omnipose.Odometry(calibration, threads=1)
    odometry.process(frames[0], 0.0)
    progress = []
    for k in range(1, 6):
        worker = threading.Thread(target=odometry.process, args=(frames[k], k / 30))
        count = 0
        start = time.perf_counter()
        worker.start()
        while worker.is_alive():
            count += 1
        progress.append((count, time.perf_counter() - start))
        worker.join()
    counts = [c for c, _ in progress]
    assert min(counts) > 1000, progress


def test_a_second_caller_is_refused_while_one_processes(calibration, frames):
    odometry = omnipose.Odometry(calibration, threads=1)
    odometry.process(frames[0], 0.0)
    errors = []

    def process_many():
        for k in range(1, 8):
            try:
                odometry.process(frames[k], k / 30)
            except RuntimeError as e:
                errors.append(str(e))

    workers = [threading.Thread(target=process_many) for _ in range(3)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    assert errors, "three threads never overlapped in 21 calls"
    assert all("another thread is using this Odometry" in e for e in errors)


def test_counters_are_not_read_while_another_thread_processes(calibration, frames):
    # gyro_counters() reads what process() writes: while a frame is processed it is refused
    # like a second process(), never a torn read.
    odometry = omnipose.Odometry(calibration, threads=1)
    odometry.process(frames[0], 0.0)
    errors = []

    def read_counters(stop):
        while not stop.is_set():
            try:
                odometry.gyro_counters()
            except RuntimeError as e:
                errors.append(str(e))

    stop = threading.Event()
    reader = threading.Thread(target=read_counters, args=(stop,))
    reader.start()
    for k in range(1, 8):
        odometry.process(frames[k], k / 30)
    stop.set()
    reader.join()
    assert errors, "the reader never overlapped a process() call"
    assert all("Odometry.gyro_counters: another thread is using this Odometry" in e for e in errors)
    assert odometry.gyro_counters()["accepted"] == 0  # free again once no frame is processed


def test_the_maps_counters_say_what_became_of_each_registration(walk_dataset_dir):
    # The walk driven there and back: the return meets the places of the way out (a place every
    # 0.02 scene distances, so that more than the five newest lie in reach).
    dataset = omnipose.open_dataset(walk_dataset_dir)
    frames = [omnipose.read_frame(p) for p in dataset.frames]
    there_and_back = list(range(len(frames))) + list(range(len(frames) - 2, -1, -1))
    counts = {}
    for enabled in (True, False):
        odometry = omnipose.Odometry(dataset.calibration, threads=1, loop_closure={
            "enabled": enabled, "check_interval": 1, "place_spacing": 0.02, "search_radius": 0.1})
        closed = sum(odometry.process(frames[i], k / 30).loop_closed
                     for k, i in enumerate(there_and_back))
        counts[enabled] = odometry.loop_closure_counters()
        assert counts[enabled]["closures"] == closed
    c = counts[True]
    assert set(c) == {"compared", "no_ring_peak", "turned_too_far", "fit_failed", "too_far",
                      "verified", "disagreed", "closures"}
    assert c["closures"] >= 1, c
    assert c["verified"] >= 2 * c["closures"], c  # confirmations: 2 matches in a row
    assert c["compared"] == (c["verified"] + c["no_ring_peak"] + c["turned_too_far"]
                             + c["fit_failed"] + c["too_far"]), c
    assert c["disagreed"] == 0, c
    assert all(v == 0 for v in counts[False].values()), counts[False]


def test_type_stubs_are_installed():
    package = pathlib.Path(omnipose.__file__).parent
    assert (package / "py.typed").exists()
    stub = (package / "_omnipose.pyi").read_text()
    assert "class Odometry" in stub and "def process(" in stub
    assert "class FrameResult" in stub and "covariance" in stub


def test_the_windows_and_their_fitted_shifts_are_in_the_result(calibration, frames):
    odometry = omnipose.Odometry(calibration)
    first = odometry.process(frames[0], 0.0)
    assert len(first.windows) == 0  # a segment start has no estimate
    r = odometry.process(frames[1], 1 / 30)
    w = r.windows
    assert len(w) == r.windows_total == odometry.window_count
    assert w.valid.dtype == bool and w.du.shape == (len(w),)
    assert int(np.count_nonzero(w.valid)) >= r.windows_used
    # How much each window weighed: the heaviest 1, a window left out 0.
    assert w.weight.max() == 1.0 and np.all(w.weight[~w.valid] == 0)
    assert int(np.count_nonzero(w.weight)) >= r.windows_used
    assert np.all((w.moving_fraction >= 0) & (w.moving_fraction <= 1))
    # The fitted motion's shift at each window is the measured one up to the residual.
    residual = (w.du - w.model_du)[w.valid]
    assert np.sqrt(np.mean(residual ** 2)) < 3 * max(r.residual_rms_px, 0.05)
    # Around the ring one step (pipeline.step, 20 columns) apart, wrapping at the panorama's width.
    width = calibration.panorama_shape[1]
    assert np.all(np.mod(np.diff(w.center_u), width) == 20)


def test_on_frame_sees_every_frame_and_its_exception_is_raised(dataset_dir, dataset):
    seen = []
    omnipose.replay(dataset_dir, on_frame=lambda i, path, r: seen.append((i, path, r.state)))
    assert [i for i, _, _ in seen] == list(range(24))
    assert seen[0][2] == "start" and all(s == "tracked" for _, _, s in seen[1:])
    assert [path for _, path, _ in seen] == dataset.frames
    calls = []

    def fail(i, path, r):
        calls.append(i)
        raise KeyError("stop here")

    with pytest.raises(KeyError, match="stop here"):
        omnipose.replay(dataset_dir, on_frame=fail)
    assert calls == [0]  # no call after the first exception


def test_panorama_and_jpeg(calibration, frames):
    pano = omnipose.Panorama(calibration)
    image = pano.unwrap(frames[0])
    assert image.shape == pano.shape == tuple(calibration.panorama_shape)
    assert image.dtype == np.float32 and 20 < image.mean() < 235
    jpeg = omnipose.encode_jpeg(np.clip(image, 0, 255).astype(np.uint8), 80)
    assert jpeg[:2] == b"\xff\xd8" and len(jpeg) > 1000
    with pytest.raises(ValueError, match="quality"):
        omnipose.encode_jpeg(np.zeros((4, 4), np.uint8), 0)
    with pytest.raises(ValueError, match="input"):
        omnipose.Panorama(calibration, "donut")
    with pytest.raises(ValueError, match="frame"):
        pano.unwrap(np.zeros((3, 3), np.uint8))


def test_a_frames_stated_exposure_is_taken_and_a_bad_one_counted(calibration, frames):
    # Without a gyro the exposure changes no pose; one that is not a number of seconds in
    # [0, 0.1] is refused and counted.
    plain = omnipose.Odometry(calibration, threads=1)
    stated = omnipose.Odometry(calibration, threads=1)
    for i, f in enumerate(frames[:3]):
        a = plain.process(f, i / 30)
        b = stated.process(f, i / 30, exposure=[0.004, 0.2, -1.0][i])
        assert np.array_equal(a.pose, b.pose)
    assert plain.gyro_counters()["exposures_refused"] == 0
    assert stated.gyro_counters()["exposures_refused"] == 2
