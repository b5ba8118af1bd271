"""Initial alignment of a land vehicle's IMU from its own data and a GNSS track.

Coarse alignment at rest (Titterton & Weston 2004, sec. 10.2.1): at standstill the
specific force is the reaction to gravity, f^b = C_bn (0, 0, -g), so
    roll  = atan2(-f_y, -f_z),   pitch = atan2(f_x, sqrt(f_y^2 + f_z^2))     (vehicle axes);
the gyro bias is the static mean rate less the Earth rate C_bn w_ie^n; of the accelerometer
bias only the part along gravity is observable at rest: (|f| - g) f/|f| with the normal
gravity g at the track's position (none without a track). Heading is not
observable this way from a consumer gyro (Earth rate 0.004 deg/s against a bias of
0.1-1 deg/s), so it comes from the GNSS course once the vehicle moves: a car does not slide
sideways, its forward axis points along its velocity (the non-holonomic assumption), and the
yaw turned between standstill and that moment is taken from the gyro.

Moving alignment (`moving_attitude`, a two-vector solution of Wahba's problem by
scipy's `Rotation.align_vectors`): the mean specific force over a short interval is matched
exactly to f^n = dv^n/dt + (2 w_ie^n + w_en^n) x v^n - g^n from the GNSS velocity (T&W eq.
3.70), and the vehicle's forward axis as closely as possible to the GNSS velocity direction.
Levelling with the same accelerometers that are navigated makes the horizontal part of their
bias cancel at the start (the classic tilt/bias equilibrium), so only its change with
attitude propagates.
"""
import math
from dataclasses import dataclass

import numpy as np
import quaternion
from scipy.spatial.transform import Rotation

from . import attitude, earth
from .errors import InputError

STATIC_SPEED = 0.2          # m/s: GNSS speed below which the vehicle is taken to be at rest
STATIC_MARGIN_S = 1.0       # s cut from the end of the rest period (the car starts to roll)
MIN_STATIC_S = 2.0          # s: a shorter rest cannot give a level and a gyro bias
COURSE_SPEED = 3.0          # m/s: horizontal speed from which the GNSS course gives heading
                            # (1 cm/s RTK velocity noise -> 0.2 deg course noise)
MOVING_HALF_WINDOW_S = 0.25     # s: half the interval of the moving two-vector alignment


@dataclass
class Alignment:
    """An initial state (contract `initial_state` in SI: rad, m, m/s, q_nb wxyz) and what
    the alignment learnt: the gyro bias at rest (rad/s, sensor axes), the rest interval
    (t0, t1) s, and `method` (how each part was obtained, for the log's metadata)."""
    t: float
    lat: float
    lon: float
    h: float
    v_ned: np.ndarray
    q_nb: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray          # m/s^2, sensor axes: the part along gravity only
    static: tuple
    method: str


def level(f_v):
    """(roll, pitch) rad of a vehicle at rest from its mean specific force f_v (m/s^2,
    vehicle FRD axes)."""
    fx, fy, fz = f_v
    return math.atan2(-fy, -fz), math.atan2(fx, math.hypot(fy, fz))


def rest_end(t_track, v_ned, t_first):
    """End of the rest period that starts the track (s): the first epoch moving faster than
    STATIC_SPEED, less STATIC_MARGIN_S; t_first when the track starts moving."""
    moving = np.linalg.norm(v_ned, axis=1) > STATIC_SPEED
    if not moving.any():
        return float(t_track[-1])
    return max(float(t_first), float(t_track[np.argmax(moving)]) - STATIC_MARGIN_S)


def yaw_turned(t, w_v, t0, t1):
    """Yaw (rad) a level vehicle turned between t0 and t1 from vehicle-axis rates (rad/s):
    the integral of the rate about down (small-tilt approximation of the Euler rate)."""
    k = (t > t0) & (t <= t1)
    dt = np.diff(t, prepend=t[0])
    return float(np.sum(w_v[k, 2] * dt[k]))


def initial_alignment(t, w, f, mounting, track=None):
    """Initial state at the first IMU stamp: level and gyro bias from the rest that starts
    the recording, heading from the course of `track` {t s, lat, lon rad, h m, v_ned m/s}
    once it moves faster than COURSE_SPEED. t s, w rad/s, f m/s^2 (sensor axes).
    Without a track, or without a rest, the missing parts are assumed (say so in `method`)."""
    q_vs = mounting.q_vs
    notes = []
    if track is not None and len(track["t"]) >= 2:
        t_end = rest_end(track["t"], track["v_ned"], t[0])
    else:
        t_end = t[0] + MIN_STATIC_S
        notes.append(f"rest assumed for the first {MIN_STATIC_S:g} s (no GNSS track)")
    rest = (t >= t[0]) & (t <= t_end)
    if t_end - t[0] < MIN_STATIC_S or rest.sum() < 10:
        raise InputError(f"the recording does not start at rest (rest {t_end - t[0]:.2f} s, "
                         f"need {MIN_STATIC_S:g} s): level and gyro bias cannot be found")
    f_v = attitude.rotate(q_vs, f[rest].mean(axis=0))
    roll, pitch = level(f_v)
    notes.append(f"level from the mean specific force over the rest {t[0]:.2f}-{t_end:.2f} s")
    if track is not None:
        lat, lon, h = (float(np.interp(t[0], track["t"], track[k])) for k in ("lat", "lon", "h"))
        speed = np.hypot(track["v_ned"][:, 0], track["v_ned"][:, 1])
        fast = np.flatnonzero(speed >= COURSE_SPEED)
        if len(fast):
            k = fast[0]
            course = math.atan2(track["v_ned"][k, 1], track["v_ned"][k, 0])
            w_bias_v = attitude.rotate(q_vs, w[rest].mean(axis=0))
            w_v = attitude.rotate(q_vs, w) - w_bias_v
            yaw = course - yaw_turned(t, w_v, t_end, float(track["t"][k]))
            notes.append(f"heading from the GNSS course at t = {track['t'][k]:.2f} s "
                         f"({speed[k]:.1f} m/s) less the gyro's yaw since the rest "
                         "(non-holonomic: no side slip)")
        else:
            yaw = 0.0
            notes.append(f"heading assumed 0 (the track never exceeds {COURSE_SPEED:g} m/s)")
    else:
        lat = lon = h = 0.0
        yaw = 0.0
        notes.append("position and heading assumed 0 (no GNSS track)")
    q_nb = attitude.from_euler(np.array(yaw), np.array(pitch), np.array(roll))
    w_ie_s = attitude.rotate(np.conjugate(q_nb * q_vs), earth.earth_rate_ned(lat))
    bias = w[rest].mean(axis=0) - w_ie_s
    f_rest = f[rest].mean(axis=0)
    norm = np.linalg.norm(f_rest)
    accel_bias = ((norm - float(earth.normal_gravity(lat, h))) * f_rest / norm
                  if track is not None else np.zeros(3))
    return Alignment(float(t[0]), lat, lon, h, np.zeros(3), quaternion.as_float_array(q_nb),
                     bias, accel_bias, (float(t[0]), float(t_end)), "; ".join(notes))


def moving_attitude(t, f, mounting, track, t0, half=MOVING_HALF_WINDOW_S):
    """q_nb (wxyz) of a moving vehicle at t0 (s): the mean specific force of the IMU over
    (t0 - half, t0 + half] (f m/s^2 sensor axes at stamps t) matched exactly to the
    track's (its velocity's difference over the same interval, Coriolis and gravity), the
    forward axis to the track's velocity direction. See the module's docstring."""
    k = (t > t0 - half) & (t <= t0 + half)
    if k.sum() < 2:
        raise InputError(f"no IMU samples around t = {t0:.2f} s")
    f_b = attitude.rotate(mounting.q_vs, f[k].mean(axis=0))
    v = lambda s: np.array([np.interp(s, track["t"], track["v_ned"][:, i])  # noqa: E731
                            for i in range(3)])
    v0 = v(t0)
    lat, h = float(np.interp(t0, track["t"], track["lat"])), float(np.interp(t0, track["t"],
                                                                                track["h"]))
    a_n = (v(t0 + half) - v(t0 - half)) / (2 * half)
    coriolis = np.cross(2 * earth.earth_rate_ned(lat) + earth.transport_rate_ned(lat, h, v0), v0)
    f_n = a_n + coriolis - earth.gravity_ned(lat, h)
    rot, _ = Rotation.align_vectors([f_n, v0 / np.linalg.norm(v0)], [f_b, [1.0, 0, 0]],
                                    weights=[np.inf, 1.0])
    x, y, z, w = rot.as_quat()
    return np.array([w, x, y, z])
