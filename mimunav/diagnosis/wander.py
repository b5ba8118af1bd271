"""Least squares against a wandering bias: generalised least squares by the Kalman filter.

One channel's residual on its bins is modelled as
    y_k = x_k' beta + b_k + v_k,    b_k = b_(k-1) + u_k,
    v_k ~ N(0, r s_k) white,        u_k ~ N(0, lam r) (the bias wanders as a random walk),
with b_0 diffuse; s_k the bin's relative white variance, 1 unless a reference's own error
varies along the record (`sensor.diagnose`'s noise_shape: a vehicle model's yaw rate is a
smoothed acceleration over the speed).
Generalised least squares under this covariance is ordinary least squares
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
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..kernels import njit

LAMBDA_GRID = np.geomspace(1e-9, 1e-1, 17)   # q / r per bin, searched by profile likelihood
DIFFUSE = 1e8                                  # initial bias variance over r (diffuse start)


@njit(nogil=True)
def _innovations(cols, present, lam, shape):
    """Standardized innovations (m - 1, k) of every column at the present rows after the
    first (the diffuse start's) and their innovation variances over r (m - 1,), m the number
    of present rows; absent rows are predicted across. shape (n,): each row's white variance
    over r."""
    n, k = cols.shape
    m = 0
    for i in range(n):
        m += 1 if present[i] else 0
    out = np.empty((max(m - 1, 0), k))
    s = np.empty(max(m - 1, 0))
    b = np.zeros(k)
    p = DIFFUSE
    row = -1                        # the output row of the present row being filtered
    for i in range(n):
        p += lam
        if present[i]:
            si = p + shape[i]
            g = p / si
            root = math.sqrt(si)
            for j in range(k):
                e = cols[i, j] - b[j]
                if row >= 0:
                    out[row, j] = e / root
                b[j] += g * e
            if row >= 0:
                s[row] = si
            row += 1
            p = p * shape[i] / si         # p - p^2 / si
    return out, s


def innovations(cols, present, lam, shape=None):
    """(standardized innovations of the present rows (m, k), log-determinant term sum log s
    over the present rows, excluding the diffuse first one). cols (n, k): the residual and
    regressors, one column each; present (n,) bool; lam the random walk's step variance
    over the white variance, per row; shape (n,) each row's white variance over r (None:
    1)."""
    shape = np.ones(len(cols)) if shape is None else np.ascontiguousarray(shape, float)
    z, s = _innovations(np.ascontiguousarray(cols, float), np.ascontiguousarray(present), lam,
                        shape)
    return z, float(np.log(s).sum())


THREADS = min(2, os.cpu_count() or 1)   # levels filtered side by side: the filter (numba, no
                                        # GIL) and the Gram (BLAS) release the interpreter


def grams(cols, present, levels, shape=None):
    """(Grams (L, k, k) of the standardized innovations at every level of `levels` (L,), their
    log-determinant terms (L,), the number of innovations): `innovations` level by level,
    THREADS at a time; each level's result is the same whatever the number of threads.
    shape: (n,) each row's relative white variance (`innovations`)."""
    def one(lam):
        z, logdet = innovations(cols, present, lam, shape)
        return z.T @ z, logdet, len(z)
    with ThreadPoolExecutor(THREADS) as pool:
        out = list(pool.map(one, levels))
    return np.stack([g for g, _, _ in out]), np.array([d for _, d, _ in out]), out[0][2]
