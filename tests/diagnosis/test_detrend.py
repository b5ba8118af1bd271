"""The sensor level's detrending (`design.Design.detrend`: hat functions every DETREND_KNOT_S
through their tridiagonal Gram) against the least-squares projection on the dense hat basis
by numpy's lstsq, written here from the definition."""
import numpy as np
import pytest

from mimunav.diagnosis.design import DETREND_KNOT_S, Design


def _projected_out(t, x):
    """x less its least-squares fit by the hats max(0, 1 - |t - k| / K) at knots k every K
    from t[0], those with a total weight of at most half a bin left out."""
    knots = np.arange(t[0], t[-1] + DETREND_KNOT_S, DETREND_KNOT_S)
    basis = np.clip(1 - np.abs((t[:, None] - knots[None, :]) / DETREND_KNOT_S), 0, None)
    basis = basis[:, basis.sum(axis=0) > 0.5]
    return x - basis @ np.linalg.lstsq(basis, x, rcond=None)[0]


@pytest.mark.parametrize("times", [
    np.arange(0.0, 35.0, 0.01),                                         # knots 0 .. 40 s
    np.r_[np.arange(0.0, 20.0, 0.01), np.arange(41.0, 60.0, 0.01)],     # a gap of a knot
    np.r_[np.arange(0.0, 50.0, 0.01), [65.0], np.arange(95.0, 200.0, 0.01)],  # a lone bin
    np.arange(0.0, 7.3, 0.01),                                          # under one knot step
    np.r_[np.arange(0.0, 5.0, 0.01), [25.0, 25.0]],                     # a singular Gram
])
def test_detrend_is_the_least_squares_projection_on_the_hats(times):
    rng = np.random.default_rng(3)
    x = rng.normal(size=(len(times), 3)) + np.column_stack([0.1 * times, np.sin(times), 0 * times])
    design = Design.__new__(Design)
    design.t = times
    assert np.abs(design.detrend(x) - _projected_out(times, x)).max() < 1e-10
