"""Tests of candidate terms against a residual, with the bias wander and coloured noise as
nuisance, on chosen rows (training or held-out segments).

A tier holds bin means of the residual (6 channels: accel x y z, gyro x y z) and of every
candidate's regressor columns. Per channel, the nuisance is removed by projection:
    fast tier: a piecewise-linear bias in time fitted on the chosen rows, its knots as far
               apart as the channel's flicker allows (`knot_spacing`); the remaining coloured noise is handled by a block-robust (HAC)
               covariance: blocks of BLOCK_S are treated as independent, the score
               g_b = X_b' e_b summed inside each block;
    slow tier: generalised least squares with a constant bias and the covariance of white
               noise plus the unit's flicker wander (its datasheet instability B), i.e. the
               noise model of `sensors.noise` over bins: Sigma = s_w^2/m I + B^2 F.
Channels are stacked, each scaled by its noise level, so a term that acts on several
channels (time skew, misalignment) is one parameter vector fitted to all of them.
"""
import math
from dataclasses import dataclass, field

import numpy as np
from scipy import linalg, stats

KNOT_S = (10.0, 60.0)   # bias-wander knot spacing: limits, s
BLOCK_S = 5.0       # HAC blocks of the fast tier


@dataclass
class Tier:
    name: str
    t: np.ndarray                   # bin centres, s (nb,)
    residual: np.ndarray            # (nb, 6) bin means
    columns: list                   # per candidate: {channel: (nb, k)}
    k: list                         # per candidate: parameter count
    samples_per_bin: int = 1        # m: raw samples averaged into one bin
    kept: np.ndarray = None         # which bins of the raw binning are usable (all samples good)
    knot_s: tuple = ()              # (6,) bias-wander knot spacing per channel, s (fast tier)
    white: np.ndarray = None        # (6,) white noise of a bin mean (slow tier)
    flicker: np.ndarray = None      # (6,) flicker instability B (slow tier)
    flicker_cov: np.ndarray = None  # (nb, nb) unit-B flicker covariance of the bins (slow)
    _cache: dict = field(default_factory=dict)

    def prepared(self, rows):
        """Whitening of the chosen rows (bool mask): a function v (nrows,) , channel ->
        nuisance-free scaled v, and the block index of each row."""
        key = rows.tobytes()
        if key not in self._cache:
            self._cache[key] = (self._fast(rows) if self.name == "fast" else self._slow(rows))
        return self._cache[key]

    def _fast(self, rows):
        t = self.t[rows]
        bases = {}
        for spacing in set(self.knot_s):
            knots = np.arange(t[0], t[-1] + spacing, spacing)
            basis = np.clip(1 - np.abs((t[:, None] - knots[None, :]) / spacing), 0, None)
            bases[spacing] = np.linalg.qr(basis[:, basis.sum(axis=0) > 0.5])[0]
        project = lambda v, c: v - bases[self.knot_s[c]] @ (bases[self.knot_s[c]].T @ v)  # noqa
        scale = [np.std(project(self.residual[rows, c], c)) or 1.0 for c in range(6)]
        blocks = np.floor((t - t[0]) / BLOCK_S).astype(int)
        # a gap (held-out segment) starts a new block
        blocks += np.concatenate([[0], np.cumsum(np.diff(t) > 1.5 * np.median(np.diff(t)))])
        return (lambda v, c: project(v, c) / scale[c]), _renumber(blocks), np.asarray(scale)

    def _slow(self, rows):
        idx = np.flatnonzero(rows)
        fc = self.flicker_cov[np.ix_(idx, idx)]
        whiten = []
        for c in range(6):
            cov = self.white[c] ** 2 * np.eye(len(idx)) + self.flicker[c] ** 2 * fc
            chol = linalg.cholesky(cov, lower=True)
            one = linalg.solve_triangular(chol, np.ones(len(idx)), lower=True)
            one /= np.linalg.norm(one)
            whiten.append((chol, one))

        def apply(v, c):
            chol, one = whiten[c]
            w = linalg.solve_triangular(chol, v, lower=True)
            return w - np.outer(one, one @ w) if w.ndim == 2 else w - one * (one @ w)
        return apply, np.arange(len(idx)), np.ones(6)


def knot_spacing(white, flicker):
    """Knot spacing (s) of the bias-wander nuisance for a channel with white noise density
    `white` (per sqrt(Hz)) and flicker instability `flicker`: the period at which the
    flicker's one-sided PSD B^2/(pi f) falls to the white 2 N^2 (`sensors.noise`), within
    KNOT_S. Below that frequency the wander dominates and the nuisance carries it."""
    f_cross = flicker ** 2 / (2 * math.pi * white ** 2)
    return float(np.clip(round(1 / f_cross), *KNOT_S))


def _renumber(blocks):
    _, inv = np.unique(blocks, return_inverse=True)
    return inv


@dataclass
class Fit:
    beta: np.ndarray            # all parameters, stacked in term order
    cov: np.ndarray
    slices: list                # per term: slice into beta
    dof: list                   # per term: degrees of freedom of its variance (blocks - 1,
                                # or rows - parameters)
    resid_ms: float

    def test(self, j):
        """(F statistic, p value) of term j's parameters being zero."""
        s = self.slices[j]
        b, v = self.beta[s], self.cov[s, s]
        try:
            w = float(b @ np.linalg.solve(v, b))
        except np.linalg.LinAlgError:
            return 0.0, 1.0
        k = len(b)
        return w / k, float(stats.f.sf(w / k, k, self.dof[j]))

    def interval(self, j, level=0.95):
        s = self.slices[j]
        q = stats.t.ppf(0.5 + level / 2, self.dof[j])
        se = np.sqrt(np.diag(self.cov[s, s]))
        return self.beta[s] - q * se, self.beta[s] + q * se


def design(tier, terms, rows):
    """Stacked, nuisance-free, scaled response and design over the chosen rows for the
    candidate indices `terms`: (y, X, block ids, slices)."""
    whiten, blocks, _ = tier.prepared(rows)
    ys, xs, bl = [], [], []
    widths = [tier.k[j] for j in terms]
    slices, start = [], 0
    for w in widths:
        slices.append(slice(start, start + w))
        start += w
    for c in range(6):
        cols = np.zeros((rows.sum(), start))
        used = False
        for j, s in zip(terms, slices):
            block = tier.columns[j].get(c)
            if block is not None:
                cols[:, s] = block[rows]
                used = True
        if not used and terms:
            continue
        ys.append(whiten(tier.residual[rows, c], c))
        xs.append(whiten(cols, c) if start else cols)
        bl.append(blocks)
    return np.concatenate(ys), np.vstack(xs), np.concatenate(bl), slices


def fit(tier, terms, rows):
    """Least squares of the residual on the candidates `terms` over `rows`, with the tier's
    covariance (fast: block-robust; slow: GLS, scaled up if the residual is noisier than the
    noise model says)."""
    y, x, blocks, slices = design(tier, terms, rows)
    xtx = x.T @ x
    try:
        inv = np.linalg.inv(xtx)
    except np.linalg.LinAlgError:
        inv = np.linalg.pinv(xtx)
    beta = inv @ (x.T @ y)
    e = y - x @ beta
    if tier.name == "fast":
        nb = blocks.max() + 1
        g = np.zeros((nb, x.shape[1]))
        np.add.at(g, blocks, x * e[:, None])
        meat = g.T @ g * nb / max(nb - 1, 1)
        cov = inv @ meat @ inv
        dof = [nb - 1] * len(slices)
    else:
        n_dof = len(y) - x.shape[1]
        s2 = max(1.0, float(e @ e) / max(n_dof, 1))
        cov = inv * s2
        dof = [n_dof] * len(slices)
    return Fit(beta, cov, slices, dof, float(e @ e) / len(e))


def block_scores(tier, j, terms, rows):
    """Per-block sums of the score of candidate j added to `terms` (for the bootstrap):
    (s_b = sum x e0 (nb, k), q_b = sum x x' (nb, k, k)) with x, e0 the candidate's columns
    and the residual, both with `terms` projected out."""
    y, x, blocks, slices = design(tier, list(terms) + [j], rows)
    xc, xo = x[:, slices[-1]], x[:, :slices[-1].start]
    if xo.shape[1]:
        coef = np.linalg.lstsq(xo, np.column_stack([y, xc]), rcond=None)[0]
        y, xc = y - xo @ coef[:, 0], xc - xo @ coef[:, 1:]
    nb = blocks.max() + 1
    s = np.zeros((nb, xc.shape[1]))
    q = np.zeros((nb, xc.shape[1], xc.shape[1]))
    np.add.at(s, blocks, xc * y[:, None])
    np.add.at(q, blocks, xc[:, :, None] * xc[:, None, :])
    return s, q


def wald_from_blocks(s, q, weights):
    """Wald statistic per bootstrap replicate from block sums weighted by how often each
    block was drawn (weights (R, nb))."""
    ss = weights @ s                                    # (R, k)
    qq = np.einsum("rb,bij->rij", weights, q)
    beta = np.linalg.solve(qq, ss[:, :, None])[:, :, 0]
    g = s[None, :, :] - np.einsum("bij,rj->rbi", q, beta)        # block scores at beta
    meat = np.einsum("rb,rbi,rbj->rij", weights, g, g)
    inv = np.linalg.inv(qq)
    cov = inv @ meat @ inv
    return np.einsum("ri,rij,rj->r", beta, np.linalg.inv(cov), beta) / s.shape[1]


def holm_threshold(alpha, m, step):
    """Holm's step-down threshold for the step-th smallest of m p-values (step from 0)."""
    return alpha / max(m - step, 1)
