"""What the drift tools share (bridge_error.py, segment_errors.py): reading a TUM trajectory's
rotations and the quaternion products they compare them with. Quaternions are (w, x, y, z)."""
import sys


def read_tum(path):
    """The (timestamp, quaternion) of every pose of a TUM file, in file order; exits with
    "PATH:LINE: ..." on a line without 8 fields, or "PATH: reason" when it cannot be read."""
    poses = []
    try:
        with open(path) as f:
            for n, line in enumerate(f, 1):
                if line.startswith("#") or not line.strip():
                    continue
                v = line.split()
                if len(v) != 8:
                    sys.exit(f"{path}:{n}: expected 8 fields, got {len(v)}")
                x, y, z, w = (float(t) for t in v[4:8])
                poses.append((float(v[0]), (w, x, y, z)))
    except OSError as e:
        sys.exit(f"{path}: {e.strerror}")
    return poses


def conj(q):
    return (q[0], -q[1], -q[2], -q[3])


def mul(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return (w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2)
