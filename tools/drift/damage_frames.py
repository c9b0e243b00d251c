#!/usr/bin/env python3
"""Damages frames of a dataset directory (DESIGN.md section 6) in place, for the drift
benchmark (tools/drift_benchmark.sh): the way a camera delivers bad frames and outages.

--corrupt A[-B]   frames A..B (indices into the sorted frame list, inclusive) keep their
                  names and timestamps but their files become undecodable, cycling through:
                  the first half of the real file (truncated), an empty file, 4096 random
                  bytes, and a valid but all-black image of the frame's size (PNG frames
                  only; JPEG frames get the truncated copy instead).
--remove A[-B]    frames A..B are missing: their files and their timestamps.txt lines are
                  deleted (groundtruth.tum keeps its poses: the truth goes on).
Both options may be repeated. Damaged files are replaced, not rewritten, so a dataset that
shares its files with another (cp -l) can be damaged without touching the other. Prints one line per damaged range. Seeded: the same seed gives
the same bytes. Exit code 1 with a message naming the file or range on bad input.

Usage: damage_frames.py DATASET [--corrupt A[-B]]... [--remove A[-B]]... [--seed N]
"""
import argparse
import os
import random
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
from hostile_dataset import zero_png  # noqa: E402  (a valid all-zero grey PNG)


def frame_range(text):
    try:
        first, _, last = text.partition("-")
        a, b = int(first), int(last or first)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not A or A-B (frame indices)")
    if a < 0 or b < a:
        raise argparse.ArgumentTypeError(f"'{text}': need 0 <= A <= B")
    return a, b


def png_size(data):
    """(width, height) from a PNG's IHDR, or None."""
    if data[:8] != b"\x89PNG\r\n\x1a\n" or data[12:16] != b"IHDR":
        return None
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset")
    parser.add_argument("--corrupt", type=frame_range, action="append", default=[])
    parser.add_argument("--remove", type=frame_range, action="append", default=[])
    parser.add_argument("--seed", type=int, default=27)
    args = parser.parse_args()
    rng = random.Random(args.seed)
    frames_dir = os.path.join(args.dataset, "frames")
    stamps_path = os.path.join(args.dataset, "timestamps.txt")
    if not os.path.isdir(frames_dir):
        sys.exit(f"damage_frames: {frames_dir}: no such directory")
    if not os.path.isfile(stamps_path):
        sys.exit(f"damage_frames: {stamps_path}: missing (frames would be re-stamped i / 30 s)")
    names = sorted(os.listdir(frames_dir))
    for a, b in args.corrupt + args.remove:
        if b >= len(names):
            sys.exit(f"damage_frames: range {a}-{b} is past the last frame ({len(names) - 1}) of {frames_dir}")

    kind = 0
    for a, b in args.corrupt:
        for i in range(a, b + 1):
            path = os.path.join(frames_dir, names[i])
            with open(path, "rb") as f:
                good = f.read()
            size = png_size(good)
            makers = [lambda: good[: len(good) // 2], lambda: b"",
                      lambda: bytes(rng.randrange(256) for _ in range(4096))]
            if size:
                makers.append(lambda: zero_png(*size))
            data = makers[kind % len(makers)]()
            kind += 1
            # A new file, not a rewrite: the dataset may share its files with a copy (cp -l).
            with open(path + ".tmp", "wb") as f:
                f.write(data)
            os.replace(path + ".tmp", path)
        print(f"damage_frames: corrupted frames {a}-{b} ({names[a]} .. {names[b]})")

    removed = set()
    for a, b in args.remove:
        for i in range(a, b + 1):
            os.remove(os.path.join(frames_dir, names[i]))
            removed.add(names[i])
        print(f"damage_frames: removed frames {a}-{b} ({names[a]} .. {names[b]}) and their timestamps")
    if removed:
        with open(stamps_path) as f:
            lines = f.readlines()
        with open(stamps_path + ".tmp", "w") as f:
            f.writelines(line for line in lines if line.split()[:1] and line.split()[0] not in removed)
        os.replace(stamps_path + ".tmp", stamps_path)


if __name__ == "__main__":
    main()
