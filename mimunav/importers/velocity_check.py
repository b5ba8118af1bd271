"""A reference's motion checked against itself and the IMU.

Its velocity against its own positions: each NED axis of the velocity it gives
must match the same axis of its positions' central differences better than the same axis
negated (an up velocity read as down: a KITTI OXTS packet's `vu`), and its horizontal part
better than north and east swapped. Judged by the rms of the differences, not by
correlation: two slow trends (a descent while an aircraft slows eastward) correlate at 0.9
without being one motion. Where the positions' differencing noise hides an axis' motion,
the two readings differ little and the velocity is left as given.

Its acceleration against the IMU's: where the reference has an attitude, the IMU's
horizontal specific force in NED over 1 s must be the reference's horizontal acceleration
in size, within SCALE_LIMIT either way, where the two are one motion (coherence at least
COHERENT) - a unit of the positions (mm and m confused) reads a thousand times off.
"""
import math

import numpy as np

from ..motion.track import velocity_from_positions
from ..navigation.rests import G0, span_means
from ..navigation.travel import acceleration_match
from .recording import RecordingError

AXES = ("north", "east", "down")
BETTER = 0.5        # the other reading's rms difference at most this share of the given's
#                     decides: a sign error leaves twice the motion in the given reading's
#                     difference, and noise, which both readings share, pulls them together
MIN_EPOCHS = 20     # epochs with both finite, at least, for any decision
MIN_MOTION = 0.05   # m/s: an axis whose velocity differs from its positions' by under twice
#                     this is left as given (a still vehicle's both readings are zero; at
#                     this speed a sign makes 5 cm a second, below a GNSS fix's error)


def positions_velocity(ref):
    """(M, 3) m/s: the central differences of a reference's positions
    (`velocity_from_positions`), for this check, `checks.differenced` and
    `checks.velocity_lag_s` to share."""
    return velocity_from_positions(ref["ns"], ref["lat"], ref["lon"], ref["h"])


def misfits(ref):
    """{"given": (3,), "negated": (3,), "swapped": (2,)} rms (m/s) of the reference's
    velocity less its positions' central differences per NED axis - as given, each axis
    negated, and north and east swapped (the better of either sign) - over the epochs both
    hold; None with fewer than MIN_EPOCHS such epochs."""
    v = np.asarray(ref["v_ned"], float)
    v_pos = positions_velocity(ref)
    ok = np.isfinite(v).all(axis=1) & np.isfinite(v_pos).all(axis=1)
    if ok.sum() < MIN_EPOCHS:
        return None
    v, p = v[ok], v_pos[ok]

    def rms(x):
        return np.sqrt(np.mean(x ** 2, axis=0))
    swapped = np.minimum(rms(v[:, [1, 0]] - p[:, :2]), rms(v[:, [1, 0]] + p[:, :2]))
    return {"given": rms(v - p), "negated": rms(v + p), "swapped": swapped}


def check_velocity(rec):
    """Refuse (RecordingError) a reference whose velocity, on an axis, matches its positions
    negated (rms difference at most BETTER of the given's), or whose north and east match
    them swapped, naming the axes and the rms differences; an axis whose given difference is
    under 2 MIN_MOTION is not judged."""
    if rec.reference is None or rec.reference.get("v_ned") is None:
        return
    m = misfits(rec.reference)
    if m is None:
        return
    given, negated = m["given"], m["negated"]
    moved = given >= 2 * MIN_MOTION
    if np.all(moved[:2]) and np.all(m["swapped"] <= BETTER * given[:2]):
        raise RecordingError(
            f"{rec.name}: the reference's north and east velocities match its positions' "
            f"east and north motion (rms difference {m['swapped'].max():.2g} m/s; as given "
            f"{given[:2].min():.2g}): are they swapped (NED expected)?")
    for i, axis in enumerate(AXES):
        if moved[i] and negated[i] <= BETTER * given[i]:
            raise RecordingError(
                f"{rec.name}: the reference's {axis} velocity runs against its positions' "
                f"(rms difference from their central differences {given[i]:.2g} m/s, "
                f"{negated[i]:.2g} with its sign turned): "
                + ("is it an up velocity (a KITTI OXTS packet's vu) given as down?"
                   if axis == "down" else "is its sign the other way?"))


SCALE_LIMIT = 10.0  # the two sizes of one motion, either way: an IMU's specific force reads a
#                     track's acceleration at 0.8-1.25 (`travel.TRACK_FORCE_RATIO`) where the
#                     vehicle leans and the road cants; a unit's factor is 1000 (mm) or 100
COHERENT = 0.5      # coherence of the two, at least, for them to be compared at all
MOVING = 0.1        # m/s^2: the larger of the two's rms about its mean, at least (a steady
#                     drive's both are round-off, whose coherence means nothing)


STILL_LEAK = 0.5    # m/s^2: gravity's leak through an attitude 3 deg off, more than a
#                     reference's attitude errs (the IMU's f in NED of a still vehicle varies
#                     by that leak alone); a leg's IMU on a walk: 1.16, a hand's 0.2-1.0


STILL_FLOOR = 1e-6  # m/s^2 rms over 1 s: a reference held still, its velocity's rounding
#                     aside (a zero velocity differenced from positions reads 1e-8 m/s)


def check_acceleration_scale(rec, t, v_ned, f_ned):
    """Refuse (RecordingError) a reference whose horizontal acceleration over 1 s (from its
    velocity v_ned, m/s, at t - 0.5 and t + 0.5 s) is more than SCALE_LIMIT times the IMU's
    horizontal specific force (f_ned: (M, 3) m/s^2 in NED at the reference's epochs t, s,
    where its attitude holds; of the trajectory's point: the IMU's lever arm's force taken
    out), or less than 1/SCALE_LIMIT, where the two are coherent and
    one of them moves (MOVING); a reference that holds still (within STILL_FLOOR) where the
    IMU's horizontal specific force in NED varies beyond STILL_LEAK."""
    v = np.asarray(v_ned, float)
    inside = (t - 0.5 >= t[0]) & (t + 0.5 <= t[-1])
    a = np.column_stack([np.interp(t + 0.5, t, v[:, i]) - np.interp(t - 0.5, t, v[:, i])
                         for i in range(2)])
    f = span_means(f_ned[:, :2], np.searchsorted(t, t - 0.5), np.searchsorted(t, t + 0.5))
    ok = inside & np.isfinite(a).all(axis=1) & np.isfinite(f).all(axis=1)
    if ok.sum() < MIN_EPOCHS:
        return
    z_imu, z_track = f[ok, 0] + 1j * f[ok, 1], a[ok, 0] + 1j * a[ok, 1]
    spreads = [float(np.sqrt(np.mean(np.abs(z - z.mean()) ** 2))) for z in (z_imu, z_track)]
    if spreads[1] <= STILL_FLOOR and spreads[0] >= STILL_LEAK:
        raise RecordingError(
            f"{rec.name}: the reference holds still (its velocity the same at every epoch) "
            f"where the IMU's horizontal specific force, turned into NED by the reference's "
            f"attitude, varies by {spreads[0]:.3g} m/s^2 rms over 1 s - more than an attitude "
            f"{math.degrees(STILL_LEAK / G0):.0f} deg off leaks of gravity: its positions are "
            "not this motion's (a placeholder?). A reference of attitude alone is not read: "
            "leave the reference out to import the IMU alone")
    if max(spreads) < MOVING:
        return
    gain, coherence = acceleration_match(z_imu, z_track)
    if coherence >= COHERENT and not 1 / SCALE_LIMIT <= abs(gain) <= SCALE_LIMIT:
        raise RecordingError(
            f"{rec.name}: the reference's horizontal acceleration (from its velocity, over "
            f"1 s) is {1 / abs(gain):.3g} times the IMU's horizontal specific force in NED "
            f"(coherence {coherence:.2f}): are its positions in the unit given (mm and m "
            "confused: a factor of 1000)?")
