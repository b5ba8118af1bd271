"""Fits from static positions: seed S2's twelve-position gyro biases, and the hand-held
ellipsoid (accelerometers from |A0 + A1 u| = g at unknown orientations, gyro biases from the
Earth rate's vertical part).
"""
import math

import numpy as np
import scipy.linalg
import scipy.optimize

from .gls import FitError, Fitted, add_covariance_sources, merge_errors
from .runs import NOMINAL_SCALE, NOMINAL_SCALE_TOLERANCE, slice_means


def fit_gyro_bias(run):
    """Seed S2: gyro bias = -W1_nominal @ mean V over all positions (each axis up and
    down, each turned 180 deg: Earth rate and the g term average out)."""
    if len(run.windows) < 12:
        raise FitError(f"{run.path}: the twelve-position run has {len(run.windows)} steady "
                       "positions; gyro biases need all twelve")
    v = run.means(run.raw["gyro_volts"]).mean(axis=0)
    var = run.mean_variances(run.raw["gyro_volts"]).sum(axis=0) / len(run.windows) ** 2
    fitted = Fitted({})
    for i in range(3):
        fitted.values[f"W0[{i}]"] = float(-NOMINAL_SCALE["gyro"] * v[i])
        for j in range(3):
            fitted.values[f"W1[{i}][{j}]"] = NOMINAL_SCALE["gyro"] * (i == j)
        fitted.errors[f"W0[{i}]"] = {
            f"twelve-gyro{i}": NOMINAL_SCALE["gyro"] * math.sqrt(var[i]),
            f"turn-on-gyro{i}": run.turn_on("gyro")}
    _nominal_gyro_scale_errors(fitted, v)
    return fitted


def _nominal_gyro_scale_errors(fitted, v):
    """The datasheet gyro scale N is nominal: the unit's own is N (1 + e), e ~ the class's
    tolerance (1 sigma, sensors.mimu). Per unit e the fitted W1[i][i] is off by -N and a bias
    W0 = ... - N v (v: the mean voltage) by +N v[i]: one source per axis, in both."""
    k = NOMINAL_SCALE_TOLERANCE * NOMINAL_SCALE["gyro"]
    for i in range(3):
        merge_errors(fitted.errors, f"W0[{i}]", {f"nominal-scale-gyro{i}": k * float(v[i])})
        merge_errors(fitted.errors, f"W1[{i}][{i}]", {f"nominal-scale-gyro{i}": -k})


def fit_ellipsoid(run, windows=None):
    """Accelerometer triad from static windows at unknown orientations: per window k the
    mean voltage u_k and |A0 + A1 u_k| = g (site gravity). A1 upper triangular (its rotation
    is not observable from magnitudes: the calibrated frame has z along the sensor z axis,
    x in the sensor x-z plane), A0 (3): 9 unknowns, so >= 9 windows, well spread. Whitened
    nonlinear least squares (scipy), each window's magnitude weighted by its mean's white
    noise plus the unit's bias instability; the covariance is scaled by the Birge ratio
    chi^2/dof when above 1 and carries the turn-on repeatability in A0.
    `windows`: indices of the run's windows to use (default all).
    The calibrated frame is the accelerometers' own (z along sensor z, x in the sensor x-z
    plane); it differs from the gyros' frame by the triad's misalignment (0.1-2 % couplings:
    up to about 1-2 deg), which no magnitude can show - the A1 errors hold within this
    gauge. Use a turntable method where the gyro and accelerometer frames must agree."""
    ws = run.windows if windows is None else [run.windows[k] for k in windows]
    if len(ws) < 9:
        raise FitError(f"{run.path}: {len(ws)} static orientations; the ellipsoid fit has 9 "
                       "unknowns and needs at least 9 (more, well spread, for accuracy)")
    k0, k1 = np.array([w.k0 for w in ws]), np.array([w.k1 for w in ws])
    u = slice_means(run.raw["accel_volts"], k0, k1)
    var = np.array([np.diff(run.raw["accel_volts"][a:b], n=2, axis=0).var(axis=0) / 6.0 / (b - a)
                    for a, b in zip(k0, k1)])
    g = run.site["gravity_m_s2"]
    sigma = np.sqrt(NOMINAL_SCALE["accel"] ** 2 * var.mean(axis=1) + run.instability("accel") ** 2)
    upper = np.triu_indices(3)

    def unpack(p):
        a1 = np.zeros((3, 3))
        a1[upper] = p[3:]
        return p[:3], a1

    def resid(p):
        a0, a1 = unpack(p)
        return (np.linalg.norm(a0 + u @ a1.T, axis=1) - g) / sigma
    p0 = np.concatenate([np.zeros(3), np.diag([NOMINAL_SCALE["accel"]] * 3)[upper]])
    sol = scipy.optimize.least_squares(resid, p0, method="lm", x_scale="jac")
    chi2 = float(sol.fun @ sol.fun)
    dof = len(ws) - 9
    birge = max(chi2 / dof, 1.0) if dof > 0 else 1.0
    cov = birge * np.linalg.pinv(sol.jac.T @ sol.jac)
    if dof <= 0 or not np.all(np.isfinite(cov)) or np.linalg.cond(sol.jac) > 1e12:
        raise FitError(f"{run.path}: the orientations do not determine the ellipsoid (too few "
                       "or too alike); hold the unit in more, well-spread attitudes")
    a0, a1 = unpack(sol.x)
    names = [f"A0[{i}]" for i in range(3)] + [f"A1[{i}][{j}]" for i, j in zip(*upper)]
    fitted = Fitted({n: float(v) for n, v in zip(names, sol.x)}, stage="hand-held accel",
                    rms={"magnitude": float(np.sqrt(np.mean((sol.fun * sigma) ** 2))),
                         "birge_ratio": birge})
    for i, j in zip(*np.tril_indices(3, -1)):
        fitted.values[f"A1[{i}][{j}]"] = 0.0
    add_covariance_sources(fitted, names, cov, "ellipsoid")
    for i in range(3):
        merge_errors(fitted.errors, f"A0[{i}]", {f"ellipsoid-turn-on-accel{i}": run.turn_on("accel")})
    return fitted


def fit_gyro_bias_unknown_attitude(run, accel, windows=None):
    """Gyro biases from static windows at unknown orientations, the datasheet scale (like
    seed S2): per window, the Earth rate's vertical part (Omega sin(lat) along the up
    direction the fitted accelerometers give) minus the nominally scaled output; the horizontal
    part (Omega cos(lat), heading unknown) averages out over varied headings and stays in
    the scatter, whose standard error of the mean is the reported error with the nominal
    scale's tolerance and the turn-on repeatability."""
    ws = run.windows if windows is None else [run.windows[k] for k in windows]
    k0, k1 = np.array([w.k0 for w in ws]), np.array([w.k1 for w in ws])
    a0 = np.array([accel.values[f"A0[{i}]"] for i in range(3)])
    a1 = np.array([[accel.values[f"A1[{i}][{j}]"] for j in range(3)] for i in range(3)])
    f = slice_means(run.raw["accel_volts"], k0, k1) @ a1.T + a0
    up = f / np.linalg.norm(f, axis=1)[:, None]
    omega_up = run.site["earth_rate_rad_s"] * math.sin(run.site["latitude"])
    # w = W0 + N v must read the Earth rate at rest: W0 = Omega_up up - N v, per window
    v = slice_means(run.raw["gyro_volts"], k0, k1)
    w0 = omega_up * up - NOMINAL_SCALE["gyro"] * v
    mean = w0.mean(axis=0)
    sem = w0.std(axis=0, ddof=1) / math.sqrt(len(ws))
    fitted = Fitted({}, stage="hand-held gyro")
    for i in range(3):
        fitted.values[f"W0[{i}]"] = float(mean[i])
        for j in range(3):
            fitted.values[f"W1[{i}][{j}]"] = NOMINAL_SCALE["gyro"] * (i == j)
        fitted.errors[f"W0[{i}]"] = {
            f"hand-held-gyro{i}": float(sem[i]), f"turn-on-gyro{i}": run.turn_on("gyro")}
    _nominal_gyro_scale_errors(fitted, v.mean(axis=0))
    return fitted
