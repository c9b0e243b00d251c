"""The yaw of a straight drive read from the windows at the focus of expansion and contraction
(docs/results/ANALYSIS.md, "The yaw at the focus of expansion").

Where the camera translates towards azimuth theta_t, a window's du * gamma is
omega_z + lambda(theta) |tau| sin(theta_t - theta): at theta_t and theta_t + 180 deg it is the yaw
alone, whatever the scene's depth there. Each pair of a rendered dataset is replayed frame to
frame (`keyframes: {slots: 0}`) through the Python package; the windows within FOE_DEG of the
translation's axis (the fit's, or the ground truth's with direction=gt) are fitted for one
common intercept and a slope in sin(theta - theta_t) of their own at each end (quad=1: and a
term in sin^2, a depth that changes across the end), weighted by the fit's window weights. The
intercept less the fit's own (the constant of the fitted model_du) is that reading's
correction of the fit's yaw; with fuse=1 the correction is the inverse-variance mean's (the band's
variance from its residuals, the fit's from the published covariance).

Printed: over the straights' pairs (segment_yaw.py's segments of the ground truth: a run of
pairs whose camera moves), the summed yaw error of the fit and of the fit corrected by the focus
windows (degrees: what each adds to the chained heading), their RMS per pair (mrad) and the
correlation of the fit's error with the correction; then the same sums per straight.

Usage (the package installed by tools/python_test.sh):
  build-python/venv/bin/python3 docs/results/experiments/foe_yaw.py DATASET \
      [foe_deg=20] [quad=0|1] [fuse=0|1] [direction=fit|gt] [wisdom=FILE] [pipeline key=value ...]
"""
import os
import sys

import numpy as np

import omnipose
from segment_yaw import load_tum, segments  # beside this script


def rotation_vector(R):
    angle = np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))
    axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return axis * (0.5 if angle < 1e-9 else angle / (2 * np.sin(angle)))


def parse(argv):
    opts = {"threads": 1}
    for arg in argv:
        key, value = arg.split("=", 1)
        opts[key] = {"true": True, "false": False}.get(value, value)
    exp = {"foe_deg": float(opts.pop("foe_deg", 20)), "quad": opts.pop("quad", "0") == "1",
           "direction": opts.pop("direction", "fit"), "fuse": opts.pop("fuse", "0") == "1"}
    if "wisdom" in opts:
        opts["fftw_wisdom"] = opts.pop("wisdom")
    return exp, opts


def focus_correction(result, t_true, exp):
    """The focus windows' yaw less the fit's (radians), or NaN when too few windows are near."""
    w = result.windows
    gamma = w.gamma
    az = gamma * (np.asarray(w.center_u) - w.forward_column)
    weight = np.asarray(w.weight)
    used = np.asarray(w.valid) & (weight > 0)
    model = np.asarray(w.model_du) * gamma
    basis = np.column_stack([np.ones_like(az), np.cos(az), np.sin(az)])
    fit_yaw = np.linalg.lstsq(basis, model, rcond=None)[0][0]
    axis = t_true if exp["direction"] == "gt" else np.asarray(result.translation_direction)
    theta_t = np.arctan2(axis[1], axis[0])
    s = np.sin(az - theta_t)
    focus = used & (np.abs(s) < np.sin(np.radians(exp["foe_deg"])))
    front = np.cos(az - theta_t) > 0
    columns = [np.ones_like(s), s * front, s * ~front]
    if exp["quad"]:
        columns += [s ** 2 * front, s ** 2 * ~front]
    if focus.sum() < len(columns) + 2:
        return np.nan, int(focus.sum())
    A = np.column_stack(columns)[focus] * np.sqrt(weight[focus])[:, None]
    b = np.asarray(w.du)[focus] * gamma * np.sqrt(weight[focus])
    x = np.linalg.lstsq(A, b, rcond=None)[0]
    correction = x[0] - fit_yaw
    if exp["fuse"]:
        # Inverse-variance mean of the two readings: the band's from its residuals, the fit's
        # from its published covariance (the focus windows are in both: a probe, not a model).
        dof = max(1, len(b) - len(columns))
        var_band = (np.sum((b - A @ x) ** 2) / dof) * np.linalg.pinv(A.T @ A)[0, 0]
        var_fit = np.asarray(result.covariance)[2, 2]
        correction *= var_fit / (var_fit + var_band)
    return correction, int(focus.sum())


def main():
    exp, opts = parse(sys.argv[2:])
    ds = omnipose.open_dataset(sys.argv[1])
    straights = [(first, last) for kind, first, last in
                 segments(load_tum(os.path.join(ds.root, "groundtruth.tum"))) if kind == "S"]
    odometry = omnipose.Odometry(ds.calibration, keyframes={"slots": 0}, **opts)
    gt = ds.groundtruth["poses"]
    err, corr, focus_n = {}, {}, {}  # pair k (frames k-1 -> k) -> value
    for k, (path, t) in enumerate(zip(ds.frames, ds.timestamps)):
        result = odometry.process(omnipose.read_frame(path), t, sequence=k)
        if k == 0 or not result.has_motion:
            continue
        R_true = gt[k - 1][:3, :3].T @ gt[k][:3, :3]
        t_true = gt[k - 1][:3, :3].T @ (gt[k][:3, 3] - gt[k - 1][:3, 3])
        err[k] = result.rotation_vector[2] - rotation_vector(R_true)[2]
        moving = np.linalg.norm(t_true[:2]) > 1e-6
        corr[k], focus_n[k] = focus_correction(result, t_true, exp) if moving else (np.nan, 0)
    pairs = [k for first, last in straights for k in range(first, last + 1) if k in err]
    es = np.array([err[k] for k in pairs])
    cs = np.array([corr[k] for k in pairs])
    known = ~np.isnan(cs)
    print(f"pairs {len(err)}, straight {len(pairs)}, focus windows per straight pair median "
          f"{np.median([focus_n[k] for k in pairs]):.0f}, without a reading {(~known).sum()}")
    print(f"straights: yaw error summed: fit {np.degrees(es.sum()):+.4f} deg, corrected "
          f"{np.degrees((es + np.nan_to_num(cs)).sum()):+.4f} deg; RMS per pair: fit "
          f"{1e3 * np.sqrt(np.mean(es ** 2)):.4f} mrad, corrected "
          f"{1e3 * np.sqrt(np.mean((es[known] + cs[known]) ** 2)):.4f} mrad; "
          f"corr(error, -correction) {np.corrcoef(es[known], -cs[known])[0, 1]:+.3f}")
    for first, last in straights:
        ks = [k for k in range(first, last + 1) if k in err]
        fit = sum(err[k] for k in ks)
        corrected = fit + sum(np.nan_to_num(corr[k]) for k in ks)
        print(f"  straight pairs {first}-{last}: fit {np.degrees(fit):+.4f} deg, corrected "
              f"{np.degrees(corrected):+.4f} deg")


if __name__ == "__main__":
    main()
