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
def _innovations(cols, present, lam, shape, state):
    """Standardized innovations (m', k) of every column at the present rows of this block
    and their innovation variances over r (m',), the diffuse start's first present row of
    the record left out; absent rows are predicted across. shape (n,): each row's white
    variance over r. state: the filter carried from block to block, updated in place -
    [p, row, b_1 .. b_k] (p the bias variance over r, DIFFUSE at the start; row -1 until the
    first present row; b the filtered bias of each column)."""
    n, k = cols.shape
    m = 0
    for i in range(n):
        m += 1 if present[i] else 0
    start = 1 if state[1] < 0 and m > 0 else 0      # the record's first present row: no output
    out = np.empty((m - start, k))
    s = np.empty(m - start)
    b = state[2:]
    p = state[0]
    row = -1 if start else 0        # the output row of the present row being filtered
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
            state[1] = 0.0                # a present row seen
            p = p * shape[i] / si         # p - p^2 / si
    state[0] = p
    return out, s


def innovations(cols, present, lam, shape=None):
    """(standardized innovations of the present rows (m, k), log-determinant term sum log s
    over the present rows, excluding the diffuse first one). cols (n, k): the residual and
    regressors, one column each; present (n,) bool; lam the random walk's step variance
    over the white variance, per row; shape (n,) each row's white variance over r (None:
    1)."""
    shape = np.ones(len(cols)) if shape is None else np.ascontiguousarray(shape, float)
    z, s = _innovations(np.ascontiguousarray(cols, float), np.ascontiguousarray(present), lam,
                        shape, _start(cols.shape[1]))
    return z, float(np.log(s).sum())


def _start(k):
    """The filter's state before the first row (`_innovations`): diffuse, nothing seen."""
    state = np.zeros(2 + k)
    state[0], state[1] = DIFFUSE, -1.0
    return state


BLOCK_ROWS = 1 << 15    # rows filtered at a time by `grams`: its memory is this many rows'
                        # innovations, whatever the record's length (2 h at 10 ms: 720,000)


THREADS = min(2, os.cpu_count() or 1)   # levels filtered side by side: the filter (numba, no
                                        # GIL) and the Gram (BLAS) release the interpreter


def grams(cols, present, levels, shape=None):
    """(Grams (L, k, k) of the standardized innovations at every level of `levels` (L,), their
    log-determinant terms (L,), the number of innovations) of `innovations`, filtered
    BLOCK_ROWS rows at a time with each level's filter state carried across: the innovations
    are the same numbers, the Gram's sums taken block by block (an ulp's difference from one
    product). Each block of `cols` (n, k: an array, or anything read as cols[a:b], such as
    `spill.ScratchMatrix`) is read once for every level, the levels filtered THREADS at a
    time; each level's result is the same whatever the number of threads. shape: (n,) each
    row's relative white variance (`innovations`)."""
    n, k = cols.shape
    shape = np.ones(n) if shape is None else np.ascontiguousarray(shape, float)
    present = np.ascontiguousarray(present)
    states = [_start(k) for _ in levels]
    totals, logdets, count = np.zeros((len(levels), k, k)), np.zeros(len(levels)), 0
    with ThreadPoolExecutor(THREADS) as pool:
        for a in range(0, n, BLOCK_ROWS):
            block = np.ascontiguousarray(cols[a:a + BLOCK_ROWS], float)
            rows, weights = present[a:a + BLOCK_ROWS], shape[a:a + BLOCK_ROWS]

            def one(i):
                z, s = _innovations(block, rows, levels[i], weights, states[i])
                return z.T @ z, float(np.log(s).sum()), len(z)
            for i, (g, logdet, m) in enumerate(pool.map(one, range(len(levels)))):
                totals[i] += g
                logdets[i] += logdet
            count += m
    return totals, logdets, count
