"""Seed S1 eqs. 1-4: raw MIMU outputs (volts, frequencies) to specific force (m/s^2) and
angular rate (rad/s) in the MIMU's axes, and the model's exact inverse (Newton on each triad).
"""
import functools

import numpy as np

from .effects import Conditions, temperature_change
from .effects import apply as apply_effects
from ..errors import InputError
from .wild_values import SATURATED, UNUSABLE, clipped, wild_value_filter


class CalibrationError(InputError):
    """A calibration file that does not follow the contract, or cannot be applied."""


# ---- equations ---------------------------------------------------------------------------
def poly2(c: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Per-axis quadratic c[i,0] + c[i,1] x_i + c[i,2] x_i^2 for x (N, 3) -> (N, 3)."""
    return c[:, 0] + x * (c[:, 1] + x * c[:, 2])


def triad(p0: np.ndarray, p1: np.ndarray, p2: np.ndarray, p3: np.ndarray, v: np.ndarray
          ) -> np.ndarray:
    """p0 + p1 @ v + p2 * v^2 + p3 * v^3 for v (N, 3): eqs. 1 and 3 without C."""
    return p0 + v @ p1.T + v * v * (p2 + p3 * v)


def compensate(cal, accel_volts: np.ndarray, gyro_volts: np.ndarray, accel_temperature: np.ndarray,
               gyro_frequency: np.ndarray, range_accel: float = np.inf, range_gyro: float = np.inf,
               filter_outliers: bool = True, t: np.ndarray | None = None, record=None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Raw MIMU samples -> specific force f (m/s^2) and rate w (rad/s), sensor axes, and a
    flag per sample (REPLACED | SATURATED | UNUSABLE bits).

    Inputs (N, 3): accel_volts U_a and gyro_volts U_w (V), accel_temperature T (degC),
    gyro_frequency f (Hz). range_*: the unit's range (m/s^2, rad/s); outputs whose magnitude
    on any axis reaches it are flagged SATURATED, and so are raw outputs stuck at their
    extreme (`clipped`: an ADC or amplifier limit below the declared range). t: sample
    times, s (N,), needed by the
    cold-start model's dT window. record: `RecordStats` of the whole record when these
    samples are a block of it (`compensate_log`): the wild-value filter's noise level and
    the clipping extremes are then the record's, as if it were compensated whole.
    """
    if cal is None:
        raise CalibrationError("the MIMU is recorded raw (/mimu/raw: volts and frequencies); "
                               "its calibration is needed to compensate it (--cal CAL.json)")
    chans = [np.ascontiguousarray(x, dtype=float) for x in
             (accel_volts, gyro_volts, accel_temperature, gyro_frequency)]
    n = len(chans[0])
    for name, x in zip(("accel_volts", "gyro_volts", "accel_temperature", "gyro_frequency"),
                       chans):
        if x.shape != (n, 3):
            raise InputError(f"{name} must have shape (N, 3) = ({n}, 3), got {x.shape}")
    flags = np.zeros(n, dtype=np.uint8)
    sigmas, extremes = (record.sigma, record.extremes) if record else ([None] * 4, [None] * 2)
    if filter_outliers:
        chans = [wild_value_filter(x, flags, sigma=sigma) for x, sigma in zip(chans, sigmas)]
    else:
        for x in chans:
            flags[~np.isfinite(x).all(axis=1)] |= UNUSABLE
    u_a, u_w, temp, freq = chans
    flags[clipped(u_a, extremes[0]) | clipped(u_w, extremes[1])] |= SATURATED
    if (cal.base_model == "cold-start" or cal.found) and t is None:
        raise CalibrationError(f"model {cal.model!r} needs the sample times t")
    if cal.base_model == "cold-start":
        f, w = _cold_start(cal, u_a, u_w, temp, freq, np.asarray(t, dtype=float))
    else:
        v_a = u_a - poly2(cal.ct, temp)                                   # eq. 2
        v_w = u_w - poly2(cal.cw, freq)                                   # eq. 4
        f = triad(cal.A0, cal.A1, cal.A2, cal.A3, v_a)                    # eq. 1
        w = triad(cal.W0, cal.W1, cal.W2, cal.W3, v_w) + f @ cal.C.T      # eq. 3
    if cal.found:                      # terms found by a diagnosis, removed (effects.apply)
        cond = Conditions.from_outputs(np.asarray(t, float), f, w, temp, freq)
        f, w = apply_effects(cal.found, cond, sign=-1.0)
    flags[(np.abs(f) >= range_accel).any(axis=1) | (np.abs(w) >= range_gyro).any(axis=1)] \
        |= SATURATED
    return f, w, flags


def _cold_start(cal, u_a, u_w, temp, freq, t):
    """Seed S3: E = E(T)/(a + b T) + (c + d T) + e dT per axis on the linear triad output."""
    out = []
    window = cal.cold_start["window_s"]
    for triad_name, u, p1, temperature in (("accel", u_a, cal.A1, temp),
                                           ("gyro", u_w, cal.W1, freq)):
        k = cal.cold_start[triad_name]
        p0 = cal.A0 if triad_name == "accel" else cal.W0
        e_t = p0 + u @ p1.T
        d_t = temperature_change(temperature, window, t)
        out.append(e_t / (k["a"] + k["b"] * temperature) + k["c"] + k["d"] * temperature
                   + k["e"] * d_t)
    return out[0], out[1]


def raw_from_physics(cal, f: np.ndarray, w: np.ndarray, accel_temperature: np.ndarray,
                     gyro_frequency: np.ndarray, f_gyro: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of `compensate` for the triad models (entire-63, linear): the raw voltages
    U_a, U_w (V, (N, 3)) whose compensation gives specific force f (m/s^2) and rate w
    (rad/s) at the given temperature readings. Solved by Newton's method to round-off:
    the cubic terms and the C @ a coupling make the equations implicit. f_gyro: the
    specific force that drives the g-sensitivity C (default f; a simulation passes the
    true one, so the compensation's use of the measured f is a realistic residual)."""
    if cal.model not in ("entire-63", "linear"):
        raise CalibrationError(f"raw_from_physics has no inverse for model {cal.model!r}")
    f = np.ascontiguousarray(f, dtype=float)
    w = np.ascontiguousarray(w, dtype=float)
    v_a = invert_triad(cal.A0, cal.A1, cal.A2, cal.A3, f)
    f_gyro = f if f_gyro is None else np.asarray(f_gyro, dtype=float)
    v_w = invert_triad(cal.W0, cal.W1, cal.W2, cal.W3, w - f_gyro @ cal.C.T)
    return v_a + poly2(cal.ct, accel_temperature), v_w + poly2(cal.cw, gyro_frequency)


def invert_triad(p0: np.ndarray, p1: np.ndarray, p2: np.ndarray, p3: np.ndarray, y: np.ndarray
                 ) -> np.ndarray:
    v = np.empty_like(y)
    worst = _newton_kernel()(p0, p1, np.linalg.inv(p1), p2, p3, y, v)
    if not worst < 1e-12:
        raise CalibrationError(f"inverse of the triad model did not converge (relative "
                               f"residual {worst:.3g}): input beyond the model's monotonic range")
    return v


@functools.cache
def _newton_kernel():
    """`_newton_triad` compiled by numba on first use: only the simulation and the tests
    invert the compensation, and `compensate` need not import numba."""
    from ..kernels import njit
    return njit(nogil=True)(_newton_triad)


def _newton_triad(p0, p1, p1_inv, p2, p3, y, v):
    """Solve p0 + p1 v + p2 v^2 + p3 v^3 = y per row (Newton, 3x3 steps by Cramer's rule);
    returns the worst relative residual."""
    worst = 0.0
    for k in range(y.shape[0]):
        y0, y1, y2 = y[k, 0] - p0[0], y[k, 1] - p0[1], y[k, 2] - p0[2]
        a = p1_inv[0, 0] * y0 + p1_inv[0, 1] * y1 + p1_inv[0, 2] * y2
        b = p1_inv[1, 0] * y0 + p1_inv[1, 1] * y1 + p1_inv[1, 2] * y2
        c = p1_inv[2, 0] * y0 + p1_inv[2, 1] * y1 + p1_inv[2, 2] * y2
        scale = (abs(y[k, 0]) + abs(y[k, 1]) + abs(y[k, 2]) + abs(p0[0]) + abs(p0[1])
                 + abs(p0[2]) + 1e-300)           # relative to the outputs and the offset
        res = 0.0
        for it in range(30):
            r0 = p1[0, 0] * a + p1[0, 1] * b + p1[0, 2] * c + (p2[0] + p3[0] * a) * a * a - y0
            r1 = p1[1, 0] * a + p1[1, 1] * b + p1[1, 2] * c + (p2[1] + p3[1] * b) * b * b - y1
            r2 = p1[2, 0] * a + p1[2, 1] * b + p1[2, 2] * c + (p2[2] + p3[2] * c) * c * c - y2
            res = abs(r0) + abs(r1) + abs(r2)
            if res <= 1e-15 * scale or it == 29:
                break
            j00 = p1[0, 0] + (2.0 * p2[0] + 3.0 * p3[0] * a) * a
            j11 = p1[1, 1] + (2.0 * p2[1] + 3.0 * p3[1] * b) * b
            j22 = p1[2, 2] + (2.0 * p2[2] + 3.0 * p3[2] * c) * c
            j01, j02, j10, j12, j20, j21 = p1[0, 1], p1[0, 2], p1[1, 0], p1[1, 2], p1[2, 0], p1[2, 1]
            c00, c01, c02 = j11 * j22 - j12 * j21, j02 * j21 - j01 * j22, j01 * j12 - j02 * j11
            c10, c11, c12 = j12 * j20 - j10 * j22, j00 * j22 - j02 * j20, j02 * j10 - j00 * j12
            c20, c21, c22 = j10 * j21 - j11 * j20, j01 * j20 - j00 * j21, j00 * j11 - j01 * j10
            det = j00 * c00 + j01 * c10 + j02 * c20
            a -= (c00 * r0 + c01 * r1 + c02 * r2) / det
            b -= (c10 * r0 + c11 * r1 + c12 * r2) / det
            c -= (c20 * r0 + c21 * r1 + c22 * r2) / det
        v[k, 0], v[k, 1], v[k, 2] = a, b, c
        worst = max(worst, res / scale)
    return worst
