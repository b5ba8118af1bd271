"""What removing a found term leaves in the residual the bias tests read
(`removal.removal_sigma`): the term's estimate is off by its own error, and on a quiet
flight that error is an offset - a mounting's tilt of g. Closed forms on a stand-in design."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from mimunav.diagnosis import removal

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
    sigma = removal.removal_sigma(design, _fit(cov_all),
                                       [_finding("mounting_misalignment imu.all", se)], rows)
    c, s = G * math.cos(a), G * math.sin(a)
    want_x = math.sqrt((c * se[1]) ** 2 + (s * se[2]) ** 2 - 2 * c * s * rho * se[1] * se[2])
    assert sigma[:3] == pytest.approx([want_x, c * se[0], s * se[0]], rel=1e-9)
    assert not sigma[3:].any()
    none = removal.removal_sigma(design, _fit(cov_all), [], rows)
    assert not none.any()


def test_a_lever_arms_interval_is_turned_from_the_vehicle_frame():
    """A lever arm's interval is stated in the vehicle frame: with the sensor yawed 90 deg
    (sensor x = vehicle y, sensor y = -vehicle x), a term acting on each accelerometer as
    its own sensor-axis component carries the vehicle's y error into accel.x and x into y."""
    term = {"effect": "lever_arm", "sensor": "imu", "axis": "all"}
    design = _design(term, np.eye(3), q_vs=(math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)))
    se_vehicle = np.array([0.01, 0.03, 0.002])
    sigma = removal.removal_sigma(design, _fit(np.eye(3)),
                                       [_finding("lever_arm imu.all", se_vehicle, "vehicle")],
                                       np.ones(200, bool))
    assert sigma[:3] == pytest.approx([0.03, 0.01, 0.002], rel=1e-9)


def _two_term_design(f_quiet, n=200):
    """A stand-in design with accel.z's scale factor (column f_z) and its coupling to f_y
    (column f_y), on a steady specific force `f_quiet` (3,) m/s^2."""
    terms = [{"effect": "scale_factor", "sensor": "accel", "axis": "z"},
             {"effect": "cross_coupling", "sensor": "accel", "axis": "z", "input_axis": "y"}]
    columns = [{2: np.full((n, 1), f_quiet[2])}, {2: np.full((n, 1), f_quiet[1])}]
    return SimpleNamespace(t=np.arange(n) * 0.01, channels=6, columns=columns, terms=terms,
                           q_vs=np.array([1.0, 0, 0, 0]), calibrated=False)


def test_terms_not_confirmed_move_a_quiet_mean_by_their_steady_inputs():
    """Closed form: a scale factor b1 (1 sigma s1, from its interval) on f_z = -g and a
    coupling b2 on f_y = g/2 found within the stated errors (total 1 sigma s2) move accel.z's
    quiet mean by -g b1 + g/2 b2, 1 sigma hypot(g s1, g/2 s2); a term beyond its physical
    range (5 %) and a label the design lacks are left out; no other channel moves."""
    design = _two_term_design(np.array([0.0, G / 2, -G]))
    b1, s1, b2, s2 = 0.0022, 0.0013, -0.0025, 0.0009
    rejected = {"label": "scale_factor accel.z", "coefficient": b1,
                "ci95": [b1 - 1.959964 * s1, b1 + 1.959964 * s1]}
    within = {"label": "cross_coupling accel.z <- f_y", "coefficient": b2,
              "total_1sigma": [s2]}
    absurd = dict(rejected, coefficient=0.3, ci95=[0.29, 0.31])
    alien = dict(rejected, label="scale_factor gyro.x")
    rows = np.ones(200, bool)
    shift, sigma, names = removal.unconfirmed_offset(design, [rejected, within, alien], rows,
                                                     {"accel": 80.0, "gyro": 10.0})
    assert shift[2] == pytest.approx(-G * b1 + G / 2 * b2, rel=1e-9)
    assert sigma[2] == pytest.approx(math.hypot(G * s1, G / 2 * s2), rel=1e-9)
    assert names[2] == ["scale_factor accel.z", "cross_coupling accel.z <- f_y"]
    assert not np.delete(shift, 2).any() and not np.delete(sigma, 2).any()
    only = removal.unconfirmed_offset(design, [absurd], rows, {"accel": 80.0, "gyro": 10.0})
    assert not only[0].any() and only[2][2] == []


def _shift_finding(mu, lo, hi):
    return {"effect": "bias_shift", "sensor": "accel", "axis": "z", "coefficient": mu,
            "ci95": [lo, hi], "note": "a constant"}


def test_an_offsets_interval_holds_the_reading_without_the_unconfirmed_terms():
    """The rate table's null twin: -0.204 [-0.2175, -0.1906] m/s^2 read beside a scale factor
    and a coupling not confirmed, which move the quiet mean by -0.0163 (1 sigma 0.004): the
    interval becomes the hull of both readings and holds the unit's -0.1878."""
    from mimunav.diagnosis.outputs import beside_unconfirmed
    f = _shift_finding(-0.204, -0.2175, -0.1906)
    se = (0.2175 - 0.1906) / (2 * 1.959964)
    out = beside_unconfirmed(f, -0.0163, 0.004, ["scale_factor accel.z"])
    other, half = -0.204 + 0.0163, 1.959964 * math.hypot(se, 0.004)
    assert out["ci95"] == pytest.approx([-0.2175, other + half])
    assert out["ci95"][0] <= -0.1878 <= out["ci95"][1] and "rejected" not in out
    assert out["beside_unconfirmed"]["coefficient"] == pytest.approx(other)
    assert f["ci95"] == [-0.2175, -0.1906]                  # the input is not changed
    # no term, or a move the interval already holds: as it was
    assert beside_unconfirmed(f, -0.0163, 0.004, []) is f
    assert beside_unconfirmed(f, -1e-4, 1e-5, ["scale_factor accel.z"]) is f
    # the offset may be the terms' alone: set aside
    gone = beside_unconfirmed(_shift_finding(-0.03, -0.035, -0.025), -0.03, 0.002, ["x"])
    assert gone["ci95"][0] < 0.0 < gone["ci95"][1] and "holds zero" in gone["rejected"]


def test_a_bias_read_after_a_reference_error_beyond_its_stated_accuracy_is_set_aside():
    """The reference's fitted linear error against its prior, channel by channel: accel.z's
    scale fitted at -0.0759 under a stated 1 sigma of 0.0025 is 30 sigma off, so an offset
    read on accel.z after it is set aside; gyro.x's row at 2 sigma leaves its offset be; a
    component with no stated prior counts 0; a term other than the bias's is not judged."""
    sd = np.full(18, 0.0025)
    sd[9:] = 0.0                                    # gyros: no stated prior (pinned)
    gamma = np.zeros(18)
    gamma[8] = -0.0759                              # accel.z <- f_z, the scale
    gamma[1] = 2 * 0.0025                           # accel.x <- f_y: 2 sigma
    gamma[9] = 1e-9
    design = SimpleNamespace(prior=np.diag(sd ** 2))
    beyond = removal.reference_beyond_stated(design, SimpleNamespace(gamma=lambda: gamma))
    assert beyond[2][0] == pytest.approx(0.0759 / 0.0025)
    assert "accel.z <- f_z -0.0759" in beyond[2][1]
    assert beyond[0][0] == pytest.approx(2.0) and beyond[3][0] == 0.0
    shift_z = {"effect": "bias_shift", "sensor": "accel", "axis": "z"}
    shift_x = dict(shift_z, axis="x")
    scale_z = {"effect": "scale_factor", "sensor": "accel", "axis": "z"}
    out = removal.beside_reference([shift_z, shift_x, scale_z], beyond)
    assert "beyond its stated accuracy" in out[0]["rejected"]
    assert "rejected" not in out[1] and "rejected" not in out[2]
    assert "rejected" not in shift_z                 # the input is not changed
