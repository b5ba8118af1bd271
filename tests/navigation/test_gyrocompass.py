"""Gyrocompassing at rest (`navigation.gyrocompass`) against its closed forms, and the ground
start it gives a flight (`evaluation.ground`): an east gyro bias turns the heading by
eps / (W cos L), an accelerometer bias tilts the level by b / g (Titterton & Weston sec. 10.2.1)."""
import math

import numpy as np
import pytest
import quaternion

from mimunav.errors import InputError
from mimunav.evaluation.flight import Flight
from mimunav.evaluation.ground import ground_start
from mimunav.frames import earth
from mimunav.frames.mounting import Mounting
from mimunav.motion.trajectory import State, Trajectory
from mimunav.navigation.gyrocompass import gyrocompass

LAT, H = math.radians(40.0), 1000.0
DEG_H = math.pi / 180 / 3600


def _at_rest(q_nb):
    """(w_b rad/s, f_b m/s^2) an ideal body at rest with attitude q_nb reads."""
    c_bn = quaternion.as_rotation_matrix(q_nb).T
    g = float(earth.normal_gravity(LAT, H))
    return c_bn @ earth.earth_rate_ned(LAT), c_bn @ np.array([0.0, 0.0, -g])


def _error(q, truth):
    turn = q * truth.conjugate()
    return quaternion.as_rotation_vector(-turn if turn.w < 0 else turn)


def test_an_ideal_body_at_rest_is_aligned_exactly():
    for rv in ([0.0, 0.0, 0.0], [0.02, -0.03, 1.1], [0.1, 0.05, -2.9]):
        q = quaternion.from_rotation_vector(rv)
        assert np.abs(_error(gyrocompass(*_at_rest(q), LAT, H), q)).max() < 1e-12


def test_an_east_gyro_bias_turns_the_heading_and_an_accel_bias_tilts_the_level():
    q = quaternion.from_rotation_vector([0.0, 0.0, 0.7])
    c_bn = quaternion.as_rotation_matrix(q).T
    w_b, f_b = _at_rest(q)
    eps = 0.5 * DEG_H
    heading = _error(gyrocompass(w_b + c_bn @ [0.0, eps, 0.0], f_b, LAT, H), q)
    assert heading[2] == pytest.approx(-eps / (earth.OMEGA * math.cos(LAT)), rel=1e-3)
    b = 50e-6 * 9.80665                 # 50 ug along north
    tilt = _error(gyrocompass(w_b, f_b + c_bn @ [b, 0.0, 0.0], LAT, H), q)
    assert np.hypot(tilt[0], tilt[1]) == pytest.approx(b / 9.80665, rel=2e-3)


def _flight(speed_after, hold_s=150.0, bias=0.0):
    """A flight whose FOG-IMU (at 100 Hz, level, heading 30 deg) stands still for hold_s and
    then moves at speed_after m/s north; its east gyro bias rad/s."""
    t = np.arange(1, int(200 * 100) + 1) / 100.0
    q = quaternion.from_rotation_vector([0.0, 0.0, math.radians(30.0)])
    w_b, f_b = _at_rest(q)
    c_bn = quaternion.as_rotation_matrix(q).T
    n = len(t)
    v = np.zeros((n, 3))
    v[t > hold_s, 0] = speed_after
    truth = Trajectory(t, np.full(n, LAT), np.zeros(n), np.full(n, H), v, np.full(n, q))
    initial = State(0.0, LAT, 0.0, H, np.zeros(3), q)
    return Flight("synthetic", "rest", 0, initial, t, None, Mounting(), {}, t,
                  np.tile(w_b + c_bn @ [0.0, bias, 0.0], (n, 1)), np.tile(f_b, (n, 1)),
                  Mounting(), truth)


def test_a_ground_start_is_the_fog_imus_gyrocompass_and_refuses_a_moving_start():
    eps = 0.5 * DEG_H
    aligned, said = ground_start(_flight(100.0, bias=eps))
    assert aligned.initial.t == pytest.approx(120.01, abs=0.011)
    assert math.radians(said["heading_error_deg"]) == pytest.approx(
        -eps / (earth.OMEGA * math.cos(LAT)), rel=1e-3)
    assert said["level_error_deg"] < 1e-9
    with pytest.raises(InputError, match="moves there .speed up to 100 m/s.*--start air"):
        ground_start(_flight(100.0, hold_s=60.0))
    with pytest.raises(InputError, match="does not stand still enough to gyrocompass"):
        ground_start(_flight(0.0, bias=20 * DEG_H))
