"""Tests of candidate terms against the navigation level's observation (`navigation`: the
MIMU's velocity-error increments N E D over epochs), with a bias wander and the error
signatures of the nuisance (biases, initial attitude) removed, on chosen rows (training or
held-out segments). Per channel, the nuisance is removed by projection:
    wander   a piecewise-linear bias in time fitted on the chosen rows, knots `knot_s` apart;
    linear   extra nuisance columns per channel (the navigation level's nuisance signatures);
the remaining coloured noise is handled by a block-robust (HAC) covariance: blocks of
`block_s` are treated as independent, the score g_b = X_b' e_b summed inside each block, with
Satterthwaite's degrees of freedom (`effective_blocks`). Channels are stacked, each scaled by
its noise level, so a term that acts on several channels is one parameter vector fitted to
all of them. (The sensor level has its own GLS: `sensor`, `wander`.)

The blocks are not independent (an attitude error integrates the gyro noise of the whole
flight; the bias wander is only piecewise linear), and the residual of a short record has
given most of its degrees of freedom to the nuisance, so the block-robust variance falls
short of the scatter - by how much is measured on the flight itself: under no missing
physics most of the library's terms are null, and the median of their test statistics
(as chi-square, 1 dof) over its expected 0.455 is the variance inflation lambda >= 1 of
these rows (genomic control: Devlin & Roeder, Biometrics 55, 1999), by which a test's
covariance is multiplied (`variance_inflation`) - measured beside the terms under test, for
a real effect shows in most of the library's signatures (a 0.1 deg/s/g g-sensitivity
raised the median statistic 8-11 times; beside it, the rest is null again). On null flights
(the foreign development nulls and this simulator's, true coefficients) the library's
held-out tests had lambda 1.6-4.3 and P(p < 0.05) 6-27 %; corrected, 0-5 % (issue 53 note).
"""
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from .outputs import block_index

BLOCK_S = 5.0       # HAC blocks
MIN_CALIBRATION_TERMS = 20      # a median over fewer candidates is no measure of the bulk


@dataclass
class Tier:
    name: str
    t: np.ndarray                   # bin centres, s (nb,)
    residual: np.ndarray            # (nb, channels) bin means
    columns: list                   # per candidate: {channel: (nb, k)}
    k: list                         # per candidate: parameter count
    kept: np.ndarray = None         # which bins are usable
    knot_s: tuple = ()              # per channel: bias-wander knot spacing, s
    linear: list = None             # per channel (nb, q) extra nuisance columns
    block_s: float = BLOCK_S        # HAC block length, s
    inflation: dict = field(default_factory=dict)  # (rows, given) -> lambda
    _cache: dict = field(default_factory=dict)

    def prepared(self, rows):
        """Whitening of the chosen rows (bool mask): a function v (nrows,) , channel ->
        nuisance-free scaled v, the block index of each row, and the channels' scales."""
        key = rows.tobytes()
        if key not in self._cache:
            self._cache[key] = self._project(rows)
        return self._cache[key]

    def _project(self, rows):
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
        blocks = block_index(t, self.block_s)
        # a gap (held-out segment) starts a new block
        blocks += np.concatenate([[0], np.cumsum(np.diff(t) > 1.5 * np.median(np.diff(t)))])
        return (lambda v, c: project(v, c) / scale[c]), _renumber(blocks), np.asarray(scale)

    def whitened(self, rows, j, c):
        """Candidate j's columns (None: the residual) on channel c over `rows`, nuisance-free
        and scaled (`prepared`), kept: a fit of the library re-uses them; None where j does
        not act on c."""
        key = ("whitened", rows.tobytes(), j, c)
        if key not in self._cache:
            whiten = self.prepared(rows)[0]
            block = self.residual[:, c] if j is None else self.columns[j].get(c)
            self._cache[key] = None if block is None else whiten(block[rows], c)
        return self._cache[key]

    @property
    def channels(self):
        return self.residual.shape[1]

    def _with_linear(self, basis, c, rows):
        return basis if self.linear is None else np.hstack([basis, self.linear[c][rows]])


def _renumber(blocks):
    _, inv = np.unique(blocks, return_inverse=True)
    return inv


@dataclass
class Fit:
    beta: np.ndarray            # all parameters, stacked in term order
    cov: np.ndarray
    slices: list                # per term: slice into beta
    dof: list                   # per term: degrees of freedom of its variance (effective
                                # blocks, `effective_blocks`)
    resid_ms: float
    dof_nominal: list = None    # per term: blocks - 1

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


def p_text(p):
    """A p-value for people: two digits, or "< 1e-300" where it underflowed to 0."""
    return f"{p:.2g}" if p > 0 else "< 1e-300"


def design(tier, terms, rows):
    """Stacked, nuisance-free, scaled response and design over the chosen rows for the
    candidate indices `terms`: (y, X, block ids, slices)."""
    _, blocks, _ = tier.prepared(rows)
    ys, xs, bl = [], [], []
    widths = [tier.k[j] for j in terms]
    slices, start = [], 0
    for w in widths:
        slices.append(slice(start, start + w))
        start += w
    n = int(rows.sum())
    for c in range(tier.channels):
        parts = [tier.whitened(rows, j, c) for j in terms]
        if terms and all(p is None for p in parts):
            continue
        ys.append(tier.whitened(rows, None, c))
        xs.append(np.hstack([np.zeros((n, w)) if p is None else p
                             for p, w in zip(parts, widths)]) if start else np.zeros((n, 0)))
        bl.append(blocks)
    return np.concatenate(ys), np.vstack(xs), np.concatenate(bl), slices


def variance_inflation(tier, rows, given=()):
    """lambda >= 1 of `rows` (bool mask) given the candidates `given` (positions): the median
    over the tier's other candidates of each one's test statistic beside `given`, as
    chi-square with 1 dof (from its p-value), over that law's median (module doc) - given
    the terms a flight has, the rest of the library is null. Kept per (rows, given) in
    `tier.inflation`; 1 where fewer than MIN_CALIBRATION_TERMS others (with a finite p) are
    left. A chi-square reading of F tests of k parameters: for k > 1 it over-corrects
    (conservative)."""
    given = list(given)
    key = (rows.tobytes(), tuple(sorted(given)))
    if key not in tier.inflation:
        others = [j for j in range(len(tier.columns)) if j not in given]
        lam = 1.0
        if len(others) >= MIN_CALIBRATION_TERMS:
            p = np.array([fit(tier, given + [j], rows).test(len(given))[1] for j in others])
            p = p[np.isfinite(p)]
            if len(p) >= MIN_CALIBRATION_TERMS:
                lam = max(1.0, median_inflation(np.log(np.clip(p, 1e-300, 1.0))))
        tier.inflation[key] = lam
    return tier.inflation[key]


def median_inflation(logp):
    """The median of the tests' statistics, each read as chi-square with 1 dof from its log
    p-value, over that law's median 0.455 (genomic control: Devlin & Roeder 1999)."""
    chi2 = stats.chi2.isf(np.exp(np.clip(logp, -745.0, 0.0)), 1)
    return float(np.median(chi2) / stats.chi2.ppf(0.5, 1))


def fit(tier, terms, rows, inflation=1.0):
    """Least squares of the residual on the candidates `terms` over `rows`, with the
    block-robust covariance (times `inflation`, the rows' `variance_inflation`) and its
    effective degrees of freedom."""
    y, x, blocks, slices = design(tier, terms, rows)
    xtx = x.T @ x
    try:
        inv = np.linalg.inv(xtx)
    except np.linalg.LinAlgError:
        inv = np.linalg.pinv(xtx)
    beta = inv @ (x.T @ y)
    e = y - x @ beta
    nb = blocks.max() + 1
    g = np.zeros((nb, x.shape[1]))
    np.add.at(g, blocks, x * e[:, None])
    meat = g.T @ g * nb / max(nb - 1, 1)
    cov = inv @ meat @ inv * inflation
    nominal = [nb - 1] * len(slices)
    dof = [min(nb - 1, effective_blocks(x @ inv, blocks, nb, s)) for s in slices]
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
    block was drawn (weights (R, nb)); NaN in a replicate whose sandwich covariance is
    singular - a k-dimensional term's scores span at most one fewer dimension than the
    blocks drawn (they sum to zero at the fit), so 3 of 6 blocks cannot test a lever arm
    (a quarter of the replicates of a 90 s flight's 6 blocks had made every replicate fail,
    and a lever arm right to 2 cm was never chosen)."""
    out = np.full(len(weights), np.nan)
    for r, w in enumerate(weights):
        if np.count_nonzero(w) <= s.shape[1]:
            continue
        qq = np.einsum("b,bij->ij", w, q)
        try:
            beta = np.linalg.solve(qq, w @ s)
            g = s - q @ beta                                    # block scores at beta
            inv = np.linalg.inv(qq)
            cov = inv @ np.einsum("b,bi,bj->ij", w, g, g) @ inv
            out[r] = beta @ np.linalg.solve(cov, beta) / s.shape[1]
        except np.linalg.LinAlgError:
            continue
    return out


def holm_threshold(alpha, m, step):
    """Holm's step-down threshold for the step-th smallest of m p-values (step from 0)."""
    return alpha / max(m - step, 1)
