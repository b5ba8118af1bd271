"""Free-inertial windows on a recording with an external reference trajectory.

How fast does the IMU alone lose position? Along the drive, the IMU is restarted every
`step` seconds from the reference's position and velocity, with the reference's attitude
where it has one (an autopilot's or a fused pose's), else that of a moving two-vector
alignment (`alignment.moving_attitude`), and
navigated free-inertial (no aiding of any kind, vertical channel included) by the project's
strapdown navigator for 10, 30 and 60 s; the error is the navigated position minus the
reference's, NED m, at every reference epoch inside the window.

The gyro bias and the accelerometer bias along gravity are those of the rest at the start
of the recording, else of the longest rest in it, else 0 (`alignment`), removed from every
window; nothing else is calibrated. A window starts only where the reference is
moving faster than `alignment.COURSE_SPEED` (heading needs a course) and has no gap
longer than MAX_GAP_S inside. Windows of one length overlap when step < length, so they are
not independent: the summary gives the count of disjoint windows the recording holds.
"""
import math
import re
from dataclasses import dataclass

import numpy as np

from ..navigation import alignment
from ..navigation.rests import quiet_stretches, velocity_noise
from ..navigation.strapdown import check_median_force
from .replay import compensated_mimu, navigate, resample
from .flight import no_reference
from ..errors import InputError
from ..flightlog.stamps import missed_spans
from ..frames import attitude
from ..motion.carrier import course_keys, declared, recorded_kind
from ..motion.trajectory import State
from ..motion.track import position_jumps

WINDOW_LENGTHS_S = (10.0, 30.0, 60.0)
START_STEP_S = 5.0
MAX_GAP_S = 1.0             # s: largest reference gap allowed inside a window, at least
GAP_STEPS = 2.5             # and at least this many of the reference's own median steps: a
                            # 1 Hz GNSS track steps by 1 s +- its jitter, which a 1 s limit
                            # refused; one missed epoch (2 s) passes, two (3 s) do not


def gap_allowed(truth, max_gap=None):
    """The longest reference step (s) a window may hold: max_gap when given, else the larger
    of MAX_GAP_S and GAP_STEPS of the reference's median step."""
    if max_gap is not None:
        return max_gap
    step = float(np.median(np.diff(truth.t))) if len(truth.t) > 1 else 0.0
    return max(MAX_GAP_S, GAP_STEPS * step)


@dataclass
class Window:
    """One free-inertial run: start t0 (s), length (s), reference epochs t (s) inside it,
    position error (M, 3) NED m at them."""
    t0: float
    length: float
    t: np.ndarray
    error_ned: np.ndarray

    @property
    def horizontal(self):
        return np.hypot(self.error_ned[:, 0], self.error_ned[:, 1])


def track_of(truth):
    """The reference as the dict `alignment` takes (t s, lat, lon rad, h m, v_ned m/s,
    q_nb wxyz: NaN rows where the reference has no attitude)."""
    return dict(t=truth.t, lat=truth.lat, lon=truth.lon, h=truth.h, v_ned=truth.v_ned,
                q_nb=attitude.as_wxyz(truth.q_nb))


def starts(truth, length, step=START_STEP_S, first=0.0, min_speed=alignment.COURSE_SPEED,
           max_gap=MAX_GAP_S, t_imu=None, parked=(), half=alignment.MOVING_HALF_WINDOW_S,
           jumps=()):
    """Window starts (s) on a grid of `step` from `first`: moving faster than min_speed
    (m/s, horizontal; the track's velocity averaged over the alignment interval, t0 +-
    half: a walker's 4 m fixes had passed 3 m/s epoch by epoch while it stood), the whole
    window (and the alignment interval before it) covered without a gap longer than max_gap
    (s) in the reference or in the IMU's stamps t_imu, and the alignment interval without a
    step of the reference beyond GAP_STEPS of its median step,
    the alignment interval (t0 +- half s) outside the rests `parked` [(t0, t1) s] (a noisy
    fix's differenced speed passes the speed gate while the car stands: its course, and so
    the window's heading, is noise), and no step of the reference off its own velocity
    (`jumps`, s: `reference_jumps`) from the alignment interval to the window's end (an
    INS's 2.3 m jump back to its fixes after an outage had made a 10 s window's 3.46 m,
    its neighbours' 0.55 m, with no word)."""
    end = truth.t[-1] if t_imu is None else min(truth.t[-1], t_imu[-1])    # both must cover it
    grid = np.arange(max(first, truth.t[0] + half), end - length, step)
    speed = alignment.mean_speed({"t": truth.t, "v_ned": truth.v_ned}, half)   # not one epoch
    gaps = [truth.t] + ([] if t_imu is None else [t_imu])
    wide = [np.diff(t) > max_gap for t in gaps]
    gap_start = np.concatenate([t[:-1][w] for t, w in zip(gaps, wide)])
    gap_end = np.concatenate([t[1:][w] for t, w in zip(gaps, wide)])
    # the start state is the reference's at t0: no step beyond GAP_STEPS of its own in the
    # alignment interval (a multicopter's window started inside a 0.5 s mocap dropout, its
    # state interpolated across it, had ended 76 m off where its neighbours ended 22 m off)
    missed_from, missed_to = missed_spans(truth.t, GAP_STEPS)
    out = []
    for t0 in grid:
        if np.interp(t0, truth.t, speed) < min_speed:
            continue
        # a gap [start, end] that meets the window with its alignment interval
        if np.any((gap_end > t0 - half) & (gap_start < t0 + length)):
            continue
        if np.any((missed_to > t0 - half) & (missed_from < t0 + half)):
            continue
        if any(a - half < t0 < b + half for a, b in parked):
            continue
        if any(t0 - half < t_j <= t0 + length for t_j in jumps):
            continue
        out.append(float(t0))
    return np.asarray(out)


def why_no_windows(truth, lengths, first, min_speed, max_gap, half):
    """Why a recording holds no window: the conditions of `starts` the reference fails as a
    whole (its speed never reaching min_speed; too short a span after the rest for the
    shortest window and its alignment interval of +-half s), named as such, then those it
    meets; a reference gap above max_gap only leaves out the windows it meets, so it is said
    as such, not as the cause. All met: the windows' other conditions (the gaps, the IMU's,
    the rests at standstill) leave none."""
    speed = alignment.mean_speed({"t": truth.t, "v_ned": truth.v_ned}, half)   # as `starts`
    span = truth.t[-1] - max(first, truth.t[0] + half)
    gaps = np.diff(truth.t)
    largest, length = (gaps.max() if len(gaps) else 0.0), min(lengths)
    conditions = [
        (span > length, f"{length:g} s of reference after the rest and the alignment's "
                        f"{half:.3g} s (it holds {max(span, 0.0):.1f} s: a shorter window, "
                        "mimunav windows --lengths)")]
    if min_speed > 0:                       # a speed of 0 is no condition to name
        conditions.insert(0, (speed.max() >= min_speed,
                              f"a horizontal speed of {min_speed:g} m/s at a window's start "
                              f"(the reference peaks at {speed.max():.2f} m/s over "
                              f"+-{half:.3g} s: mimunav windows --min-speed)"))
    failed = [text for ok, text in conditions if not ok]
    met = [text for ok, text in conditions if ok]
    head = f"no free-inertial window of {length:g} s fits this recording: "
    gap = (f"; the reference's gaps above {max_gap:g} s (the largest {largest:.2f} s: "
           "mimunav windows --max-gap) leave out the windows they meet"
           if largest > max_gap else "")
    if failed:
        return head + "it lacks " + "; ".join(failed) + \
            (f" (it has {'; '.join(met)}{gap})" if met else gap)
    return head + f"it has {'; '.join(met)}, but the gaps (the reference's and the IMU's), " \
        f"the rests at standstill and the reference's jumps leave no window{gap}"


def run(flight, t0, length, w, f, t_imu=None, half=alignment.MOVING_HALF_WINDOW_S):
    """One window from reference start t0 (moved to the IMU stamp at or before it) over
    `length` s; w rad/s, f m/s^2 sensor axes at stamps t_imu (default flight.mimu_t), the
    biases already removed; `half`: the moving alignment's half interval (s) when the
    reference has no attitude."""
    t = flight.mimu_t if t_imu is None else t_imu
    truth = flight.truth
    k0 = int(np.searchsorted(t, t0, side="right")) - 1
    t_start = float(t[k0])
    start = resample(truth, np.array([t_start]))
    q_nb = attitude.as_wxyz(start.q_nb[0])
    if not np.isfinite(q_nb).all():         # the reference has no attitude: align moving
        q_nb = alignment.moving_attitude(t, w, f, flight.mimu_mounting, track_of(truth),
                                         t_start, half)
    initial = State(t_start, float(start.lat[0]), float(start.lon[0]), float(start.h[0]),
                    start.v_ned[0].copy(), attitude.from_wxyz(q_nb))
    sel = slice(k0, int(np.searchsorted(t, t_start + length, side="right")) + 1)
    nav = navigate(t[sel], w[sel], f[sel], flight.mimu_mounting, initial, whole_record=False)
    epochs = truth.t[(truth.t > t_start) & (truth.t <= min(t_start + length, nav.t[-1]))]
    err = resample(nav, epochs).position_error(resample(truth, epochs))
    return Window(t_start, length, epochs, err)


def run_all(flight, cal=None, lengths=WINDOW_LENGTHS_S, step=START_STEP_S, time_shift_s=0.0,
            progress=False, min_speed=None, max_gap=None):
    """All windows of each length: {length: [Window]}, and the alignment at rest that gave
    the gyro bias. The MIMU is compensated with `cal` (`evaluation.compensated_mimu`: for a
    recorded /mimu/imu, None or found terms on an identity base); time_shift_s is added to
    the IMU's stamps (negative: the IMU lags); min_speed (m/s; default: the course speed
    `alignment.COURSE_SPEED` when the reference has no attitude, 0 when it has one) and
    max_gap (s; default `gap_allowed`) as `starts`.
    A recording that holds no window at all is a ValueError that says why."""
    if flight.mimu_platform is not None:
        raise InputError(f"{flight.path}: the MIMU turns on a platform (/mimu/platform); "
                         "this analysis does not follow the rotation yet - replay and table do")
    if flight.truth is None:
        raise no_reference(flight.path, "the free-inertial windows")
    w, f, _ = compensated_mimu(flight, cal)
    max_gap = gap_allowed(flight.truth, max_gap)
    t = flight.mimu_t + time_shift_s
    check_median_force(t[1:], f[1:] * np.diff(t)[:, None])    # the whole record's, once
    track = dict(track_of(flight.truth), **course_keys(*recorded_kind(flight.recording or {})))
    half = moving_half(track)
    if half and not track["faces_course"]:
        raise InputError(
            f"{flight.path}: the windows would start each from the reference's velocity, its "
            f"course taken for the heading - and {declared(track['vehicle'])} need not face "
            "its course (a balloon spins under its envelope, a walker's phone points "
            "anywhere): a reference with attitude is needed")
    rest = alignment.initial_alignment(t, w, f, flight.mimu_mounting, track)
    w, f = w - rest.gyro_bias, f - rest.accel_bias
    out = {}
    if min_speed is None:
        min_speed = alignment.COURSE_SPEED if half else 0.0
    first = rest.navigable_from
    parked = quiet_stretches(t, w, f, track) if half else ()
    jumps = [t_j for t_j, _ in reference_jumps(flight.truth)]
    todo = [(length, t0) for length in lengths
            for t0 in starts(flight.truth, length, step, first, min_speed, max_gap, t, parked,
                             half or alignment.MOVING_HALF_WINDOW_S, jumps)]
    if not todo:
        raise InputError(f"{flight.path}: " + why_no_windows(
            flight.truth, lengths, first, min_speed, max_gap,
            half or alignment.MOVING_HALF_WINDOW_S))
    if progress:
        from tqdm import tqdm
        todo = tqdm(todo, desc="windows", unit="window", disable=None)   # a terminal's only
    for length, t0 in todo:
        out.setdefault(length, []).append(run(flight, t0, length, w, f, t,
                                              half or alignment.MOVING_HALF_WINDOW_S))
    return out, rest


def reference_jumps(truth):
    """[(t s, m)]: the reference's steps off its own velocity (`motion.track.position_jumps`),
    which no window spans."""
    return position_jumps(truth.t, truth.lat, truth.lon, truth.h, truth.v_ned)


def moving_half(track):
    """The moving alignment's half interval (s, `alignment.moving_half_window`) when the
    windows align on the reference's velocity (it has no attitude), else None."""
    if np.isfinite(track["q_nb"]).all():
        return None
    return alignment.moving_half_window(track)


def summary(results, reference_meta=None, track=None, half=None):
    """Per length: number of windows, how many of them are disjoint, and percentiles
    (50, 68, 95, max) of the end-point horizontal and vertical errors (m), the median
    drift rate (horizontal end error / length, m/s), and the part of the end error the
    reference alone explains (`reference_floor`; `track` and `half`: the reference track
    whose velocity noise stands in for an unstated velocity sigma, and the moving
    alignment's half interval when the windows were aligned on it)."""
    sigma_v = None if track is None else velocity_noise(track)
    rows = {}
    for length, wins in sorted(results.items()):
        hor = np.array([w.horizontal[-1] for w in wins])
        up = np.array([abs(w.error_ned[-1, 2]) for w in wins])
        rows[length] = {"windows": len(wins), "disjoint": _disjoint(wins, length),
                        "horizontal_m": _percentiles(hor), "vertical_m": _percentiles(up),
                        "median_rate_m_s": float(np.median(hor) / length),
                        "reference_floor": reference_floor(reference_meta or {}, length,
                                                           sigma_v, half)}
    return rows


def _disjoint(wins, length):
    """The most windows of `wins` (each `length` s) that do not overlap, taken in order of
    their starts (the span's capacity had been given: '13 (45)' for 13 windows)."""
    count, free_from = 0, -math.inf
    for t0 in sorted(w.t0 for w in wins):
        if t0 >= free_from:
            count, free_from = count + 1, t0 + length
    return count


def reference_floor(meta, length, measured_sigma_v=None, half=None):
    """The horizontal end error (m, rms of the 2-D norm) a window of `length` s shows from
    the reference's own errors alone, from its stated sigmas (`reference` metadata:
    position_sigma_m horizontal, velocity_sigma_m_s horizontal): the start position (taken
    from the reference) and the end position it is compared with each carry sigma_p, the
    start velocity sigma_v grows as sigma_v * length; independent, so
    floor = sqrt(2 sigma_p^2 + (sigma_v length)^2). An unstated velocity sigma is taken from
    `measured_sigma_v` (per axis, `alignment.velocity_noise`: 2-D sqrt(2) times it) when
    given, and said ("estimated"). With `half` (s, a moving alignment on the reference's
    velocity) its tilt adds sqrt(2) a length^2 / 2, a = sqrt(2) sigma_axis / (2 half) the
    error of the interval's mean acceleration (`alignment_tilt_m`, with `alignment_half_s`:
    it grows as length^2 and soon is most of the floor; `position_ends_m` the position's
    part, sqrt(2) sigma_p). Unstated sigmas are left out and
    named; a reference attitude's own error (g sigma_tilt length^2 / 2) is not included: no
    source states it."""
    def number(key):            # a leading number: "3 (horizontalAccuracy column)" is 3
        said = re.match(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)",
                        str(meta.get(key, "")))
        value = float(said.group(1)) if said else math.nan
        return value if np.isfinite(value) and value >= 0 else None
    sigma_p, sigma_v = number("position_sigma_m"), number("velocity_sigma_m_s")
    estimated = []
    if sigma_v is None and measured_sigma_v is not None:
        sigma_v = math.sqrt(2) * measured_sigma_v
        estimated.append("velocity")
    missing = [k for k, v in (("position", sigma_p), ("velocity", sigma_v)) if v is None]
    if sigma_p is None and sigma_v is None:
        return {"horizontal_m": None, "not_stated": missing, "estimated": estimated}
    terms = 2 * (sigma_p or 0.0) ** 2 + ((sigma_v or 0.0) * length) ** 2
    out = {"not_stated": missing, "estimated": estimated}
    if sigma_p:             # the ends' errors taken independent: a drift shared by both is
        out["position_ends_m"] = math.sqrt(2) * sigma_p      # less (an INS+DVL's, 6 cm in 10 s)
    if half and sigma_v:        # a difference of two velocities: sqrt(2) sigma_v, 2-D already
        tilt = math.sqrt(2) * sigma_v / (2 * half) * length ** 2 / 2
        terms += tilt ** 2
        out.update(alignment_tilt_m=tilt, alignment_half_s=half)
    return {"horizontal_m": math.sqrt(terms), **out}


def _percentiles(x):
    return {"p50": float(np.percentile(x, 50)), "p68": float(np.percentile(x, 68)),
            "p95": float(np.percentile(x, 95)), "max": float(np.max(x))}
