"""The motion of a land vehicle from a GNSS track, as a `truth.Motion`, so that the same exact
increment generator that simulates flights simulates the ideal IMU of a recorded drive.

A GNSS track gives position and velocity but no attitude; a car's attitude follows from
its velocity under two assumptions, stated wherever the result is used:
  - non-holonomic: the car moves along its forward axis (no side slip, no reversing), so
    yaw = atan2(v_E, v_N) and pitch = atan2(-v_D, v_H), v_H the horizontal speed;
  - roll = 0: the body does not bank (road camber and body roll on the springs are
    unknown; a car rolls a few degrees per g of lateral acceleration).
Below HOLD_SPEED the course is noise: yaw and pitch hold their last value (the first
moving one for a rest that starts the track) and the rates are zero. Velocity and its
derivative come from a smoothing spline per NED component (scipy `make_smoothing_spline`,
smoothing chosen by generalised cross-validation). The rates follow analytically:
    yaw' = (v_N a_E - v_E a_N) / v_H^2,   pitch' = (v_D v_H' - a_D v_H) / (v_H^2 + v_D^2),
    w_nb^b = (-yaw' sin(pitch), pitch', yaw' cos(pitch))      (roll = 0, T&W eq. 3.19)
and their derivatives from the spline's second derivative (jerk) in the same way.
"""
import numpy as np
from scipy.interpolate import make_smoothing_spline

from . import attitude
from .truth import Kinematics, Motion
from .errors import InputError

HOLD_SPEED = 0.5            # m/s: below it the attitude holds and the rates are zero
TRUSTED_SPEED = 2.0         # m/s: above it (or at rest) the attitude model is taken as valid
REST_SPEED = 0.05           # m/s: at rest


class TrackMotion(Motion):
    """Land-vehicle motion through the GNSS track (t s, lat, lon rad, h m, v_ned m/s)."""

    def __init__(self, t, lat, lon, h, v_ned):
        t = np.asarray(t, float)
        self.t0, self.t1 = float(t[0]), float(t[-1])
        self.lat0, self.lon0, self.h0 = float(lat[0]), float(lon[0]), float(h[0])
        self._v = [make_smoothing_spline(t, v_ned[:, i]) for i in range(3)]
        self._a = [s.derivative() for s in self._v]
        self._j = [s.derivative(2) for s in self._v]
        v = self._velocity(t)
        yaw, pitch = _yaw_pitch(v)
        moving = np.hypot(v[:, 0], v[:, 1]) >= HOLD_SPEED
        if not moving.any():
            raise InputError(f"the reference never moves faster than {HOLD_SPEED:g} m/s "
                             f"horizontally in its smoothed velocity (peak "
                             f"{np.hypot(v[:, 0], v[:, 1]).max():.2g} m/s; recorded "
                             f"{np.nanmax(np.hypot(v_ned[:, 0], v_ned[:, 1])):.2g}): the track level "
                             "models a land vehicle whose attitude follows its course, so it "
                             "does not apply here (it does not read a reference's own attitude)")
        first = np.argmax(moving)
        last = np.maximum.accumulate(np.where(moving, np.arange(len(t)), first))
        self._t, self._yaw_hold, self._pitch_hold = t, yaw[last], pitch[last]

    def _velocity(self, t):
        return np.column_stack([s(t) for s in self._v])

    def speed(self, t):
        """|v| (m/s) of the smoothed track at times t (s)."""
        return np.linalg.norm(self._velocity(np.asarray(t, float)), axis=1)

    def trusted(self, t):
        """True where the attitude model holds: at rest or faster than TRUSTED_SPEED."""
        s = self.speed(t)
        return (s < REST_SPEED) | (s > TRUSTED_SPEED)

    def kinematics(self, t):
        t = np.asarray(t, float)
        v = self._velocity(t)
        a = np.column_stack([s(t) for s in self._a])
        j = np.column_stack([s(t) for s in self._j])
        yaw, pitch = _yaw_pitch(v)
        vh2 = v[:, 0] ** 2 + v[:, 1] ** 2
        vh = np.sqrt(vh2)
        moving = vh >= HOLD_SPEED
        with np.errstate(invalid="ignore", divide="ignore"):
            yaw_dot = (v[:, 0] * a[:, 1] - v[:, 1] * a[:, 0]) / vh2
            yaw_ddot = (v[:, 0] * j[:, 1] - v[:, 1] * j[:, 0]) / vh2 \
                - 2 * yaw_dot * (v[:, 0] * a[:, 0] + v[:, 1] * a[:, 1]) / vh2
            vh_dot = (v[:, 0] * a[:, 0] + v[:, 1] * a[:, 1]) / vh
            vh_ddot = (a[:, 0] ** 2 + a[:, 1] ** 2 + v[:, 0] * j[:, 0] + v[:, 1] * j[:, 1]) / vh \
                - vh_dot ** 2 / vh
            den = vh2 + v[:, 2] ** 2
            pitch_dot = (v[:, 2] * vh_dot - a[:, 2] * vh) / den
            pitch_ddot = (v[:, 2] * vh_ddot - j[:, 2] * vh
                          - 2 * pitch_dot * (vh * vh_dot + v[:, 2] * a[:, 2])) / den
        k = np.clip(np.searchsorted(self._t, t, side="right") - 1, 0, len(self._t) - 1)
        yaw = np.where(moving, yaw, self._yaw_hold[k])
        pitch = np.where(moving, pitch, self._pitch_hold[k])
        yd, pd, ydd, pdd = (np.where(moving, x, 0.0)
                            for x in (yaw_dot, pitch_dot, yaw_ddot, pitch_ddot))
        s_p, c_p = np.sin(pitch), np.cos(pitch)
        w = np.column_stack([-yd * s_p, pd, yd * c_p])
        dw = np.column_stack([-ydd * s_p - yd * pd * c_p, pdd, ydd * c_p - yd * pd * s_p])
        q = attitude.from_euler(yaw, pitch, np.zeros_like(yaw))
        return Kinematics(v, a, q, w, dw)


def _yaw_pitch(v):
    return np.arctan2(v[:, 1], v[:, 0]), np.arctan2(-v[:, 2], np.hypot(v[:, 0], v[:, 1]))
