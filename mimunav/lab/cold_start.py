"""Seed S3: the cold-start model, the bias's drift after power-on against the
temperature change, fitted per axis on time bins.
"""
import math

import numpy as np
import scipy.linalg
import scipy.optimize

from ..compensation.calibration_file import Calibration
from ..compensation.effects import temperature_change
from ..sensors.noise import FLICKER_SPAN
from .runs import (CLASS_CROSS_COUPLING, CLASS_G_SENSITIVITY, NOMINAL_SCALE, known_inputs,
                   slice_means)
from .gls import FitError, flicker_covariance


COLD_START_WINDOWS_S = (60.0, 120.0, 180.0, 300.0)     # n = 1, 2, 3, 5 min (seed S3)
COLD_START_BIN_S = 60.0


def fit_cold_start(run, unit=""):
    """Seed S3 on a cold-start run (one power-on per axis up): per axis
        E = E(T) / (a + b T) + (c + d T) + e dT_n
    with E(T) the nominally scaled raw output (datasheet 0.1 V/g, 5 mV/(deg/s); A1, W1
    diagonal, no bias), T the accelerometer thermistor (degC) or the gyro resonance (Hz),
    E the known input (gravity and Earth rate of each position). Gyros keep a = 1, b = 0:
    Earth rate is too small to separate their scale from their bias.
    Data: 60 s bin means; GLS with flicker + per-power-on turn-on covariance (white noise
    of a 60 s mean is below 5 % of the flicker there),
    solved by scipy.optimize.least_squares on the whitened residuals. The window n is
    chosen among the basic model (no e) and n = 1, 2, 3, 5 min by BIC; every candidate's
    chi2, BIC and e are written to the file ("selection")."""
    if len(run.windows) < 3:
        raise FitError(f"{run.path}: the cold-start run has {len(run.windows)} power-ons; "
                       "seed S3 needs x, y and z up")
    f_in, w_in = known_inputs(run)
    edges = []                                  # bins: (k0, k1, power-on index)
    for j, w in enumerate(run.windows):
        step = max(2, int(round(COLD_START_BIN_S / np.median(np.diff(run.t)))))
        edges += [(k, min(k + step, w.k1), j) for k in range(w.k0, w.k1 - 1, step)]
    k0 = np.array([e[0] for e in edges])
    k1 = np.array([e[1] for e in edges])
    power_on = np.array([e[2] for e in edges])
    t0, t1 = run.t[k0 - 1], run.t[k1 - 1]
    same = (power_on[:, None] == power_on[None, :]).astype(float)

    def bins(x):
        return slice_means(x, k0, k1)
    flick = flicker_covariance(t0, t1, 1.0 / (FLICKER_SPAN * (run.t[-1] - run.t[0])),
                               0.5 / np.median(np.diff(run.t)))
    cal = Calibration(model="cold-start", unit=unit, procedure="cold-start (seed S3)",
                      A1=np.diag([NOMINAL_SCALE["accel"]] * 3),
                      W1=np.diag([NOMINAL_SCALE["gyro"]] * 3))
    selection, fits = {}, {}
    for sensor, volts, reading, truth_in in (("accel", "accel_volts", "accel_temperature", f_in),
                                             ("gyro", "gyro_volts", "gyro_frequency", w_in)):
        e_t = run.raw[volts] * NOMINAL_SCALE[sensor]
        temp = run.raw[reading]
        cov_base = (run.instability(sensor) ** 2 * flick + run.turn_on(sensor) ** 2 * same)
        covs = [cov_base + _cold_start_omitted(sensor, i, f_in[power_on]) for i in range(3)]
        for n in (None,) + COLD_START_WINDOWS_S:
            d_t = bins(_power_on_temperature_change(run, temp, n or 60.0))
            fit = [fit_cold_axis(bins(e_t[:, i]), bins(temp[:, i]), d_t[:, i],
                                  truth_in[power_on, i], covs[i], sensor == "accel",
                                  n is not None) for i in range(3)]
            fits[sensor, n] = fit
            label = "basic" if n is None else f"{n:g}"
            selection.setdefault(sensor, {})[label] = {
                "chi2": [f["chi2"] for f in fit], "bic": float(sum(f["bic"] for f in fit)),
                "e": [f["values"][4] for f in fit], "e_se": [f["se"][4] for f in fit]}
    # one window for the file: the best total BIC over both triads
    best = min((None,) + COLD_START_WINDOWS_S, key=lambda n: sum(
        selection[s]["basic" if n is None else f"{n:g}"]["bic"] for s in ("accel", "gyro")))
    for sensor in ("accel", "gyro"):
        fit = fits[sensor, best]
        cal.cold_start[sensor] = {k: np.array([f["values"][j] for f in fit])
                                  for j, k in enumerate("abcde")}
        cal.covariance[sensor] = {k: [f["se"][j] for f in fit] for j, k in enumerate("abcde")}
        cal.covariance[sensor]["matrix"] = [f["cov"] for f in fit]      # per axis, a..e
    cal.cold_start["window_s"] = best or 60.0
    cal.extra["selection"] = {"chosen": "basic" if best is None else f"{best:g} s",
                              "criterion": "BIC (GLS chi2 + k ln N)", "candidates": selection}
    return cal


def _cold_start_omitted(sensor, i, f_bins):
    """Covariance (bins x bins) of what seed S3's per-axis model leaves out of axis i, each
    power-on's gravity f_bins (m/s^2, sensor axes, per bin) through terms of seed S1 Table 2's
    class as random effects: the accelerometer's cross-coupling to the other axes, the gyro's
    acceleration effect C on all three (a per-power-on offset the turn-on term alone
    understated: zero-g offsets came out at z up to 24, zero-rate at 12)."""
    if sensor == "accel":
        shapes = CLASS_CROSS_COUPLING["accel"] * np.delete(f_bins, i, axis=1)
    else:
        shapes = CLASS_G_SENSITIVITY * f_bins
    return shapes @ shapes.T


def _power_on_temperature_change(run, temp, window):
    """dT = T(t) - T(t - window) within each power-on (effects.temperature_change)."""
    out = np.zeros_like(temp)
    for w in run.windows:
        first = w.k0 - 1
        out[first:w.k1] = temperature_change(temp[first:w.k1], window, run.t[first:w.k1])
    return out


def fit_cold_axis(e_t, temp, d_t, known, cov, scale_free, with_rate):
    """One axis of the S3 model by whitened nonlinear least squares."""
    chol = np.linalg.cholesky(cov + np.eye(len(cov)) * 1e-12 * np.trace(cov) / len(cov))
    t_c = temp - temp.mean()                           # centred for conditioning

    def model(p):
        a, b, c, d, e = p
        return e_t / (a + b * t_c) + c + d * t_c + e * d_t
    free = np.array([scale_free, scale_free, True, True, with_rate])
    p0 = np.array([1.0, 0.0, 0.0, 0.0, 0.0])

    def resid(q):
        p = p0.copy()
        p[free] = q
        return scipy.linalg.solve_triangular(chol, model(p) - known, lower=True)
    sol = scipy.optimize.least_squares(resid, p0[free], method="lm", x_scale="jac")
    p = p0.copy()
    p[free] = sol.x
    jac = sol.jac
    chi2 = float(sol.fun @ sol.fun)
    # a model that misses part of the data (chi^2/dof > 1) has wider errors than its GLS
    # covariance says: scale by the Birge ratio chi^2/dof (never shrink)
    birge = max(chi2 / max(len(known) - int(free.sum()), 1), 1.0)
    cov_q = birge * np.linalg.inv(jac.T @ jac)
    cov_p = np.zeros((5, 5))                        # all five parameters, 0 for fixed ones
    cov_p[np.ix_(free, free)] = cov_q
    # back from centred temperature: a + b (T - Tm) = (a - b Tm) + b T, likewise c + d T
    tm = temp.mean()
    jac_abs = np.eye(5)
    jac_abs[0, 1] = jac_abs[2, 3] = -tm
    values = jac_abs @ p
    cov_abs = jac_abs @ cov_p @ jac_abs.T
    return {"values": values.tolist(), "se": np.sqrt(np.diag(cov_abs)).tolist(),
            "cov": cov_abs.tolist(), "chi2": chi2, "birge": birge,
            "bic": chi2 + int(free.sum()) * math.log(len(known))}
