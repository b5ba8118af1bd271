"""Initial alignment of a land vehicle's IMU from its own data and a GNSS track.

Coarse alignment at rest (Titterton & Weston 2004, sec. 10.2.1): at standstill the
specific force is the reaction to gravity, f^b = C_bn (0, 0, -g), so
    roll  = atan2(-f_y, -f_z),   pitch = atan2(f_x, sqrt(f_y^2 + f_z^2))     (vehicle axes);
the gyro bias is the static mean rate less the Earth rate C_bn w_ie^n; of the accelerometer
bias only the part along gravity is observable at rest: (|f| - g) f/|f| with the normal
gravity g at the track's position (none without a track) - unless the reference carries the
vehicle's attitude at the rest: then its level is taken, and the whole bias measured against
it (`rest_biases`). Heading is not
observable this way from a consumer gyro (Earth rate 0.004 deg/s against a bias of
0.1-1 deg/s), so it comes from the GNSS course once the vehicle moves: a car does not slide
sideways, its forward axis points along its velocity (the non-holonomic assumption), and the
yaw turned between standstill and that moment is taken from the gyro. The courses are those
of its straight driving (`_course_epochs`: in a turn an antenna ahead of the axle moves w x r
across the heading) from the speed at which the track's averaged velocity holds them
(`course_speed`).

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
from ..motion.carrier import declared
from .rest_biases import (ACROSS_GRAVITY, biases_at_a_rest, horizontal_earth_rate, level,
                          reference_attitude, reference_level, rest_biases, up_at_rest,
                          vertical_note)
from .rests import (MIN_STATIC_S, QUIET_WINDOW_S, STATIC_MARGIN_S, STATIC_SPEED, felt_at_rest,
                    means_around, quiet_stretches, rest_intervals, track_still, velocity_noise,
                    vertical_rate_said, yaw_turned)
from .travel import travel_sign


COURSE_SPEED = 3.0          # m/s: horizontal speed from which the GNSS course gives heading
#                             where the track's velocity noise is not measured or large
COURSE_SIGMA_DEG = 2.0      # deg: the error of a course averaged over COURSE_SPAN_S, at
#                             most - what one epoch of a 0.1 m/s plain fix makes at
#                             COURSE_SPEED (1.9 deg)
COURSE_SPEED_MIN = 1.0      # m/s: the least, however quiet the track: a walker's sway
#                             (+-0.2 m/s across) turns a slower course by more than that
MOVING_HALF_WINDOW_MAX_S = 5.0  # s: the longest (the gyro's bias turns the increment by
                                # b x 5 s: 0.1 deg for 0.02 deg/s left after the rest)
MOVING_ACCEL_ERROR = 0.02       # m/s^2: the interval's acceleration error aimed at (0.1 deg)
MOVING_HALF_WINDOW_S = 0.25     # s: half the interval of the moving two-vector alignment
COURSE_SPAN_S = 5.0         # s of fast epochs whose courses give the heading at a rest's end
STRAIGHT_RATE = math.radians(1.0)   # rad/s: the gyro's yaw rate below which a vehicle drives
#                             straight - its course its heading, with no antenna lever arm's
#                             w x r across it: the RTKLIB drive's courses as it pulled out
#                             turning at 4-12 deg/s put its heading at rest 2-3 deg from the
#                             -4.1 its 189 straight epochs of 40-120 s give
COURSE_SEARCH_S = 60.0      # s after the first fast epoch in which straight ones are sought
#                             (a residual gyro bias of 0.003 deg/s turns 0.2 deg over it)


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
    or a moving alignment's; "reference_level" - roll and pitch the reference's at a rest,
    the heading as `heading` says), and what the biases measured (`bias_basis`: gyro
    "reference_attitude" (the Earth rate removed with the reference's attitude), "course" (at
    the course's heading), "vertical_earth_rate" (its horizontal part, up to Omega cos(lat),
    left in), "earth_rate_left" (a rest's mean rate, the Earth's in it: no position, no
    heading) or "none" (taken as 0);
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


def initial_alignment(t, w, f, mounting, track=None):
    """Initial state of a recording: t s, w rad/s, f m/s^2 (sensor axes), `track` the
    reference {t s, lat, lon rad, h m, v_ned m/s, optional q_nb wxyz of the vehicle (NaN rows:
    unknown), heading_known (False: its north is no true north)}. In order of preference:

    1. a rest that starts the recording (MIN_STATIC_S or more): level from its mean specific
       force (from the reference's attitude where it has one there), heading from the
       reference's attitude once moving, turned back by the gyro
       (else the course of straight driving less the gyro's yaw since), state at the first
       IMU stamp; the rest ends where the IMU starts to move (`rests.settled_until`);
    2. the reference's own attitude at its first epoch with one (an autopilot's estimate,
       a fused pose): the whole state from the reference;
    3. moving: the two-vector alignment (`moving_attitude`) at the first reference epoch
       faster than COURSE_SPEED.
    The biases come from the rest of case 1, else from the longest rest anywhere (with the
    Earth rate removed as far as the attitude there is known), else are 0. Without a track
    the first rest the IMU shows starts the state, position and heading 0 (`_untracked`). When no
    case applies, an InputError says what the recording lacks."""
    if track is None or len(track["t"]) < 2:
        return _untracked(t, w, f, mounting)
    heights = (track["t"], track["h"]) if "h" in track else None
    rests, not_rests = felt_at_rest(t, w, f, rest_intervals(
        track["t"], track["v_ned"], float(t[0]), float(t[-1]), h=track.get("h")), heights)
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
        notes.append(f"moving alignment at t = {t0:.2f} s ({speed[fast[0]]:.1f} m/s, the "
                     f"horizontal speed's mean over +-{half:g} s): the "
                     f"IMU's velocity increment over {2 * half:.1f} s (turned by its gyro) "
                     "matched to the reference's, forward axis to its velocity"
                     + ("" if track.get("faces_course", True) else f" - "
                        f"{declared(track.get('vehicle'))} need not face its course: its "
                        "heading is assumed, no measurement"))
    else:
        raise _no_initial_state(t, track, speed, inside, half)
    lat, lon, h = (float(np.interp(t0, track["t"], x)) for x in (
        track["lat"], unwrapped_longitude(track["lon"]), track["h"]))
    v0 = np.array([np.interp(t0, track["t"], track["v_ned"][:, i]) for i in range(3)])
    notes.append(bias_note)
    return Alignment(t0, lat, lon, h, v0, q_nb, gyro_bias, accel_bias, static,
                     "; ".join(notes), at_rest_start=False,
                     heading="reference" if q_ref is not None else "course"
                     if track.get("faces_course", True) else "assumed",
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
            f"its epochs faster than {COURSE_SPEED:g} m/s all lie in stretches the "
            "IMU and its positions show at rest (a noisy fix's speed)"
            if moving.any() else
            f"at its epochs with {half:.3g} s of IMU and of it on both sides its speed "
            f"peaks at {speed[inside].max():.2f} m/s, below {COURSE_SPEED:g} m/s (over all "
            f"of it: {speed.max():.2f} m/s)" if inside.any() else
            f"none of its epochs has {half:.3g} s of IMU and of it on both sides (the "
            f"IMU's record is {t[-1] - t[0]:.2f} s, its "
            f"{track['t'][-1] - track['t'][0]:.2f} s): too short") +
        " for a moving alignment")


def _untracked(t, w, f, mounting):
    """No reference: the first rest the IMU itself shows (`quiet_stretches`) gives the level
    and the gyro bias - the Earth's rate left in it (no position, no heading) - and the
    state starts there, position and heading 0. A rest had been assumed for the first
    MIN_STATIC_S, unchecked: a rate-table record starting at 20 deg/s read a gyro bias of
    -11.3 deg/s (truth +0.26). Without one: `_unrested`."""
    rests = quiet_stretches(t, w, f)
    if not rests:
        return _unrested(t, w, f, mounting)
    t0, t1 = rests[0]
    rest = (t >= t0) & (t <= t1)
    roll, pitch = level(attitude.rotate(mounting.q_vs, f[rest].mean(axis=0)))
    q_nb = attitude.from_euler(np.array(0.0), np.array(pitch), np.array(roll))
    later = f"; the IMU moves before it, from {t[0]:.2f} s" if t0 > t[0] + QUIET_WINDOW_S else ""
    return Alignment(float(t0), 0.0, 0.0, 0.0, np.zeros(3), attitude.as_wxyz(q_nb),
                     w[rest].mean(axis=0), np.zeros(3), (float(t0), float(t1)),
                     f"a rest {t0:.2f}-{t1:.2f} s judged from the IMU alone (no GNSS track)"
                     f"{later}{vertical_rate_said(t, w, f, t0, t1)}; level from its mean "
                     "specific force; position and heading "
                     "assumed 0; the Earth's rate (up to 7.3e-05 rad/s) left in the gyro bias: "
                     "no position, no heading", at_rest_start=t0 <= t[0] + QUIET_WINDOW_S,
                     bias_basis={"gyro": "earth_rate_left", "accel": "none"})


def _unrested(t, w, f, mounting):
    """No reference and no rest the IMU shows: a state at the start leveled on the first
    MIN_STATIC_S's mean specific force, said to be no rest (its tilt as wrong as the motion
    there makes it), biases not observed (0) - what a reference IMU beside it needs of a
    state (two IMUs navigated alike), no more."""
    first = t <= t[0] + MIN_STATIC_S
    if first.sum() < 10:
        raise InputError(f"fewer than 10 IMU samples in the first {MIN_STATIC_S:g} s: no level")
    roll, pitch = level(attitude.rotate(mounting.q_vs, f[first].mean(axis=0)))
    q_nb = attitude.from_euler(np.array(0.0), np.array(pitch), np.array(roll))
    return Alignment(float(t[0]), 0.0, 0.0, 0.0, np.zeros(3), attitude.as_wxyz(q_nb),
                     np.zeros(3), np.zeros(3), (math.nan, math.nan),
                     "no GNSS track or reference, and the IMU shows no rest of "
                     f"{MIN_STATIC_S:g} s anywhere (its first {MIN_STATIC_S:g} s: |mean w| "
                     f"{math.degrees(np.linalg.norm(w[first].mean(axis=0))):.3g} deg/s, |mean f| "
                     f"{np.linalg.norm(f[first].mean(axis=0)):.4g} m/s^2): level from their mean "
                     "specific force, which is no rest's (the tilt unreliable); biases not "
                     "observed; position and heading assumed 0", at_rest_start=False,
                     bias_basis={"gyro": "none", "accel": "none"})


def _no_heading(track, interval):
    """Why a rest's heading is assumed 0: a track without attitude that is too slow for its
    course, or of a vehicle declared not to face its course."""
    if not track.get("faces_course", True):
        return (f"heading assumed 0 ({declared(track.get('vehicle'))} need not face its "
                "course, and the track carries no attitude)")
    return (f"heading assumed 0 (the track never exceeds {course_speed(track, interval):.2g} "
            "m/s and carries no attitude)")


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
    q_ref, t_ref = reference_attitude(track, float(t[0]))
    at_rest = reference_level(track, float(t[0]), t_end)   # the reference's level at rest
    level_known = at_rest is not None
    roll, pitch, notes = _rest_level(t, f[rest].mean(axis=0), q_vs, t_end, at_rest)
    lat, lon, h = (float(np.interp(t[0], track["t"], x)) for x in (
        track["lat"], unwrapped_longitude(track["lon"]), track["h"]))
    speed = mean_speed(track, moving_half_window(track))
    after = track["t"] > max(t_end, still_until)
    # an INS's heading is taken once the vehicle moves as a car's course would give one
    # (COURSE_SPEED: where it has converged), else its course at that speed, else its
    # heading at rest; a track without attitude gives a course from the speed its noise allows
    moving = np.flatnonzero((speed >= COURSE_SPEED) & after)
    fast = moving if q_ref is not None else \
        np.flatnonzero((speed >= course_speed(track, interval)) & after)
    if q_ref is None and not track.get("faces_course", True):
        fast = moving = fast[:0]            # a declared walker's course is not its heading
    w_v = attitude.rotate(q_vs, w - w[rest].mean(axis=0))
    back = _reference_heading_back(t, w_v, t_end, track, moving)
    k, straight = _course_epochs(t, w_v, track, fast)
    if len(k) and speed[k[0]] < COURSE_SPEED and \
            travel_sign(t, f, mounting, track, float(track["t"][k[0]]), undecided=0.0) == 0:
        # slower than COURSE_SPEED, which way it moves must be read off the data (a car
        # backing out straight at 1.6 m/s had faced 180 deg off, taken as forward)
        fast = moving
        k, straight = _course_epochs(t, w_v, track, fast)
    if back is not None:
        yaw, i = back
        heading = "reference"
        notes.append(f"heading from the reference's attitude at t = {track['t'][i]:.2f} s, "
                     f"moving ({speed[i]:.1f} m/s), turned back to the rest by the gyro")
    elif len(fast):
        yaw, heading = _heading_from_course(t, f, w_v, mounting, track, (k, straight), speed,
                                            t_end, notes), "course"
    elif q_ref is not None:
        yaw = float(attitude.as_euler(attitude.from_wxyz(q_ref))[0])
        heading = "reference"
        notes.append(f"heading from the reference's attitude at t = {t_ref:.2f} s")
    else:
        yaw, heading = 0.0, "assumed"
        notes.append(_no_heading(track, interval))
    q_nb = attitude.from_euler(np.array(yaw), np.array(pitch), np.array(roll))
    gyro_bias, accel_bias = rest_biases(w[rest], f[rest], q_nb * q_vs, lat, h, level_known)
    vertical = vertical_note(track, t, w, f, float(t[0]), float(t_end))
    if vertical:                    # a turntable's rate beside a still track
        notes.append(vertical[2:])
    if level_known:
        notes.append(ACROSS_GRAVITY + _tilt_alike(accel_bias, f[rest].mean(axis=0)))
    true_north = heading != "assumed" and track.get("heading_known", True)
    if not true_north:              # no true heading: the Earth rate's vertical part only
        gyro_bias = gyro_bias + horizontal_earth_rate(q_nb * q_vs, lat)
        notes.append("only the Earth rate's vertical part removed from the gyro bias (up to "
                     f"{earth.OMEGA * math.cos(lat):.1e} rad/s of it remain: "
                     + ("no heading)" if heading == "assumed" else
                        "the reference's frame has no known azimuth)"))
    basis = {"gyro": {"reference": "reference_attitude", "course": "course"}.get(
                 heading, "vertical_earth_rate") if true_north else "vertical_earth_rate",
             "accel": "all" if level_known else "along_gravity",
             "gravity_sensor_axes": up_at_rest(f[rest])}
    return Alignment(float(t[0]), lat, lon, h, np.zeros(3), attitude.as_wxyz(q_nb),
                     gyro_bias, accel_bias, (float(t[0]), float(t_end)), "; ".join(notes),
                     heading=heading, bias_basis=basis,
                     attitude_from="reference_level" if level_known else "leveled")


def _heading_from_course(t, f, w_v, mounting, track, chosen, speed, t_end, notes):
    """The heading (rad) at the rest's end t_end (s) from the track's courses at its
    `chosen` epochs (`_course_epochs`' (indices, straight)), each less the gyro's yaw since
    (vehicle-axis rates w_v, rad/s): their circular mean weighted by speed^2, so one noisy
    course (a plain fix's differenced velocity, ~1 m/s of noise) does not set it; how,
    appended to `notes`."""
    k, straight = chosen
    course = np.arctan2(track["v_ned"][k, 1], track["v_ned"][k, 0])
    if travel_sign(t, f, mounting, track, float(track["t"][k[0]])) < 0:
        course = course + math.pi               # it drives off in reverse
        notes.append("reversing (the horizontal specific force opposes the track's "
                     "acceleration)")
    at_rest = course - np.array([yaw_turned(t, w_v, t_end, float(x)) for x in track["t"][k]])
    weight = speed[k] ** 2          # a course's noise falls as the speed rises
    notes.append(f"heading from the GNSS course over {len(k)} epoch(s) from t = "
                 f"{track['t'][k[0]]:.2f} s ({speed[k[0]]:.1f} m/s"
                 + (f", driving straight: yaw rate under {math.degrees(STRAIGHT_RATE):g} "
                    "deg/s" if straight else ", turning: none drove straight") +
                 ") less the gyro's yaw since the rest (non-holonomic: no side slip)")
    return math.atan2(np.sum(weight * np.sin(at_rest)), np.sum(weight * np.cos(at_rest)))


MEMS_ACCEL_BIAS = 0.1 * 9.80665     # m/s^2: a consumer accelerometer's bias, at most (a
#                                    phone's 40-60 mg); across gravity beyond it, a tilt


def _tilt_alike(accel_bias, f_mean):
    """'' or, where the bias measured across gravity (m/s^2, sensor axes; the rest's mean
    specific force f_mean) is beyond MEMS_ACCEL_BIAS, that it more likely is the mounting
    given tilted by its angle (taken out as bias all the same: the navigation beside the
    reference's attitude sees it so, while the vehicle is level)."""
    up = f_mean / np.linalg.norm(f_mean)
    across = float(np.linalg.norm(accel_bias - (accel_bias @ up) * up))
    if across <= MEMS_ACCEL_BIAS:
        return ""
    return (f" - {across / 9.80665 * 1e3:.0f} mg of it, beyond a MEMS part's 100 mg: more "
            f"likely the mounting given tilted by {math.degrees(across / 9.80665):.1f} deg")


def _rest_level(t, f_mean, q_vs, t_end, reference=None):
    """(roll, pitch rad, [the note]) of the vehicle at the rest from t[0] to t_end (s): the
    reference's mean level there (`rest_biases.reference_level`'s (roll, pitch, epochs))
    where it has an attitude there, else leveled on the IMU's mean specific force f_mean
    (m/s^2, sensor axes) through the mounting q_vs."""
    if reference is not None:
        roll, pitch, epochs = reference
        return roll, pitch, [f"level from the reference's attitude over the rest "
                             f"{t[0]:.2f}-{t_end:.2f} s (the mean of its {epochs} epochs)"]
    roll, pitch = level(attitude.rotate(q_vs, f_mean))
    return roll, pitch, [f"level from the mean specific force over the rest {t[0]:.2f}-"
                         f"{t_end:.2f} s"]


def _course_epochs(t, w_v, track, fast):
    """(the track's epochs whose courses give the heading, whether they drive straight):
    the first COURSE_SPAN_S's worth of the `fast` ones within COURSE_SEARCH_S of the first
    where the gyro's yaw rate (vehicle axes w_v, rad/s at stamps t; its mean over +-0.5 s)
    is below STRAIGHT_RATE, else the first COURSE_SPAN_S of them all. The earliest: an
    aircraft's courses on its runway are its heading, in the air a crosswind crabs them."""
    if not len(fast):
        return fast, False
    t_k = track["t"][fast]
    rate = means_around(t, w_v[:, 2:], t_k, 0.5)[:, 0]
    straight = fast[(t_k <= t_k[0] + COURSE_SEARCH_S) & (np.abs(rate) < STRAIGHT_RATE)]
    if len(straight):           # the first COURSE_SPAN_S's worth of them: the earliest, an
        step = float(np.median(np.diff(track["t"])))      # aircraft's still on its runway
        return straight[:max(1, int(round(COURSE_SPAN_S / step)))], True
    return fast[t_k <= t_k[0] + COURSE_SPAN_S], False


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


def course_speed(track, rest):
    """The horizontal speed (m/s) from which the track's courses, averaged over COURSE_SPAN_S,
    give the heading at the end of the rest (t0, t1) s: where the noise of the velocity's
    COURSE_SPAN_S means - measured at that rest, as the scatter of its consecutive blocks'
    means (a still vehicle's velocity is its noise, time-correlated or not) - turns a course
    by COURSE_SIGMA_DEG (at its 95 % upper bound), within COURSE_SPEED_MIN .. COURSE_SPEED;
    COURSE_SPEED for a rest of fewer than 3 blocks. An RTK robot's differenced track (its 5 s means: millimetres per
    second) gives it its heading at 1.2 m/s (a fixed 3 m/s had left it assumed); a
    receiver's filtered Doppler (0.1 m/s correlated over 2 s: its 5 s means 0.09 m/s, where
    second differences had read 0.018) keeps 2.6 m/s."""
    t = np.asarray(track["t"], float)
    n = int((rest[1] - rest[0]) // COURSE_SPAN_S)
    k = np.flatnonzero((t >= rest[0]) & (t < rest[0] + n * COURSE_SPAN_S))
    if n < 3 or len(k) < n:
        return COURSE_SPEED
    block = ((t[k] - rest[0]) // COURSE_SPAN_S).astype(int)
    counts = np.bincount(block, minlength=n)
    if (counts == 0).any():
        return COURSE_SPEED
    v = np.asarray(track["v_ned"], float)[k, :2]
    means = np.column_stack([np.bincount(block, v[:, i], n) for i in range(2)]) / counts[:, None]
    # the scatter of n block means, at its 95 % upper bound (chi-square, n - 1 degrees of
    # freedom): three blocks' scatter had read a correlated noise at half its size
    from scipy.stats import chi2
    sigma = float(np.max(np.std(means, axis=0, ddof=1))) * \
        math.sqrt((n - 1) / chi2.ppf(0.05, n - 1))
    return float(np.clip(sigma / math.tan(math.radians(COURSE_SIGMA_DEG)),
                         COURSE_SPEED_MIN, COURSE_SPEED))


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
