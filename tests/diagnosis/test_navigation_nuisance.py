"""The navigation level's nuisance signatures (`error_equations.nuisance`), built a few wander
knots at a time at the epochs only: the same numbers as every knot's hat at every bin at
once (which held 7 GB on an hour at 200 Hz)."""
import numpy as np

from mimunav.diagnosis import error_equations as equations
from mimunav.diagnosis.error_equations import ErrorModel, nuisance, signature


def _model(seconds=300.0, bin_s=0.01):
    """An ErrorModel of a vehicle turning slowly (its sensor-to-NED rotation about down) under
    1 g and a swaying horizontal force."""
    t = np.arange(1, int(seconds / bin_s) + 1) * bin_s
    yaw = 0.02 * t
    c, s = np.cos(yaw), np.sin(yaw)
    c_ns = np.zeros((len(t), 3, 3))
    c_ns[:, 0, 0], c_ns[:, 0, 1], c_ns[:, 1, 0], c_ns[:, 1, 1], c_ns[:, 2, 2] = c, -s, s, c, 1
    f_n = np.column_stack([0.5 * np.sin(0.1 * t), 0.3 * np.cos(0.07 * t), np.full(len(t), -9.81)])
    return ErrorModel(t, c_ns, f_n, np.full(len(t), bin_s), np.array([5e-5, 0.0, -5e-5]))


def _all_at_once(model, at):
    """The former construction: every knot's hat at every bin, then the epochs taken."""
    t = model.t
    knots = np.arange(t[0], t[-1] + equations.WANDER_KNOT_S, equations.WANDER_KNOT_S)
    hat = np.clip(1 - np.abs((t[:, None] - knots[None, :]) / equations.WANDER_KNOT_S), 0, None)
    hat = hat[:, hat.sum(axis=0) > 0.5]
    cols = [signature(model, {(sens, i): hat}, hat.shape[1])
            for i in range(3) for sens in ("accel", "gyro")]
    cols.append(np.cumsum(np.cross(model.f_n[:, :, None], np.eye(3)[None], axisa=1, axisb=1,
                                   axisc=1) * model.dt[:, None, None], axis=0))
    return np.concatenate(cols, axis=2)[at]


def test_the_nuisance_built_a_few_knots_at_a_time_is_the_whole_at_once(monkeypatch):
    model = _model()
    at = np.arange(99, len(model.t), 100)
    whole = _all_at_once(model, at)
    for knots in (1, 3, equations.NUISANCE_KNOTS, 1000):
        monkeypatch.setattr(equations, "NUISANCE_KNOTS", knots)
        assert np.array_equal(nuisance(model, at), whole), knots
    assert whole.shape == (len(at), 3, 6 * 6 + 3)      # 6 knots over 300 s, 6 channels, phi0
    assert np.abs(whole).max() > 1.0                    # not a column of zeros
