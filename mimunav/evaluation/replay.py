"""Replay of a flight log (seed S1 4.2): the MIMU compensated, both IMUs navigated with
the same quaternion strapdown navigator at their mountings (on a rotating platform in the
sensor frame, `VehicleNavigator`), and their errors against the truth (NED, m, m/s, rad).
"""
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np

from ..frames import attitude, earth
from ..navigation import strapdown
from ..navigation.rest_biases import level
from ..compensation.wild_values import CLIP_RUN, SATURATED, flag_counts
from ..frames.mounting import Mounting
from ..motion.trajectory import Trajectory
from ..errors import InputError
from .flight import Flight, SecondMeans, compensated_whole


def navigate(t, w, f, mounting, initial, whole_record=True):
    """Navigate sensor-axis rates w (rad/s) and specific forces f (m/s^2), interval means at
    stamps t (s), from the vehicle's initial state; returns the vehicle-origin Trajectory
    at [initial t, t after it] (`VehicleNavigator` over one block; whole_record: False for
    a piece of a longer record)."""
    nav = VehicleNavigator(mounting, initial, whole_record=whole_record)
    return Trajectory.concatenate([nav.feed(t, w, f), nav.finish()])


class VehicleNavigator:
    """`navigate` block by block, for a flight of any length in bounded memory: `feed`
    sensor-axis interval means (t s, w rad/s, f m/s^2) in time order and get the
    vehicle-origin states settled so far; `finish` returns the last one. The states equal
    those of one `navigate` over the whole record: the strapdown memory is carried
    (`strapdown.Navigator`), and a state's lever-arm velocity, which takes the mean body rate
    of the intervals on both sides of it, waits for the next block's first sample.

    On a rotating platform (`platform`: the Flight's `RecordedPlatform`; its axis through the
    vehicle origin, the IMU at the metadata's lever_arm_m from it in platform axes) the
    sensor frame itself is navigated at the IMU's point, the vehicle attitude
    q_nb = q_ns q_bs(theta)^-1 comes from the recorded platform angle (`modulation`), and
    the point's lever arm r = C_bp0 Rz(theta) r_p turns with it (its velocity theta' a x r,
    a the axis in vehicle axes, from the recorded rate).
    whole_record: False when the blocks are pieces of a longer record (`strapdown.Navigator`)."""

    def __init__(self, mounting, initial, platform=None, whole_record=True):
        self.initial, self.platform, self.whole_record = initial, platform, whole_record
        self.q_vs, self.r = mounting.q_vs, mounting.lever_arm_m
        if platform is not None:
            self.q_vs, self.r = Mounting().q_vs, np.zeros(3)
            self.r_p = np.asarray(platform.meta.get("lever_arm_m", [0.0] * 3), float)
            self.q_bp0 = attitude.from_wxyz(platform.meta["base_attitude_wxyz"])
        self.nav, self.pending, self.count = None, None, 0

    def feed(self, t, w, f):
        """The states settled by the samples stamped after the initial state's time."""
        after = t > self.initial.t + 1e-12
        t, w, f = t[after], w[after], f[after]
        if not len(t):
            return None
        w_v, f_v = attitude.rotate(self.q_vs, w), attitude.rotate(self.q_vs, f)
        if self.nav is None:
            self.nav = strapdown.Navigator(self._start(w_v[:1]),
                                           whole_record=self.whole_record)
            self.pending = (self.nav.state(), w_v[:1])      # the start: its first interval
        dt = np.diff(t, prepend=self.nav.t)
        self.count += len(t)
        held, w_held = self.pending
        states = self.nav.step(t, w_v * dt[:, None], f_v * dt[:, None], before=held)
        self.pending = (states[-1:], w_v[-1:])
        before = np.vstack([w_held, w_v[:-1]])        # the interval ending at each state
        return self._vehicle(states[:-1], 0.5 * (before + w_v))

    def finish(self):
        """The last state (its body rate: the last interval's)."""
        if self.count < 2:
            raise InputError("fewer than two samples after the initial state's time")
        held, w_held = self.pending
        return self._vehicle(held, w_held)

    def _start(self, w_v0):
        """The initial state moved to the sensor's place (position + C_nb r, velocity +
        C_nb (w_nb x r)); on a platform that of the turning IMU, in the sensor frame."""
        if self.platform is not None:
            return self._platform_start(w_v0)
        start, r = self.initial, self.r
        if np.any(r):
            q0 = start.q_nb
            w_nb0 = _body_rate(w_v0, q0, start)[0]
            lat, lon, h = _moved(start.lat, start.lon, start.h, attitude.rotate(q0, r))
            start = replace(start, lat=lat, lon=lon, h=h,
                            v_ned=start.v_ned + attitude.rotate(q0, np.cross(w_nb0, r)))
        return start

    def _vehicle(self, nav, w_at):
        """Sensor-place states back to the vehicle origin (- C_nb r, - C_nb (w_nb x r)),
        w_at the body rate at each state (rad/s, vehicle axes); on a platform the vehicle
        attitude."""
        if self.platform is not None:
            return self._platform_vehicle(nav, w_at)
        r = self.r
        if not np.any(r):
            return nav
        w_nb = _body_rate(w_at, nav.q_nb, self.initial)
        d_ned = attitude.rotate(nav.q_nb, np.broadcast_to(-r, (len(nav), 3)))
        lat, lon, h = _moved(nav.lat, nav.lon, nav.h, d_ned)
        v = nav.v_ned - attitude.rotate(nav.q_nb, np.cross(w_nb, r))
        return Trajectory(nav.t, lat, lon, h, v, nav.q_nb)

    def _turning(self, t, q_nb, w_s):
        """(q_bs, the IMU point's lever arm r and d_ned = C_nb r, its velocity relative to
        the vehicle origin C_nb (w_nb x r + r')) at times t for a vehicle attitude q_nb and
        the sensor's rate w_s (rad/s, sensor axes, w_ib)."""
        from ..motion.platform import rotation_about_z, q_bs_recorded
        p = self.platform
        angle = np.interp(t, p.t, p.angle)
        q_bs = q_bs_recorded(p.meta, angle)
        if not np.any(self.r_p):
            return q_bs, np.zeros((len(t), 3)), np.zeros((len(t), 3))
        axis = attitude.rotate(self.q_bp0, np.array([0.0, 0.0, 1.0]))
        rate = np.interp(t, p.t, p.rate)[:, None]
        r = attitude.rotate(self.q_bp0 * rotation_about_z(angle), np.broadcast_to(self.r_p, (len(t), 3)))
        # w_nb^b = C_bs w_ib^s - theta' a - C_bn w_ie^n
        w_nb = _body_rate(attitude.rotate(q_bs, w_s) - rate * axis, q_nb, self.initial)
        return (q_bs, attitude.rotate(q_nb, r),
                attitude.rotate(q_nb, np.cross(w_nb, r) + rate * np.cross(axis, r)))

    def _platform_start(self, w_s0):
        from ..motion.platform import q_bs_recorded
        start = self.initial
        q_nb = start.q_nb
        t0 = np.array([float(start.t)])
        q_bs, d_ned, v_rel = self._turning(t0, np.atleast_1d(q_nb), w_s0)
        start = replace(start, q_nb=(q_nb * q_bs_recorded(
            self.platform.meta, np.interp(t0, self.platform.t, self.platform.angle)))[0])
        if np.any(d_ned):
            lat, lon, h = _moved(start.lat, start.lon, start.h, d_ned[0])
            start = replace(start, lat=lat, lon=lon, h=h,
                            v_ned=np.asarray(start.v_ned, float) + v_rel[0])
        return start

    def _platform_vehicle(self, nav, w_s):
        """Sensor-frame states at the turning IMU's point -> the vehicle origin's."""
        from ..motion.platform import q_bs_recorded, vehicle_attitude
        angle = np.interp(nav.t, self.platform.t, self.platform.angle)
        q_nb = vehicle_attitude(nav.q_nb, q_bs_recorded(self.platform.meta, angle))
        _, d_ned, v_rel = self._turning(nav.t, q_nb, w_s)
        if not np.any(d_ned):
            return Trajectory(nav.t, nav.lat, nav.lon, nav.h, nav.v_ned, q_nb)
        lat, lon, h = _moved(nav.lat, nav.lon, nav.h, -d_ned)
        return Trajectory(nav.t, lat, lon, h, nav.v_ned - v_rel, q_nb)


def _body_rate(w_ib, q_nb, initial):
    """w_nb^b = w_ib^b - C_bn w_ie^n (transport rate < 1e-4 rad/s is neglected here: it
    moves a 1 m lever arm's velocity by < 0.1 mm/s)."""
    w_ie = earth.earth_rate_ned(initial.lat)
    return w_ib - attitude.rotate(np.conjugate(q_nb), np.broadcast_to(w_ie, w_ib.shape))


def _moved(lat, lon, h, d_ned):
    """Geodetic position moved by a small NED offset d (m)."""
    r_n, r_e = earth.radii(lat)
    d = np.asarray(d_ned)
    return (lat + d[..., 0] / (r_n + h), lon + d[..., 1] / ((r_e + h) * np.cos(lat)),
            h - d[..., 2])


def resample(traj, t):
    """Trajectory at times t (s) inside its span: linear in position and velocity, slerp
    in attitude. Longitude goes the short way across the antimeridian (a reference written
    in (-pi, pi] jumps by 2 pi there), attitude the short way between q and -q (one
    rotation: a writer may keep w >= 0)."""
    if t[0] < traj.t[0] - 1e-9 or t[-1] > traj.t[-1] + 1e-9:
        raise InputError(f"times {t[0]:.3f}-{t[-1]:.3f} s outside the trajectory's "
                         f"{traj.t[0]:.3f}-{traj.t[-1]:.3f} s")
    if len(traj) == 1:                          # a trajectory of one instant, at it
        return traj[np.zeros(len(t), dtype=int)]
    k = np.clip(np.searchsorted(traj.t, t, side="right"), 1, len(traj) - 1)
    tau = (t - traj.t[k - 1]) / (traj.t[k] - traj.t[k - 1])
    step = lambda x: x[k] - x[k - 1]                                # noqa: E731
    lerp = lambda x, d: x[k - 1] + d * (tau if x.ndim == 1 else tau[:, None])  # noqa: E731
    d_lon = step(traj.lon)
    d_lon -= 2 * np.pi * np.round(d_lon / (2 * np.pi))     # the short way; exact below pi
    q0 = traj.q_nb[k - 1]
    turn = attitude.short_way(np.conjugate(q0) * traj.q_nb[k])
    with np.errstate(invalid="ignore"):     # a reference without attitude: NaN stays NaN
        q = q0 * np.exp(np.log(turn) * tau)                             # slerp
    return Trajectory(np.asarray(t, float), lerp(traj.lat, step(traj.lat)),
                      lerp(traj.lon, d_lon), lerp(traj.h, step(traj.h)),
                      lerp(traj.v_ned, step(traj.v_ned)), q)


@dataclass
class Replay:
    """Navigated solutions (vehicle origin) and the compensation's sample flags."""
    flight: Flight
    mimu: Trajectory
    fog: Trajectory
    flags: dict


def compensated_mimu(flight, cal, per_sample=False, warn=True):
    """(w rad/s, f m/s^2, flag counts) of the flight's raw MIMU through `cal` (with
    per_sample: the flag of every sample instead of the counts). A flight recorded as
    /mimu/imu is already compensated: `cal` must then be None or an identity base with
    found terms (`Calibration.identity`, the diagnosis's `CAL+found.json`), which are removed
    from the recorded outputs. Warns (unless warn=False: a second pass over a flight already
    warned about) about outputs stuck at an extreme inside the range."""
    w, f, flags = compensated_whole(flight, cal)
    if warn:
        warn_stuck(flight, stuck_inside_range(flight, w, f, flags))
    return w, f, (flags if per_sample else flag_counts(flags))


def warn_stuck(flight, stuck):
    if stuck:
        from ..errors import warn
        warn(f"{flight.path}: {stuck} MIMU samples have a raw output stuck at its extreme for "
             f">= {CLIP_RUN} samples inside the declared range (clipped by the ADC or "
             "amplifier): flagged saturated; the navigation through them is wrong")


def stuck_inside_range(flight, w, f, flags):
    """Samples flagged saturated although their compensated outputs lie inside the declared
    range: clipped by the ADC or an amplifier below it."""
    inside = (np.abs(f) < flight.mimu_range.get("accel_m_s2", np.inf)).all(axis=1) \
        & (np.abs(w) < flight.mimu_range.get("gyro_rad_s", np.inf)).all(axis=1)
    return int(np.count_nonzero((flags & SATURATED).astype(bool) & inside))


def navigate_mimu(flight, w, f):
    """The MIMU navigated from the flight's initial state: through its mounting, or, on a
    rotating platform (`flight.mimu_platform`), in the sensor frame (`VehicleNavigator`)."""
    nav = _mimu_navigator(flight)
    return Trajectory.concatenate([nav.feed(flight.mimu_t, w, f), nav.finish()])


def navigate_mimu_at(flight, cal, at, less=(0.0, 0.0)):
    """The MIMU through `cal` navigated from the flight's initial state, kept at times `at`
    (s, increasing): block by block when the flight streams (`replay` without the reference
    IMU, the flags' counts or the checks); `less` (gyro rad/s, accel m/s^2, sensor axes)
    taken out of its outputs first."""
    nav, keep = _mimu_navigator(flight), Sampler(at)
    for t, w, f, _ in flight.mimu_blocks(cal):
        keep.add(nav.feed(t, w - less[0], f - less[1]))
    keep.add(nav.finish())
    return keep.trajectory()


def _mimu_navigator(flight):
    return VehicleNavigator(flight.mimu_mounting, flight.initial, flight.mimu_platform,
                            whole_record=flight.stream_block is None)


def navigate_fog(flight, at=None):
    """The reference IMU navigated from the flight's initial state (a recording's levelled
    on its own specific force: `reference_initial`), at times `at` (s; default every
    sample), block by block when the flight streams."""
    nav = VehicleNavigator(flight.fog_mounting, reference_initial(flight),
                           whole_record=flight.stream_block is None)
    keep = Sampler(at)
    for t, w, f in flight.fog_blocks():
        keep.add(nav.feed(t, w, f))
    keep.add(nav.finish())
    return keep.trajectory()


def reference_initial(flight):
    """The state the reference IMU is navigated from: the flight's initial state, but where
    an imported recording's attitude was levelled on the MIMU's own specific force over a
    rest (its `recording` metadata: initial_attitude "leveled", static_s), levelled again
    on the reference IMU's own over that rest, the heading kept - a quadrotor's MEMS unit,
    its horizontal accelerometer biases 2 mg, had tilted the shared start 0.13 deg and its
    FOG-grade reference ended 1.76 km off (174 m levelled so; 161 m from the true attitude),
    every ratio of the table to it 10 times too small. A simulated flight starts from the
    truth."""
    rec = flight.recording or {}
    if flight.source != "recording" or rec.get("initial_attitude") != "leveled" \
            or not rec.get("static_s") or flight.fog_t is None:
        return flight.initial
    t0, t1 = rec["static_s"]
    total, count = np.zeros(3), 0
    for t, _, f in flight.fog_blocks():
        inside = (t >= t0) & (t <= t1)
        total, count = total + f[inside].sum(axis=0), count + int(inside.sum())
        if t[-1] > t1:
            break
    if count < 10:
        return flight.initial
    roll, pitch = level(attitude.rotate(flight.fog_mounting.q_vs, total / count))
    yaw = attitude.as_euler(flight.initial.q_nb)[0]
    return replace(flight.initial, q_nb=attitude.from_euler(yaw, pitch, roll))


class Sampler:
    """Consecutive trajectory pieces (in time order) kept whole, or only at times `at` (s,
    increasing, inside the pieces' span within `resample`'s 1e-9 s; linear/slerp between
    states as `resample`)."""

    def __init__(self, at=None):
        self.at, self.parts, self.last, self.taken = at, [], None, None

    def add(self, piece):
        if piece is None or not len(piece):
            return
        if self.at is None:
            self.parts.append(piece)
            return
        span = piece if self.last is None else Trajectory.concatenate([self.last, piece])
        lo = (np.searchsorted(self.at, span.t[0] - 1e-9, side="left") if self.taken is None
              else self.taken)
        hi = max(lo, np.searchsorted(self.at, span.t[-1] + 1e-9, side="right"))
        if hi > lo:
            self.parts.append(resample(span, self.at[lo:hi]))
        self.last, self.taken = piece[-1:], hi

    def trajectory(self):
        out = Trajectory.concatenate(self.parts) if self.parts else None
        if self.at is not None and (out is None or len(out) != len(self.at)):
            raise InputError(f"times {self.at[0]:.3f}-{self.at[-1]:.3f} s lie outside the "
                             "navigated span"
                             + (f" {out.t[0]:.3f}-{self.last.t[-1]:.3f} s" if out else ""))
        return out


COMPENSATION_WARN = {"accel_m_s2": 0.2, "gyro_rad_s": 0.01}   # medians of |f|, |w| apart
QUIET = {"gyro_rad_s": 0.05, "accel_m_s2": 0.5}   # a quiet second: |w| and ||f| - g| below


def check_compensation(flight, mimu, label="the calibration"):
    """Warn when, in the flight's quiet seconds (the reference IMU turning slower than
    QUIET and feeling 1 g within QUIET), the compensated MIMU's and the reference IMU's
    1 s means differ in size (|f|, |w|: no mounting changes them, averaging removes the
    noise) by more than COMPENSATION_WARN (20 mg, 0.6 deg/s) in the median: a calibration
    written in other units (A0 in mg, ct scaled) gives navigation errors of 1e5 m without
    another sign. `mimu`: the compensated MIMU's SecondMeans of (f, w). Returns the two
    differences (m/s^2, rad/s), or None without a reference IMU or a quiet second."""
    from ..errors import warn
    if flight.fog_t is None:
        return None
    (fog_f, fog_w), seconds = flight.fog_second_means()
    (mimu_f, mimu_w), mimu_seconds = mimu.means()
    size = lambda x: np.linalg.norm(x, axis=1)                           # noqa: E731
    g = float(np.median(size(fog_f)))
    quiet = (size(fog_w) < QUIET["gyro_rad_s"]) & (np.abs(size(fog_f) - g) < QUIET["accel_m_s2"])
    common, i, j = np.intersect1d(seconds[quiet], mimu_seconds, return_indices=True)
    if not len(common):
        return None
    k = np.flatnonzero(quiet)[i]
    df = float(np.median(np.abs(size(mimu_f[j]) - size(fog_f[k]))))
    dw = float(np.median(np.abs(size(mimu_w[j]) - size(fog_w[k])))) \
        if flight.mimu_platform is None else 0.0        # a turning MIMU's |w| is not the FOG's
    if df > COMPENSATION_WARN["accel_m_s2"] or dw > COMPENSATION_WARN["gyro_rad_s"]:
        warn(f"{flight.path}: with {label}, in {len(common)} quiet seconds the MIMU's |f| "
             f"differs from the reference IMU's by {df:.3g} m/s^2 and its |w| by {dw:.3g} "
             f"rad/s in the median (a calibration that fits this unit leaves below "
             f"{COMPENSATION_WARN['accel_m_s2']:g} and {COMPENSATION_WARN['gyro_rad_s']:g}): "
             "another unit's file, units other than mimunav-calibration/1's (A0 in mg, ct "
             "scaled), or a model that misses this flight's temperatures?")
    return df, dw


def replay(flight, cal, fog=None, check=None, at=None):
    """Compensate and navigate the MIMU with `cal` and the FOG (or reuse `fog`), at times
    `at` (s; default every sample), block by block when the flight streams; with a `check`
    label, `check_compensation` warns about a calibration far off in quiet flight. The FOG
    is navigated on a thread meanwhile (reading, numpy and the navigator release the
    interpreter; the two read the log through their own handles)."""
    nav, keep, seconds = _mimu_navigator(flight), Sampler(at), SecondMeans()
    counts, stuck = dict.fromkeys(("replaced", "saturated", "unusable"), 0), 0
    with ThreadPoolExecutor(1) as pool:
        fog_nav = pool.submit(navigate_fog, flight, at) if fog is None else None
        for t, w, f, flags in flight.mimu_blocks(cal):
            if check is not None:
                seconds.add(t, f, w)
            for name, count in flag_counts(flags).items():
                counts[name] += count
            stuck += stuck_inside_range(flight, w, f, flags)
            keep.add(nav.feed(t, w, f))
        keep.add(nav.finish())
        fog = fog if fog_nav is None else fog_nav.result()
    warn_stuck(flight, stuck)
    if check is not None:
        check_compensation(flight, seconds, check)
    return Replay(flight, keep.trajectory(), fog, counts)


def comparison_times(flight, end=None, rate_hz=100.0):
    """Common comparison instants: the truth's stamps (or a rate_hz grid) from the initial
    state to `end` (default: the last instant every channel covers)."""
    t0, last = flight.initial.t, flight.end
    if end is None:
        end = last
    if end > last + 1e-9:
        raise InputError(f"{flight.path}: the requested end point {end:.3f} s is after the "
                         f"end of the recorded flight ({last:.3f} s since the epoch)")
    if end <= t0:
        raise InputError(f"the end point {end:.3f} s is not after the initial state "
                         f"({t0:.3f} s)")
    if flight.truth is not None:
        t = flight.truth.t[(flight.truth.t >= t0 - 1e-9) & (flight.truth.t <= end + 1e-9)]
    else:
        t = np.arange(t0, end + 1e-9, 1.0 / rate_hz)
    return t if abs(t[-1] - end) < 1e-9 else np.append(t, end)


def errors_at(rep, t):
    """Position (NED m), velocity (NED m/s) and attitude (rad) errors at times t of MIMU and
    FOG against the truth (if any) and of the MIMU against the FOG."""
    mimu, fog = resample(rep.mimu, t), resample(rep.fog, t)
    out = {"t": t, "mimu-fog": _diff(mimu, fog)}
    if rep.flight.truth is not None:
        ref = resample(rep.flight.truth, t)
        out["mimu-truth"], out["fog-truth"] = _diff(mimu, ref), _diff(fog, ref)
    return out


def _diff(a, b):
    return {"position": a.position_error(b), "velocity": a.velocity_error(b),
            "attitude": a.attitude_error(b)}


def ned_to_enu(d):
    return np.stack([d[..., 1], d[..., 0], -d[..., 2]], axis=-1)
