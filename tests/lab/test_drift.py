"""Seed S4's AR + Kalman drift model (`mimunav.lab.drift`, `mimunav drift`) on records whose drift
is known: an AR(1) drift under white noise made with numpy, its parameters recovered and the
filter's estimate closer to the drift than the raw output; a rate step under the filter is
smeared (what it removes is motion, far above the noise); a constant bias passes untouched."""
import json

import numpy as np
import pytest

from mimunav.lab import drift
from mimunav.cli import main


def _ar1(n, a, q, r, seed):
    rng = np.random.default_rng(seed)
    d = np.zeros(n)
    e = rng.normal(0, np.sqrt(q), n)
    for k in range(1, n):
        d[k] = a * d[k - 1] + e[k]
    return d, d + rng.normal(0, np.sqrt(r), n)


@pytest.mark.slow
def test_ar1_drift_is_identified_and_the_filter_estimates_it():
    a, q, r = 0.95, 1e-10, 4e-9                  # (rad/s)^2 per step: drift sd 3.2e-5
    d, y = _ar1(4000, a, q, r, 1)
    bic, fit = drift.identify(y - y.mean(), max_order=3)
    assert drift.describe(fit)["order"] <= 2          # AR(1) + noise: BIC stays low
    _, one = drift.identify(y - y.mean(), max_order=1)
    m = drift.describe(one)
    assert m["ar"][0] == pytest.approx(a, abs=0.03)
    assert m["q"] == pytest.approx(q, rel=0.5) and m["r"] == pytest.approx(r, rel=0.2)
    est = drift.apply(fit, y - y.mean()) + y.mean()
    assert np.std(est - d) < 0.6 * np.std(y - d)          # closer to the drift than raw
    red = drift.variance_reduction(fit, y - y.mean())
    assert 0 < red["variance_ratio"] < 1


@pytest.mark.slow
def test_the_filter_smears_motion_and_leaves_a_constant_bias():
    d, y = _ar1(4000, 0.95, 1e-10, 4e-9, 2)
    _, fit = drift.identify(y - y.mean(), max_order=2)
    noise_sd = float(np.std(y))
    step = np.where(np.arange(600) < 300, 0.0, 0.01)        # a 0.57 deg/s rate step
    rng = np.random.default_rng(3)
    moving = step + rng.normal(0, np.sqrt(4e-9), 600)
    m = drift.under_motion(fit, moving - moving.mean(), noise_sd)
    assert m["ratio"] > 5                                    # motion taken out, not noise
    const = np.full(600, 0.0)                                # a bias is removed before the
    assert np.allclose(drift.apply(fit, const), 0.0)         # model: nothing to filter


@pytest.mark.slow
def test_drift_command_on_a_recorded_rest(tmp_path):
    """The command end to end on a log written as a recording would be (/mimu/imu with an
    AR(1) drift on gyro x at 100 Hz), and its refusal of a too-short rest."""
    from mimunav.flightlog import LogWriter
    from mimunav.flightlog import schemas as S
    n = 100 * 900
    d, y = _ar1(n, 0.9995, 1e-11, 1e-6, 4)              # drift sd 1e-4 = white at 1 s
    w = np.column_stack([y, *(np.random.default_rng(5).normal(0, 1e-3, (2, n)))])
    f = np.tile([0.0, 0.0, -9.8], (n, 1)) + np.random.default_rng(6).normal(0, 1e-3, (n, 3))
    stamps = 1_700_000_000_000_000_000 + np.arange(n) * 10_000_000
    log = tmp_path / "rest.mcap"
    with LogWriter(log) as out:
        out.write("/mimu/imu", S.IMU, "mimu", stamps, **S.imu_fields(w, f))
    assert main(["drift", str(log), "--static", "0:880", "-o", str(tmp_path / "d")]) == 0
    doc = json.load(open(tmp_path / "d" / "drift.json"))
    assert doc["format"] == "mimunav-drift/1"
    assert doc["gyro"]["x"]["model"]["order"] >= 1
    assert doc["gyro"]["x"]["static"]["variance_ratio"] > doc["gyro"]["y"]["static"][
        "variance_ratio"]                                    # x has drift, y is white
    assert main(["drift", str(log), "--static", "0:20", "-o", str(tmp_path / "e")]) == 2
