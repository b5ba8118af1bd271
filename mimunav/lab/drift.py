"""Gyro drift as a time series (seed S4): an AR model of the compensated gyro output at rest,
its state-space form with a measurement-noise term, and the Kalman filter on it.

The model per axis, on means over `window_s` (the output decimated; the mean removed):
    d_k = a_1 d_(k-1) + ... + a_p d_(k-p) + w_k,   w ~ N(0, q)     (the drift, AR(p))
    y_k = d_k + v_k,                                v ~ N(0, r)     (what the gyro reads)
fitted by maximum likelihood (statsmodels SARIMAX, the Kalman filter's own likelihood), the
order p by BIC over 1..max_order. The filtered drift is the Kalman filter's estimate of d_k
from y_1..y_k; the seed's "variance reduction" is var(filtered) / var(raw) at rest.

What such a filter can and cannot do, plainly: it is a low-pass filter fitted to the
sensor's own output at rest. It removes part of the white noise (the v_k the model
separates) - never a constant bias (the mean is removed before and restored after, the
filter passes it untouched), never anything correlated with motion (scale factor, cross-
coupling, g-sensitivity: they are not in the model), and under motion it treats the true
rate changes as drift and smears them: the filtered output lags the motion. `apply` on a
dynamic span measures that: how much of what the filter removes there is motion, not noise.
"""
import math
import warnings
from dataclasses import dataclass

import numpy as np
from ..errors import require


def decimate(x, rate_hz, window_s):
    """Means of x (n, k) over consecutive windows of window_s (s) -> (m, k), rate 1/window_s."""
    k = max(1, int(round(window_s * rate_hz)))
    m = len(x) // k
    return x[:m * k].reshape(m, k, -1).mean(axis=1)


IDENTIFIABLE_AR = 0.3       # sum of AR coefficients below this: not a drift (white or oscillating)


def _model(y, order):
    sarimax = require("statsmodels.tsa.statespace.sarimax", "stats",
                      "seed S4's drift model (mimunav drift)")
    return sarimax.SARIMAX(y, order=(order, 0, 0), measurement_error=True, trend="n")


@dataclass
class DriftModel:
    """A fitted AR(p) + noise model: the statsmodels results on the record divided by
    `scale` (its sd: the optimizer works on O(1) numbers, not (rad/s)^2 of 1e-10)."""
    fit: object
    scale: float


def identify(y, max_order=4):
    """AR(p) + measurement noise of a zero-mean rest record y (m,): the BIC of each order
    and the chosen `DriftModel`. Raises ValueError on too short a record."""
    if len(y) < 50 * max_order:
        raise ValueError(f"{len(y)} samples: an AR({max_order}) drift model needs at least "
                         f"{50 * max_order}")
    scale = float(np.std(y)) or 1.0
    fits = {}
    for p in range(1, max_order + 1):
        with warnings.catch_warnings(record=True):     # convergence is reported, not printed
            warnings.simplefilter("always")
            fits[p] = _model(y / scale, p).fit(disp=False)
    bic = {p: float(f.bic) for p, f in fits.items()}
    best = min(bic, key=bic.get)
    return bic, DriftModel(fits[best], scale)


def describe(model):
    """The fitted model in plain numbers: order, AR coefficients, q and r (output units^2)."""
    fit = model.fit
    values = dict(zip(fit.model.param_names, np.asarray(fit.params, float)))
    ar = [values[n] for n in fit.model.param_names if n.startswith("ar.L")]
    # a drift is positively correlated: AR coefficients summing to under IDENTIFIABLE_AR make
    # it white like the noise (their split arbitrary), a negative sum an oscillation
    # (vibration), and any "variance reduction" is then not a drift model's
    return {"order": len(ar), "ar": ar, "q": values["sigma2"] * model.scale**2,
            "r": values["var.measurement_error"] * model.scale**2,
            "converged": bool(fit.mle_retvals.get("converged", False)),
            "identified": bool(sum(ar) >= IDENTIFIABLE_AR)}


def apply(model, y):
    """The fitted model's Kalman filter run over y (zero-mean, same decimation): the filtered
    drift estimate (m,), i.e. what the filtered gyro output would read."""
    res = _model(np.asarray(y, float) / model.scale, describe(model)["order"]).filter(
        model.fit.params)
    return np.asarray(res.filtered_state[0], float) * model.scale


def variance_reduction(model, y):
    """std of the raw record and of its filtered estimate, and their variance ratio."""
    filtered = apply(model, y)
    raw_sd, filt_sd = float(np.std(y)), float(np.std(filtered))
    return {"raw_sd": raw_sd, "filtered_sd": filt_sd, "variance_ratio": (filt_sd / raw_sd) ** 2}


def under_motion(model, y, noise_sd):
    """The filter on a span with motion (y: that span's output minus its mean): the sd of
    what the filter removes, against the sd of the noise it could remove (the raw output's
    sd at rest, `noise_sd`); a removed part far above the noise is motion the filter smears."""
    removed = y - apply(model, y)
    sd = float(np.std(removed))
    return {"removed_sd": sd, "noise_sd": noise_sd, "ratio": sd / noise_sd if noise_sd else
            math.inf}
