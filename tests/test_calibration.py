"""Calibration lab and fits against truth: the fit's closed-form lab inputs against the
simulator's exact increments, recovery of drawn coefficients within their reported
uncertainty, held-out residuals against seed S1 Table 1, refusals of incomplete runs."""
import dataclasses
import re

import numpy as np
import pytest

from mimunav import calibration, lab
from mimunav.compensation import compensate, poly2
from mimunav.sensors import MimuUnit
from mimunav.sensors.mimu import NoiseModel

ENTIRE = ("thermal-chamber", "rate-table", "centrifuge")
TRADITIONAL = ("multi-position", "single-axis-rate")


def _run(tmp_path, procedure, unit, seed, plan=None, **kw):
    path = tmp_path / f"{procedure}-{unit.name}-{seed}.mcap"
    lab.run(plan or lab.plan(procedure), unit, path, seed, progress=False, **kw)
    return str(path)


def true_in_gauge(unit, cal):
    """The unit's true coefficients in the fit's gauge (temperature polynomials vanishing
    at the reference readings the fit wrote)."""
    ref = cal.extra["reference"]
    truth = unit.coefficients
    d_a = poly2(truth.ct, np.array([ref["accel_temperature_c"]]))[0]
    d_w = poly2(truth.cw, np.array([ref["gyro_frequency_hz"]]))[0]
    return truth.with_voltage_offset(d_a, d_w)


def z_scores(unit, cal):
    truth = true_in_gauge(unit, cal)
    out = {}
    for name, se in calibration.standard_errors(cal).items():
        key, *idx = re.findall(r"\w+", name)
        idx = tuple(int(i) for i in idx)
        out[name] = (getattr(cal, key)[idx] - getattr(truth, key)[idx]) / se
    return out


def test_voltage_offset_gauge_is_the_same_compensation():
    cal = MimuUnit.draw(3).coefficients
    shifted = cal.with_voltage_offset([1e-3, -2e-3, 5e-4], [3e-3, 1e-3, -4e-3])
    rng = np.random.default_rng(0)
    u_a, u_w = rng.normal(0, 1, (50, 3)), rng.normal(0, 1, (50, 3))
    temp, freq = rng.uniform(0, 70, (50, 3)), rng.uniform(9e3, 1.1e4, (50, 3))
    a = compensate(cal, u_a, u_w, temp, freq, filter_outliers=False)
    b = compensate(shifted, u_a, u_w, temp, freq, filter_outliers=False)
    np.testing.assert_allclose(b[0], a[0], rtol=0, atol=1e-10)
    np.testing.assert_allclose(b[1], a[1], rtol=0, atol=1e-12)


@pytest.mark.parametrize("procedure", ["rate-table", "centrifuge", "twelve-position"])
def test_known_inputs_match_the_simulated_motion(tmp_path, procedure):
    """A noiseless unit with no setting errors, compensated with its true coefficients,
    outputs per window exactly the closed-form known input of the fit (Earth rate, gravity,
    centripetal and Coriolis terms) - two independent codes of the same physics."""
    unit = MimuUnit.draw(11)
    unit.noise = NoiseModel(*(0.0,) * 6)
    unit.thermal.thermistor_noise = unit.thermal.frequency_noise = 0.0
    unit.adc_lsb = 1e-15                  # no quantization: static inputs would not dither it
    plan = lab.plan(procedure)
    if procedure == "rate-table":
        plan.points = [p for p in plan.points if abs(p.rate) in (0.0, 200 * lab.DEG,
                                                                400 * lab.DEG)]
    zero = {k: 0.0 for k in lab.EQUIPMENT}
    run = calibration.LabRun.load(_run(tmp_path, procedure, unit, 1, plan, equipment=zero))
    res = calibration.check(unit.coefficients, run)
    assert np.abs(res["accel_error"]).max() < 1e-8 * 30 * 9.8
    assert np.abs(res["gyro_error"]).max() < 1e-8 * 7
    # and the inputs are what the lab says: full g and 30 g, 400 deg/s on the vertical
    f_max = np.abs(res["accel_input"]).max() / 9.80665
    w_max = np.degrees(np.abs(res["gyro_input"]).max())
    expect = {"rate-table": (1.0, 400.0), "centrifuge": (30.0, 385.4),
              "twelve-position": (1.0, np.degrees(7.292115e-5 * np.cos(lab.SITE["latitude"])))
              }[procedure]
    assert f_max == pytest.approx(expect[0], rel=2e-3)
    assert w_max == pytest.approx(expect[1], rel=2e-2)


@pytest.fixture(scope="module")
def entire_lab(tmp_path_factory):
    """Two units through the entire lab, fitted, plus held-out runs of the first."""
    tmp = tmp_path_factory.mktemp("lab")
    units, cals = [], []
    for seed in (21, 22):
        unit = MimuUnit.draw(seed)
        paths = [_run(tmp, p, unit, seed) for p in ENTIRE]
        units.append(unit)
        cals.append(calibration.calibrate(paths, "entire", unit=unit.name))
    trad = calibration.calibrate([_run(tmp, p, units[0], 5) for p in TRADITIONAL],
                                 "traditional")
    fresh = {p: calibration.LabRun.load(_run(tmp, p, units[0], 99)) for p in ENTIRE}
    return units, cals, trad, fresh


def test_entire_recovers_every_coefficient_within_its_reported_uncertainty(entire_lab):
    units, cals, _, _ = entire_lab
    z = np.concatenate([list(z_scores(u, c).values()) for u, c in zip(units, cals)])
    assert len(z) == 2 * 63
    assert np.abs(z).max() < 4.0
    assert 0.7 < np.sqrt(np.mean(z**2)) < 1.3


def test_fit_residuals_sit_at_the_noise_level(entire_lab):
    """Window-mean residual rms ~ bias instability of the noise model (flicker B: accel
    0.5 mg, gyro 15 deg/h) plus white noise of a 10 s mean, not model error."""
    _, cals, _, _ = entire_lab
    for cal in cals:
        rms = cal.covariance["residual_rms"]
        assert max(rms["centrifuge accel"].values()) < 1.5e-3 * 9.80665
        assert max(rms["rate-table gyro"].values()) < np.radians(30 / 3600 + 0.02 / np.sqrt(10))


def test_held_out_entire_meets_table1_and_traditional_does_not(entire_lab):
    units, cals, trad, fresh = entire_lab
    fs, lim = calibration.TABLE1_FULL_SCALE, calibration.TABLE1_RESIDUAL
    worst = {}
    for name, cal in (("entire", cals[0]), ("traditional", trad)):
        for proc, run in fresh.items():
            res = calibration.check(cal, run)
            worst[name, proc] = (np.abs(res["accel_error"]).max() / fs["accel"],
                                 np.abs(res["gyro_error"]).max() / fs["gyro"])
    for proc in ENTIRE:
        assert worst["entire", proc][0] < lim["accel"]
        assert worst["entire", proc][1] < lim["gyro"]
    assert worst["traditional", "centrifuge"][0] > lim["accel"]          # high g
    assert worst["traditional", "rate-table"][1] > lim["gyro"]           # high rate
    assert max(worst["traditional", "thermal-chamber"]) > min(lim.values())  # off 25 degC


def test_incomplete_runs_are_refused_with_what_is_missing(tmp_path):
    unit = MimuUnit.draw(5)
    plan = lab.plan("single-axis-rate")
    plan.points = [p for p in plan.points if p.position != 3]
    path = _run(tmp_path, "single-axis-rate", unit, 1, plan)
    with pytest.raises(calibration.FitError, match="y down"):
        calibration.fit_gyro_triad(calibration.LabRun.load(path), None, order=1)
    plan = lab.plan("rate-table")
    plan.points = [p for p in plan.points if abs(p.rate) <= 20 * lab.DEG + 1e-9]
    path = _run(tmp_path, "rate-table", unit, 2, plan)
    with pytest.raises(calibration.FitError, match="distinct input levels"):
        calibration.fit_gyro_triad(calibration.LabRun.load(path), None, order=3)
    plan = lab.plan("thermal-chamber")
    plan.points = [dataclasses.replace(p, hold_s=60.0, settle_s=60.0) for p in plan.points[:3]]
    path = _run(tmp_path, "thermal-chamber", unit, 3, plan)
    with pytest.raises(calibration.FitError, match="set points"):
        calibration.fit_temperature(calibration.LabRun.load(path))
    with pytest.raises(calibration.FitError, match="missing rate-table, centrifuge"):
        calibration.calibrate([path], "entire")
