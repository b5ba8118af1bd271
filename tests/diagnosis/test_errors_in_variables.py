"""`diagnosis.errors_in_variables`: the noise a MEMS-grade reference is given once more is
the residual's white variance per bin spread over the reference's samples in a bin, the
largest over each sensor's axes (closed form on white noise), added without touching the
flight it came from."""
from types import SimpleNamespace

import numpy as np
import pytest

from mimunav.diagnosis import errors_in_variables
from mimunav.diagnosis.design import CHANNELS


def test_the_noise_added_is_the_residuals_white_variance_per_sample():
    rng = np.random.default_rng(0)
    sigma_bin = np.array([0.02, 0.05, 0.03, 1e-3, 4e-3, 2e-3])      # per 10 ms bin
    design = SimpleNamespace(residual=rng.normal(0, sigma_bin, (200_000, 6))
                             + np.linspace(0, 1, 200_000)[:, None],  # a slow trend: no noise
                             bin_s=0.01)
    got = errors_in_variables.white_per_sample(design, 400.0)      # 4 samples a bin
    largest = {s: max(sigma_bin[c] for c, (t, _) in enumerate(CHANNELS) if t == s)
               for s in ("gyro", "accel")}
    for sensor in ("gyro", "accel"):
        assert got[sensor] == pytest.approx(2.0 * largest[sensor], rel=0.01)


def test_noisier_adds_that_noise_and_leaves_the_flight_as_it_was():
    from dataclasses import dataclass

    @dataclass
    class Flight:
        fog_w: np.ndarray
        fog_f: np.ndarray
    flight = Flight(np.zeros((100_000, 3)), np.full((100_000, 3), -9.8))
    again = errors_in_variables.noisier(flight, {"gyro": 0.003, "accel": 0.05})
    assert np.std(again.fog_w) == pytest.approx(0.003, rel=0.01)
    assert np.std(again.fog_f) == pytest.approx(0.05, rel=0.01)
    assert not flight.fog_w.any() and (flight.fog_f == -9.8).all()


def test_the_references_own_noise_is_read_where_it_is_quietest():
    """A car's reference at 100 Hz: white noise 2.9e-4 rad/s and 2e-3 m/s^2 per sample
    (0.1 deg/sqrt h), turns, and an engine's 30 Hz vibration over the last 70 % of the
    record - 10 times the noise. Its own noise is read from the quiet windows within 10 %
    low (the first decile of 500-sample variances sits ~5 % low in sigma) and 5 % high (the
    turns' own sample-to-sample change, up to 5.5e-4 rad/s, is in every window); the whole
    record's difference variance would read the vibration too."""
    rng = np.random.default_rng(11)
    t = np.arange(60_000) * 0.01
    turns = 0.2 * np.sin(2 * np.pi * t / 23.0)[:, None] * [0.1, 0.1, 1.0]
    engine = np.where(t > 180.0, 3e-3, 0.0)[:, None] * np.sin(2 * np.pi * 30.0 * t)[:, None]
    w = turns + engine + rng.normal(0, 2.9e-4, (len(t), 3))
    f = [0.0, 0.0, -9.81] + 30 * engine + rng.normal(0, 2e-3, (len(t), 3))
    got = errors_in_variables.reference_white_noise(t, w, f)
    assert 0.9 * 2.9e-4 < got["gyro"] < 1.05 * 2.9e-4
    assert 0.9 * 2e-3 < got["accel"] < 1.05 * 2e-3
    assert np.sqrt(np.var(np.diff(w[:, 0])) / 2) > 3 * 2.9e-4        # what the decile avoids


class _OLS:
    """A stand-in for `fitting.Fitter`: ordinary least squares of the design's residual on
    the term's regressor (one channel), on the given rows."""

    def __init__(self, design, rows):
        self.x, self.y = design.columns[0][0][rows], design.residual[rows]

    def fit(self, idx):
        b, *_ = np.linalg.lstsq(self.x, self.y, rcond=None)
        e = self.y - self.x @ b
        cov = np.var(e) * np.linalg.inv(self.x.T @ self.x)
        return SimpleNamespace(of=lambda j: (b, cov))


def test_the_read_back_through_the_regressors_share_finds_the_truth(monkeypatch):
    """Errors in variables where the reference's noise is most of a regressor (a car's
    lever arm along its vertical: the roll and pitch it hardly makes, differentiated): a
    regressor x = s + u whose noise u also enters the residual as -0.3 u (the transfer of a
    0.3 m lever arm made with the same noisy rates), true coefficient 0. The fit reads
    -0.3 s_u (s_u = 0.57 the noise's share of x); with the noise doubled the linear
    read-back 2 b - b' still reads most of it; through the share the read-back finds zero
    within its scatter - and the finding is set aside; a regressor 95 % noise is not
    measurable at all."""
    rng = np.random.default_rng(12)
    n = 200_000
    design_t = np.arange(n) * 0.01
    terms = [{"effect": "lever_arm", "sensor": "imu", "axis": "all"}]

    def designs(noise_share):
        s = rng.normal(0, 1.0, n)                                  # the motion's part
        u = rng.normal(0, np.sqrt(noise_share / (1 - noise_share)), n)   # the noise's
        u2 = rng.normal(0, u.std(), n)                             # as much again
        e = rng.normal(0, 0.5, n)                                  # the MIMU's own noise
        one = SimpleNamespace(t=design_t, terms=terms, columns=[{0: (s + u)[:, None]}],
                              residual=-0.3 * u + e)
        two = SimpleNamespace(t=design_t, terms=terms, columns=[{0: (s + u + u2)[:, None]}],
                              residual=-0.3 * (u + u2) + e)
        return one, two

    monkeypatch.setattr(errors_in_variables, "Fitter", _OLS)
    added = {"gyro": 2.9e-4, "accel": 2e-3}
    one, two = designs(0.57)
    b = _OLS(one, np.ones(n, bool)).fit([]).of(0)[0][0]
    assert b == pytest.approx(-0.3 * 0.57, abs=0.01)
    finding = {"label": "lever_arm imu.all", "coefficient": b, "ci95": [b - 0.005, b + 0.005],
               "p_heldout": 1e-300}
    every = lambda d: np.ones(n, bool)                               # noqa: E731
    kept, aside = errors_in_variables.read_back(one, two, [finding], every, added, own=True)
    record = aside[0]["errors_in_variables"]
    assert kept == [] and "holds zero" in aside[0]["rejected"]
    assert record["share"][0] == pytest.approx(0.57, abs=0.01)
    assert abs(record["read_back"][0]) < 0.01                       # truth: 0
    linear = 2 * b - record["noisier"][0]
    assert linear < -0.06                                           # most of the bias left
    one, two = designs(0.95)
    kept, aside = errors_in_variables.read_back(one, two, [finding], every, added, own=True)
    assert kept == [] and "not measurable against this reference" in aside[0]["rejected"]


def test_the_findings_the_references_noise_may_make_are_those_read_back():
    """Beside a MEMS-grade reference every finding; beside another in a recording every one
    where a lever arm's transfer differentiates its rates, else a lever arm, proof-mass
    offset or time skew only; a simulation's FOG none. (A streamed recording, whose
    reference is not held, says it could not read them back: `NOT_READ_BACK`.)"""
    from mimunav.frames.mounting import Mounting

    def flight(lever, source="recording"):
        return SimpleNamespace(mimu_mounting=Mounting(), source=source,
                               fog_mounting=Mounting((1.0, 0.0, 0.0, 0.0), lever))
    bias = [{"effect": "bias_shift"}]
    skew = [{"effect": "time_skew"}]
    assert errors_in_variables.at_risk(flight([0.0, 0.0, 0.0]), bias, True)
    assert not errors_in_variables.at_risk(flight([0.0, 0.0, 0.0]), bias, False)
    assert errors_in_variables.at_risk(flight([0.0, 0.0, 0.0]), skew, False)
    assert errors_in_variables.at_risk(flight([0.4, -0.25, -0.3]), bias, False)
    assert not errors_in_variables.at_risk(flight([0.4, -0.25, -0.3], "simulation"), skew,
                                           False)
    assert not errors_in_variables.at_risk(flight([0.4, 0.0, 0.0]), [], True)
    assert "streams" in errors_in_variables.NOT_READ_BACK
