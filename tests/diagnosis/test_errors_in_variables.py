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
