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

Printed: over the pairs with translation and no true yaw (|omega_z| < 1e-5 rad), the summed
yaw error of the fit and of the fit corrected by the focus windows (degrees: what each adds to
the chained heading), their RMS per pair (mrad) and the correlation of the fit's error with
the correction; then the same sums per straight (runs of at least 10 such pairs).

Usage (the package installed by tools/python_test.sh):
  build-python/venv/bin/python3 docs/results/experiments/foe_yaw.py DATASET \
      [foe_deg=20] [quad=0|1] [fuse=0|1] [direction=fit|gt] [wisdom=FILE] [pipeline key=value ...]
"""
import sys

import numpy as np

import omnipose


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


def focus_correction(w, result, t_true, exp):
    """The focus windows' yaw less the fit's (radians), or NaN when too few windows are near."""
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
    odometry = omnipose.Odometry(ds.calibration, keyframes={"slots": 0}, **opts)
    gt = ds.groundtruth["poses"]
    err, corr, straight, focus_n = [], [], [], []
    for k, (path, t) in enumerate(zip(ds.frames, ds.timestamps)):
        result = odometry.process(omnipose.read_frame(path), t, sequence=k)
        if k == 0 or not result.has_motion:
            continue
        R_true = gt[k - 1][:3, :3].T @ gt[k][:3, :3]
        t_true = gt[k - 1][:3, :3].T @ (gt[k][:3, 3] - gt[k - 1][:3, 3])
        yaw_true = rotation_vector(R_true)[2]
        moving = np.linalg.norm(t_true[:2]) > 1e-6
        c, n = focus_correction(result.windows, result, t_true, exp) if moving else (np.nan, 0)
        err.append(result.rotation_vector[2] - yaw_true)
        corr.append(c)
        focus_n.append(n)
        straight.append(moving and abs(yaw_true) < 1e-5)
    err, corr, straight = np.array(err), np.array(corr), np.array(straight)
    corrected = err + np.nan_to_num(corr)
    es, cs = err[straight], corr[straight]
    known = ~np.isnan(cs)
    print(f"pairs {len(err)}, straight {straight.sum()}, focus windows per straight pair median "
          f"{np.median(np.array(focus_n)[straight]):.0f}, without a reading {(~known).sum()}")
    print(f"straights: yaw error summed: fit {np.degrees(es.sum()):+.4f} deg, corrected "
          f"{np.degrees(corrected[straight].sum()):+.4f} deg; RMS per pair: fit "
          f"{1e3 * np.sqrt(np.mean(es ** 2)):.4f} mrad, corrected "
          f"{1e3 * np.sqrt(np.mean((es[known] + cs[known]) ** 2)):.4f} mrad; "
          f"corr(error, -correction) {np.corrcoef(es[known], -cs[known])[0, 1]:+.3f}")
    start = None
    for i in range(len(err) + 1):
        inside = i < len(err) and straight[i]
        if inside and start is None:
            start = i
        elif not inside and start is not None:
            if i - start >= 10:
                print(f"  straight pairs {start + 1}-{i}: fit {np.degrees(err[start:i].sum()):+.4f}"
                      f" deg, corrected {np.degrees(corrected[start:i].sum()):+.4f} deg")
            start = None


if __name__ == "__main__":
    main()
