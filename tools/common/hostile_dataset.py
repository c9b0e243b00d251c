#!/usr/bin/env python3
"""Turns a dataset directory (DESIGN.md section 6) into a hostile one, for tools/soak.sh.

Inserts bad frames after randomly chosen good ones: decompression bombs (a PNG and a JPEG whose
headers declare 60000 x 60000 pixels, a complete 32000 x 32000 PNG of zeros), truncated PNG and
JPEG copies of a real frame, and garbage named as PNG, JPEG, PGM and BMP; and, when the frames
are grey PNGs, glitches that decode (a flipped copy of the next frame, the previous frame's
bytes repeated, a frame torn between the previous and the next, noise). Each gets a timestamp
between its neighbours'. Then the timestamps themselves are damaged: one step backwards and one
forward jump of JUMP seconds. Prints what it did, one line. Seeded: the same seed gives the same
dataset.

Usage: hostile_dataset.py DATASET [--seed N] [--bad-frames N] [--jump SECONDS]
"""
import argparse
import os
import random
import struct
import sys
import zlib


def png_chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def png_header(width, height):
    return b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))


def png_bomb(width, height):
    return png_header(width, height) + png_chunk(b"IDAT", zlib.compress(bytes(65), 9)) + png_chunk(b"IEND", b"")


def zero_png(width, height):
    z = zlib.compressobj(1)
    row = bytes(width + 1)
    data = b"".join(z.compress(row) for _ in range(height)) + z.flush()
    return png_header(width, height) + png_chunk(b"IDAT", data) + png_chunk(b"IEND", b"")


def read_grey_png(data):
    """(width, height, rows) of an 8-bit grey, non-interlaced PNG; rows are bytearrays."""
    pos, idat, width, height = 8, b"", 0, 0
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if depth != 8 or colour != 0 or interlace != 0:
                raise ValueError("not an 8-bit grey non-interlaced PNG")
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    raw = zlib.decompress(idat)
    rows, prev = [], bytearray(width)
    for r in range(height):
        kind = raw[r * (width + 1)]
        line = bytearray(raw[r * (width + 1) + 1:(r + 1) * (width + 1)])
        for x in range(width):
            a = line[x - 1] if x else 0
            b, c = prev[x], prev[x - 1] if x else 0
            if kind == 1:
                line[x] = (line[x] + a) & 255
            elif kind == 2:
                line[x] = (line[x] + b) & 255
            elif kind == 3:
                line[x] = (line[x] + (a + b) // 2) & 255
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(line)
        prev = line
    return width, height, rows


def grey_png(width, rows):
    data = zlib.compress(b"".join(b"\0" + bytes(r) for r in rows), 6)
    return png_header(width, len(rows)) + png_chunk(b"IDAT", data) + png_chunk(b"IEND", b"")


def jpeg_bomb(width, height):
    return b"\xff\xd8\xff\xc0\x00\x0b\x08" + struct.pack(">HH", height, width) + b"\x01\x01\x11\x00\xff\xd9"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--bad-frames", type=int, default=12)
    parser.add_argument("--jump", type=float, default=1e6)
    args = parser.parse_args()
    rng = random.Random(args.seed)
    frames_dir = os.path.join(args.dataset, "frames")
    stamps_path = os.path.join(args.dataset, "timestamps.txt")
    names = sorted(os.listdir(frames_dir))
    if len(names) < 8:
        sys.exit(f"{frames_dir}: needs at least 8 frames, has {len(names)}")
    stamps = {}
    if os.path.exists(stamps_path):
        for line in open(stamps_path):
            parts = line.split()
            if len(parts) == 2 and not parts[0].startswith("#"):
                stamps[parts[0]] = float(parts[1])
    for i, name in enumerate(names):
        stamps.setdefault(name, i / 30.0)

    with open(os.path.join(frames_dir, names[0]), "rb") as f:
        good = f.read()
    makers = [
        ("bomb_60000.png", lambda: png_bomb(60000, 60000)),
        ("bomb_60000.jpg", lambda: jpeg_bomb(60000, 60000)),
        ("zeros_32000.png", lambda: zero_png(32000, 32000)),
        ("truncated.png", lambda: good[: len(good) // 2]),
        ("garbage.jpg", lambda: bytes(rng.randrange(256) for _ in range(4096))),
        ("garbage.pgm", lambda: b"P5\n" + bytes(rng.randrange(256) for _ in range(100))),
        ("garbage.bmp", lambda: b"BM" + bytes(rng.randrange(256) for _ in range(100))),
        ("empty.png", lambda: b""),
    ]
    inserted = []
    # Glitches: frames that decode but are not the scene of their moment (a flipped copy, a
    # repeated buffer, a buffer torn between two frames, noise), when the frames are grey PNGs.
    if names[0].endswith(".png"):
        for k, label in enumerate(["flipped", "repeated", "torn", "noise"]):
            after = rng.randrange(0, len(names) - 2)
            with open(os.path.join(frames_dir, names[after]), "rb") as f:
                before = f.read()
            with open(os.path.join(frames_dir, names[after + 1]), "rb") as f:
                width, height, nxt = read_grey_png(f.read())
            if label == "flipped":
                data = grey_png(width, nxt[::-1])
            elif label == "repeated":
                data = before
            elif label == "torn":
                _, _, prev = read_grey_png(before)
                data = grey_png(width, prev[: height // 2] + nxt[height // 2:])
            else:
                data = grey_png(width, [bytearray(rng.randrange(256) for _ in range(width)) for _ in range(height)])
            name = f"{os.path.splitext(names[after])[0]}_glitch_{k}_{label}.png"
            with open(os.path.join(frames_dir, name), "wb") as f:
                f.write(data)
            t0, t1 = stamps[names[after]], stamps[names[after + 1]]
            stamps[name] = t0 + (t1 - t0) * 0.5
            inserted.append(name)
    # Damaged timestamps on good frames away from the inserted ones' neighbours.
    back, jump = sorted(rng.sample(range(2, len(names) - 1), 2))
    for k in range(args.bad_frames):
        label, make = makers[k % len(makers)]
        after = rng.randrange(0, len(names) - 1)
        name = f"{os.path.splitext(names[after])[0]}_{k:02d}_{label}"
        with open(os.path.join(frames_dir, name), "wb") as f:
            f.write(make())
        t0, t1 = stamps[names[after]], stamps[names[after + 1]]
        stamps[name] = t0 + (t1 - t0) * (k + 1) / (args.bad_frames + 2)
        inserted.append(name)
    # A backwards step: frame `back` stamped before its predecessor; a forward jump from
    # frame `jump` on.
    step = stamps[names[1]] - stamps[names[0]]
    stamps[names[back]] = stamps[names[back - 1]] - 3 * step
    for name in list(stamps):
        if name >= names[jump]:
            stamps[name] += args.jump
    with open(stamps_path, "w") as f:
        for name in sorted(stamps):
            f.write(f"{name} {stamps[name]:.9f}\n")
    print(f"hostile_dataset: {len(inserted)} bad frames inserted, timestamps step back at "
          f"{names[back]} and jump {args.jump:g} s at {names[jump]}")


if __name__ == "__main__":
    main()
