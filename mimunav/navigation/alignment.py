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
from dataclasses import dataclass, field

import numpy as np
import quaternion
from scipy.spatial.transform import Rotation

from ..frames import attitude, earth
from ..errors import InputError
from .rests import (G0, MIN_STATIC_S, felt_at_rest, rate_mean_se, QUIET_WINDOW_S, STATIC_MARGIN_S, STATIC_SPEED, track_still,
                    means_around, quiet_stretches, rest_intervals, travel_sign, velocity_noise,
                    yaw_turned)


COURSE_SPEED = 3.0          # m/s: horizontal speed from which the GNSS course gives heading
                            # weave: 0.2; IMU noise in 1 s means: ~0.01)
MOVING_HALF_WINDOW_MAX_S = 5.0  # s: the longest (the gyro's bias turns the increment by
                                # b x 5 s: 0.1 deg for 0.02 deg/s left after the rest)
MOVING_ACCEL_ERROR = 0.02       # m/s^2: the interval's acceleration error aimed at (0.1 deg)
MOVING_HALF_WINDOW_S = 0.25     # s: half the interval of the moving two-vector alignment
COURSE_SPAN_S = 5.0         # s of fast epochs whose courses give the heading at a rest's end


@dataclass
class Alignment:
    """An initial state (contract `initial_state` in SI: t s, rad, m, m/s, q_nb wxyz) and
    what the alignment learnt: the gyro bias (rad/s, sensor axes) and the accelerometer bias
    (m/s^2, sensor axes: its part along gravity at a rest, whole from a reference's attitude
    and velocity) of the rest `static` (t0, t1) s they came from ((nan, nan): no rest - the
    biases from the reference's attitude and velocity when it has them, else 0),
    `at_rest_start` (the state is that of a rest that starts the recording), `method`
    (how each part was obtained, for the log's metadata), and where the heading came from
    (`heading`: "reference" - its own attitude; "course" - the GNSS course, a vehicle that
    moves along its forward axis, true of a car, not of a walker's phone or a multicopter;
    "assumed" - nothing measured it, 0), where the attitude came from (`attitude_from`:
    "reference" - taken whole from it; "leveled" - from the IMU's own specific force, a rest's
    or a moving alignment's), and what the biases measured (`bias_basis`: gyro
    "reference_attitude" (the Earth rate removed with the reference's attitude), "course" (at
    the course's heading), "vertical_earth_rate" (its horizontal part, up to Omega cos(lat),
    left in), "assumed" (removed at a heading and latitude assumed) or "none" (taken as 0);
    accel "all" (from the reference's attitude and velocity), "along_gravity" (a rest's:
    the part along gravity only, `gravity_sensor_axes` its up in sensor axes) or "none")."""
    t: float
    lat: float
    lon: float
    h: float
    v_ned: np.ndarray
    q_nb: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    static: tuple
    method: str
    at_rest_start: bool = True
    heading: str = "assumed"
    attitude_from: str = "leveled"
    bias_basis: dict = field(default_factory=lambda: {"gyro": "none", "accel": "none"})

    @property
    def navigable_from(self):
        """First instant (s) after the rest the biases came from, when that rest starts the
        recording; else the initial state's time."""
        return self.static[1] if self.at_rest_start else self.t


def unwrapped_longitude(lon):
    """Longitudes (rad) made continuous across the antimeridian (a track written in
    (-pi, pi] jumps 2 pi there), for interpolation; a NaN stays a NaN of its own sample."""
    lon = np.array(lon, dtype=float)
    ok = np.isfinite(lon)
    lon[ok] = np.unwrap(lon[ok])
    return lon


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


def initial_alignment(t, w, f, mounting, track=None):
    """Initial state of a recording: t s, w rad/s, f m/s^2 (sensor axes), `track` the
    reference {t s, lat, lon rad, h m, v_ned m/s, optional q_nb wxyz of the vehicle (NaN rows:
    unknown), heading_known (False: its north is no true north)}. In order of preference:

    1. a rest that starts the recording (MIN_STATIC_S or more): level from its mean specific
       force, heading from the reference's attitude once moving, turned back by the gyro
       (else the course less the gyro's yaw since), state at the first IMU stamp;
    2. the reference's own attitude at its first epoch with one (an autopilot's estimate,
       a fused pose): the whole state from the reference;
    3. moving: the two-vector alignment (`moving_attitude`) at the first reference epoch
       faster than COURSE_SPEED.
    The biases come from the rest of case 1, else from the longest rest anywhere (with the
    Earth rate removed as far as the attitude there is known), else are 0. Without a track
    a rest of MIN_STATIC_S at the start is assumed and position and heading are 0. When no
    case applies, an InputError says what the recording lacks."""
    if track is None or len(track["t"]) < 2:
        return _untracked(t, w, f, mounting)
    rests, not_rests = felt_at_rest(t, w, f, rest_intervals(track["t"], track["v_ned"],
                                                            float(t[0]), float(t[-1])))
    if rests and rests[0][0] <= t[0]:
        return _from_rest(t, w, f, mounting, track, rests[0])
    # a noisy fix's differenced speed can hide a rest the IMU and the fix's positions show
    quiet = quiet_stretches(t, w, f, track)
    if quiet and quiet[0][0] <= t[0] + QUIET_WINDOW_S:
        q0, q1 = quiet[0][0], quiet[0][1] - STATIC_MARGIN_S       # the car starts to roll
        covered = (min(q1, track["t"][-1]) - max(q0, track["t"][0])) / max(q1 - q0, 1e-9)
        if q1 - q0 >= MIN_STATIC_S and covered >= 0.8 and track_still(track, q0, q1):
            align = _from_rest(t, w, f, mounting, track, (q0, q1), still_until=quiet[0][1])
            align.method = (f"a rest {q0:.2f}-{q1:.2f} s judged from the IMU and the "
                            "reference's positions (its velocity's 1 s means do not show "
                            "it: too noisy, or a vertical differenced from noisy heights); "
                            + align.method)
            return align
    notes = [f"no rest of {MIN_STATIC_S:g} s starts the recording"] + \
        [why for _, _, why in not_rests]
    q_ref, t_ref = reference_attitude(track, float(t[0]))
    half = moving_half_window(track)
    speed = mean_speed(track, half)
    parked = np.zeros(len(track["t"]), bool)      # a noisy fix "fast" while the car stands
    for a, b in quiet:
        parked |= (track["t"] > a - half) & (track["t"] < b + half)
    inside = (track["t"] >= max(t[0], track["t"][0]) + half) & \
        (track["t"] <= min(t[-1], track["t"][-1]) - half)     # IMU and reference cover it
    fast = np.flatnonzero((speed >= COURSE_SPEED) & ~parked & inside)
    gyro_bias, accel_bias, static, bias_note, basis = biases_at_a_rest(t, w, f, mounting, track,
                                                                        rests, quiet)
    if q_ref is not None:
        t0, q_nb = t_ref, q_ref
        notes.append(f"whole state from the reference at t = {t0:.2f} s (its attitude: "
                     f"{track.get('attitude_source', 'the reference')})")
    elif len(fast):
        t0 = float(track["t"][fast[0]])
        q_nb = moving_attitude(t, w - gyro_bias, f - accel_bias, mounting, track, t0, half)
        notes.append(f"moving alignment at t = {t0:.2f} s ({speed[fast[0]]:.1f} m/s): the "
                     f"IMU's velocity increment over {2 * half:.1f} s (turned by its gyro) "
                     "matched to the reference's, forward axis to its velocity")
    else:
        raise _no_initial_state(t, track, speed, inside, half)
    lat, lon, h = (float(np.interp(t0, track["t"], x)) for x in (
        track["lat"], unwrapped_longitude(track["lon"]), track["h"]))
    v0 = np.array([np.interp(t0, track["t"], track["v_ned"][:, i]) for i in range(3)])
    notes.append(bias_note)
    return Alignment(t0, lat, lon, h, v0, q_nb, gyro_bias, accel_bias, static,
                     "; ".join(notes), at_rest_start=False,
                     heading="reference" if q_ref is not None else "course",
                     attitude_from="reference" if q_ref is not None else "leveled",
                     bias_basis=basis)


def _no_initial_state(t, track, speed, inside, half):
    """The InputError of a recording without a rest at its start, a reference attitude or a
    fast epoch for a moving alignment: what it lacks, in numbers."""
    moving = (speed >= COURSE_SPEED) & inside
    what = track.get("what", "the reference")
    return InputError(
        f"no initial state can be found from {what}: it carries no attitude, the "
        f"recording does not start with a rest of {MIN_STATIC_S:g} s (its speed <= "
        f"{STATIC_SPEED:g} m/s), and " + (
            f"its epochs faster than {COURSE_SPEED:g} m/s all lie in stretches the IMU "
            "and its positions show at rest (a noisy fix's speed)"
            if moving.any() else
            f"where {half:g} s of IMU and it lie on both sides its speed peaks at "
            f"{speed[inside].max():.2f} m/s, below {COURSE_SPEED:g} m/s (over all of "
            f"it: {speed.max():.2f} m/s)" if inside.any() else
            f"none of its epochs has {half:g} s of IMU and of it on both sides (the "
            f"IMU's record is {t[-1] - t[0]:.2f} s, its "
            f"{track['t'][-1] - track['t'][0]:.2f} s): too short") +
        " for a moving alignment")


def _untracked(t, w, f, mounting):
    """No reference: a rest of MIN_STATIC_S assumed at the start, position and heading 0."""
    t_end = t[0] + MIN_STATIC_S
    rest = t <= t_end
    if rest.sum() < 10:
        raise InputError(f"fewer than 10 IMU samples in the first {MIN_STATIC_S:g} s: no level")
    roll, pitch = level(attitude.rotate(mounting.q_vs, f[rest].mean(axis=0)))
    q_nb = attitude.from_euler(np.array(0.0), np.array(pitch), np.array(roll))
    w_ie_s = attitude.rotate(np.conjugate(q_nb * mounting.q_vs), earth.earth_rate_ned(0.0))
    return Alignment(float(t[0]), 0.0, 0.0, 0.0, np.zeros(3), attitude.as_wxyz(q_nb),
                     w[rest].mean(axis=0) - w_ie_s, np.zeros(3), (float(t[0]), float(t_end)),
                     f"rest assumed for the first {MIN_STATIC_S:g} s (no GNSS track); level "
                     "from its mean specific force; position and heading assumed 0",
                     bias_basis={"gyro": "assumed", "accel": "none"})


def _from_rest(t, w, f, mounting, track, interval, still_until=-math.inf):
    """Case 1 of `initial_alignment`: the rest `interval` (t0, t1) starts the recording; the
    IMU held still until `still_until` (s), so no course before it is the vehicle's (a
    noisy fix's 'fast' epoch 1 s after the rest's margin, while the IMU still stood, had
    turned the heading 3 deg)."""
    q_vs = mounting.q_vs
    t_end = interval[1]
    rest = (t >= t[0]) & (t <= t_end)
    if rest.sum() < 10:
        raise InputError(f"fewer than 10 IMU samples in the rest {t[0]:.2f}-{t_end:.2f} s")
    roll, pitch = level(attitude.rotate(q_vs, f[rest].mean(axis=0)))
    notes = [f"level from the mean specific force over the rest {t[0]:.2f}-{t_end:.2f} s"]
    lat, lon, h = (float(np.interp(t[0], track["t"], x)) for x in (
        track["lat"], unwrapped_longitude(track["lon"]), track["h"]))
    speed = mean_speed(track, moving_half_window(track))
    fast = np.flatnonzero((speed >= COURSE_SPEED) & (track["t"] > max(t_end, still_until)))
    q_ref, t_ref = reference_attitude(track, float(t[0]))
    w_v = attitude.rotate(q_vs, w - w[rest].mean(axis=0))
    k = fast[track["t"][fast] <= track["t"][fast[0]] + COURSE_SPAN_S] if len(fast) else fast
    back = _reference_heading_back(t, w_v, t_end, track, k)
    if back is not None:
        yaw, i = back
        heading = "reference"
        notes.append(f"heading from the reference's attitude at t = {track['t'][i]:.2f} s, "
                     f"moving ({speed[i]:.1f} m/s), turned back to the rest by the gyro")
    elif len(fast):
        # each fast epoch of the first COURSE_SPAN_S gives the heading at rest (its course
        # less the gyro's yaw since): their circular mean weighted by speed^2, so one noisy
        # course (a plain fix's differenced velocity, ~1 m/s of noise) does not set it
        course = np.arctan2(track["v_ned"][k, 1], track["v_ned"][k, 0])
        if travel_sign(t, f, mounting, track, float(track["t"][k[0]])) < 0:
            course = course + math.pi               # it drives off in reverse
            notes.append("reversing (the horizontal specific force opposes the track's "
                         "acceleration)")
        at_rest = course - np.array([yaw_turned(t, w_v, t_end, float(x))
                                     for x in track["t"][k]])
        weight = speed[k] ** 2          # a course's noise falls as the speed rises
        yaw = math.atan2(np.sum(weight * np.sin(at_rest)), np.sum(weight * np.cos(at_rest)))
        heading = "course"
        notes.append(f"heading from the GNSS course over {len(k)} epoch(s) from t = "
                     f"{track['t'][k[0]]:.2f} s ({speed[k[0]]:.1f} m/s) less the gyro's yaw "
                     "since the rest (non-holonomic: no side slip)")
    elif q_ref is not None:
        yaw = float(attitude.as_euler(attitude.from_wxyz(q_ref))[0])
        heading = "reference"
        notes.append(f"heading from the reference's attitude at t = {t_ref:.2f} s")
    else:
        yaw, heading = 0.0, "assumed"
        notes.append(f"heading assumed 0 (the track never exceeds {COURSE_SPEED:g} m/s and "
                     "carries no attitude)")
    q_nb = attitude.from_euler(np.array(yaw), np.array(pitch), np.array(roll))
    gyro_bias, accel_bias = _rest_biases(w[rest], f[rest], q_nb * q_vs, lat, h)
    true_north = heading != "assumed" and track.get("heading_known", True)
    if not true_north:              # no true heading: the Earth rate's vertical part only
        gyro_bias = gyro_bias + _horizontal_earth_rate(q_nb * q_vs, lat)
        notes.append("only the Earth rate's vertical part removed from the gyro bias (up to "
                     f"{earth.OMEGA * math.cos(lat):.1e} rad/s of it remain: "
                     + ("no heading)" if heading == "assumed" else
                        "the reference's frame has no known azimuth)"))
    basis = {"gyro": {"reference": "reference_attitude", "course": "course"}.get(
                 heading, "vertical_earth_rate") if true_north else "vertical_earth_rate",
             "accel": "along_gravity", "gravity_sensor_axes": _up(f[rest])}
    return Alignment(float(t[0]), lat, lon, h, np.zeros(3), attitude.as_wxyz(q_nb),
                     gyro_bias, accel_bias, (float(t[0]), float(t_end)), "; ".join(notes),
                     heading=heading, bias_basis=basis)


def _reference_heading_back(t, w_v, t_end, track, k):
    """(yaw rad, the epoch's index in the track) at a rest's end t_end from the reference's
    attitude at the first of its moving epochs k that carries one - where an INS's heading has converged, which at
    rest it may not have - turned back by the gyro's rotation since the rest (vehicle-axis
    rates w_v rad/s at stamps t, the rest's mean removed): q_nb(t_end) = q_nb(t_k) dq^-1,
    dq the body's turn over (t_end, t_k]. Exact for any motion, where a course needs a car
    (no side slip). None when the reference carries no attitude there."""
    q = track.get("q_nb")
    if q is None or not len(k):
        return None
    k = k[np.isfinite(q[k]).all(axis=1)]
    if not len(k):
        return None
    t_k = float(track["t"][k[0]])
    # each sample is the mean rate over the interval its stamp ends: each over its part of
    # (t_end, t_k] (whole intervals only had left up to the rate times a step: 0.1 deg at
    # 100 Hz turning 20 deg/s)
    j = np.arange(np.searchsorted(t, t_end, side="right"),
                  min(np.searchsorted(t, t_k, side="left") + 1, len(t)))
    dt = np.clip(np.minimum(t[j], t_k) - np.maximum(t[np.maximum(j - 1, 0)], t_end), 0.0, None)
    dq = np.multiply.reduce(quaternion.from_rotation_vector(w_v[j] * dt[:, None])) \
        if len(j) else quaternion.one
    q_rest = attitude.from_wxyz(np.asarray(q[k[0]], float)) * np.conjugate(dq)
    return float(attitude.as_euler(q_rest)[0]), int(k[0])


def _rest_biases(w, f, q_ns, lat, h):
    """Gyro bias (mean rate less the Earth rate in sensor axes, q_ns the sensor's attitude)
    and the accelerometer bias along gravity ((|f| - g) f/|f|) of samples at rest."""
    w_ie_s = attitude.rotate(np.conjugate(q_ns), earth.earth_rate_ned(lat))
    f_rest = f.mean(axis=0)
    norm = np.linalg.norm(f_rest)
    return (w.mean(axis=0) - w_ie_s,
            (norm - float(earth.normal_gravity(lat, h))) * f_rest / norm)


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
    q_ref, _ = reference_attitude(track, t0)
    true_north = q_ref is not None and track.get("heading_known", True)
    if q_ref is not None:
        q_nb = attitude.from_wxyz(q_ref)
    else:
        roll, pitch = level(attitude.rotate(mounting.q_vs, f[k].mean(axis=0)))
        q_nb = attitude.from_euler(np.array(0.0), np.array(pitch), np.array(roll))
    note = "its Earth rate removed with the reference's attitude" if true_north else (
        "only the Earth rate's vertical part removed (heading unknown there: up to "
        f"{earth.OMEGA * math.cos(lat):.1e} rad/s of it remain)")
    gyro_bias, accel_bias = _rest_biases(w[k], f[k], q_nb * mounting.q_vs, lat, h)
    if not true_north:              # take the horizontal Earth rate back out of the removal
        gyro_bias = gyro_bias + _horizontal_earth_rate(q_nb * mounting.q_vs, lat)
    basis = {"gyro": "reference_attitude" if true_north else "vertical_earth_rate",
             "accel": "along_gravity", "gravity_sensor_axes": _up(f[k])}
    return (gyro_bias, accel_bias, (t0, t1),
            f"biases from {where} {t0:.2f}-{t1:.2f} s ({note})", basis)


REST_SCATTER = 2.0      # a rest is given up for the reference's attitude only where its 1 s
#   means scatter more than twice what its samples' noise predicts (it moves: the moored
#   hull's tens); a still rest is kept - the attitude's standard error counts its noise
#   only, not the gyro's scale times a drive's mean turn (an independent review: a still
#   30 s stop given up for a loop's attitude had left 134 deg/h on z, the rest 4)


def _horizontal_earth_rate(q_ns, lat):
    """The Earth rate's horizontal part in sensor axes (rad/s) at the attitude q_ns: what a
    removal at an unmeasured heading must put back (up to Omega cos(lat) = 7.3e-5 rad/s)."""
    w_n = earth.earth_rate_ned(lat)
    return attitude.rotate(np.conjugate(q_ns), np.array([w_n[0], w_n[1], 0.0]))


def _up(f):
    """The up direction in sensor axes of specific forces f (m/s^2) at a rest: their mean's."""
    mean = f.mean(axis=0)
    return [float(x) for x in mean / np.linalg.norm(mean)]


ATTITUDE_BIAS_WINDOW_S = 1.0    # s: windows of the gyro bias from a reference attitude
MIN_ATTITUDE_BIAS_WINDOWS = 10


def biases_from_attitude(t, w, f, mounting, track, window=ATTITUDE_BIAS_WINDOW_S):
    """The gyro and accelerometer biases (rad/s, m/s^2, sensor axes) of a recording without
    a rest whose reference carries the vehicle attitude (a fused pose, an autopilot's
    estimate): per window [a, b] between the reference's own epochs (about `window` s), the
    IMU's mean rate w and specific force f (sensor axes, stamps t s: the samples ending in
    (a, b]) less what the reference says they were:
        rate   C_sb (rotvec(q_nb(a)^-1 q_nb(b)) / (b - a) + C_bn (w_ie^n + w_en^n))
        force  C_sb C_bn ((v(b) - v(a)) / (b - a) + (2 w_ie^n + w_en^n) x v - g^n)
    (T&W eq. 3.70; C_bn at mid-window); the median over the windows and its standard error
    (1.2533 x the MAD-based sigma / sqrt n).
    Returns ((gyro bias, se), (accel bias, se), windows) or None without
    MIN_ATTITUDE_BIAS_WINDOWS windows of known attitude."""
    q = track.get("q_nb")
    if q is None:
        return None
    inside = np.isfinite(q).all(axis=1) & (track["t"] >= t[0]) & (track["t"] <= t[-1])
    t_q = track["t"][inside]
    if len(t_q) < 2:
        return None
    # windows between the reference's own epochs (no interpolated attitude)
    step = max(1, int(round(window / np.median(np.diff(t_q)))))
    a, b = slice(0, len(t_q) - step, step), slice(step, len(t_q), step)
    rot = attitude.as_scipy(attitude.from_wxyz(np.asarray(q)[inside]))
    r_a, span = rot[a], t_q[b] - t_q[a]
    w_nb = (r_a.inv() * rot[b]).as_rotvec() / span[:, None]      # vehicle axes
    edges = t_q[a]
    mid = 0.5 * (edges + t_q[b])
    lat, h = (np.interp(mid, track["t"], track[k]) for k in ("lat", "h"))
    v = np.column_stack([np.interp(mid, track["t"], track["v_ned"][:, i]) for i in range(3)])
    w_ie, w_en = earth.earth_rate_ned(lat), earth.transport_rate_ned(lat, h, v)
    if not track.get("heading_known", True):    # its north is not true north: the Earth
        w_ie[..., :2] = 0.0                     # rate's horizontal part is left in
    # C_nb(mid) = C_nb(a) R(w_nb span / 2) (body-frame turn), so C_bn(mid) = R(-..) C_bn(a)
    c_bn_mid = Rotation.from_rotvec(-0.5 * w_nb * span[:, None]) * r_a.inv()
    rate = w_nb + c_bn_mid.apply(w_ie + w_en)
    v_ref = np.asarray(track["v_ned"], float)[inside]
    force = c_bn_mid.apply((v_ref[b] - v_ref[a]) / span[:, None]
                           + np.cross(2 * w_ie + w_en, v)) \
        - _mean_gravity_body(rot, t_q, step, earth.gravity_ned(lat, h))
    k0, k1 = np.searchsorted(t, edges, side="right"), np.searchsorted(t, t_q[b], side="right")
    use = k1 - k0 >= 2
    if use.sum() < MIN_ATTITUDE_BIAS_WINDOWS:
        return None
    q_sv = np.conjugate(mounting.q_vs)

    def window_means(x):
        c = np.vstack([np.zeros((1, 3)), np.cumsum(x, axis=0)])
        return (c[k1[use]] - c[k0[use]]) / (k1[use] - k0[use])[:, None]

    def median_difference(x, predicted):
        d = window_means(x) - attitude.rotate(q_sv, predicted[use])
        bias = np.median(d, axis=0)
        sigma = 1.4826 * np.median(np.abs(d - bias), axis=0)
        return bias, 1.2533 * sigma / math.sqrt(len(d))
    # the IMU sits at the lever arm r from the reference's point: it also feels
    # dw/dt x r + w x (w x r) (vehicle axes, from the IMU's own rates: the window's mean
    # dw/dt is the rate's change across it) - a boat rolling 11 deg with r 1.4 m had left
    # 0.013 m/s^2 on accel.z, the centripetal mean, and the tangential's median over
    # windows of a roll does not vanish either
    w_v = attitude.rotate(mounting.q_vs, w)
    r = mounting.lever_arm_m
    force = np.array(force)
    turn = (_rate_at(t, w_v, t_q[b][use]) - _rate_at(t, w_v, edges[use])) / span[use, None]
    force[use] += window_means(np.cross(w_v, np.cross(w_v, r))) + np.cross(turn, r)
    return median_difference(w, rate), median_difference(f, force), int(use.sum())


def _mean_gravity_body(rot, t_q, step, g_n):
    """(n, 3) m/s^2: gravity g_n (n, 3, NED) in the body axes averaged over each window of
    `step` reference epochs t_q (s; attitudes rot, body -> NED), over its epochs - by
    Simpson's rule where they are even in number of steps and evenly spaced, else the
    trapezoid's: at the window's mid-rotation alone a hull rolling 2.6 deg at 6 s was off by
    g phi'' span^2 / 12 = 0.04 m/s^2 in 1 s windows, by the trapezoid over 10 Hz epochs
    4e-4."""
    starts = np.arange(0, len(t_q) - step, step)[:len(g_n)]
    times = t_q[starts[:, None] + np.arange(step + 1)]
    steps = np.diff(times, axis=1)
    if step % 2 == 0 and np.allclose(steps, steps[:, :1], rtol=1e-3):
        weights = np.tile(np.r_[1.0, np.tile([4.0, 2.0], step // 2)[:-1], 1.0] / (3 * step),
                          (len(starts), 1))
    else:
        padded = np.pad(steps, ((0, 0), (1, 1)))
        weights = 0.5 * (padded[:, :-1] + padded[:, 1:]) / steps.sum(axis=1, keepdims=True)
    out = np.zeros((len(starts), 3))
    for j in range(step + 1):
        out += rot[starts + j].inv().apply(g_n) * weights[:, j:j + 1]
    return out


def _rate_at(t, w, epochs, reach=2):
    """The rates w (N, 3) at the epochs (s): the mean of the 2 reach + 1 samples of stamps t
    (s) nearest each (an interval mean's stamp ends its interval: half a sample late)."""
    k = np.clip(np.searchsorted(t, epochs), reach, len(t) - reach - 1)
    return np.mean([w[k + d] for d in range(-reach, reach + 1)], axis=0)


def moving_attitude(t, w, f, mounting, track, t0, half=MOVING_HALF_WINDOW_S):
    """q_nb (wxyz) of a moving vehicle at t0 (s), by velocity matching over (t0 - half,
    t0 + half]: the IMU's velocity increment over the interval expressed in the body axes
    at t0 (each sample's specific force f m/s^2 turned by the gyro's rotation w rad/s since
    t0, sensor axes at stamps t, biases removed), matched exactly to the track's (its
    velocity's change less gravity and Coriolis over the interval), the forward axis to the
    track's velocity direction - against it when the vehicle reverses (`travel_sign`). With
    the rotation followed, the interval may be long enough to average a noisy reference's
    velocity (`moving_half_window`); a mean specific force over a turning interval had an
    error second order in the angle turned. See the module's docstring."""
    k = np.flatnonzero((t > t0 - half) & (t <= t0 + half))
    if len(k) < 2 or k[0] == 0:
        raise InputError(f"no IMU samples around t = {t0:.2f} s")
    dt = t[k] - t[k - 1]                               # each sample: the mean over its interval
    w_b = attitude.rotate(mounting.q_vs, w[k])
    f_b = attitude.rotate(mounting.q_vs, f[k])
    steps = quaternion.from_rotation_vector(w_b * dt[:, None])
    q = np.multiply.accumulate(steps)                  # body at the interval's start -> each
    i0 = int(np.argmin(np.abs(t[k] - t0)))
    q_mid = np.conjugate(q[i0]) * q * quaternion.from_rotation_vector(-0.5 * w_b * dt[:, None])
    dv_b = np.sum(attitude.rotate(q_mid, f_b * dt[:, None]), axis=0)     # body axes at t0
    t_a, t_b = float(t[k[0] - 1]), float(t[k[-1]])
    v = lambda s: np.array([np.interp(s, track["t"], track["v_ned"][:, i])  # noqa: E731
                            for i in range(3)])
    v0 = v(t0)
    lat, h = float(np.interp(t0, track["t"], track["lat"])), float(np.interp(t0, track["t"],
                                                                                track["h"]))
    coriolis = np.cross(2 * earth.earth_rate_ned(lat) + earth.transport_rate_ned(lat, h, v0), v0)
    dv_n = v(t_b) - v(t_a) + (coriolis - earth.gravity_ned(lat, h)) * (t_b - t_a)
    forward = travel_sign(t, f, mounting, track, t0) * v0 / np.linalg.norm(v0)
    rot, _ = Rotation.align_vectors([dv_n, forward], [dv_b, [1.0, 0, 0]],
                                    weights=[np.inf, 1.0])
    return attitude.as_wxyz(attitude.from_scipy(rot))


def mean_speed(track, half):
    """Horizontal speed (m/s) of the track's velocity averaged over +-half s about each of
    its epochs (`moving_half_window`): a noisy fix's differenced speed passes COURSE_SPEED
    while a walker stands or sets off (3.3 m/s on 4 m fixes, its course noise: a heading
    176 deg off), its mean over the alignment's interval does not; an RTK track's is its
    own. Where the vehicle turns within the interval, the mean of its speed less the speed
    its noise alone makes holds it (a skidpad's 8 m/s circle of 15 m had read 1.4 m/s)."""
    v_h = np.asarray(track["v_ned"], float)[:, :2]
    v = means_around(track["t"], v_h, track["t"], half)
    # and the mean speed less what the noise alone makes of it (sigma sqrt(pi/2), a
    # Rayleigh's mean): a car circling a skidpad turns its velocity's mean away
    sigma = velocity_noise(track) or 0.0
    speed = means_around(track["t"], np.hypot(v_h[:, 0], v_h[:, 1])[:, None], track["t"],
                         half)[:, 0]
    return np.maximum(np.hypot(v[:, 0], v[:, 1]), speed - sigma * math.sqrt(math.pi / 2))


def moving_half_window(track, accel_error=MOVING_ACCEL_ERROR):
    """Half the moving alignment's interval (s) for a reference track: long enough that its
    velocity noise sigma_v (from the second differences of its velocities, robustly:
    MAD / 0.6745 / sqrt(6)) makes an error of at most `accel_error` (m/s^2, a tilt of
    accel_error / g) in the interval's mean acceleration, sqrt(2) sigma_v / (2 half), within
    MOVING_HALF_WINDOW_S .. MOVING_HALF_WINDOW_MAX_S. An RTK track (1-2 cm/s) keeps the
    shortest; a plain fix's differenced velocity (about 1 m/s) the longest, where its tilt
    error is still about 1 deg (`moving_tilt_sigma`)."""
    sigma_v = velocity_noise(track)
    if sigma_v is None:
        return MOVING_HALF_WINDOW_S
    half = math.sqrt(2) * sigma_v / (2 * accel_error)
    # and at least one epoch interval: the reference's velocity change over a shorter
    # interval is interpolated between its epochs while the IMU's is the true one (a 1 Hz
    # track surging +-0.8 m/s^2 tilted the alignment by 2 deg at 0.25 s, 0.01 at 1 s)
    step = float(np.median(np.diff(track["t"])))
    return float(np.clip(max(half, step), MOVING_HALF_WINDOW_S, MOVING_HALF_WINDOW_MAX_S))
