"""A single-axis rotating platform carrying the MIMU (seed S4's rotation modulation).

Frames: vehicle (body) b; platform p, turning about its own z axis by the angle theta(t);
sensor s, fixed on the platform. q_bs(t) = q_bp0 Rz(theta(t)) q_ps, with q_bp0 the
platform's base attitude in the vehicle (its axis direction, plus a small axis tilt error)
and q_ps the IMU's mounting on the platform (an inclination tilts all three sensor axes out
of the plane perpendicular to the axis, so that all three are modulated). The axis passes
through the vehicle origin; the IMU's origin sits at lever arm r_p from it, in platform axes
(turning with it): in the vehicle r(t) = C_bp(theta) r_p, C_bp = C_bp0 Rz(theta).

Exact increments: `RotatingMotion` is a `truth.Motion` whose "body" is the sensor itself,
q_ns = q_nb q_bs, with the sensor's rate relative to NED and its derivative in sensor axes
    w_ns^s  = C_sb w_nb^b + C_sp theta' e_z
    dw_ns^s = C_sb dw_nb^b - (C_sp theta' e_z) x (C_sb w_nb^b) + C_sp theta'' e_z
and the IMU's own point moves with it (w = w_nb^b, a = C_bp0 e_z the axis, vehicle axes)
    r'  = theta' a x r,   r'' = theta'' a x r + theta' a x r'
    v_p = v + C_nb (w x r + r')
    a_p = a_ned + C_nb (dw x r + w x (w x r) + 2 w x r' + r'')
(the transport rate's part of the point's velocity, |w_en| |r| < 1e-5 m/s at 300 m/s and
0.1 m, is left out; v_p and a_p agree with each other exactly), so `truth.generate`
integrates the true sensor-axis increments at the IMU's point by quadrature, as for any
motion: no sampled rotation of interval means.
"""
import math
from dataclasses import dataclass

import numpy as np
import quaternion

from ..frames import attitude, earth
from . import truth
from ..errors import InputError
from .profile import Ramp, rate_ppoly


MODES = ("fixed", "continuous", "back-and-forth")


@dataclass
class Platform:
    """A single-axis rotation platform. mode: fixed | continuous | back-and-forth; rate_rad_s:
    the turning rate; swing_rad: the back-and-forth amplitude (turn +swing, dwell, turn back,
    dwell, ...); dwell_s: the pause at each end; ramp_s: the rate's smooth rise and fall;
    inclination_rad: the IMU tilted on the platform about the horizontal platform axis at
    azimuth tilt_azimuth_rad from platform x (MAGIC_INCLINATION at -45 deg puts every sensor
    axis at 54.74 deg from the turning axis); axis_tilt_rad: a small error of the axis
    direction (rotation vector about vehicle x, y); base_wxyz: the axis' nominal attitude
    in the vehicle (platform frame at angle 0 -> vehicle, identity: the axis along vehicle z);
    imu_wxyz: the IMU's nominal mounting on the platform (sensor -> platform), before the
    inclination; imu_deviation_rad: the installation's deviation from that design (rotation
    vector, platform axes: the true mounting is exp(deviation) q_ps_nominal) - a log's
    metadata states the design, the deviation is what `installation_tilt` finds;
    encoder_resolution_rad: the step of the recorded platform angle (a circular grating);
    encoder_noise_rad: its white read-out noise (1 sigma), drawn per sample index from
    encoder_seed (`counter_normal`), so a record made in blocks reads the same angles;
    lever_arm_m: the IMU's origin from the axis point (the vehicle origin), m, platform axes."""
    mode: str = "continuous"
    rate_rad_s: float = math.radians(10.0)
    swing_rad: float = 2 * math.pi
    dwell_s: float = 0.0
    ramp_s: float = 1.0
    inclination_rad: float = 0.0
    axis_tilt_rad: tuple = (0.0, 0.0)
    tilt_azimuth_rad: float = 0.0
    base_wxyz: tuple = (1.0, 0.0, 0.0, 0.0)
    imu_wxyz: tuple = (1.0, 0.0, 0.0, 0.0)
    imu_deviation_rad: tuple = (0.0, 0.0, 0.0)
    encoder_resolution_rad: float = 0.0
    encoder_noise_rad: float = 0.0
    encoder_seed: int = 0
    lever_arm_m: tuple = (0.0, 0.0, 0.0)     # the IMU's origin from the axis point, platform axes

    def __post_init__(self):
        if self.mode not in MODES:
            raise InputError(f"platform mode {self.mode!r}: one of {', '.join(MODES)}")
        if self.mode != "fixed" and not self.rate_rad_s > 0:
            raise InputError("a turning platform needs rate_rad_s > 0")

    def angle_ppoly(self, t_end):
        """PPoly of the platform rate (rad/s) over [0, t_end] (its antiderivative is the angle)."""
        if self.mode == "fixed":
            return rate_ppoly([], t_end)
        if self.mode == "continuous":
            return rate_ppoly([Ramp(0, 0.0, t_end + self.ramp_s, self.rate_rad_s,
                                    self.ramp_s)], t_end + self.ramp_s)
        ramps, t, sign = [], 0.0, 1.0
        turn = self.swing_rad / self.rate_rad_s + self.ramp_s     # a trapezoid's length
        while t < t_end:
            ramps.append(Ramp(0, t, t + turn, sign * self.rate_rad_s, self.ramp_s))
            t += turn + self.dwell_s
            sign = -sign
        return rate_ppoly(ramps, max(t, t_end))

    def encoder(self, angle, first_index=0):
        """The platform angle as the encoder records it (rad): read with its noise, rounded to
        its resolution. first_index: the sample index of angle[0] (the noise's counter)."""
        x = np.asarray(angle, float)
        if self.encoder_noise_rad > 0:
            x = x + self.encoder_noise_rad * counter_normal(self.encoder_seed, first_index, len(x))
        res = self.encoder_resolution_rad
        return np.round(x / res) * res if res > 0 else x

    def q_bp0(self):
        return (quaternion.from_rotation_vector([*self.axis_tilt_rad, 0.0])
                * attitude.from_wxyz(self.base_wxyz))

    def q_ps_nominal(self):
        """The designed mounting of the IMU on the platform (sensor -> platform)."""
        a = self.tilt_azimuth_rad
        return (quaternion.from_rotation_vector(
            self.inclination_rad * np.array([math.cos(a), math.sin(a), 0.0]))
            * attitude.from_wxyz(self.imu_wxyz))

    def q_ps(self):
        """The true mounting: the design turned by the installation deviation."""
        return quaternion.from_rotation_vector(self.imu_deviation_rad) * self.q_ps_nominal()


def counter_normal(seed, first, n):
    """n standard normal numbers for the sample indices first .. first + n - 1, the same
    for an index however the record is cut into blocks: a counter-based generator (Philox)
    advanced to the index, one counter step (four 64-bit words) per sample, by the inverse
    normal CDF of its first uniform."""
    from scipy.special import ndtri
    bits = np.random.Philox(key=seed)
    bits.advance(int(first))
    u = np.random.Generator(bits).random((n, 4))[:, 0]
    return ndtri(np.clip(u, 1e-300, 1.0))


def rotation_about_z(theta):
    half = 0.5 * np.asarray(theta, float)
    z = np.zeros_like(half)
    return attitude.from_wxyz(np.stack([np.cos(half), z, z, np.sin(half)], axis=-1))


class RotatingMotion(truth.Motion):
    """A vehicle motion seen by an IMU on a `Platform` (module doc): the sensor as the body."""

    def __init__(self, base, platform, t_end):
        self.base, self.platform = base, platform
        self.t0, self.t1 = base.t0, min(base.t1, t_end)
        self._rate = platform.angle_ppoly(t_end - base.t0)
        self._angle = self._rate.antiderivative()
        self._accel = self._rate.derivative()
        self.knots = np.union1d(np.asarray(base.knots, float), self._rate.x + base.t0)
        # the IMU's point at the start: the vehicle origin's position + C_nb r
        self.lat0, self.lon0, self.h0 = base.lat0, base.lon0, base.h0
        if np.any(platform.lever_arm_m):
            t0 = np.array([self.t0])
            d = attitude.rotate(base.kinematics(t0).q_nb, self._lever_arm(t0)[0])[0]
            self.lat0, self.lon0, self.h0 = (float(x) for x in earth.ned_offset_to_geodetic(
                d, base.lat0, base.lon0, base.h0))

    def _lever_arm(self, t):
        """(r, r', r'') of the IMU's point, vehicle axes (m, m/s, m/s^2; (N, 3) each)."""
        u = np.asarray(t, float) - self.t0
        rate, accel = self._rate(u)[:, 0, None], self._accel(u)[:, 0, None]
        q_bp = self.platform.q_bp0() * rotation_about_z(self.angle(t))
        r = attitude.rotate(q_bp, np.broadcast_to(np.asarray(self.platform.lever_arm_m, float),
                                                  (len(u), 3)))
        axis = attitude.rotate(self.platform.q_bp0(), np.array([0.0, 0.0, 1.0]))
        r_dot = rate * np.cross(axis, r)
        return r, r_dot, accel * np.cross(axis, r) + rate * np.cross(axis, r_dot)

    def angle(self, t):
        """Platform angle theta (rad) at times t (s)."""
        return self._angle(np.asarray(t, float) - self.t0)[..., 0]

    def rate(self, t):
        """Platform rate theta' (rad/s) at times t (s)."""
        return self._rate(np.asarray(t, float) - self.t0)[..., 0]

    def q_bs(self, t):
        p = self.platform
        return p.q_bp0() * rotation_about_z(self.angle(t)) * p.q_ps()

    def kinematics(self, t):
        t = np.asarray(t, float)
        kin = self.base.kinematics(t)
        u = t - self.t0
        rate, accel = self._rate(u)[:, 0], self._accel(u)[:, 0]
        q_bs = self.q_bs(t)
        q_sp = np.conjugate(self.platform.q_ps())
        e_z = np.zeros((len(t), 3))
        e_z[:, 2] = 1.0
        w_rel = attitude.rotate(q_sp, e_z * rate[:, None])       # C_sp theta' e_z
        w_b = attitude.rotate(np.conjugate(q_bs), kin.w_nb_b)      # C_sb w_nb^b
        dw_b = attitude.rotate(np.conjugate(q_bs), kin.dw_nb_b)
        v, a = kin.v_ned, kin.a_ned
        if np.any(self.platform.lever_arm_m):           # the IMU's own point (module doc)
            r, r_dot, r_ddot = self._lever_arm(t)
            w, dw = kin.w_nb_b, kin.dw_nb_b
            v = v + attitude.rotate(kin.q_nb, np.cross(w, r) + r_dot)
            a = a + attitude.rotate(kin.q_nb, np.cross(dw, r) + np.cross(w, np.cross(w, r))
                                    + 2 * np.cross(w, r_dot) + r_ddot)
        return truth.Kinematics(v, a, kin.q_nb * q_bs, w_b + w_rel,
                                dw_b - np.cross(w_rel, w_b) +
                                attitude.rotate(q_sp, e_z * accel[:, None]))


def vehicle_attitude(q_ns, q_bs):
    """q_nb = q_ns q_bs^-1 (quaternion arrays)."""
    return q_ns * np.conjugate(q_bs)


# the platform angle's circular grating: 1.58 arcsec (seed S4, Xu et al. 2011)
ENCODER_RESOLUTION_RAD = 1.58 * math.pi / 180 / 3600


def platform_metadata(platform):
    """The `platform` object of a log's `sensor/mimu` metadata (README: rotating MIMUs):
    what a replay needs to turn the navigated sensor attitude into the vehicle's."""
    return {"joint": "/mimu/platform (sensor_msgs/msg/JointState, joint 'platform': angle "
                     "rad, rate rad/s, about the platform z axis)",
            "base_attitude_wxyz": attitude.as_wxyz(platform.q_bp0()).tolist(),
            "imu_on_platform_wxyz": attitude.as_wxyz(platform.q_ps_nominal()).tolist(),
            "lever_arm_m": [float(x) for x in platform.lever_arm_m], "mode": platform.mode,
            "rate_rad_s": platform.rate_rad_s, "swing_rad": platform.swing_rad,
            "dwell_s": platform.dwell_s, "inclination_rad": platform.inclination_rad,
            "tilt_azimuth_rad": platform.tilt_azimuth_rad,
            "axis_tilt_rad": list(platform.axis_tilt_rad),
            "encoder_resolution_rad": platform.encoder_resolution_rad,
            "encoder_noise_rad": platform.encoder_noise_rad}


def q_bs_recorded(meta, angle):
    """q_bs for recorded platform angles (rad, (N,)) and the `platform` metadata."""
    return (attitude.from_wxyz(meta["base_attitude_wxyz"]) * rotation_about_z(angle)
            * attitude.from_wxyz(meta["imu_on_platform_wxyz"]))
