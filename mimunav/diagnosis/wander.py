"""Least squares against a wandering bias: generalised least squares by the Kalman filter.

One channel's residual on its bins is modelled as
    y_k = x_k' beta + b_k + v_k,    b_k = b_(k-1) + u_k,
    v_k ~ N(0, r) white,            u_k ~ N(0, lam r) (the bias wanders as a random walk),
with b_0 diffuse. Generalised least squares under this covariance is ordinary least squares
on the standardized one-step innovations of y and of every column of x, all run through the
same Kalman filter (its gains do not depend on the data; Harvey, *Forecasting, structural time
series models and the Kalman filter*, 1989, sec. 3.4.2 and 6.4). Rows that are absent (the
other half of a split, unusable bins) are skipped: the filter predicts across them, so a gap
costs only its wander and no absent row leaks into a present one.

The wander level lam is not taken from a datasheet: it maximises the profile likelihood of
the channel's own residual under the model in force (`sensor.Fitter`), so a bias that wanders
more than the noise model says widens every interval instead of passing for a term, and a
slow term (a temperature bias) competes with a wander of the level the data show, not with an
arbitrary piecewise-linear nuisance that would absorb it.
"""
import math

import numba
import numpy as np

LAMBDA_GRID = np.geomspace(1e-9, 1e-1, 17)   # q / r per bin, searched by profile likelihood
DIFFUSE = 1e8                                  # initial bias variance over r (diffuse start)


@numba.njit(cache=True)
def _innovations(cols, present, lam):
    """Standardized innovations (n, k) of every column (absent rows 0) and the innovation
    variances over r (n,) (absent rows 1) of the random-walk-bias filter."""
    n, k = cols.shape
    out = np.zeros((n, k))
    s = np.ones(n)
    b = np.zeros(k)
    p = DIFFUSE
    for i in range(n):
        p += lam
        if present[i]:
            si = p + 1.0
            g = p / si
            root = math.sqrt(si)
            for j in range(k):
                e = cols[i, j] - b[j]
                out[i, j] = e / root
                b[j] += g * e
            p = p / si
            s[i] = si
    return out, s


def innovations(cols, present, lam):
    """(standardized innovations of the present rows (m, k), log-determinant term sum log s
    over the present rows, excluding the diffuse first one). cols (n, k): the residual and
    regressors, one column each; present (n,) bool; lam the random walk's step variance
    over the white variance, per row."""
    z, s = _innovations(np.ascontiguousarray(cols, float), np.ascontiguousarray(present), lam)
    idx = np.flatnonzero(present)
    return z[idx[1:]], float(np.log(s[idx[1:]]).sum())
