"""A track's positions checked against its own velocity (`motion.track.position_jumps`),
on tracks given in closed form: a circle driven at 20 m/s in the local level plane, its
positions and velocities exact at every stamp."""
import numpy as np

from mimunav.frames import earth
from mimunav.motion.track import position_jumps

LAT0, LON0, H0 = np.radians(48.0), np.radians(11.0), 500.0
RADIUS, SPEED = 200.0, 20.0


def circle(t, stamps=None, north_offset=None):
    """(t, lat, lon, h, v_ned) of the circle at times t (s), stamped at `stamps` (default t):
    position n = R (sin wt, 1 - cos wt, 0) about the origin's NED, velocity its derivative in
    each epoch's own NED; `north_offset` (m, (N,)) moves the positions only."""
    w = SPEED / RADIUS
    n = np.column_stack([RADIUS * np.sin(w * t), RADIUS * (1 - np.cos(w * t)), 0 * t])
    n_dot = np.column_stack([SPEED * np.cos(w * t), SPEED * np.sin(w * t), 0 * t])
    if north_offset is not None:
        n[:, 0] += north_offset
    c0 = earth.ned_to_ecef_matrix(LAT0, LON0)
    lat, lon, h = earth.ecef_to_geodetic(earth.geodetic_to_ecef(LAT0, LON0, H0) + n @ c0.T)
    v_e = n_dot @ c0.T
    v = np.einsum("kji,kj->ki", earth.ned_to_ecef_matrix(lat, lon), v_e)
    return (t if stamps is None else stamps), lat, lon, h, v


def test_a_position_jump_is_found_where_and_as_large_as_it_is():
    """0.5 m north from t = 60 s on, at 100 Hz: one jump, at 60 s, of 0.5 m (to a mm); the
    same track without it none (the Hermite quadrature on an exact track misses by far less
    than JUMP_FLOOR_M)."""
    t = np.arange(0.0, 120.0, 0.01)
    assert position_jumps(*circle(t)) == []
    got = position_jumps(*circle(t, north_offset=np.where(t >= 60.0 - 1e-9, 0.5, 0.0)))
    assert len(got) == 1 and abs(got[0][0] - 60.0) < 1e-6 and abs(got[0][1] - 0.5) < 1e-3, got


def test_late_stamps_and_noise_are_no_jumps_and_a_jump_in_noise_is_found():
    """1 % of the stamps 4-6.5 ms late (0.1 m off the velocity at 20 m/s, into the epoch and
    back out of it: the track does not stay off) and an INS's noise (5 mm in position, 1 cm/s
    in velocity) make no jump; a 0.2 m jump inside that noise is found, at its epoch."""
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 120.0, 0.01)
    late = np.where(rng.random(len(t)) < 0.01, rng.uniform(0.004, 0.0065, len(t)), 0.0)
    assert position_jumps(*circle(t, stamps=t + late)) == []
    noise = rng.normal(0.0, 0.005, len(t))
    track = list(circle(t, north_offset=noise))
    track[4] = track[4] + rng.normal(0.0, 0.01, (len(t), 3))
    assert position_jumps(*track) == []
    jumped = list(circle(t, north_offset=noise + np.where(t >= 80.0 - 1e-9, 0.2, 0.0)))
    jumped[4] = track[4]
    got = position_jumps(*jumped)
    assert len(got) == 1 and abs(got[0][0] - 80.0) < 1e-6, got


def test_a_one_hertz_track_braking_is_no_jump():
    """A 1 Hz track stopping from 20 m/s at 4 m/s^2, its jerk 4 m/s^3 at the braking's onset
    and end (ramps of 1 s): the trapezoid alone misses by dt^3 jerk / 12 = 0.33 m
    there and would call it a jump; the Hermite quadrature follows it."""
    t = np.arange(0.0, 60.0, 1.0)
    fine = np.arange(0.0, 60.0, 0.001)
    a = np.interp(fine, [0, 20, 21, 25, 26, 60], [0, 0, -4, -4, 0, 0])   # ramps of 1 s
    v = SPEED + np.cumsum(a) * 0.001
    x = np.cumsum(v) * 0.001
    on = np.searchsorted(fine, t)
    n = np.column_stack([x[on], 0 * t, 0 * t])
    c0 = earth.ned_to_ecef_matrix(LAT0, LON0)
    lat, lon, h = earth.ecef_to_geodetic(earth.geodetic_to_ecef(LAT0, LON0, H0) + n @ c0.T)
    v_ned = np.einsum("kji,kj->ki", earth.ned_to_ecef_matrix(lat, lon),
                      np.column_stack([v[on], 0 * t, 0 * t]) @ c0.T)
    assert position_jumps(t, lat, lon, h, v_ned) == []
