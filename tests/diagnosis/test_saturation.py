"""Saturation on the outputs themselves (`outputs.saturation`): a rail is where the output
stays flat while its input goes beyond anything it output - judged on the input as the
output reads it, its own offset included."""
import numpy as np

from mimunav.diagnosis import outputs

FULL_SCALE = {"accel": 16 * 9.80665, "gyro": 35.0}


def _record(n=20000, seed=3):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.002
    predicted = np.zeros((n, 6))
    predicted[:, 2] = -4.98                         # accel.z at a tilted rest
    predicted[: n // 2, 2] = 3.0 * np.sin(0.5 * t[: n // 2])     # +-3 m/s^2 before it
    measured = predicted + 0.01 * rng.standard_normal((n, 6))
    rows, train = np.ones(n, bool), (np.arange(n) // 250) % 2 == 0
    return t, measured, predicted, rows, train


def test_an_offset_at_rest_is_no_clip():
    """The rocket's ground rest: accel.z reads its input plus an uncorrected 25 mg bias, so
    the input lies 0.245 m/s^2 beyond the most negative reading for a minute, and the output
    is flat there - a rest, not a rail."""
    t, measured, predicted, rows, train = _record()
    measured[:, 2] += 0.245
    found, clipped = outputs.saturation(t, measured, predicted, rows, train, FULL_SCALE)
    assert found == [] and not clipped.any()


def test_a_rail_below_the_range_is_found_at_its_level():
    """The same channel clipped at +1.5 m/s^2 while its input swings to +3, biased as above:
    found on the + side at the rail's level, the clipped samples flagged."""
    t, measured, predicted, rows, train = _record()
    measured[:, 2] = np.minimum(measured[:, 2] + 0.245, 1.5)
    found, clipped = outputs.saturation(t, measured, predicted, rows, train, FULL_SCALE)
    assert [(f["sensor"], f["axis"], f["side"]) for f in found] == [("accel", "z", "+")]
    assert abs(found[0]["coefficient"] - 1.5) < 0.01
    truly = predicted[:, 2] + 0.245 > 1.5 + 0.05
    assert clipped[truly].all()
