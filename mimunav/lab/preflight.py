"""The gyro zero taken before flight: the MIMU standing still in its launch attitude at the
end of its warm-up, its compensated rate set to the Earth's rate there.

Seed S1 (introduction) lists what the traditional methods of its refs [2-5] calibrate in the
lab: the cross-coupling, the accelerometer zero and first-order scale factor and the gyro
scale factor - no gyro zero. A MEMS gyro's zero is ordinarily taken at power-on before each
flight, in the launch attitude, which takes up the unit's turn-on bias, the offset of the
temperature it has reached and its g-sensitivity at 1 g in that attitude (issue 54).
"""
from dataclasses import replace

import numpy as np

from ..compensation.model import compensate

ZERO_WINDOW_S = 1.0     # s: the means whose scatter gives the zero's standard error


def gyro_zero(cal, raw, w_expected, rate_hz):
    """(calibration with W0 taken from `raw`, {"standard_error_rad_s", "samples"}).

    cal: the lab calibration (its W0 replaced, everything else kept); raw: the /mimu/raw
    fields (accel_volts, gyro_volts V; accel_temperature degC; gyro_frequency Hz; (N, 3))
    of a still span; w_expected: the rate the gyros see there (rad/s, sensor axes: the
    Earth's rate in the launch attitude); rate_hz: the samples' rate. W0 enters the model
    linearly, so the zero solves J dW0 = w_expected - mean(w) with J the response of the
    mean compensated rate to a unit change of each W0 component (exact, 4 compensations).
    The standard error is the scatter of ZERO_WINDOW_S means over sqrt(their number)."""
    mean = lambda c: _rates(c, raw).mean(axis=0)                        # noqa: E731
    base = mean(cal)
    jac = np.empty((3, 3))
    for i in range(3):
        jac[:, i] = (mean(replace(cal, W0=cal.W0 + np.eye(3)[i] * 1e-3)) - base) / 1e-3
    zeroed = replace(cal, W0=cal.W0 + np.linalg.solve(jac, np.asarray(w_expected, float) - base),
                     extra=dict(cal.extra))
    w = _rates(zeroed, raw)
    k = max(int(round(ZERO_WINDOW_S * rate_hz)), 1)
    windows = w[:len(w) // k * k].reshape(-1, k, 3).mean(axis=1)
    se = windows.std(axis=0, ddof=1) / np.sqrt(len(windows)) if len(windows) > 1 \
        else np.full(3, np.nan)
    return zeroed, {"standard_error_rad_s": se.tolist(), "samples": len(w)}


def _rates(cal, raw):
    return compensate(cal, raw["accel_volts"], raw["gyro_volts"], raw["accel_temperature"],
                      raw["gyro_frequency"], filter_outliers=False)[1]
