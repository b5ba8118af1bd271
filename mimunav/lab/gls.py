"""Generalised least squares with a known covariance (`gls`), the flicker covariance of
window means, and fitted coefficients with every covariance source carried through the
stages (`Fitted`).
"""
import math
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.optimize

from ..errors import InputError


class FitError(InputError):
    """Lab data that cannot give the requested coefficients, saying what is missing."""


# ---- estimator -----------------------------------------------------------------------------
def gls(x, y, cov, omitted=None):
    """Generalised least squares y = x b + e, Cov(e) = cov (n, n). Returns (b, Cov(b),
    chi2 / dof, rms residual); Cov(b) is scaled by chi2 / dof when that exceeds 1 (scatter
    beyond the noise model is reported, never hidden).

    `omitted` (n, k): shapes the model leaves out, each column scaled to its 1-sigma prior
    size (a random effect). The estimate is unchanged (weights from `cov` alone); Cov(b)
    adds their projection P P^T, P = (x' cov^-1 x)^-1 x' cov^-1 omitted, and chi2 is taken
    against cov + omitted omitted^T, so scatter they explain does not inflate twice."""
    n, p = x.shape
    if n <= p:
        raise FitError(f"{n} data points for {p} coefficients")
    scale = np.abs(x).max(axis=0)
    scale[scale == 0] = 1.0
    xs = x / scale
    chol = np.linalg.cholesky(cov + np.eye(n) * 1e-12 * np.trace(cov) / n)
    a = scipy.linalg.solve_triangular(chol, xs, lower=True)
    yw = scipy.linalg.solve_triangular(chol, y, lower=True)
    cond = np.linalg.cond(a)
    if cond > 1e10:
        raise FitError(f"the design cannot separate the {p} coefficients (condition number "
                       f"{cond:.2g})")
    b, *_ = np.linalg.lstsq(a, yw, rcond=None)
    inv = np.linalg.inv(a.T @ a)
    if omitted is None:
        ratio = float(np.sum((yw - a @ b) ** 2)) / (n - p)
        cov_b = inv * max(1.0, ratio)
    else:
        r = y - xs @ b
        ratio = float(r @ np.linalg.solve(cov + omitted @ omitted.T, r)) / (n - p)
        proj = inv @ a.T @ scipy.linalg.solve_triangular(chol, omitted, lower=True)
        cov_b = inv * max(1.0, ratio) + proj @ proj.T
    rms = float(np.sqrt(np.mean((y - xs @ b) ** 2)))
    return b / scale, cov_b / np.outer(scale, scale), ratio, rms


def flicker_covariance(t0, t1, f_min, f_max, n_freq=4000):
    """Covariance of the means over windows [t0_k, t1_k] (s) of a flicker process of unit
    instability (one-sided PSD 1 / (pi f), `sensors.noise`) between f_min and f_max (Hz):
    C_jk = int S(f) cos(2 pi f (c_j - c_k)) sinc(f T_j) sinc(f T_k) df, c the window
    centres, T the lengths (numerical, log-spaced frequencies). Read-only; up to
    KEPT_WINDOWS windows kept for the process's later calls with the same windows (every
    unit of a campaign has its lab's)."""
    t0, t1 = np.asarray(t0, dtype=float), np.asarray(t1, dtype=float)
    key = (t0.tobytes(), t1.tobytes(), float(f_min), float(f_max), int(n_freq))
    cov = _FLICKER_COVARIANCES.get(key)
    if cov is None:
        cov = _flicker_covariance(t0, t1, f_min, f_max, n_freq)
        cov.flags.writeable = False
        if len(t0) <= KEPT_WINDOWS:
            if len(_FLICKER_COVARIANCES) >= 32:
                _FLICKER_COVARIANCES.pop(next(iter(_FLICKER_COVARIANCES)))
            _FLICKER_COVARIANCES[key] = cov
    return cov


KEPT_WINDOWS = 512                # a lab run's (the rate table has 252): at most 2 MiB each
_FLICKER_COVARIANCES = {}         # (windows, band, grid) -> covariance, oldest first


def _flicker_covariance(t0, t1, f_min, f_max, n_freq):
    f = np.geomspace(f_min, f_max, n_freq)
    weight = np.gradient(np.log(f)) * f / (math.pi * f)          # S(f) df on a log grid
    c, length = 0.5 * (t0 + t1), t1 - t0
    h = np.sinc(np.outer(length, f))
    phase = 2 * math.pi * np.outer(c, f)
    re, im = h * np.cos(phase), h * np.sin(phase)
    return (re * weight) @ re.T + (im * weight) @ im.T


@dataclass
class Fitted:
    """Coefficients with their error as a linear map from independent unit sources:
    error = E @ z, z ~ N(0, I); sources named so later stages can extend E."""
    values: dict                                    # name -> float
    errors: dict = field(default_factory=dict)      # name -> {source: sensitivity}
    stage: str = ""
    rms: dict = field(default_factory=dict)         # residual rms per output axis

    def covariance(self, names):
        sources = sorted({s for n in names for s in self.errors.get(n, {})})
        e = np.array([[self.errors.get(n, {}).get(s, 0.0) for s in sources] for n in names])
        return e @ e.T if sources else np.zeros((len(names), len(names)))


def merge_errors(into, name, sens):
    row = into.setdefault(name, {})
    for s, v in sens.items():
        row[s] = row.get(s, 0.0) + v


def add_covariance_sources(fitted, names, cov, tag):
    """Own GLS covariance of `names` as sources tag:0.. (its Cholesky columns)."""
    vals, vecs = np.linalg.eigh(cov)
    cols = vecs * np.sqrt(np.clip(vals, 0, None))
    for i, name in enumerate(names):
        merge_errors(fitted.errors, name, {f"{tag}:{j}": cols[i, j] for j in range(len(names))})


def propagated(fitted, names, refit, base, upstream, parents):
    """Add to `names` the effect of the errors of `parents` (names in `upstream`): for every
    source of the parents, refit with the parents moved by that source's sensitivity."""
    sources = sorted({s for n in parents for s in upstream.errors.get(n, {})})
    for s in sources:
        delta = {n: upstream.errors.get(n, {}).get(s, 0.0) for n in parents}
        if not any(delta.values()):
            continue
        new = refit(delta)
        for i, name in enumerate(names):
            merge_errors(fitted.errors, name, {s: new[i] - base[i]})
