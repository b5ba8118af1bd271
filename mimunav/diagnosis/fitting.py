"""Generalised least squares of the sensor level: per channel and wander level, the Gram
matrices of the Kalman innovations (`wander`), the reference's linear error under its prior
(Woodbury), the wander level profiled by maximum likelihood; a candidate's test (likelihood
ratio for a term of one channel, Wald otherwise) and its profile-likelihood interval.
"""
import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

from . import library, wander
from .design import gamma_slots


PIN = 1e12                      # prior precision factor that holds the reference error at zero
CHI2_95_1DOF = float(stats.chi2.isf(0.05, 1))   # 3.84: a 95 % profile-likelihood interval


# ---- fits --------------------------------------------------------------------------------
class Fitter:
    """GLS fits on a set of rows. For each channel and each wander level of `design.levels`,
    the Gram matrix of the Kalman innovations of [residual, reference inputs, every candidate
    column of the channel] is computed once; a fit then takes, per channel, the level of
    maximum profile likelihood under its own model (so a slow term is tested against the
    wander that remains with it in the model, not against one inflated by it)."""

    def __init__(self, design, rows):
        self.design, self.rows = design, rows
        self.gram, self.logdet, self.slot = [], [], []
        self._levels, self._nuisances = {}, {}    # `_level`'s, `_nuisance_shift`'s
        for c in range(6):
            x, slot = design.channel_columns[c]
            gram, logdet, self.n = wander.grams(
                x, rows, design.levels, None if design.shape is None else design.shape[:, c])
            self.gram.append(gram)
            self.logdet.append(logdet)
            self.slot.append(slot)
        self.precision = np.linalg.inv(design.prior + 1e-24 * np.eye(18))
        self.row_prior = [design.prior[np.ix_(gamma_slots(c), gamma_slots(c))]
                          for c in range(6)]
        self.row_precision = [np.linalg.inv(p + 1e-24 * np.eye(3)) for p in self.row_prior]

    def _profile(self, c, cols, factor=1.0, gram=None):
        """(Grams, r, log-likelihood) of channel c at every wander level, with the candidate
        columns `cols` (indices into the channel's columns) in the mean and the reference
        inputs (columns 1-3) under the reference's prior: the
        likelihood of y ~ N(X beta, r (wander) + R P R'), by Woodbury over the 3 prior
        columns, with r profiled (fixed-point on the penalized residual); and the
        coefficients of the reference inputs and `cols` at every level. `factor`: the prior's
        precision multiplied by it (`prior_factor`); `gram`: the channel's Grams with another
        residual (`profile_interval`)."""
        g = self.gram[c] if gram is None else gram
        every = [1, 2, 3] + list(cols)
        m = g[:, every][:, :, every]
        h = g[:, every, 0]
        pen = np.zeros((len(every), len(every)))
        pen[:3, :3] = self.row_precision[c] * factor
        r = np.maximum(g[:, 0, 0], 1e-300) / self.n
        for _ in range(4):
            theta = np.linalg.solve(m + r[:, None, None] * pen + 1e-12 * np.eye(len(every)) *
                                    np.maximum(np.einsum("lii->l", m), 1e-300)[:, None, None]
                                    / len(every), h[:, :, None])[:, :, 0]
            q = np.maximum(g[:, 0, 0] - np.einsum("li,li->l", h, theta), 1e-300)
            r = q / self.n
        _, logdet_prior = np.linalg.slogdet(np.eye(3) + self.row_prior[c] @ m[:, :3, :3]
                                            / (r[:, None, None] * factor))
        loglik = -0.5 * (self.logdet[c] + self.n * np.log(r) + logdet_prior + q / r)
        if self.design.wander_steps is not None:    # levels whose step exceeds the cap: out
            over = self.design.levels * r > self.design.wander_steps[c]
            over[0] = False                         # (the lowest level stays)
            loglik = np.where(over, -np.inf, loglik)
        return g, r, loglik, theta

    def _level(self, c, cols, factor=1.0, shift=None):
        """(Gram, r, log-likelihood) of channel c at the wander level of maximum marginal
        likelihood (`_profile`); kept per (channel, columns in their order, factor, shift): a
        selection step fits every candidate with the same chosen terms on the channels the
        candidate does not touch, and the likelihood ratio refits the fit's own model.
        shift: (column, beta) - the residual less beta times that column (`_shifted`)."""
        key = (c, tuple(cols), factor, shift)
        if key not in self._levels:
            g, r, loglik, _ = self._profile(c, cols, factor, None if shift is None else
                                            self._shifted(c, *shift))
            best = int(np.argmax(loglik))
            self._levels[key] = g[best], float(r[best]), float(loglik[best])
        return self._levels[key]

    def _shifted(self, c, x, beta):
        """Channel c's Grams at every wander level with the residual y - beta x_x (x: a
        column index of the channel)."""
        return _less(self.gram[c], x, beta)

    def _nuisance_shift(self, c, terms):
        """(column, beta) of the design's nuisance on channel c fitted with `terms` (its
        estimate from `fit`, the six channels together: the clock is one for them), or None
        where none acts on c. One nuisance at most (the reference's clock)."""
        acting = [n for n in self.design.nuisance if n in self.slot[c] and n not in terms]
        if not acting:
            return None
        key = tuple(terms)
        if key not in self._nuisances:
            self._nuisances[key] = float(self.fit(terms).of(acting[0])[0][0])
        return self.slot[c][acting[0]][0], self._nuisances[key]

    def _columns(self, c, terms):
        return [i for j in terms if j in self.slot[c] for i in self.slot[c][j]]

    def likelihood_ratio(self, terms, j):
        """2 (max log-likelihood with candidate j - without it), the other `terms` in both and
        each channel's wander level profiled in each (the reference error under its prior,
        marginalised: `_level`); a nuisance (`Design.nuisance`, the reference's clock) held
        at its estimate without j, from all channels (`_nuisance_shift`): j's channel cannot
        fit it alone, and it is not refitted with j - a ratio no larger than the full one."""
        return 2 * sum(self._level(c, self._columns(c, terms + [j]), shift=shift)[2]
                       - self._level(c, self._columns(c, terms), shift=shift)[2]
                       for c in self.design.columns[j]
                       for shift in [self._nuisance_shift(c, terms)])

    def profile_interval(self, terms, j, sd, chi2=CHI2_95_1DOF):
        """95 % profile-likelihood interval of the one-parameter candidate j of one channel,
        fitted with `terms` (which hold j; sd: its Wald standard deviation, the search's
        step): the values beta at which 2 (max log-likelihood - log-likelihood with j held
        at beta) = chi2, the wander level, its scale and the other columns of the channel
        profiled at each beta. It is the interval of the likelihood-ratio test that named
        the term (beta = 0 lies outside it exactly when the test's statistic exceeds chi2),
        and wider than the Wald interval at the fitted level where a slow term and the
        wander can stand in for each other (a temperature ramp on a cold start): the Wald
        interval takes the level as known."""
        (c,) = self.design.columns[j]
        cols = self._columns(c, terms)
        (x,) = self._columns(c, [j])
        others = list(cols)
        others.remove(x)                    # one occurrence: a twin's column stays
        shift = self._nuisance_shift(c, terms)      # the clock held at its estimate
        g = self.gram[c] if shift is None else self._shifted(c, *shift)
        _, _, loglik, theta = self._profile(c, cols, gram=g)
        best = int(np.argmax(loglik))
        top, centre = float(loglik[best]), float(theta[best, 3 + cols.index(x)])

        def deficit(beta):                  # 2 (max - profile at beta) - chi2
            held = _less(g, x, beta)        # the Grams of the residual y - beta x
            return 2 * (top - float(np.max(self._profile(c, others, gram=held)[2]))) - chi2

        def edge(direction):                # the first crossing, stepping out by sd / 2
            inside, step = 0.0, 0.5 * max(sd, 1e-12 * max(abs(centre), 1e-300))
            for _ in range(200):
                if deficit(centre + direction * step) > 0:
                    return optimize.brentq(lambda d: deficit(centre + direction * d), inside,
                                           step, xtol=1e-6 * step)
                inside, step = step, step * 1.25
            return math.inf
        if not deficit(centre) < 0:         # the profile's top not resolved (its scale's
            return -math.inf, math.inf      # fixed point): unbounded, the caller keeps Wald's
        lo, hi = centre - edge(-1.0), centre + edge(1.0)
        if deficit(0.0) <= 0:               # the test does not reject zero: neither does the
            lo, hi = min(lo, 0.0), max(hi, 0.0)     # interval (a profile of several tops)
        return lo, hi

    def fit(self, terms, pinned=False, accuracy=1.0, clock=1.0):
        """`Fit` of the candidates `terms` (indices) with the reference error gamma under its
        prior (`pinned`: gamma held at zero - the candidates against the noise alone;
        `accuracy`: the prior's 1 sigma as a multiple of the stated one) and the design's
        nuisances under theirs (`Design.nuisance`, the reference's clock; `clock`: their
        1 sigma as a multiple of the stated); parameters [gamma (18), terms..., nuisances]."""
        factor = prior_factor(pinned, accuracy)
        nuisance = [n for n in self.design.nuisance if n not in terms]
        terms = list(terms) + nuisance
        k = [self.design.k[j] for j in terms]
        offsets = 18 + np.concatenate([[0], np.cumsum(k)]).astype(int)
        size = offsets[-1]
        a, h = np.zeros((size, size)), np.zeros(size)
        for c in range(6):
            cols, slots = [1, 2, 3], list(gamma_slots(c))
            for j, o, kj in zip(terms, offsets, k):
                if j in self.slot[c]:
                    cols += list(self.slot[c][j])
                    slots += list(range(o, o + kj))
            g, r, _ = self._level(c, cols[3:], factor)
            a[np.ix_(slots, slots)] += g[np.ix_(cols, cols)] / r
            h[slots] += g[cols, 0] / r
        a[:18, :18] += self.precision * factor
        for n in nuisance:
            span = slice(offsets[terms.index(n)], offsets[terms.index(n) + 1])
            a[span, span] += 1.0 / max(clock ** 2 * self.design.nuisance[n], 1e-300)
        cov = _covariance(a)
        beta = cov @ h
        return Fit(beta, cov, [slice(o, o + kj) for o, kj in zip(offsets, k)], list(terms))


def _less(g, x, beta):
    """Grams (levels, cols, cols) of [y, X] made those of [y - beta x_x, X]."""
    held = g.copy()
    held[:, 0, :] -= beta * g[:, x, :]
    held[:, :, 0] = held[:, 0, :]
    held[:, 0, 0] = g[:, 0, 0] - 2 * beta * g[:, 0, x] + beta ** 2 * g[:, x, x]
    return held


def prior_factor(pinned=False, accuracy=1.0):
    """The multiplier of the reference prior's precision: PIN holds the error at zero; a
    reference `accuracy` times as accurate as stated (its 1 sigma scaled) divides it by
    accuracy^2."""
    return PIN if pinned else 1.0 / accuracy ** 2


def _covariance(a):
    """The inverse of the normal matrix `a`: a near-singular one (terms that the flight
    cannot tell apart, a channel recording twice its input) is inverted over its eigenvalues
    floored at 1e-15 of the largest, so the unresolved directions get a huge variance - a
    wide interval - instead of a negative one from round-off (whose square root was NaN)."""
    try:
        cov = np.linalg.inv(a)
        if np.all(np.diag(cov) > 0):
            return cov
    except np.linalg.LinAlgError:
        pass
    lam, vec = np.linalg.eigh(0.5 * (a + a.T))
    lam = np.maximum(lam, 1e-15 * max(float(lam.max()), 1e-300))
    return (vec / lam) @ vec.T


@dataclass
class Fit:
    beta: np.ndarray
    cov: np.ndarray
    slices: list
    terms: list

    def gamma(self):
        return self.beta[:18]

    def of(self, j):
        """(estimate, covariance) of candidate j."""
        s = self.slices[self.terms.index(j)]
        return self.beta[s], self.cov[s, s]


def reference_direction(design, j):
    """Covariance of the reference's error expressed as candidate j's parameter (the part of
    j the reference can fake); None for a term the reference's linear error cannot make."""
    v = design.along[j]
    if v is None:
        return None
    vp = np.linalg.pinv(v)
    return vp @ design.prior @ vp.T


def wald(b, cov):
    """(chi-square statistic, log p) of b = 0."""
    try:
        stat = float(b @ np.linalg.solve(cov, b))
    except np.linalg.LinAlgError:
        return 0.0, 0.0
    return stat, float(stats.chi2.logsf(stat, len(b)))


def term_test(fitter, terms, j):
    """Test of candidate j within the fit of `terms` (which holds j): dict with the estimate,
    its covariance (with the reference's share), log p of the statistical test and log p
    with the reference's (and the calibration's) stated accuracy. A term the reference's
    linear error cannot make is tested by the likelihood ratio when it acts on one channel
    (wander level profiled with and without it: a slow term must beat the wander it would
    otherwise be), by Wald when it acts on several (one parameter shared by the channels:
    time skew); a linear one by Wald twice: with the reference error under its prior, and
    with it held at zero (the evidence against the noise alone). The design's nuisances
    (the reference's clock) are in every fit; a one-channel term's likelihood ratio holds
    them at their estimates (`likelihood_ratio`), blind to their uncertainty, so it must
    also pass Wald's test with them fitted."""
    design = fitter.design
    b, cov = fitter.fit(terms).of(j)
    ref = reference_direction(design, j)
    if ref is None and len(design.columns[j]) == 1:
        stat = max(fitter.likelihood_ratio([i for i in terms if i != j], j), 0.0)
        logp = float(stats.chi2.logsf(stat, len(b)))
        logp_ref = logp
        if design.allowance[j].any() or shares_a_nuisance(design, j):
            # must also beat the stated uncertainty that is no missing physics: the
            # calibration's own, the reference's through the transfer, its clock's (fitted)
            logp_ref = max(logp, wald(b, cov + design.allowance[j])[1])
        return {"b": b, "cov": cov, "stat": stat, "logp": logp, "logp_ref": logp_ref,
                "linear": False}
    if ref is None:                 # a term of several channels (time skew, lever arm): Wald
        stat, logp = wald(b, cov)
        logp_ref = max(logp, wald(b, cov + design.allowance[j])[1]) \
            if design.allowance[j].any() else logp
        return {"b": b, "cov": cov, "stat": stat, "logp": logp, "logp_ref": logp_ref,
                "linear": False}
    stat, logp = wald(*fitter.fit(terms, pinned=True).of(j))
    _, logp_ref = wald(b, cov)
    return {"b": b, "cov": cov, "stat": stat, "logp": logp, "logp_ref": logp_ref,
            "linear": True}


def shares_a_nuisance(design, j):
    """Candidate j acts on a channel a nuisance of the design acts on (`Design.nuisance`):
    its likelihood ratio holds the nuisance at its estimate, its Wald test (`Fitter.fit`)
    fits it too - `term_test` asks both."""
    return j not in design.nuisance and any(
        c in design.columns[n] for n in design.nuisance for c in design.columns[j])


def plausible(design, j, b, full_scale):
    """(within the physical range, the range) of candidate j's coefficient b."""
    limit = library.physical_limit(design.terms[j], full_scale, design.calibrated,
                                   design.arm_given)
    return float(np.linalg.norm(b)) <= limit, limit
