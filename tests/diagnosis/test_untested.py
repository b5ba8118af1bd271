"""A navigation-level finding beside the terms that level cannot test
(`diagnosis.untested.beside_untested`), on a tier of known columns: least squares alone
absorbs a correlated term it does not carry; beside it the interval holds the truth."""
import numpy as np

from mimunav.diagnosis import inference, library
from mimunav.diagnosis.inference import Tier
from mimunav.diagnosis.untested import beside_untested

FOUND = {"effect": "scale_factor", "sensor": "accel", "axis": "x"}
ALIKE = {"effect": "cross_coupling", "sensor": "accel", "axis": "x", "input_axis": "y"}
APART = {"effect": "scale_factor", "sensor": "gyro", "axis": "z"}


def _tier(alike_coefficient, share=0.8, seed=7):
    """One channel of 3000 epochs: residual = 1.0 x_found + c x_alike + white noise, x_alike
    `share` x_found plus its own part, x_apart independent; columns in that order."""
    rng = np.random.default_rng(seed)
    n = 3000
    found = np.cumsum(rng.normal(size=n)) / 30.0
    alike = share * found + 0.6 * np.cumsum(rng.normal(size=n)) / 30.0
    apart = np.cumsum(rng.normal(size=n)) / 30.0
    y = found + alike_coefficient * alike + rng.normal(0.0, 0.05, n)
    return Tier("navigation", np.arange(n, dtype=float), y[:, None],
                [{0: x[:, None]} for x in (found, alike, apart)], [1, 1, 1],
                kept=np.ones(n, bool), knot_s=(float(n),))


def _finding(tier, rows):
    fit = inference.fit(tier, [0], rows)
    lo, hi = fit.interval(0)
    return dict(FOUND, label=library.label(FOUND), coefficient=float(fit.beta[0]),
                ci95=[float(lo[0]), float(hi[0])], p_heldout=1e-30, heldout_threshold=0.05,
                units="1")


def test_a_finding_that_absorbs_an_untested_look_alike_is_widened_to_the_truth():
    """The unit carries 0.5 of a term this level cannot test, 0.8 correlated with the found
    one: alone the finding reads about 1.4, its interval far from its true 1.0; beside the
    look-alike (not beside the independent term) its interval is widened until it holds
    1.0 - and so wide its held-out test fails: set aside, naming that term. Less alike
    (0.2), the finding is kept, widened to hold its truth; with no term untested, as it was."""
    cands = [("navigation", term, j) for j, term in enumerate((FOUND, ALIKE, APART))]
    noisy = lambda term: term is not FOUND                  # noqa: E731
    tier = _tier(0.5)
    rows = np.ones(len(tier.t), bool)
    alone = _finding(tier, rows)
    assert alone["ci95"][0] > 1.2, alone["ci95"]
    kept, (aside,) = beside_untested(tier, cands, [alone], noisy, rows)
    assert kept == [] and aside["untested"]["term"] == library.label(ALIKE)
    assert aside["ci95"][0] < 1.0 < aside["ci95"][1], aside["ci95"]
    assert aside["rejected"].startswith(f"beside {library.label(ALIKE)}, a term made of")
    tier = _tier(0.5, share=0.2, seed=9)
    alone = _finding(tier, rows)
    assert not alone["ci95"][0] < 1.0 < alone["ci95"][1], alone["ci95"]
    (kept,), aside = beside_untested(tier, cands, [alone], noisy, rows)
    assert aside == [] and kept["untested"]["term"] == library.label(ALIKE)
    assert kept["ci95"][0] < 1.0 < kept["ci95"][1], kept["ci95"]
    assert beside_untested(tier, cands, [alone], lambda term: False, rows) == ([alone], [])
