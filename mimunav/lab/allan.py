"""Random errors of an inertial sensor from a static record: the overlapping Allan deviation
with its confidence interval, and the five IEEE Std 952-1997 (Annex C) terms fitted to it.

For a rate output (gyro rad/s, accelerometer m/s^2) sampled as interval means, the Allan
variance of the five independent processes adds (IEEE 952 eq. C.17 ff.):

    AVAR(tau) = 3 Q^2 / tau^2 + N^2 / tau + (2 ln 2 / pi) B^2 + K^2 tau / 3 + R^2 tau^2 / 2

Q quantization (rad, m/s), N angle/velocity random walk (rad/sqrt(s), m/s/sqrt(s)), B bias
instability (rad/s, m/s^2; the flat floor is 0.664 B), K rate/acceleration random walk
(rad/s/sqrt(s), m/s^2/sqrt(s)), R rate ramp (rad/s^2, m/s^3). The terms are found by
non-negative weighted least squares on AVAR (linear in Q^2 ... R^2; weights from each
point's equivalent degrees of freedom, floored at a 10 % model uncertainty), so a term the
data do not show comes out zero with an upper bound instead of a fitted negative square.

Deviations by allantools (overlapping ADEV, Greenhall's EDF, chi-squared intervals), with
the noise type at each tau from the local slope of the curve.
"""
import itertools
import math

import numpy as np
from scipy.optimize import nnls
from ..errors import require

TERMS = ("quantization", "random_walk", "bias_instability", "rate_random_walk", "rate_ramp")
FLICKER_FLOOR = math.sqrt(2 * math.log(2) / math.pi)       # ADEV floor / B = 0.664
CI68 = 0.6826894921370859
# Relative uncertainty floor of an AVAR point in the fit: the five-term model is itself an
# approximation (pulse quantization of a constant rate, sampling and filters bend the short-tau
# end by more than the chi-squared error of millions of averages), so no point weighs more
# than a 10 % AVAR (5 % ADEV) uncertainty; the fit's chi^2/dof then inflates the intervals.
MODEL_FLOOR = 0.1


def avar_basis(tau):
    """(len(tau), 5) columns of AVAR per unit squared term (module doc)."""
    tau = np.asarray(tau, dtype=float)
    return np.column_stack([3 / tau**2, 1 / tau, np.full_like(tau, FLICKER_FLOOR**2),
                            tau / 3, tau**2 / 2])


def allan_deviation(x, rate_hz, points_per_decade=8):
    """Overlapping Allan deviation of a rate record x (n,) sampled at rate_hz: dict with
    tau_s, adev, lo, hi (68 % chi-squared interval) and edf, for tau from 1/rate_hz to a
    tenth of the record (so that every point has >= ~10 degrees of freedom)."""
    allantools = require("allantools", "stats", "the Allan deviation (mimunav noise)")
    x = np.asarray(x, dtype=float)
    n = len(x)
    if n < 100 or not np.isfinite(x).all():
        raise ValueError(f"an Allan deviation needs >= 100 finite samples, got {n}")
    m = np.unique(np.round(np.logspace(0, math.log10(max(n / 10, 2)),
                                       int(points_per_decade * math.log10(max(n / 10, 2))) + 2)))
    taus, adev, _, _ = allantools.oadev(x, rate=rate_hz, data_type="freq", taus=m / rate_hz)
    m = np.round(taus * rate_hz).astype(int)
    slope = np.gradient(np.log(adev**2), np.log(taus)) if len(taus) > 1 else np.array([-1.0])
    alpha = np.clip(np.round(-slope - 1), -2, 2).astype(int)       # AVAR ~ tau^(-alpha-1)
    edf = np.array([allantools.edf_greenhall(alpha=int(a), d=2, m=int(mm), N=n,
                                             overlapping=True) for a, mm in zip(alpha, m)])
    lo, hi = np.array([allantools.confidence_interval(d, e, ci=CI68)
                       for d, e in zip(adev, edf)]).T
    return {"tau_s": taus, "adev": adev, "lo": lo, "hi": hi, "edf": edf}


def _weights(curve):
    """sd of each AVAR point in the fit (chi-squared, floored at MODEL_FLOOR)."""
    avar = curve["adev"] ** 2
    return avar * np.maximum(np.sqrt(2.0 / np.maximum(curve["edf"], 1.0)), MODEL_FLOOR)


def goodness(curve, terms):
    """chi^2/dof of fitted terms against the curve, in the fit's weights: about 1 when the
    five-term model describes the data; well above 1 (say > 3) when it misses the curve's
    shape and the terms are approximate."""
    sigma = _weights(curve)
    model = model_adev(terms, curve["tau_s"]) ** 2
    used = sum(1 for t in TERMS if (terms[t][0] if isinstance(terms[t], tuple) else terms[t]) > 0)
    chi2 = float(np.sum(((curve["adev"] ** 2 - model) / sigma) ** 2))
    return chi2 / max(len(sigma) - used, 1)


def fit_terms(curve):
    """The five terms (module doc) from an `allan_deviation` curve: dict term -> (value,
    68 % interval (lo, hi)); a term at zero reports (0, (0, upper bound))."""
    tau, adev = curve["tau_s"], curve["adev"]
    avar = adev**2
    sigma = _weights(curve)
    a = avar_basis(tau) / sigma[:, None]
    b = avar / sigma
    scale = np.abs(a).max(axis=0)                                # conditioning of the columns
    fits = []                          # every subset of the terms: overlapping terms trade off
    for subset in itertools.product((False, True), repeat=len(TERMS)):
        cols = np.flatnonzero(subset)
        if len(cols) == 0:
            continue
        sol, _ = nnls(a[:, cols] / scale[cols], b)
        c = np.zeros(len(TERMS))
        c[cols] = sol / scale[cols]
        fits.append((float(np.sum((b - a @ c) ** 2)), c))
    chi2, c = min(fits, key=lambda fc: fc[0])
    dof = max(len(b) - int((c > 0).sum()), 1)
    s2 = max(chi2 / dof, 1.0)                                   # chi^2/dof above 1 inflates
    # 68 % intervals: the unconstrained covariance around the best fit, its variance times
    # the points per octave (overlapping estimates at neighbouring taus share most of their
    # data, so they count as about one independent point per octave), widened to every subset
    # fit within delta chi^2 <= 1 (scaled) of the best - the terms' trade-off
    per_octave = len(tau) / max(math.log2(tau[-1] / tau[0]), 1.0)
    cov = s2 * max(per_octave, 1.0) * np.linalg.pinv(a.T @ a)
    near = np.array([ck for chi, ck in fits if chi <= chi2 + s2])
    out = {}
    for k, name in enumerate(TERMS):
        sd = math.sqrt(max(cov[k, k], 0.0))
        lo = min(max(c[k] - sd, 0.0), near[:, k].min())
        hi = max(c[k] + sd, near[:, k].max())
        out[name] = (math.sqrt(c[k]), (math.sqrt(lo), math.sqrt(hi)))
    return out


def model_adev(terms, tau):
    """ADEV of fitted terms (dict term -> value or (value, interval)) at tau (s)."""
    v = np.array([terms[t][0] if isinstance(terms[t], tuple) else terms[t] for t in TERMS])
    return np.sqrt(avar_basis(tau) @ v**2)
