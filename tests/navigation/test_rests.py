"""Rests need the IMU to feel one (`navigation.rests`): |f| near g and |w| small, not
quietness alone - a rocket's coast (free fall, a quiet IMU) under a reference whose speed
stalls near apogee is no rest, and no bias is taken from it."""
import numpy as np

from mimunav.navigation import rests

G = rests.G0


def _rocket(rate=100.0):
    """t (s), w (rad/s), f (m/s^2) of a rocket's IMU: 10 s on the pad (1 g up, still), 3 s
    of a 6 g boost, 12 s of coast (free fall: |f| ~ 0, quiet), each with a MEMS part's
    noise (0.05 m/s^2, 0.005 rad/s per sample)."""
    rng = np.random.default_rng(7)
    t = np.arange(1, int(25 * rate) + 1) / rate
    f = np.zeros((len(t), 3))
    f[t <= 10, 2] = -G
    f[(t > 10) & (t <= 13), 2] = -6 * G
    return t, rng.normal(0, 0.005, (len(t), 3)), f + rng.normal(0, 0.05, (len(t), 3))


def test_a_coast_under_a_still_reference_is_no_rest_and_the_pad_is():
    t, w, f = _rocket()
    kept, refused = rests.felt_at_rest(t, w, f, [(1.0, 9.0), (15.0, 24.0)])
    assert kept == [(1.0, 9.0)]
    (t0, t1, why), = refused
    assert (t0, t1) == (15.0, 24.0) and "feels |f| 0.0" in why and "no rest" in why


def test_quiet_stretches_of_the_imu_alone_skip_the_free_fall():
    """The coast is as quiet as the pad (quieter than the boost); only the pad is a rest."""
    t, w, f = _rocket()
    found = rests.quiet_stretches(t, w, f)
    assert found and all(t1 <= 10.0 + 1e-9 for _, t1 in found)
    assert sum(t1 - t0 for t0, t1 in found) > 8.0


def test_a_phones_biased_accelerometer_on_a_table_is_at_rest():
    """A phone's accelerometer 45 mg off along gravity (|f| 0.44 m/s^2 above g) lying 60 s
    on a table, then carried: the table is a rest (0.3 m/s^2 had refused it and lost the
    walk's import); the boost of `_rocket` and its coast stay none."""
    rng = np.random.default_rng(8)
    t = np.arange(1, 9001) / 100.0
    f = np.tile([0.0, 0.0, -(G + 0.045 * G)], (len(t), 1)) + rng.normal(0, 0.02, (len(t), 3))
    w = rng.normal(0, 0.002, (len(t), 3))
    moving = t > 60.0
    w[moving] += 0.3 * np.sin(2 * np.pi * 1.8 * t[moving])[:, None]
    f[moving] += 2.0 * np.sin(2 * np.pi * 1.8 * t[moving])[:, None]
    found = rests.quiet_stretches(t, w, f)
    assert found and found[0][0] < 1.0 and 58.0 < found[0][1] <= 60.5, found
    assert abs(0.045 * G) < rests.REST_GRAVITY
