"""Compensation equations (seed S1 eqs. 1-4) and the calibration-file contract."""
import json

import numpy as np
import pytest

from mimunav.compensation import (REPLACED, SATURATED, UNUSABLE, Calibration,
                                  CalibrationError, compensate, raw_from_physics)
from mimunav.sensors import MimuUnit

G0 = 9.80665


def spec_transcription(doc, u_a, u_w, temp, freq):
    """The contract's equations, written out term by term from log-format.md section 2,
    one sample and one axis at a time (an independent implementation)."""
    acc, gyr = doc["accel"], doc["gyro"]
    out_a, out_w = [], []
    for k in range(len(u_a)):
        v_a = [u_a[k][i] - (acc["ct"][i][0] + acc["ct"][i][1] * temp[k][i]
                            + acc["ct"][i][2] * temp[k][i] ** 2) for i in range(3)]
        v_w = [u_w[k][i] - (gyr["cw"][i][0] + gyr["cw"][i][1] * freq[k][i]
                            + gyr["cw"][i][2] * freq[k][i] ** 2) for i in range(3)]
        a = [acc["A0"][i] + sum(acc["A1"][i][j] * v_a[j] for j in range(3))
             + acc["A2"][i] * v_a[i] ** 2 + acc["A3"][i] * v_a[i] ** 3 for i in range(3)]
        w = [gyr["W0"][i] + sum(gyr["W1"][i][j] * v_w[j] for j in range(3))
             + gyr["W2"][i] * v_w[i] ** 2 + gyr["W3"][i] * v_w[i] ** 3
             + sum(gyr["C"][i][j] * a[j] for j in range(3)) for i in range(3)]
        out_a.append(a)
        out_w.append(w)
    return np.array(out_a), np.array(out_w)


def test_compensation_agrees_with_a_transcription_of_the_spec():
    rng = np.random.default_rng(3)
    for seed in range(5):
        unit = MimuUnit.draw(seed)
        doc = json.loads(json.dumps(unit.coefficients.as_dict()))
        n = 200
        u_a, u_w = rng.uniform(-3, 3, (n, 3)), rng.uniform(-2.2, 2.2, (n, 3))
        temp = rng.uniform(0, 70, (n, 3))
        freq = rng.uniform(7900, 12100, (n, 3))
        a_ref, w_ref = spec_transcription(doc, u_a, u_w, temp, freq)
        f, w, flags = compensate(Calibration.from_dict(doc), u_a, u_w, temp, freq,
                                 filter_outliers=False)
        np.testing.assert_allclose(f, a_ref, rtol=1e-12, atol=1e-10)
        np.testing.assert_allclose(w, w_ref, rtol=1e-12, atol=1e-12)
        assert not flags.any()


def test_round_trip_physics_raw_physics_over_range_and_temperature():
    rng = np.random.default_rng(5)
    for seed in range(10):
        unit = MimuUnit.draw(seed)
        n = 20000
        f = rng.uniform(-1, 1, (n, 3)) * unit.range_accel
        w = rng.uniform(-1, 1, (n, 3)) * unit.range_gyro
        t_acc = rng.uniform(0, 70, (n, 3))
        freq = unit.thermal.resonance_frequency(rng.uniform(0, 70, (n, 3)))
        u_a, u_w = raw_from_physics(unit.coefficients, f, w, t_acc, freq)
        f2, w2, _ = compensate(unit.coefficients, u_a, u_w, t_acc, freq, filter_outliers=False)
        assert np.abs(f2 - f).max() <= 1e-9 * unit.range_accel
        assert np.abs(w2 - w).max() <= 1e-9 * unit.range_gyro


def _cal_doc(**changes):
    doc = MimuUnit.draw(1).coefficients.as_dict()
    for path, value in changes.items():
        block, _, key = path.partition("__")
        if key:
            doc[block][key] = value
        elif value is None:
            doc.pop(block)
        else:
            doc[block] = value
    return doc


@pytest.mark.parametrize("changes, message", [
    (dict(format="other/1"), "format is 'other/1'"),
    (dict(model="quadratic"), "model 'quadratic' is not one of"),
    (dict(accel__A1=[[1, 0], [0, 1]]), r"accel.A1 has shape \(2, 2\), expected \(3, 3\)"),
    (dict(gyro__W0=[0, float("nan"), 0]), "gyro.W0 has non-finite values"),
    (dict(gyro__W1=[[1, 2, 3], [2, 4, 6], [0, 0, 1]]), "W1 is singular"),
    (dict(accel__A7=[0, 0, 0]), r"keys \['A7'\]"),
    (dict(accel__ct="hot"), "accel.ct is not numeric|accel.ct has shape"),
    (dict(accel=None), "accel.A1 is required"),
])
def test_malformed_calibration_files_say_what_is_wrong(changes, message):
    with pytest.raises(CalibrationError, match=message):
        Calibration.from_dict(_cal_doc(**changes), source="cal.json")


def test_linear_and_cold_start_models(tmp_path):
    doc = _cal_doc()
    lin = {"format": doc["format"], "model": "linear", "unit": "u",
           "accel": {"A0": doc["accel"]["A0"], "A1": doc["accel"]["A1"]},
           "gyro": {"W0": doc["gyro"]["W0"], "W1": doc["gyro"]["W1"]}}
    cal = Calibration.from_dict(lin)
    assert not cal.A2.any() and not cal.C.any()           # absent keys mean zero
    with pytest.raises(CalibrationError, match='takes only A0, A1, W0, W1'):
        Calibration.from_dict(dict(lin, accel=dict(lin["accel"], A2=[0, 0, 0])))
    path = tmp_path / "lin.json"
    cal.save(path)
    assert Calibration.load(path).as_dict() == cal.as_dict()
    with pytest.raises(FileExistsError):
        cal.save(path)
    # cold start: E = E(T)/(a + b T) + (c + d T) + e dT, per axis (seed S3)
    coef = {k: [v] * 3 for k, v in dict(a=1.02, b=-1e-4, c=0.01, d=2e-4, e=-3e-3).items()}
    cold = dict(lin, model="cold-start", window_s=2.0,
                accel=dict(lin["accel"], **coef), gyro=dict(lin["gyro"], **coef))
    cal = Calibration.from_dict(cold)
    n = 10
    temp = np.linspace(10, 19, n)[:, None] * np.ones(3)
    u = np.full((n, 3), 0.5)
    f, w, _ = compensate(cal, u, u, temp, temp, filter_outliers=False, t=np.arange(n) * 1.0)
    e_t = np.asarray(lin["accel"]["A0"]) + u @ np.asarray(lin["accel"]["A1"]).T
    d_t = temp - temp[np.maximum(np.arange(n) - 2, 0)]
    expected = e_t / (1.02 - 1e-4 * temp) + 0.01 + 2e-4 * temp - 3e-3 * d_t
    np.testing.assert_allclose(f, expected, rtol=1e-14)
    with pytest.raises(CalibrationError, match="needs the sample times"):
        compensate(cal, u, u, temp, temp)
    with pytest.raises(CalibrationError, match="window_s"):
        Calibration.from_dict({k: v for k, v in cold.items() if k != "window_s"})


def test_bad_raw_samples_are_flagged_never_silent():
    unit = MimuUnit.draw(2)
    n = 2000
    t = np.arange(n) / 1000
    f = np.stack([np.sin(t), np.cos(t), -G0 + 0 * t], -1) * 10
    w = np.stack([np.sin(2 * t), 0 * t, np.cos(t)], -1)
    temp = np.full((n, 3), 25.0)
    freq = unit.thermal.resonance_frequency(temp)
    u_a, u_w = raw_from_physics(unit.coefficients, f, w, temp, freq)
    u_a[500, 1] += 0.5                     # a wild value (5 g)
    u_w[900, 2] = np.nan                   # a dropped reading
    u_a[1500:1510, 0] = 10.0               # beyond the range: saturated
    f2, w2, flags = compensate(unit.coefficients, u_a, u_w, temp, freq,
                               unit.range_accel, unit.range_gyro)
    assert flags[500] & REPLACED and flags[900] & REPLACED
    assert np.all(flags[1500:1510] & SATURATED)
    assert abs(f2[500, 1] - f[500, 1]) < 1e-3 and abs(w2[900, 2] - w[900, 2]) < 1e-4
    good = np.setdiff1d(np.arange(n), [500, 900, *range(1500, 1510)])
    assert not flags[good].any()
    np.testing.assert_allclose(f2[good], f[good], atol=1e-9)
    u_w[:, 1] = np.nan                     # a whole channel missing
    _, _, flags = compensate(unit.coefficients, u_a, u_w, temp, freq)
    assert np.all(flags & UNUSABLE)
    with pytest.raises(ValueError, match=r"gyro_volts must have shape \(N, 3\)"):
        compensate(unit.coefficients, u_a, u_w[:, :2], temp, freq)
