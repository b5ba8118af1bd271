"""The bias's models on its span means (`outputs.bias_tests`): a unit of the class (a
flicker wander and a turn-on offset), an offset beyond it (bias_shift), a Gauss-Markov
wander beyond it (bias_instability) - their profiled Gaussian likelihoods, the covariance of
window means of a Gauss-Markov process in closed form."""
import math
from functools import lru_cache

import numpy as np
from scipy import stats

from ..lab.gls import flicker_covariance
from ..sensors.noise import FLICKER_SPAN

GM_TAU_S = 100.0                 # correlation time the wander level is read with
SPAN_S = 2.0        # the bias is read from SPAN_S means of quiet flight: what is faster (a
                    # colored noise, flicker at seconds) is no bias instability nor offset
FAST_S = 0.1        # the flicker's highest frequency in the class model, 1/FAST_S Hz (the
                    # means' sinc makes faster terms negligible)


def profiled_loglik(x, nuisance, cov):
    """Gaussian log-likelihood of x under cov with the columns `nuisance` (m, k) at their
    generalised-least-squares values (k = 0: none); and the fitted x."""
    if nuisance.shape[1]:
        inv = np.linalg.solve(cov, nuisance)
        x = x - nuisance @ np.linalg.solve(nuisance.T @ inv, inv.T @ x)
    _, logdet = np.linalg.slogdet(cov)
    return -0.5 * (logdet + x @ np.linalg.solve(cov, x) + len(x) * math.log(2 * math.pi))


def wander_profile(x, nuisance, base, corr, grid):
    """`profiled_loglik` of x under s^2 corr + base for every s of `grid`, at once: with the
    generalised eigenvectors V of (corr, base) (V' base V = I, V' corr V = diag(lam)) the
    covariance is diagonal, diag(1 + s^2 lam), in y = V' x (scipy.linalg.eigh)."""
    from scipy.linalg import eigh
    lam, vec = eigh(corr, base)
    lam = np.maximum(lam, 0.0)
    _, logdet_base = np.linalg.slogdet(base)
    y, z = vec.T @ x, vec.T @ nuisance
    d = 1.0 + np.outer(grid ** 2, lam)                  # (g, m) the diagonal per s
    if z.shape[1]:
        a = np.einsum("mk,gm,ml->gkl", z, 1.0 / d, z)
        b = np.einsum("mk,gm,m->gk", z, 1.0 / d, y)
        beta = np.linalg.solve(a, b[:, :, None])[:, :, 0]
        r = y[None, :] - beta @ z.T
    else:
        r = np.broadcast_to(y, d.shape)
    quad = np.sum(r ** 2 / d, axis=1)
    return -0.5 * (logdet_base + np.log(d).sum(axis=1) + quad + len(x) * math.log(2 * math.pi))


FLICKER_LEVELS = (0.0, 0.25, 0.5, 0.75, 1.0)     # the unit's flicker, fractions of the class's


def gm_mean_correlation(t, span, tau):
    """Covariance, per unit variance, of the means over windows [t - span/2, t + span/2] of
    a Gauss-Markov process of correlation time tau (closed form of the double integral of
    exp(-|s - u| / tau)): for windows d >= span apart (r = span / tau)
        (tau / span)^2 exp(-d / tau) 2 (cosh r - 1),
    and for a window with itself 2 (tau / span)^2 (r - 1 + exp(-r)). Point values'
    exp(-d / tau) overstate how much adjacent means differ (a random walk's mean over a
    window differs from the next by 2/3 of its point difference's variance) and so
    understated sigma by a fifth."""
    r = span / tau
    d = np.abs(t[:, None] - t[None, :])
    out = (tau / span) ** 2 * np.exp(-d / tau) * 2 * (math.cosh(r) - 1)
    np.fill_diagonal(out, 2 * (tau / span) ** 2 * (r - 1 + math.exp(-r)))
    return out


@lru_cache(maxsize=4)
def _mean_correlations(t_bytes, span):
    """(flicker covariance of unit instability, Gauss-Markov correlation) of the `span` (s)
    means at the times t (s, float64 bytes): the same for every channel whose quiet means
    are at the same times, so made once (read-only arrays)."""
    t = np.frombuffer(t_bytes)
    length = float(t[-1] - t[0]) + span
    flicker = flicker_covariance(t - span / 2, t + span / 2,
                                 1.0 / (FLICKER_SPAN * length), 1.0 / FAST_S)
    corr = gm_mean_correlation(t, span, GM_TAU_S)
    flicker.flags.writeable = corr.flags.writeable = False
    return flicker, corr


def bias_models(t, x, instability, offset, white, nuisance=None, span=SPAN_S,
                about_mean=False):
    """The class, shift and wander models of `bias_tests` on the `span` (s) means x at times
    t (s), each
    with the columns `nuisance` (m, k: the channel's temperature, so a slow thermal term
    too weak for the library is not read as wander) at their best values:
    {"shift": {"lr", "mu", "se"}, "wander": {"lr", "sigma", "lower", "upper"}}.
    about_mean: the class and the wander carry a free mean too, so the wander's test asks
    for a wander beyond an offset (the shift's likelihood ratio, against a class with its
    mean free, is then no test of an offset)."""
    n = len(x)
    nuisance = np.zeros((n, 0)) if nuisance is None else nuisance
    unit_flicker, corr = _mean_correlations(np.ascontiguousarray(t, float).tobytes(), span)
    flicker = instability ** 2 * unit_flicker
    ones = np.ones((n, 1))
    base = flicker + white * np.eye(n)
    turn_on = offset ** 2 * (ones @ ones.T)
    with_mean = np.hstack([ones, nuisance])
    fixed = with_mean if about_mean else nuisance       # the columns class and wander carry
    l_class = profiled_loglik(x, fixed, base + turn_on)
    inv = np.linalg.solve(base, with_mean)
    cov_mu = np.linalg.inv(with_mean.T @ inv)
    mu = float((cov_mu @ inv.T @ x)[0])
    l_shift = profiled_loglik(x, with_mean, base)
    grid = instability * np.geomspace(1e-2, 1e3, 301)
    ll = wander_profile(x, fixed, base + turn_on, corr, grid)
    # sigma and its interval with the unit's own flicker level b a nuisance within the class
    # (0 <= b <= B, profiled on FLICKER_LEVELS): the class's flicker is the test's null, but a
    # unit wanders as much as it does - fixed at B it took a fifth of a Gauss-Markov truth,
    # left out it read a flicker unit's 1/f as a wander three times too large; and without
    # the temperature, which once the wander is called would take part of it away
    ridge = max(white, 1e-12 * (float(np.var(x)) + offset ** 2)) * np.eye(n)  # white ~ 0
    plain = np.max([wander_profile(x, with_mean[:, :int(about_mean)],
                                   b ** 2 * flicker + ridge + turn_on, corr, grid)
                    for b in FLICKER_LEVELS], axis=0)
    inside = grid[plain >= plain.max() - 0.5 * stats.chi2.isf(0.05, 1)]
    lr_wander = max(2 * (ll.max() - l_class), 0.0)
    # the offset's test: its GLS mean against the class's turn-on spread added to its own
    # variance, z^2 = mu^2 / (se^2 + s0^2) ~ chi2(1) under the class (the likelihood ratio of
    # a free mean against a random one is not nested: its chi2 would overstate it)
    z2 = mu ** 2 / (cov_mu[0, 0] + offset ** 2)
    return {"shift": {"lr": max(2 * (l_shift - l_class), 0.0), "mu": mu,
                      "se": math.sqrt(cov_mu[0, 0]), "p": float(stats.chi2.sf(z2, 1))},
            "wander": {"lr": lr_wander, "p": float(stats.chi2.sf(lr_wander, 1)),
                       "sigma": float(grid[int(np.argmax(plain))]), "lower": float(inside[0]),
                       "upper": float(inside[-1])}}
