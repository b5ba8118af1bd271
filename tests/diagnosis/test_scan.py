"""`scan`: localized excursions of the residual, found on a fit that leaves them out."""
from types import SimpleNamespace

import numpy as np

from mimunav.diagnosis.scan import excursions, excursions_left_out


def test_an_excursion_left_out_of_the_fit_makes_no_excursion_elsewhere():
    """A reference-error column u (a specific force, m/s^2) large in two 2 s events, A and B;
    the residual holds a shortfall of 0.025 u in A alone (a launch's clipped samples) and
    white noise. A least-squares coupling fitted on every bin takes 0.016 of it and leaves
    -0.47 m/s^2 in B, an excursion the outputs do not hold; fitted without A's and B's bins
    it takes none: B is quiet, A stands. What the refit makes anew on the bins it left out
    (there it extrapolates: gyro.y here) is not taken."""
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 600.0, 0.05)
    a, b = (t >= 100.0) & (t < 102.0), (t >= 400.0) & (t < 402.0)
    u = np.where(a, 40.0, 0.0) + np.where(b, 30.0, 0.0)
    x = rng.normal(0.0, 0.05, (len(t), 6))
    x[:, 0] += np.where(a, 0.025 * u, 0.0)

    def residual_on(rows):
        gamma = (u[rows] @ x[rows, 0]) / (u[rows] @ u[rows] + 1.0)
        r = x.copy()
        r[:, 0] -= gamma * u
        r[~rows & a, 4] += 0.05        # the refit's own error where it never saw A's motion
        return r

    design = SimpleNamespace(t=t, shape=None)
    every = excursions(design, residual_on(np.ones(len(t), bool)), 0.05)
    assert [(e["channel"], round(e["peak_t0"])) for e in every] == [("accel.x", 100),
                                                                   ("accel.x", 400)]
    found = excursions_left_out(design, residual_on, 0.05, every)
    assert found == every[:1]                   # as the all-rows fit read it (0.35 of 1.0)
    assert excursions_left_out(design, residual_on, 0.05, []) == []


def test_bins_longer_than_the_window_stand_out_only_where_they_lie():
    """A 1 Hz track's 4 s bins: a 2 s window holds one bin or none. One bin 0.2 rad/s off (20
    times the others' noise) stands out once, in the windows that hold it - an empty
    window is no mean of 0 (two 'excursions' 11 s apart, where no bin lies, each the bin 5 s
    off, had been listed for every real one)."""
    rng = np.random.default_rng(8)
    t = 7.9 + 4.01 * np.arange(110)
    x = rng.normal(0.0, 0.01, (len(t), 6))
    x[50, 5] += 0.2
    found = excursions(SimpleNamespace(t=t, shape=None), x, 0.05)
    assert [e["channel"] for e in found] == ["gyro.z"]
    assert found[0]["t0"] <= t[50] < found[0]["t1"]
    assert abs(found[0]["size"] - 0.2) < 0.05


def test_rows_either_side_of_a_hole_in_the_stamps_are_one_span():
    """The samples left out beside a 1.92 s hole in a drive's stamps (KITTI's first): one
    span 0.0-2.0 s, not '0.0 s, 1.9-2.0 s'; flagged rows with unflagged ones between them
    and further apart than gap_s stay two."""
    from mimunav.diagnosis.outputs import spans
    t = np.r_[0.0, np.arange(1.92, 10.0, 0.01)]
    rows = t < 2.0
    assert [(s["t0"], round(s["t1"], 2)) for s in spans(t, rows, "gap", gap_s=0.5)] == \
        [(0.0, 1.99)]
    rows |= (t > 5.0) & (t < 5.5)
    assert len(spans(t, rows, "gap", gap_s=0.5)) == 2
