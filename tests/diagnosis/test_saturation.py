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


def test_a_rail_too_short_to_name_is_left_out_and_a_peak_is_not():
    """A Shimmer's low-noise accelerometer flat at -24.6145 m/s^2 on 7 samples while its
    wide-range twin read to -57.5: too few to name a saturation (SATURATION_MIN_SAMPLES),
    but those samples - and those whose input comes near the rail - are left out of the fit
    (they had hidden a cross-coupling and left an excursion); a live peak beyond every other
    sample, however far its input, is no rail; nor is one sample at the extreme (a spike
    of the reference's)."""
    from mimunav.diagnosis.rails import short_rails
    t, measured, predicted, rows, train = _record()
    burst = np.arange(5000, 5007)
    predicted[burst, 1] = -np.linspace(30.0, 57.5, 7)        # accel.y's input beyond the rail
    measured[:, 1] = predicted[:, 1] + 0.01 * np.random.default_rng(7).standard_normal(len(t))
    measured[burst, 1] = -24.6145
    sigma = np.full(6, 0.01)
    assert outputs.saturation(t, measured, predicted, rows, train, FULL_SCALE)[0] == []
    rails = short_rails(measured, predicted, rows, sigma, set())
    assert set(np.flatnonzero(rails)) == set(burst)
    live = measured.copy()
    live[burst, 1] = predicted[burst, 1] * 0.98 + 0.01        # a peak: scale error, no rail
    assert not short_rails(live, predicted, rows, sigma, set()).any()
    once = measured.copy()
    once[burst[1:], 1] = -24.0 - 0.01 * np.arange(6)          # at the extreme on one sample
    assert not short_rails(once, predicted, rows, sigma, set()).any()
    assert not short_rails(measured, predicted, rows, sigma, {("accel", "y")}).any()
