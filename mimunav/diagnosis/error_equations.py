"""The linearised strapdown error equations the navigation level fits (`navigation`): the
MIMU compensated and navigated free-inertial from the log's initial state, its 10 ms bins,
and the velocity error any sensor-axis error of those bins produces (psi-angle form, Titterton
& Weston, Strapdown Inertial Navigation Technology, 2nd ed., section 12.2):

    d(phi)/dt = - C_nb d(w_b)                    attitude error, rad
    d(dv)/dt  =   C_nb d(f_b) + f_n x phi        velocity error, m/s

with the transport-rate error closing the Schuler loop, the Coriolis term and the vertical
channel's gravity gradient (`ErrorModel.velocity`). The regressors' inputs (what drives each
candidate term) come from a simulation's exact truth with attitude
(`reference.trajectory_outputs`); else from the MIMU's own outputs, whose noise the velocity
error integrates too (errors in variables) - as a recorded
reference's noise would be, differenced into them (`independent_inputs`).
"""
from dataclasses import dataclass

import numpy as np
import quaternion

from ..frames import earth
from ..compensation import effects
from ..compensation.effects import Conditions
from ..evaluation.replay import compensated_mimu, navigate_mimu, resample
from ..kernels import njit
from .reference import DERIVATIVE_WINDOW_S, has_attitude, trajectory_outputs
from ..errors import InputError

EARTH_RADIUS_M = 6.371e6        # mean radius: the transport-rate error's scale (Schuler)
G0 = 9.80665                    # m/s^2, the gravity gradient 2 g / R of the vertical channel
BIN_S = 0.01                    # regressors and the error equations are integrated on 10 ms bins


@dataclass
class ErrorModel:
    """What the signatures need, on bins of BIN_S: time t (s), the sensor-to-NED rotation
    c_ns (nb, 3, 3), the specific force in NED f_n (nb, 3), the bin length dt (s)."""
    t: np.ndarray
    c_ns: np.ndarray
    f_n: np.ndarray
    dt: np.ndarray
    w_ie: np.ndarray = None     # Earth rate in NED at the start, rad/s (Coriolis of dv)

    def velocity(self, d_f, d_w):
        """Velocity error (nb, 3, k), NED m/s, at the bin ends caused by sensor-axis
        specific-force errors d_f (nb, 3, k) m/s^2 and rate errors d_w (nb, 3, k) rad/s:
        d(phi)/dt = -C_ns d_w + d(w_en), d(w_en) = (dv_E, -dv_N, 0) / R (the transport-rate
        error, which with f_n x phi closes the Schuler loop: over 400 s the open loop
        overstates a tilt's velocity error by 4 %, sin(w_s t) / (w_s t)),
        d(dv)/dt = C_ns d_f + f_n x phi - 2 w_ie x dv + (0, 0, 2 g / R dD), dD the down error
        (the vertical channel's gravity gradient: cosh(sqrt(2 g / R) t) = 1.26 at 400 s)
        (Titterton & Weston sec. 12.2.1, phi-angle form)."""
        dt = self.dt[:, None, None]
        drive_phi = -np.einsum("nij,njk->nik", self.c_ns, d_w) * dt
        drive_v = np.einsum("nij,njk->nik", self.c_ns, d_f) * dt
        out = np.empty_like(drive_v)
        w_ie = np.zeros(3) if self.w_ie is None else np.asarray(self.w_ie, float)
        _schuler(drive_phi, drive_v, self.f_n, self.dt, EARTH_RADIUS_M, w_ie, out)
        return out


@njit(nogil=True)
def _schuler(drive_phi, drive_v, f_n, dt, radius, w_ie, out):
    """The phi-angle error equations of `ErrorModel.velocity`, bin by bin: phi and dv carry
    each other (transport-rate error, f x phi), the down error its gravity gradient; out
    (nb, 3, k) the velocity error."""
    nb, _, k = drive_v.shape
    for c in range(k):
        p0 = p1 = p2 = v0 = v1 = v2 = down = 0.0
        for n in range(nb):
            T = dt[n]
            p0 += drive_phi[n, 0, c] + v1 / radius * T
            p1 += drive_phi[n, 1, c] - v0 / radius * T
            p2 += drive_phi[n, 2, c]
            f0, f1, f2 = f_n[n, 0], f_n[n, 1], f_n[n, 2]
            c0 = 2.0 * (w_ie[1] * v2 - w_ie[2] * v1)          # 2 w_ie x dv (Coriolis)
            c1 = 2.0 * (w_ie[2] * v0 - w_ie[0] * v2)
            c2 = 2.0 * (w_ie[0] * v1 - w_ie[1] * v0)
            v0 += drive_v[n, 0, c] + (f1 * p2 - f2 * p1 - c0) * T
            v1 += drive_v[n, 1, c] + (f2 * p0 - f0 * p2 - c1) * T
            v2 += drive_v[n, 2, c] + ((f0 * p1 - f1 * p0) - c2 + 2.0 * G0 / radius * down) * T
            down += v2 * T
            out[n, 0, c], out[n, 1, c], out[n, 2, c] = v0, v1, v2


def observed_error(flight, cal):
    """(MIMU navigation Trajectory, w rad/s, f m/s^2 sensor-axis outputs) of the compensated
    MIMU, navigated from the log's initial state. A recording's outputs (no raw, no
    calibration of the unit) have the biases its import measured removed first (`recording`
    metadata: a phone's 3.9 deg/s gyro bias tilted the free-inertial run 36 deg in a
    minute, beyond the error model's small angles)."""
    w, f, _ = compensated_mimu(flight, cal)
    w, f = w - recorded_bias(flight, "gyro_bias_static_rad_s"), \
        f - recorded_bias(flight, "accel_bias_m_s2")
    if not (np.isfinite(w).all() and np.isfinite(f).all()):
        raise InputError(f"{flight.path}: the compensated MIMU has non-finite samples: the "
                         "navigation level needs an unbroken free-inertial run")
    nav = navigate_mimu(flight, w, f)
    return nav, w, f


def recorded_bias(flight, key):
    """The bias (3,) sensor axes, SI, that a recording's import measured (`key` of its
    `recording` metadata), or 0 for a log with raw outputs or without one."""
    doc = flight.recording or {}
    value = doc.get(key) if flight.mimu_raw is None else None
    return np.zeros(3) if value is None else np.asarray(value, float)


def error_model(flight, nav, w, f, reference=None):
    """The ErrorModel on BIN_S bins after the initial state, and the bins' Conditions: the
    regressors' inputs. From `reference` (a Trajectory) when it carries an attitude over the
    bins (`reference.trajectory_outputs`: free of the MIMU's noise), the bins ending with it;
    else from the MIMU's own outputs w, f (sensor axes, rad/s, m/s^2), whose noise the
    velocity error integrates too (errors in variables: `independent_inputs`)."""
    if flight.mimu_platform is not None:
        raise InputError(f"{flight.path}: the MIMU turns on a platform (/mimu/platform); "
                         "this analysis does not follow the rotation yet - replay and table do")
    t = flight.mimu_t
    after = t > flight.initial.t + 1e-12
    reference = independent_inputs(flight, reference)
    if reference is not None:
        after &= t <= reference.t[-1] + 1e-9
    rate = 1.0 / np.median(np.diff(t))
    m = max(1, round(BIN_S * rate))
    idx = np.flatnonzero(after)
    n = len(idx) // m * m
    idx = idx[:n]
    mean = lambda x: x[idx].reshape(n // m, m, *x.shape[1:]).mean(axis=1)  # noqa: E731
    t_end = t[idx].reshape(n // m, m)[:, -1]
    t_start = np.r_[flight.initial.t, t_end[:-1]]
    q_nb = resample(nav, t_end - 0.5 * (t_end - t_start)).q_nb
    q_ns = q_nb * flight.mimu_mounting.q_vs
    c_ns = quaternion.as_rotation_matrix(q_ns)
    f_b, w_b = mean(f), mean(w)
    model = ErrorModel(t_end, c_ns, np.einsum("nij,nj->ni", c_ns, f_b), t_end - t_start,
                       earth.earth_rate_ned(flight.initial.lat))
    temperature, frequency = flight.mimu_temperatures()
    if reference is not None:
        f_in, w_in = trajectory_outputs(reference, np.r_[t_start[0], t_end],
                                        flight.mimu_mounting)
    else:
        f_in, w_in = f_b, w_b
    cond = Conditions.from_outputs(t_end, f_in, w_in, mean(temperature), mean(frequency),
                                   DERIVATIVE_WINDOW_S)
    if reference is not None:       # the vibration the MIMU felt: its own outputs' power
        cond.vibration = effects.vibration_power(t_end, f_b)
    return model, cond


def independent_inputs(flight, reference):
    """`reference` when it can give the regressors' inputs - a simulation's exact truth with
    an attitude from the initial state to its end (`reference.has_attitude`) - else None.
    A recorded reference's own velocity noise sits in the velocity error with one sign and,
    differenced, in every specific-force regressor with the other: errors in variables
    again (an independent review: a 10 Hz reference with 0.02 m/s of white noise gave a
    gentle flight 'time_skew accel.all -0.127 s, held-out p 5e-8'); its terms are then made
    of the MIMU's outputs, and those of its own outputs are no finding (`OWN_NOISE`)."""
    if reference is None or reference is not flight.truth or flight.source != "simulation" \
            or not has_attitude(reference, flight.initial.t, reference.t[-1]):
        return None
    return reference


def signature(model, regressor, k):
    """Velocity-error signature (nb, 3, k) of a regressor {(sensor, axis index): (nb, k)}."""
    d = {"accel": np.zeros((len(model.t), 3, k)), "gyro": np.zeros((len(model.t), 3, k))}
    for (sens, i), x in regressor.items():
        d[sens][:, i, :] = x
    return model.velocity(d["accel"], d["gyro"])


# the navigation level's nuisance: bias wander as hats with knots this far apart, s
WANDER_KNOT_S = 60.0
NUISANCE_KNOTS = 8      # wander knots whose signatures are built at once: an hour at 200 Hz
#                         held all 61 of a channel at every 10 ms bin (6 x 0.5 GB, 7 GB peak)


def nuisance(model, at):
    """Signatures (len(at), 3, q) at the bins `at` of what the navigation level does not
    test: piecewise-linear (wandering) accelerometer and gyro biases, the initial attitude
    error; built NUISANCE_KNOTS columns at a time (each column's is its own)."""
    t = model.t
    knots = np.arange(t[0], t[-1] + WANDER_KNOT_S, WANDER_KNOT_S)
    keep = [k for k in knots if np.clip(1 - np.abs(t - k) / WANDER_KNOT_S, 0, None).sum() > 0.5]
    cols = []                                           # the hats sum to 1: constants included
    for i in range(3):
        for sens in ("accel", "gyro"):
            for a in range(0, len(keep), NUISANCE_KNOTS):
                part = np.asarray(keep[a:a + NUISANCE_KNOTS])
                hat = np.clip(1 - np.abs((t[:, None] - part[None, :]) / WANDER_KNOT_S), 0, None)
                cols.append(signature(model, {(sens, i): hat}, len(part))[at])
    phi0 = np.cumsum(np.cross(model.f_n[:, :, None], np.eye(3)[None], axisa=1, axisb=1,
                              axisc=1) * model.dt[:, None, None], axis=0)
    cols.append(phi0[at])
    return np.concatenate(cols, axis=2)
