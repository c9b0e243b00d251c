#!/usr/bin/env python3
"""The Python binding's overhead per frame: the same frames through Odometry.process() from a
Python loop and through the C++ library's Odometry::process in a C++ loop (the module's
_process_loop_seconds), each on a fresh Odometry with the same options, alternating, several
rounds; prints the medians and the overhead in percent (docs/PERFORMANCE.md).

    python tools/python_overhead.py DATASET [--rounds 7] [--threads 0] [--fftw-wisdom FILE]

Run it with the venv that has the package (tools/python_test.sh makes build-python/venv)."""

import argparse
import statistics
import time

import numpy as np

import omnipose


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset")
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--threads", type=int, default=0, help="pipeline.threads (0: every core)")
    parser.add_argument("--fftw-wisdom", default="", help="pipeline.fftw_wisdom")
    args = parser.parse_args()

    dataset = omnipose.open_dataset(args.dataset)
    frames = np.stack([omnipose.read_frame(p) for p in dataset.frames])
    if frames.ndim != 3:
        raise SystemExit("python_overhead: the comparison takes grey frames")
    times = np.ascontiguousarray(dataset.timestamps)
    options = {"threads": args.threads, "fftw_wisdom": args.fftw_wisdom}

    def python_loop():
        odometry = omnipose.Odometry(dataset.calibration, **options)
        start = time.perf_counter()
        for i in range(len(frames)):
            odometry.process(frames[i], times[i], sequence=i)
        return (time.perf_counter() - start) / len(frames)

    def cpp_loop():
        odometry = omnipose.Odometry(dataset.calibration, **options)
        return odometry._process_loop_seconds(frames, times) / len(frames)

    python_loop(), cpp_loop()  # warm-up: plans, caches
    py, cpp = [], []
    for _ in range(args.rounds):
        py.append(python_loop())
        cpp.append(cpp_loop())
    py_median, cpp_median = statistics.median(py), statistics.median(cpp)
    print(f"frames={len(frames)} rounds={args.rounds} threads={args.threads}")
    print(f"C++ loop:    {cpp_median * 1e3:.3f} ms/frame (median; min {min(cpp) * 1e3:.3f})")
    print(f"Python loop: {py_median * 1e3:.3f} ms/frame (median; min {min(py) * 1e3:.3f})")
    # The binding's own work per call, apart from the pipeline: the array checked and wrapped.
    n = 20000
    start = time.perf_counter()
    for _ in range(n):
        omnipose._omnipose._frame_view(frames[0], dataset.calibration)
    wrap_us = (time.perf_counter() - start) / n * 1e6
    print(f"array checked and wrapped: {wrap_us:.2f} us/call")
    print(f"overhead: {(py_median / cpp_median - 1) * 100:+.2f} % (medians), "
          f"{(min(py) / min(cpp) - 1) * 100:+.2f} % (minima), "
          f"{(py_median - cpp_median) * 1e6:+.1f} us/frame")


if __name__ == "__main__":
    main()
