"""Tests of candidate terms against a residual, with the bias wander, coloured noise and
the reference's own linear error as nuisance, on chosen rows (training or held-out segments).

A tier holds bin means of the residual (sensor level: 6 channels, accel x y z, gyro x y z;
navigation level: velocity-error increments N E D) and of every candidate's columns. Per channel, the nuisance is removed by projection:
    fast kind: a piecewise-linear bias in time fitted on the chosen rows, its knots as far
               apart as the channel's flicker allows (`knot_spacing`); the remaining
               coloured noise is handled by a block-robust (HAC) covariance: blocks of
               BLOCK_S are treated as independent, the score g_b = X_b' e_b summed inside
               each block, with Satterthwaite's degrees of freedom (`effective_blocks`);
    slow kind: generalised least squares with a constant bias and the covariance of white
               noise plus the unit's flicker wander (its datasheet instability B), i.e. the
               noise model of `sensors.noise` over bins: Sigma = s_w^2/m I + B^2 F.
    linear   (optional, either kind): the channel's sensor input x (3 columns: specific
               force for an accelerometer, rate for a gyro), i.e. a full scale and
               cross-coupling row. The reference IMU carries such an error of its own
               (`sensor.REFERENCE_ACCURACY`), which leaks into any regressor that
               correlates with x (x^3 of a roll rate with the rate itself); non-linear
               candidates are tested with it removed.
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
    kind: str                       # "fast" (wander + HAC) or "slow" (GLS), see above
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
    linear: list = None             # per channel (nb, q) extra nuisance columns (the sensor
                                    # input: linear response; navigation: error signatures)
    block_s: float = BLOCK_S        # HAC block length, s (fast kind)
    _cache: dict = field(default_factory=dict)

    def prepared(self, rows):
        """Whitening of the chosen rows (bool mask): a function v (nrows,) , channel ->
        nuisance-free scaled v, and the block index of each row."""
        key = rows.tobytes()
        if key not in self._cache:
            self._cache[key] = (self._fast(rows) if self.kind == "fast" else self._slow(rows))
        return self._cache[key]

    def _fast(self, rows):
        t = self.t[rows]
        wander = {}
        for spacing in set(self.knot_s):
            knots = np.arange(t[0], t[-1] + spacing, spacing)
            basis = np.clip(1 - np.abs((t[:, None] - knots[None, :]) / spacing), 0, None)
            wander[spacing] = basis[:, basis.sum(axis=0) > 0.5]
        bases = [np.linalg.qr(self._with_linear(wander[self.knot_s[c]], c, rows))[0]
                 for c in range(self.channels)]
        project = lambda v, c: v - bases[c] @ (bases[c].T @ v)  # noqa
        scale = [np.std(project(self.residual[rows, c], c)) or 1.0 for c in range(self.channels)]
        blocks = np.floor((t - t[0]) / self.block_s).astype(int)
        # a gap (held-out segment) starts a new block
        blocks += np.concatenate([[0], np.cumsum(np.diff(t) > 1.5 * np.median(np.diff(t)))])
        return (lambda v, c: project(v, c) / scale[c]), _renumber(blocks), np.asarray(scale)

    def _slow(self, rows):
        idx = np.flatnonzero(rows)
        fc = self.flicker_cov[np.ix_(idx, idx)]
        whiten = []
        for c in range(self.channels):
            cov = self.white[c] ** 2 * np.eye(len(idx)) + self.flicker[c] ** 2 * fc
            chol = linalg.cholesky(cov, lower=True)
            nuisance = self._with_linear(np.ones((len(idx), 1)), c, rows)
            q = np.linalg.qr(linalg.solve_triangular(chol, nuisance, lower=True))[0]
            whiten.append((chol, q))

        def apply(v, c):
            chol, q = whiten[c]
            w = linalg.solve_triangular(chol, v, lower=True)
            return w - q @ (q.T @ w)
        return apply, np.arange(len(idx)), np.ones(self.channels)

    @property
    def channels(self):
        return self.residual.shape[1]

    def _with_linear(self, basis, c, rows):
        return basis if self.linear is None else np.hstack([basis, self.linear[c][rows]])


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
    dof: list                   # per term: degrees of freedom of its variance (fast tier:
                                # effective blocks, `effective_blocks`; slow: rows - parameters)
    resid_ms: float
    dof_nominal: list = None    # per term: blocks - 1 (fast tier) / rows - parameters (slow)

    def test(self, j, nominal=False):
        """(F statistic, p value) of term j's parameters being zero; `nominal`: with the
        nominal degrees of freedom (a ranking of the evidence, not a test)."""
        s = self.slices[j]
        b, v = self.beta[s], self.cov[s, s]
        try:
            w = float(b @ np.linalg.solve(v, b))
        except np.linalg.LinAlgError:
            return 0.0, 1.0
        k = len(b)
        dof = (self.dof_nominal or self.dof)[j] if nominal else self.dof[j]
        return w / k, float(stats.f.sf(w / k, k, dof))

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
    for c in range(tier.channels):
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
    if tier.kind == "fast":
        nb = blocks.max() + 1
        g = np.zeros((nb, x.shape[1]))
        np.add.at(g, blocks, x * e[:, None])
        meat = g.T @ g * nb / max(nb - 1, 1)
        cov = inv @ meat @ inv
        nominal = [nb - 1] * len(slices)
        dof = [min(nb - 1, effective_blocks(x @ inv, blocks, nb, s)) for s in slices]
    else:
        n_dof = len(y) - x.shape[1]
        s2 = max(1.0, float(e @ e) / max(n_dof, 1))
        cov = inv * s2
        dof = nominal = [n_dof] * len(slices)
    return Fit(beta, cov, slices, dof, float(e @ e) / len(e), nominal)


def effective_blocks(a, blocks, nb, s):
    """Degrees of freedom of the block-robust variance of the parameters in slice s
    (Satterthwaite's approximation, as in Bell & McCaffrey 2002 for clustered errors): the
    variance is a sum over blocks of terms with weights h_b = sum_(rows of b) a_ri^2 (a = X
    (X'X)^-1), and such a sum carries (sum h_b)^2 / sum h_b^2 degrees of freedom - nb - 1
    when every block weighs the same, few when a regressor (x^3 of a roll rate, say) lives
    in few blocks, whose scatter then cannot measure its variance. The smallest over the
    slice's parameters."""
    h = np.zeros((nb, s.stop - s.start))
    np.add.at(h, blocks, a[:, s] ** 2)
    return float(np.min(h.sum(axis=0) ** 2 / np.maximum((h ** 2).sum(axis=0), 1e-300)))


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
