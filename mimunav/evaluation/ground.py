"""A ground start: both IMUs navigated from the reference FOG-IMU's own alignment on the pad
instead of the exact state.

The FOG-IMU gyrocompasses over the flight's first ALIGN_S seconds at rest
(`navigation.gyrocompass`): level from its mean specific force, heading from the Earth's rate
its gyros see. The MIMU cannot (its zero drift, seed S1 Table 1: 30 deg/h, is twice the
Earth's rate), so it is given the same initial attitude - the reading of the seed's "the same
quaternion strapdown algorithm" for both (section 4.2) taken here: one initial state, the
reference's, whose error both IMUs then carry. Position and velocity are the pad's (known;
zero velocity at rest).
"""
import math
from dataclasses import replace

import numpy as np
import quaternion

from ..errors import InputError
from ..frames import attitude, earth
from ..motion.trajectory import State
from ..navigation.gyrocompass import gyrocompass
from ..navigation.rests import STATIC_SPEED

ALIGN_S = 120.0             # s of the pad hold the FOG-IMU gyrocompasses over: a FOG INS's
                            # coarse alignment takes 1-5 min (datasheet class; assumed)
RATE_TOLERANCE = 0.5        # x the Earth's rate: the FOG's mean rate must lie within it of
                            # the Earth's rate - beyond, a sway or bias this large turns the
                            # heading by tens of degrees (error eps / (W cos L)), no alignment


def begins_at_rest(profile, align_s=ALIGN_S):
    """Refuse (InputError) a profile (`motion.profile.Profile`) that does not begin at rest
    with a hold of at least align_s s - before any work (`ground_start` checks the flown
    data again)."""
    first = profile.segments[0]
    if profile.start["speed"] == 0.0 and first["kind"] == "hold" and \
            float(first["duration_s"]) >= align_s:
        return
    raise _moving(profile.name, align_s, f"{profile.start['speed']:g} m/s at its start")


def _moving(name, align_s, speed):
    return InputError(f"flight {name}: a ground start aligns on the pad over the flight's first "
                      f"{align_s:g} s, and this flight moves there ({speed}): a profile that "
                      f"begins at rest with a hold of at least {align_s:g} s (the shipped "
                      "flights/boost-coast.toml, flights/ground-gentle.toml), or the air start "
                      "(--start air)")


def ground_start(flight, align_s=ALIGN_S):
    """(`flight` with its initial state from the FOG-IMU's gyrocompass over its first
    `align_s` s, what the alignment did: {"align_s", "t", "heading_error_deg",
    "level_error_deg"} against the truth). The flight must begin at rest for that long -
    checked on its truth (speed at most `rests.STATIC_SPEED` m/s) and on the FOG's own rate
    (within RATE_TOLERANCE of the Earth's) - else InputError."""
    if flight.truth is None or flight.fog_t is None:
        raise InputError(f"flight {flight.name or flight.path}: a ground start needs the "
                         "reference IMU and the truth")
    tr = flight.truth
    t_end = float(flight.fog_t[0] + align_s)
    pad = tr.t <= t_end
    speed = np.linalg.norm(tr.v_ned[pad], axis=1).max() if pad.any() else math.inf
    if tr.t[-1] < t_end or not speed <= STATIC_SPEED:
        raise _moving(flight.name or flight.path, align_s, f"speed up to {speed:.3g} m/s")
    k = (flight.fog_t > flight.fog_t[0]) & (flight.fog_t <= t_end)
    w_v = attitude.rotate(flight.fog_mounting.q_vs, flight.fog_w[k].mean(axis=0))
    f_v = attitude.rotate(flight.fog_mounting.q_vs, flight.fog_f[k].mean(axis=0))
    end = int(np.searchsorted(tr.t, t_end))
    truth = tr.state(min(end, len(tr.t) - 1))
    if abs(np.linalg.norm(w_v) - earth.OMEGA) > RATE_TOLERANCE * earth.OMEGA:
        raise InputError(f"flight {flight.name or flight.path}: the FOG-IMU's mean rate on "
                         "the pad is "
                         f"{math.degrees(np.linalg.norm(w_v)) * 3600:.3g} deg/h against the "
                         f"Earth's {math.degrees(earth.OMEGA) * 3600:.3g}: it does not stand "
                         "still enough to gyrocompass")
    q_nb = gyrocompass(w_v, f_v, truth.lat, truth.h)
    initial = State(truth.t, truth.lat, truth.lon, truth.h, np.array(truth.v_ned), q_nb)
    aligned = replace(flight, initial=initial)
    return aligned, dict(alignment_error(aligned), align_s=align_s)


def alignment_error(flight):
    """{"t", "heading_error_deg", "level_error_deg"}: the flight's initial attitude against
    its truth at that instant (the error both IMUs start with; NED, the rotation from the
    truth's attitude to the initial one)."""
    tr = flight.truth
    k = min(int(np.searchsorted(tr.t, flight.initial.t - 1e-9)), len(tr.t) - 1)
    turn = flight.initial.q_nb * tr.state(k).q_nb.conjugate()
    error = quaternion.as_rotation_vector(-turn if turn.w < 0 else turn)     # rad
    return {"t": flight.initial.t, "heading_error_deg": float(np.degrees(error[2])),
            "level_error_deg": float(np.degrees(np.hypot(error[0], error[1])))}
