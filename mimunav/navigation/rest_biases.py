"""The biases an IMU's rest measures (T&W 2004, sec. 10.2.1): at standstill the specific
force is the reaction to gravity, f^b = C_bn (0, 0, -g), the rate the Earth's, C_bn w_ie^n.
The gyro bias is the mean rate less the Earth rate at the attitude known there. Of the
accelerometer bias, levelled on the IMU's own specific force, only the part along gravity
is observable (across it a bias reads as tilt: 1 mg as 0.057 deg); where the reference
carries the vehicle's attitude at the rest, its level gives the whole bias (a phone's 41 mg
across gravity had been left in every free-inertial window beside that attitude: 21 m at
10 s where levelling on its own gave 1.3 m).
"""
import math

import numpy as np

from ..frames import attitude, earth
from .attitude_biases import ATTITUDE_BIAS_WINDOW_S, biases_from_attitude
from .rests import (G0, MIN_STATIC_S, quiet_stretches, rate_mean_se, vertical_rate,
                    vertical_rate_said)

ACROSS_GRAVITY = ("the accelerometers' bias across gravity from the reference's level (a "
                  "mounting's tilt error reads as that bias, g per rad)")


def level(f_v):
    """(roll, pitch) rad of a vehicle at rest from its mean specific force f_v (m/s^2,
    vehicle FRD axes)."""
    fx, fy, fz = f_v
    return math.atan2(-fy, -fz), math.atan2(fx, math.hypot(fy, fz))


def reference_attitude(track, t0):
    """q_nb (wxyz) of the reference at its first epoch at or after t0 with a finite attitude,
    and that epoch (s); (None, None) when the reference carries no attitude."""
    q = track.get("q_nb")
    if q is None:
        return None, None
    ok = np.flatnonzero(np.isfinite(q).all(axis=1) & (track["t"] >= t0))
    if not len(ok):
        return None, None
    return np.asarray(q[ok[0]], float), float(track["t"][ok[0]])


def reference_level(track, t0, t1):
    """(roll, pitch rad, epochs) of the reference's mean level over its attitudes within
    [t0, t1] s - the mean of the up directions they give in the vehicle frame, C_bn (0, 0,
    -1) - or None without one there: one epoch's (an INS still converging, 0.3 deg of
    tilt: 5 mg of 'measured' bias) had been taken, an independent review."""
    q = track.get("q_nb")
    if q is None:
        return None
    k = np.flatnonzero(np.isfinite(q).all(axis=1) & (track["t"] >= t0) & (track["t"] <= t1))
    if not len(k):
        return None
    up = attitude.rotate(np.conjugate(attitude.from_wxyz(np.asarray(q[k], float))),
                         np.array([0.0, 0.0, -1.0])).mean(axis=0)
    roll, pitch = level(up)
    return roll, pitch, len(k)


def rest_biases(w, f, q_ns, lat, h, level_known=False):
    """Gyro bias (mean rate less the Earth rate in sensor axes, q_ns the sensor's attitude)
    and accelerometer bias of samples at rest: along gravity only ((|f| - g) f/|f|) where
    the level is the IMU's own - across gravity a bias reads as tilt -, whole (the mean f
    less C_sn (0, 0, -g)) where q_ns's level is known (`level_known`: the reference's
    attitude at the rest turned by the mounting given - a mounting's tilt error reads as
    that bias, g per rad, and is so taken out of the navigation beside that attitude)."""
    w_ie_s = attitude.rotate(np.conjugate(q_ns), earth.earth_rate_ned(lat))
    f_rest = f.mean(axis=0)
    g = float(earth.normal_gravity(lat, h))
    if level_known:
        return w.mean(axis=0) - w_ie_s, f_rest - attitude.rotate(np.conjugate(q_ns),
                                                                 np.array([0.0, 0.0, -g]))
    norm = np.linalg.norm(f_rest)
    return w.mean(axis=0) - w_ie_s, (norm - g) * f_rest / norm


def biases_at_a_rest(t, w, f, mounting, track, rests, quiet=None):
    """(gyro bias, accel bias, (t0, t1), note, bias_basis as `Alignment`'s) of the longest
    rest anywhere in the recording; zeros and (nan, nan) without one. The Earth rate is
    removed with the reference's attitude there when it has one and a true north; else only
    its vertical part (the level is known, the heading is not), leaving at most
    Omega cos(lat) = 7.3e-5 rad/s."""
    where = "the rest"
    if not rests:           # `quiet`: the IMU's quiet stretches when already found
        rests = quiet_stretches(t, w, f, track) if quiet is None else quiet
        where = "the IMU's quietest stretch (no reference rest; judged from the IMU alone)"
    none = f"no rest of {MIN_STATIC_S:g} s in the reference and no quiet stretch of " \
           f"{MIN_STATIC_S:g} s in the IMU"
    moving = biases_from_attitude(t, w, f, mounting, track) if rests else None
    if rests:               # a rest's gyro bias against the reference attitude's: the better
        t0, t1 = max(rests, key=lambda r: r[1] - r[0])
        se, scatter = rate_mean_se(t, w, t0, t1)
        if moving is not None and scatter > REST_SCATTER and \
                np.linalg.norm(moving[0][1]) < np.linalg.norm(se):
            rests = []
            none = (f"the rest {t0:.2f}-{t1:.2f} s measures the gyro bias less well than the "
                    "reference's attitude does: its 1 s means scatter "
                    f"{scatter:.1f} times what its samples' noise predicts - the IMU moves "
                    "there - (standard errors "
                    + ", ".join(f"{math.degrees(x) * 3600:.0f}" for x in se) + " deg/h)")
    if not rests:
        moving = biases_from_attitude(t, w, f, mounting, track) if moving is None else moving
        if moving is None:
            return (np.zeros(3), np.zeros(3), (math.nan, math.nan),
                    f"biases taken as 0: {none}", {"gyro": "none", "accel": "none"})
        gyro, accel, n = moving
        return (gyro[0], accel[0], (math.nan, math.nan),
                f"{none}: biases from the reference's attitude and velocity, the medians of "
                f"{n} {ATTITUDE_BIAS_WINDOW_S:g} s windows' differences (standard errors: gyro "
                + ", ".join(f"{math.degrees(x) * 3600:.0f}" for x in gyro[1])
                + " deg/h, accelerometer " + ", ".join(f"{x / G0 * 1e3:.2g}" for x in accel[1])
                + " mg; the reference's own errors and any time lag in it)"
                + ("" if track.get("heading_known", True) else
                   "; the Earth rate's horizontal part left in the gyro's: the reference's "
                   "frame has no known azimuth"),
                {"gyro": "reference_attitude" if track.get("heading_known", True) else
                 "vertical_earth_rate", "accel": "all"})
    t0, t1 = max(rests, key=lambda r: r[1] - r[0])
    k = (t >= t0) & (t <= t1)
    lat, h = (float(np.interp(0.5 * (t0 + t1), track["t"], track[x])) for x in ("lat", "h"))
    at_rest = reference_level(track, t0, t1)    # the reference's attitude at the rest (one
    # after it had removed the Earth rate at a heading the vehicle had turned from: 21
    # deg/h left after a 180 deg turn, an independent review)
    level_known = at_rest is not None
    true_north = level_known and track.get("heading_known", True)
    if level_known:
        roll, pitch, _ = at_rest
        yaw = attitude.as_euler(attitude.from_wxyz(reference_attitude(track, t0)[0]))[0]
        q_nb = attitude.from_euler(np.array(yaw), np.array(pitch), np.array(roll))
    else:
        roll, pitch = level(attitude.rotate(mounting.q_vs, f[k].mean(axis=0)))
        q_nb = attitude.from_euler(np.array(0.0), np.array(pitch), np.array(roll))
    note = "its Earth rate removed with the reference's attitude" if true_north else (
        "only the Earth rate's vertical part removed (heading unknown there: up to "
        f"{earth.OMEGA * math.cos(lat):.1e} rad/s of it remain)")
    if level_known:
        note += "; " + ACROSS_GRAVITY
    gyro_bias, accel_bias = rest_biases(w[k], f[k], q_nb * mounting.q_vs, lat, h, level_known)
    if not true_north:              # take the horizontal Earth rate back out of the removal
        gyro_bias = gyro_bias + horizontal_earth_rate(q_nb * mounting.q_vs, lat)
    basis = {"gyro": "reference_attitude" if true_north else "vertical_earth_rate",
             "accel": "all" if level_known else "along_gravity",
             "gravity_sensor_axes": up_at_rest(f[k])}
    return (gyro_bias, accel_bias, (t0, t1),
            f"biases from {where} {t0:.2f}-{t1:.2f} s "
            f"({note}{vertical_note(track, t, w, f, t0, t1)})", basis)


def vertical_note(track, t, w, f, t0, t1):
    """'' or what a rest [t0, t1] s says of the IMU's mean rate about its down (rad/s, from
    samples w, f at stamps t s) where it reaches `rests.QUIET_RATE`: a turn, where the
    reference's heading over the rest turns (`heading_turn`) by more than a quarter of what
    that rate turns - the gyro's bias about the vertical then not measured there, and where
    the IMU reads under half the turn's rate, the two said to disagree (an AHRS's heading
    settling by 3.5 deg at a rest had been called the IMU's -0.01 deg/s); '' where it turns
    less (a bias); else `rests.vertical_rate_said` (the IMU alone cannot tell)."""
    k = (t >= t0) & (t <= t1)
    along = vertical_rate(w[k], f[k])[2]
    turn = heading_turn(track, t0, t1)
    if turn is None:
        return vertical_rate_said(t, w, f, t0, t1)
    turned, span = turn
    if abs(turned) < 0.25 * abs(along) * span:
        return ""
    said = (f"; the reference's heading turns {math.degrees(turned):+.1f} deg over the rest "
            f"({math.degrees(turned) / span:+.2f} deg/s)")
    if abs(along - turned / span) <= 0.5 * abs(turned / span):
        return (f"{said}: the IMU's {math.degrees(along):+.2f} deg/s about the vertical is "
                "that turn's, and the gyro's bias about the vertical is not measured here")
    return (f"{said} where the IMU reads {math.degrees(along):+.2f} deg/s about the vertical: "
            "the reference's heading drifts (an AHRS settling?) or the gyro misses the turn - "
            "the gyro bias's part about the vertical is not confirmed here")


def heading_turn(track, t0, t1):
    """(the reference's heading turn over [t0, t1] s, rad - its epoch-to-epoch changes
    unwrapped: a turntable's 300 deg had read -60 -, the span it covers, s), or None where its
    attitude covers under half of [t0, t1]."""
    q = track.get("q_nb")
    if q is None:
        return None
    inside = np.flatnonzero(np.isfinite(q).all(axis=1) & (track["t"] >= t0) &
                            (track["t"] <= t1))
    if len(inside) < 2:
        return None
    e0, e1 = (float(track["t"][j]) for j in inside[[0, -1]])
    if e1 - e0 < 0.5 * (t1 - t0):       # the reference covers half the rest at least
        return None
    yaw = np.unwrap(attitude.as_euler(attitude.from_wxyz(np.asarray(q[inside], float)))[0])
    return float(yaw[-1] - yaw[0]), e1 - e0


REST_SCATTER = 2.0      # a rest is given up for the reference's attitude only where its 1 s
#   means scatter more than twice what its samples' noise predicts (it moves: the moored
#   hull's tens); a still rest is kept - the attitude's standard error counts its noise
#   only, not the gyro's scale times a drive's mean turn (an independent review: a still
#   30 s stop given up for a loop's attitude had left 134 deg/h on z, the rest 4)


def horizontal_earth_rate(q_ns, lat):
    """The Earth rate's horizontal part in sensor axes (rad/s) at the attitude q_ns: what a
    removal at an unmeasured heading must put back (up to Omega cos(lat) = 7.3e-5 rad/s)."""
    w_n = earth.earth_rate_ned(lat)
    return attitude.rotate(np.conjugate(q_ns), np.array([w_n[0], w_n[1], 0.0]))


def up_at_rest(f):
    """The up direction in sensor axes of specific forces f (m/s^2) at a rest: their mean's."""
    mean = f.mean(axis=0)
    return [float(x) for x in mean / np.linalg.norm(mean)]
