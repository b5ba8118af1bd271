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


def _quiet_design(f_quiet, n=200, prior_sd=0.0025):
    """A stand-in design on a steady specific force `f_quiet` (3,) m/s^2 with one term,
    accel.z's scale factor (its column f_z): the reference's accelerometer inputs are
    `f_quiet` on every bin, its prior `prior_sd` on every component."""
    term = {"effect": "scale_factor", "sensor": "accel", "axis": "z"}
    inputs = np.tile(np.r_[f_quiet, 0.0, 0.0, 0.0], (n, 1))
    design = SimpleNamespace(t=np.arange(n) * 0.01, channels=6, terms=[term],
                             columns=[{2: np.full((n, 1), f_quiet[2])}],
                             prior=np.eye(18) * prior_sd ** 2, calibrated=False, arm_given=True,
                             q_vs=np.array([1.0, 0, 0, 0]))
    design.ref_columns = lambda c: inputs[:, :3] if c < 3 else inputs[:, 3:]
    return design


def _fitted(gamma, terms=(), b=(), cov=None):
    """A stand-in `Fit`: gamma (18,), the terms' indices and their coefficients."""
    beta = np.r_[gamma, b]
    slices = [slice(18 + i, 19 + i) for i in range(len(terms))]
    cov = np.zeros((len(beta), len(beta))) if cov is None else cov
    return SimpleNamespace(beta=beta, cov=cov, terms=list(terms), slices=slices,
                           gamma=lambda: beta[:18], of=lambda j: (beta[slices[j]],
                                                                  cov[slices[j], slices[j]]))


def test_a_term_not_confirmed_moves_an_offset_by_what_its_refit_removes_once():
    """Closed form: level on f_z = -g, the base fit's reference error takes accel.z's scale
    as gamma_zz = 0.002; with accel.z's scale factor fitted too, the split is gamma_zz =
    0.0005, b = 0.0015 - together they remove what gamma alone did, and the offset moves by
    nothing (the term had been subtracted a second time: a 2000 ppm scale within the
    stated errors set a true 0.047 m/s^2 offset aside). Split otherwise (gamma 0.0005, b
    0.0025) it moves by -g x 0.001, with the 1 sigma the refit adds (g x 0.0004)."""
    design = _quiet_design(np.array([0.0, 0.0, -G]))
    gamma0, gamma1 = np.zeros(18), np.zeros(18)
    gamma0[8], gamma1[8] = 0.002, 0.0005
    base = _fitted(gamma0)
    term = {"label": "scale_factor accel.z", "coefficient": 0.0015, "ci95": [0.0, 0.003]}
    rows = np.ones(200, bool)
    cov = np.zeros((19, 19))
    cov[18, 18] = 0.0004 ** 2
    for b, moved in ((0.0015, 0.0), (0.0025, -G * 0.001)):
        fitter = SimpleNamespace(fit=lambda idx, b=b: _fitted(gamma1, idx, [b], cov))
        shift, sigma, names = removal.unconfirmed_offset(design, fitter, base, [term], rows,
                                                         {"accel": 80.0, "gyro": 10.0})
        assert shift[2] == pytest.approx(moved, abs=1e-12)
        assert sigma[2] == pytest.approx(G * 0.0004) and names[2] == ["scale_factor accel.z"]
        assert not np.delete(shift, 2).any()
    absurd = dict(term, coefficient=0.3)                    # beyond its physical range
    none = removal.unconfirmed_offset(design, fitter, base, [absurd], rows,
                                      {"accel": 80.0, "gyro": 10.0})
    assert not none[0].any() and none[2][2] == []
    pushed = SimpleNamespace(fit=lambda idx: _fitted(gamma1, idx, [0.3], cov))
    none = removal.unconfirmed_offset(design, pushed, base, [term], rows,   # refit: absurd
                                      {"accel": 80.0, "gyro": 10.0})
    assert not none[0].any() and none[2][2] == []


def _shift_finding(mu, lo, hi, p=1e-20):
    return {"effect": "bias_shift", "sensor": "accel", "axis": "z", "coefficient": mu,
            "ci95": [lo, hi], "note": "a constant", "normal_offset_1sigma": 0.002,
            "p_train": p, "p_heldout": p, "holm_threshold": 1e-3}


def test_an_offsets_interval_holds_its_other_readings():
    """The rate table's null twin: -0.204 [-0.2175, -0.1906] m/s^2, which the terms not
    confirmed would move by -0.0163 (1 sigma 0.004): the interval becomes the hull of both
    readings and holds the unit's -0.1878; its own interval is kept, and a later widening
    widens each reading about itself. A reading inside its interval adds nothing; one
    whose interval reaches zero sets the offset aside, and so does one whose p misses."""
    from mimunav.diagnosis.confirmation import judged_wider
    f = _shift_finding(-0.204, -0.2175, -0.1906)
    se = (0.2175 - 0.1906) / (2 * 1.959964)
    out = removal.with_other_readings(f, [(-0.0163, 0.004, "with X fitted too")])
    other, half = -0.204 + 0.0163, 1.959964 * math.hypot(se, 0.004)
    assert out["ci95"] == pytest.approx([-0.2175, other + half])
    assert out["ci95"][0] <= -0.1878 <= out["ci95"][1] and "rejected" not in out
    assert out["other_readings"][0]["coefficient"] == pytest.approx(other)
    assert out["ci95_alone"] == [-0.2175, -0.1906] and f["ci95"] == [-0.2175, -0.1906]
    ok, wide = judged_wider(out, 2.0, 1, "test", "library_inflation", {})
    assert wide["ci95"] == pytest.approx([-0.204 - 2 * (0.2175 - 0.204), other + 2 * half])
    assert removal.with_other_readings(f, []) is f
    assert removal.with_other_readings(f, [(-1e-4, 1e-5, "x")]) is f
    gone = removal.with_other_readings(_shift_finding(-0.03, -0.035, -0.025),
                                       [(-0.03, 0.002, "x")])
    assert gone["ci95"][0] < 0.0 < gone["ci95"][1] and "holds zero" in gone["rejected"]
    weak = removal.with_other_readings(_shift_finding(-0.03, -0.035, -0.025),
                                       [(-0.024, 0.0, "x")])      # reads -0.006: p 0.06
    assert "rejected" in weak and weak["p_heldout"] > 0.01


def test_an_offset_read_after_a_reference_error_beyond_its_stated_accuracy_is_read_again():
    """The reference's fitted linear error against its prior: accel.z's scale fitted at
    -0.0759 under a stated 1 sigma of 0.0025 is 30 sigma off; held to 5 sigma (-0.0125) on
    f_z = -g the quiet mean reads -g x (-0.0759 + 0.0125) = +0.62 m/s^2 more, and the words
    name it; accel.x's row at 2 sigma moves nothing. A wander read there is set aside, an
    offset is not (it is read both ways: `with_other_readings`)."""
    design = _quiet_design(np.array([0.0, 0.0, -G]))
    gamma = np.zeros(18)
    gamma[8], gamma[1] = -0.0759, 2 * 0.0025
    fit = _fitted(gamma)
    shift, words = removal.reference_held_offset(design, fit, np.ones(200, bool))
    assert shift[2] == pytest.approx(-G * (0.0759 - 5 * 0.0025))    # it reads mu - shift
    assert "accel.z <- f_z -0.0759 (30 times its stated 1 sigma 0.0025)" in words[2]
    assert shift[0] == 0.0 and words[0] == ""
    beyond = removal.reference_beyond_stated(design, fit)
    wander = {"effect": "bias_instability", "sensor": "accel", "axis": "z"}
    offset = dict(wander, effect="bias_shift")
    out = removal.beside_reference([wander, offset], beyond)
    assert "beyond its stated accuracy" in out[0]["rejected"] and "rejected" not in out[1]


def test_an_offset_the_reference_held_reading_moves_is_set_aside():
    """The reading with the reference's fitted error held to its stated accuracy (a phone
    beside a tactical INS: the INS's accel.z scale fitted 66 times its stated 1e-3, the
    phone's offset read 0.84 m/s^2 where its bias was 0.20): where it lies outside the
    offset's own interval, the offset is set aside, naming that reading; inside, it widens
    the interval (or, inside with its own interval, leaves the finding as it is)."""
    held = "with the reference's fitted error held to 5 sigma of its stated accuracy (x)"
    f = _shift_finding(0.84, 0.83, 0.85)
    out = removal.with_other_readings(f, [(0.59, 0.0, held, removal.REFERENCE_HELD)])
    assert out["rejected"].startswith(held + " it reads 0.25: the reference is worse")
    assert out["ci95"][0] < 0.25 and out["other_readings"][0]["coefficient"] == \
        pytest.approx(0.25)
    assert removal.with_other_readings(f, [(0.0, 0.0, held, removal.REFERENCE_HELD)]) is f
    near = removal.with_other_readings(f, [(0.005, 0.0, held, removal.REFERENCE_HELD)])
    assert "rejected" not in near and near["ci95"][0] < 0.83    # inside: it widens only
    unconfirmed = removal.with_other_readings(f, [(0.59, 0.0, "with the terms x")])
    assert "rejected" not in unconfirmed           # another reading widens, it sets nothing aside


def test_an_excursion_only_the_reference_error_beyond_its_accuracy_makes_is_set_aside():
    """Where the reference's fitted error lies beyond 5 sigma of its stated accuracy, an
    excursion stands only if the residual read with that error held at zero shows one on
    its channel, overlapping it; the others are set aside with the reference's words."""
    spans = [{"channel": "accel.x", "t0": 63.0, "t1": 65.0},
             {"channel": "accel.z", "t0": 100.0, "t1": 102.0}]
    held = [{"channel": "accel.z", "t0": 101.0, "t1": 103.0},
            {"channel": "accel.x", "t0": 300.0, "t1": 302.0}]
    beyond = [(41.0, "accel.x <- f_z 0.041 (41 times its stated 1 sigma 0.001)")] + \
        [(0.5, "")] * 5
    kept, why = removal.held_excursions(spans, held, beyond)
    assert kept == spans[1:]
    assert why == ["1 excursion(s) (accel.x 63.0-65.0 s) stand only with the reference's "
                   "fitted error, which lies beyond its stated accuracy (accel.x <- f_z 0.041 "
                   "(41 times its stated 1 sigma 0.001)): the reference is worse than stated "
                   "or the model lacks something charged to it - set aside"]
    assert removal.held_excursions(spans[1:], held, beyond) == (spans[1:], [])
