"""Seed S4's rotation scale-factor calibration (`rotation_calibration`): its inputs against
the simulator's exact increments, its truth gauge against the exact inverse of eqs. 3-4, and
the recovery of a unit's coefficients within their standard errors through the CLI."""
import dataclasses
import json

import numpy as np
import pytest

from mimunav.lab import procedures as lab
from mimunav.compensation.calibration_file import Calibration
from mimunav.compensation.model import CalibrationError, raw_from_physics
from mimunav.lab import rotation as rc
from mimunav.lab.gls import FitError
from mimunav.cli import main
from mimunav.sensors.mimu import MimuUnit

NO_SETTING_ERRORS = {k: 0.0 for k in lab.EQUIPMENT}


def test_known_inputs_equal_the_simulated_motion(tmp_path):
    """The fit's closed-form inputs (nominal lab state + encoder angle) against the
    increments the simulator integrates by quadrature through quaternions
    (`modulation.RotatingMotion`, `truth.generate`): no shared code but the lab state."""
    full = lab.plan("rotation")
    pts = [p for p in full.points if p.position in (0, 1)
           and abs(p.rate) in (0.0, 280 * lab.DEG)]
    plan = dataclasses.replace(full, points=pts)
    unit = MimuUnit.draw(3, beyond_model=False)
    log, _ = lab.run(plan, unit, tmp_path / "r.mcap", 0, progress=False,
                     equipment=NO_SETTING_ERRORS)
    segments, _ = lab.lab_motion(plan, lab.draw_setting_errors(plan, 0, NO_SETTING_ERRORS))
    seg = segments[0]
    dt = np.diff(seg.t)
    rate_true = seg.dtheta[1:] / dt[:, None]
    force_true = seg.dv[1:] / dt[:, None]
    rr = rc.RotationRun.load(log)
    assert np.allclose(rr.lab.t, seg.t)
    assert len(rr.lab.windows) == len(pts)
    for w in rr.lab.windows:
        rate, force = rc.known_inputs(rr, w)
        k = np.arange(w.k0, w.k1) - 1
        # per sample: the grating's 1.58 arcsec steps (mechanism rate 7.7e-4 rad/s per 10 ms)
        assert np.abs(rate - rate_true[k]).max() < 1e-3
        assert np.abs(force - force_true[k]).max() < 1e-4
        # over a window the steps cancel: the inputs are exact
        assert np.abs((rate - rate_true[k]).mean(axis=0)).max() < 2e-6
        assert np.abs((force - force_true[k]).mean(axis=0)).max() < 2e-6


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_truth_gauge_is_the_exact_inverse_of_eqs_3_4(seed):
    """The series reversion's forward coefficients reproduce the exact inverse of eqs. 3-4
    (Newton, `compensation.raw_from_physics`) along each axis to < 1 deg/h at 400 deg/s,
    a tenth of k2's standard error there; without the cross-axis nonlinearity Q they miss
    by ~10 deg/h (that is why the model has Q)."""
    unit = MimuUnit.draw(seed, beyond_model=False)
    freq = np.array(unit.thermal.f0, float)[None]
    cal = rc.RotationCalibration(*rc.true_in_gauge(unit.coefficients, freq[0]), {}, {})
    no_q = dataclasses.replace(cal, Q=np.zeros((3, 3)))
    rng = np.random.default_rng(seed)
    n = 500
    worst, worst_no_q = 0.0, 0.0
    for a in range(3):
        w = np.zeros((n, 3))
        w[:, a] = rng.uniform(-1, 1, n) * 400 * lab.DEG
        f = rng.normal(size=(n, 3))
        f *= 9.8 / np.linalg.norm(f, axis=1)[:, None]
        _, u = raw_from_physics(unit.coefficients, f, w, np.full((n, 3), 25.0),
                                             np.repeat(freq, n, axis=0), f_gyro=f)
        to_deg_h = 1 / np.diag(cal.M) / lab.DEG * 3600
        worst = max(worst, np.abs((cal.gyro_output(w, f) - u) * to_deg_h).max())
        worst_no_q = max(worst_no_q, np.abs((no_q.gyro_output(w, f) - u) * to_deg_h).max())
    assert worst < 1.0
    assert worst_no_q > 3.0


@pytest.mark.slow
def test_a_unit_recovered_within_its_standard_errors_and_held_out(tmp_path, capsys):
    """lab rotation -> calibrate --method rotation -> calibration compare, as a user would,
    on a unit that is exactly eqs. 1-4; then a fresh run of the same unit predicted."""
    unit = MimuUnit.draw(11, beyond_model=False)
    unit.save(tmp_path / "unit.json")
    for s in (1, 2):
        assert main(["lab", "rotation", "--unit", str(tmp_path / "unit.json"), "-o",
                     str(tmp_path / f"run{s}.mcap"), "--seed", str(s)]) == 0
    cal_path = tmp_path / "cal.json"
    assert main(["calibrate", str(tmp_path / "run1.mcap"), "--method", "rotation",
                 "-o", str(cal_path)]) == 0
    capsys.readouterr()
    assert main(["calibration", "compare", str(cal_path), str(tmp_path / "unit.json")]) == 0
    printed = capsys.readouterr().out
    cal = rc.RotationCalibration.from_dict(json.loads(cal_path.read_text()))
    rows, families = rc.compare(cal, unit)
    z = np.array([r[4] for r in rows])
    assert len(z) == 33 and f"n = {len(z)}" in printed
    assert np.abs(z).max() < 4.0
    assert 0.5 < np.sqrt(np.mean(z ** 2)) < 1.6
    rel = np.array([r[3] / abs(r[2]) for r in rows if r[0].endswith("][1]")
                    and r[0].startswith("k")])
    assert (rel < 3e-5).all()                    # k1 to a few ppm: the method's point
    check = rc.held_out(cal, tmp_path / "run2.mcap")
    assert all(0.8 < z < 1.4 for z in check["z_rms"])
    # the same file with k1 off by 100 ppm fails the held-out check
    worse = dataclasses.replace(cal, k=cal.k * [1, 1 + 1e-4, 1, 1], M=cal.M * (1 + 1e-4))
    assert min(rc.held_out(worse, tmp_path / "run2.mcap")["z_rms"]) > 1.4


def test_wrong_inputs_are_refused_clearly(tmp_path):
    unit = MimuUnit.draw(5, beyond_model=False)
    plan = dataclasses.replace(lab.plan("multi-position"))
    log, _ = lab.run(plan, unit, tmp_path / "m.mcap", 0, progress=False)
    with pytest.raises(FitError, match="procedure 'rotation'"):
        rc.fit([log])
    doc = {"format": "mimunav-calibration/1", "model": rc.MODEL,
           "gyro": {"k": np.zeros((3, 4)).tolist()}}
    path = tmp_path / "rot.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(CalibrationError, match="cannot compensate"):
        Calibration.load(path)
    with pytest.raises(FitError, match="M, Q, G"):
        rc.RotationCalibration.from_dict(doc)
