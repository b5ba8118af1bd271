"""Analytic coarse alignment at rest by gyrocompassing (Titterton & Weston, Strapdown Inertial
Navigation Technology, 2nd ed., sec. 10.2.1): a stationary IMU's mean specific force is the
reaction to gravity and its mean rate the Earth's, known in the navigation frame (NED)
    f^n = (0, 0, -g),    w_ie^n = (W cos L, 0, -W sin L),
so the body-to-NED rotation is the one that carries the measured pair onto the known one -
the TRIAD solution with the specific force exact (the better-known vector) and the rate's
part across it giving north. A gyro bias eps across gravity turns the heading by about
eps_east / (W cos L) rad (eq. 10.13's error): 0.5 deg/h at 40 deg latitude, 2.5 deg; an
accelerometer bias b tilts the level by b / g rad.
"""
import math

import numpy as np
import quaternion

from ..frames import earth


def gyrocompass(w_b, f_b, lat, h=0.0):
    """q_nb (numpy quaternion, body -> NED) of a body at rest whose mean rate is w_b (rad/s)
    and mean specific force f_b (m/s^2), both (3,) in the body axes, at latitude lat (rad)
    and height h (m)."""
    g = float(earth.normal_gravity(lat, h))
    f_n = np.array([0.0, 0.0, -g])
    w_n = earth.OMEGA * np.array([math.cos(lat), 0.0, -math.sin(lat)])
    c_nb = _triad(f_n, w_n) @ _triad(np.asarray(f_b, float), np.asarray(w_b, float)).T
    return quaternion.from_rotation_matrix(c_nb)


def _triad(first, second):
    """(3, 3) orthonormal columns: first's direction, then the part of second across it,
    then their cross product."""
    a = first / np.linalg.norm(first)
    b = np.cross(a, second)
    b /= np.linalg.norm(b)
    return np.column_stack([a, b, np.cross(a, b)])
