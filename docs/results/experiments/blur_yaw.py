#!/usr/bin/env python3
"""What a motion-blurred frame's yaw is, as the phase correlation sees it.

A row exposed for E seconds while the camera turns is the sharp image convolved with the
blur kernel k(x): the distribution of the image's horizontal positions over the exposure,
x(tau) = (yaw(t + tau) - yaw(t)) * pixels per radian, tau in [-E/2, E/2]. Its centroid is the
mean pose over the exposure (what `sensor.exposure_s` with a gyro takes out, DESIGN.md
section 3, "Motion blur"). The registration whitens the spectra and weighs the band with
W(w) = exp(-w^2) (a Gaussian correlation peak of 1 px): where the blur is pixels long the
kernel's spectrum K(w) has zeros inside the band, and the peak of the whitened correlation is
not the centroid. This script predicts, per frame, where that peak is (Newton's method on
sum_w W(w) |K| / sqrt(|K|^2 + n) Re(conj(K / |K|) exp(-i w x)), n the noise floor relative
to the texture's power), and compares the frame-to-frame differences with the yaw errors of
an estimate made from the images alone:
  none       the errors as they are (RMS, mrad)
  centroid   the errors less the mean-pose prediction (what exposure_s does)
  whitened   the errors less the whitened-peak prediction, for a few noise floors n

Usage: blur_yaw.py DATASET ESTIMATE.tum [--exposure E]
  DATASET   omnipose-synth output with motion blur (--exposure-time) and an exact gyro
            (--gyro-rate 1000 --gyro-noise 0 --gyro-bias 0, mounted as the camera, no time
            offset: imu.csv is the camera's own rate), its panorama 1100 px wide
  ESTIMATE  omnipose-replay's estimate of DATASET from the images alone (a calibration
            without sensor.exposure_s)
  E         the exposure, seconds (default: sensor.exposure_s of DATASET/calibration.yaml)
Needs numpy and the Python package (tools/python_test.sh installs both into
build-python/venv). docs/results/ANALYSIS.md, "Motion blur", reads it.
"""
import argparse
import math
import pathlib
import re
import sys

import numpy as np

from omnipose.foxglove_topics import quaternion_matrix

PANORAMA_WIDTH = 1100  # px over 2 pi: the default calibration's panorama
OMEGA = np.linspace(0.01, 3.0, 600)  # rad/px: the translation band (W below 1e-4 beyond)
WEIGHT = np.exp(-OMEGA**2)  # the cross-power's weight for a 1 px Gaussian peak
TAUS = 400  # samples of the exposure


def yaw_of(rotation):
    """The z component of the rotation vector of a 3x3 rotation, radians."""
    angle = math.acos(max(-1.0, min(1.0, (np.trace(rotation) - 1) / 2)))
    z = rotation[1, 0] - rotation[0, 1]
    return 0.5 * z if angle < 1e-9 else z * angle / (2 * math.sin(angle))


def read_tum(path):
    poses = {}
    for line in pathlib.Path(path).read_text().splitlines():
        if not line.strip() or line.startswith('#'):
            continue
        f = line.split()
        qx, qy, qz, qw = map(float, f[4:8])
        poses[round(float(f[0]), 6)] = quaternion_matrix(qw, qx, qy, qz)
    return poses


def pair_yaw_errors(truth, estimate):
    """Per consecutive pair: the yaw of (true relative)^T (estimated relative), mrad."""
    times = sorted(t for t in truth if t in estimate)
    errors = []
    for a, b in zip(times, times[1:]):
        true_rel = truth[a].T @ truth[b]
        est_rel = estimate[a].T @ estimate[b]
        errors.append(1e3 * yaw_of(true_rel.T @ est_rel))
    return times, np.array(errors)


def whitened_peak(kernel, noise):
    """Where the whitened correlation of the blurred row with the sharp one peaks, px."""
    weight = WEIGHT * np.abs(kernel) / np.sqrt(np.abs(kernel)**2 + noise)
    phase = np.conj(kernel / np.maximum(np.abs(kernel), 1e-12))
    x = 0.0
    for _ in range(30):
        z = phase * np.exp(-1j * OMEGA * x)
        slope = np.sum(weight * np.real(-1j * OMEGA * z))
        curvature = np.sum(weight * np.real(-(OMEGA**2) * z))
        x -= slope / curvature
    return x  # the centroid for a short blur


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('dataset', type=pathlib.Path)
    parser.add_argument('estimate', type=pathlib.Path)
    parser.add_argument('--exposure', type=float)
    args = parser.parse_args()
    exposure = args.exposure
    if exposure is None:
        match = re.search(r'exposure_s:\s*([0-9.eE+-]+)',
                          (args.dataset / 'calibration.yaml').read_text())
        if not match:
            sys.exit(f'blur_yaw: {args.dataset}/calibration.yaml states no sensor.exposure_s '
                     '(pass --exposure)')
        exposure = float(match.group(1))
    imu = np.loadtxt(args.dataset / 'imu.csv', delimiter=',', skiprows=1)
    fine = np.arange(imu[0, 0], imu[-1, 0], 1e-5)
    rate = np.interp(fine, imu[:, 0], imu[:, 3])
    yaw = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * 1e-5)])
    pixels_per_rad = PANORAMA_WIDTH / (2 * math.pi)

    truth = read_tum(args.dataset / 'groundtruth.tum')
    times, errors = pair_yaw_errors(truth, read_tum(args.estimate))
    taus = ((np.arange(TAUS) + 0.5) / TAUS - 0.5) * exposure
    centroids, kernels, lengths = [], [], []
    for t in times:
        x = (np.interp(t + taus, fine, yaw) - np.interp(t, fine, yaw)) * pixels_per_rad
        centroids.append(x.mean())
        kernels.append(np.exp(-1j * np.outer(OMEGA, x)).mean(axis=1))
        lengths.append(abs(x[-1] - x[0]))
    centroids = np.array(centroids)

    def rms(v):
        return math.sqrt(float(np.mean(v**2)))

    def to_mrad(offsets):
        return np.diff(offsets) / pixels_per_rad * 1e3

    print(f'{len(errors)} pairs, exposure {exposure} s, blur {min(lengths):.2f}..'
          f'{max(lengths):.2f} px')
    print(f'{"model":<22} {"yaw error RMS after":>20} {"corr":>6}')
    print(f'{"none":<22} {rms(errors):>20.4f} {"":>6}')
    for name, offsets in [('centroid', centroids)] + [
            (f'whitened, n = {n:g}', np.array([whitened_peak(k, n) for k in kernels]))
            for n in (0.01, 0.03, 0.1, 0.3)]:
        predicted = to_mrad(offsets)
        left = errors - predicted
        corr = float(np.corrcoef(predicted, errors)[0, 1])
        print(f'{name:<22} {rms(left):>20.4f} {corr:>6.2f}')


if __name__ == '__main__':
    main()
