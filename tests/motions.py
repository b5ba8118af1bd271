"""Analytic true motions with closed-form kinematics, for tests against independent truth."""
import numpy as np
import quaternion

from mimunav.frames import attitude, earth
from mimunav.motion.truth import Kinematics, Motion


class Coning(Motion):
    """Classical coning at a fixed site: q_nb(t) = exp(alpha/2 * n(t)), n = (0, cos Wt, sin Wt).

    The body x axis traces a cone of half-angle alpha about north. The body rate is
    w = 2 conj(q) dq/dt, in closed form (differentiating q analytically)."""

    def __init__(self, alpha, omega, lat=np.radians(45.0), duration=10.0):
        self.alpha, self.omega = alpha, omega
        self.lat0, self.lon0, self.h0, self.t1 = lat, 0.3, 100.0, duration

    def _q(self, t):
        ca, sa = np.cos(self.alpha / 2), np.sin(self.alpha / 2)
        c, s = np.cos(self.omega * t), np.sin(self.omega * t)
        z = np.zeros_like(t)
        q = quaternion.from_float_array(np.stack([ca + z, z, sa * c, sa * s], -1))
        dq = quaternion.from_float_array(np.stack([z, z, -sa * self.omega * s,
                                                   sa * self.omega * c], -1))
        ddq = quaternion.from_float_array(np.stack([z, z, -sa * self.omega**2 * c,
                                                    -sa * self.omega**2 * s], -1))
        return q, dq, ddq

    def kinematics(self, t):
        t = np.asarray(t, dtype=float)
        q, dq, ddq = self._q(t)
        w = quaternion.as_vector_part(2 * np.conjugate(q) * dq)
        dw = quaternion.as_vector_part(2 * (np.conjugate(dq) * dq + np.conjugate(q) * ddq))
        zero = np.zeros((len(t), 3))
        return Kinematics(zero, zero, q, w, dw)


class Sculling(Motion):
    """Yaw oscillation psi = alpha sin(Wt) in phase with a north acceleration A sin(Wt).

    The rectified body specific force (f_y = -A sin(psi) sin(Wt)) is exactly undone by
    the attitude, so the true east velocity stays zero while an algorithm without
    sculling compensation drifts east."""

    def __init__(self, alpha, omega, accel, lat=np.radians(45.0), duration=10.0):
        self.alpha, self.omega, self.accel = alpha, omega, accel
        self.lat0, self.lon0, self.h0, self.t1 = lat, 0.3, 100.0, duration

    def kinematics(self, t):
        t = np.asarray(t, dtype=float)
        w_t = self.omega * t
        zero = np.zeros_like(t)
        v = np.stack([self.accel / self.omega * (1 - np.cos(w_t)), zero, zero], -1)
        a = np.stack([self.accel * np.sin(w_t), zero, zero], -1)
        q = attitude.from_euler(self.alpha * np.sin(w_t), zero, zero)
        w = np.stack([zero, zero, self.alpha * self.omega * np.cos(w_t)], -1)
        dw = np.stack([zero, zero, -self.alpha * self.omega**2 * np.sin(w_t)], -1)
        return Kinematics(v, a, q, w, dw)


class GreatCircle(Motion):
    """Level flight at constant ground speed along the equator (heading east) or a
    meridian (heading north): the great circles of the ellipsoid."""

    def __init__(self, speed, heading, h=1000.0, lat=0.0, duration=600.0):
        assert heading in ("north", "east")
        self.speed, self.heading = speed, heading
        self.lat0, self.lon0, self.h0, self.t1 = lat, 0.5, h, duration
        if heading == "east":
            assert lat == 0.0, "an east-bound great circle is the equator"

    def kinematics(self, t):
        t = np.asarray(t, dtype=float)
        n = len(t)
        v = np.zeros((n, 3))
        v[:, 0 if self.heading == "north" else 1] = self.speed
        yaw = np.full(n, 0.0 if self.heading == "north" else np.pi / 2)
        # flying a meridian/equator at constant speed, the vehicle keeps level and its
        # heading: it does not rotate relative to NED
        return Kinematics(v, np.zeros((n, 3)), attitude.from_euler(yaw, 0 * yaw, 0 * yaw),
                          np.zeros((n, 3)), np.zeros((n, 3)))

    def exact_position(self, t):
        """Closed-form position along the great circle (lat, lon rad, h m)."""
        from scipy.integrate import quad
        from scipy.optimize import brentq
        t = np.atleast_1d(t)
        if self.heading == "east":
            return (np.zeros_like(t), self.lon0 + self.speed * t / (earth.A + self.h0),
                    np.full_like(t, self.h0))

        def arc(lat):       # meridian arc length at height h from lat0
            return quad(lambda p: earth.radii(p)[0] + self.h0, self.lat0, lat,
                        epsabs=1e-9, epsrel=1e-13)[0]
        lat = np.array([brentq(lambda p: arc(p) - self.speed * tk, self.lat0 - 1e-6,
                               self.lat0 + 2 * self.speed * tk / earth.B + 1e-6, xtol=1e-15)
                        for tk in t])
        return lat, np.full_like(t, self.lon0), np.full_like(t, self.h0)


def pull_roll(roll_rate_deg_s, hold_s):
    """A 200 m/s vehicle heading 45 deg at 30 N: a 2 g pull-up by 10 deg, a full roll at
    roll_rate_deg_s, then hold_s of straight flight."""
    from mimunav.motion.profile import Profile
    return Profile.from_dict({"name": "pull-roll", "start": {
        "latitude_deg": 30.0, "longitude_deg": 104.0, "height_m": 1000.0, "speed_m_s": 200.0,
        "heading_deg": 45.0}, "segment": [
            {"kind": "pull", "load_factor": 2.0, "flight_path_change_deg": 10.0},
            {"kind": "roll", "rate_deg_s": roll_rate_deg_s, "angle_deg": 360.0},
            {"kind": "hold", "duration_s": hold_s}]})
