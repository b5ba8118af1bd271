"""What removing a found term leaves in the residual the bias tests read
(`confirmation.removal_sigma`): the term's estimate is off by its own error, and on a quiet
flight that error is an offset - a mounting's tilt of g. Closed forms on a stand-in design."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from mimunav.diagnosis import confirmation

G = 9.80665


def _design(term, accel_columns, q_vs=(1.0, 0.0, 0.0, 0.0), n=200):
    """A stand-in design: one term whose accelerometer columns (3 channels, (3, 3) each row
    the same) are `accel_columns`, the gyros untouched."""
    cols = {c: np.tile(accel_columns[c], (n, 1)) for c in range(3)}
    return SimpleNamespace(t=np.arange(n) * 0.01, channels=6, columns=[cols], terms=[term],
                           q_vs=np.asarray(q_vs))


def _fit(cov):
    return SimpleNamespace(of=lambda j: (np.zeros(len(cov)), cov))


def _finding(label, se, frame=None):
    v = np.zeros(len(se))
    out = {"label": label, "coefficient": 0.0, "ci95": [-1.96 * se[0], 1.96 * se[0]],
           "vector": v.tolist(), "vector_ci95": [[-1.959964 * s, 1.959964 * s] for s in se]}
    if frame:
        out["frame"] = frame
    return out


def test_a_mountings_error_tilts_g_into_the_level_accelerometers():
    """Sensor tilted by a about x, level flight: f = (0, -g sin a, -g cos a) and a turn phi
    of the axes changes it by f x phi, so accel.x moves by -g cos a phi_y + g sin a phi_z
    (correlated as the all-rows fit's rho), accel.y by g cos a phi_x, accel.z by -g sin a
    phi_x; the standard errors are the finding's, not the all-rows fit's."""
    a = math.radians(20.0)
    f = np.array([0.0, -G * math.sin(a), -G * math.cos(a)])
    skew = np.array([[0, -f[2], f[1]], [f[2], 0, -f[0]], [-f[1], f[0], 0]])   # f x phi = skew @ phi
    term = {"effect": "mounting_misalignment", "sensor": "imu", "axis": "all"}
    design = _design(term, skew)
    se, rho = np.array([0.02, 0.01, 0.05]), 0.6
    corr = np.array([[1, 0, 0], [0, 1, rho], [0, rho, 1]])
    cov_all = corr * np.outer([1e-4, 2e-4, 3e-4], [1e-4, 2e-4, 3e-4])     # other sizes
    rows = np.ones(200, bool)
    sigma = confirmation.removal_sigma(design, _fit(cov_all),
                                       [_finding("mounting_misalignment imu.all", se)], rows)
    c, s = G * math.cos(a), G * math.sin(a)
    want_x = math.sqrt((c * se[1]) ** 2 + (s * se[2]) ** 2 - 2 * c * s * rho * se[1] * se[2])
    assert sigma[:3] == pytest.approx([want_x, c * se[0], s * se[0]], rel=1e-9)
    assert not sigma[3:].any()
    none = confirmation.removal_sigma(design, _fit(cov_all), [], rows)
    assert not none.any()


def test_a_lever_arms_interval_is_turned_from_the_vehicle_frame():
    """A lever arm's interval is stated in the vehicle frame: with the sensor yawed 90 deg
    (sensor x = vehicle y, sensor y = -vehicle x), a term acting on each accelerometer as
    its own sensor-axis component carries the vehicle's y error into accel.x and x into y."""
    term = {"effect": "lever_arm", "sensor": "imu", "axis": "all"}
    design = _design(term, np.eye(3), q_vs=(math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)))
    se_vehicle = np.array([0.01, 0.03, 0.002])
    sigma = confirmation.removal_sigma(design, _fit(np.eye(3)),
                                       [_finding("lever_arm imu.all", se_vehicle, "vehicle")],
                                       np.ones(200, bool))
    assert sigma[:3] == pytest.approx([0.03, 0.01, 0.002], rel=1e-9)
