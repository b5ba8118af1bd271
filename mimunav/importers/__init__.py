"""Recordings that nobody here wrote, turned into contract logs (`mimunav-log/1`).

    rtklib   a CSV IMU log with RTKLIB time tags and an RTKLIB position solution
    ros2     any ROS 2 MCAP with sensor_msgs/msg/Imu (+ sensor_msgs/msg/NavSatFix), by topic
    ulog     a PX4 ULog (sensor_combined + vehicle_gps_position / sensor_gps), by pyulog
    dataflash  an ArduPilot DataFlash .bin (IMU, GPS, GPA; EKF3 POS/XKF1/ATT), by pymavlink

Each reader returns a `Recording` - the IMU in SI units and its own axes, the GNSS and
reference data it has, and what is measured and what is assumed - and `write_log` writes
it: `/mimu/imu` (calibrated units, not compensated beyond the recorder's own scaling),
`/truth/state` when an external reference exists (attitude unknown: NaN quaternion, and
`reference.attitude = "unknown"` in the metadata), `/gnss/fix` (latitude and longitude in
rad as the contract's conventions say - not ROS's degrees - and position_covariance ENU m^2), the `flight` metadata with
an `initial_state` from `alignment.initial_alignment`, `sensor/mimu`, and `recording` (what is
real, what was assumed).
"""
import contextlib
import json
import math
from dataclasses import dataclass, field

import numpy as np
import quaternion

from .. import alignment, attitude, earth
from ..flightlog import LogWriter
from ..flightlog import schemas as S
from ..sensors import Mounting
from ..errors import InputError

UNKNOWN_ATTITUDE = np.full(4, np.nan)
G0 = 9.80665                # m/s^2, standard gravity: the size a check of units compares with
WRITE_BLOCK_S = 10.0        # s: channels are written interleaved in blocks of this much time
# a position difference across a longer gap is no velocity (a car turns in 2 s; a few lost
# epochs at 4-10 Hz still difference well)
VELOCITY_GAP_EPOCHS, VELOCITY_GAP_S = 5, 2.0
GPS_EPOCH_UNIX_S = 315964800            # 1980-01-06T00:00:00Z, the start of GPS time
# GPS - UTC, s, from the GPS time (s since the GPS epoch) at which each took effect (IERS
# Bulletin C; none added after 2017-01-01)
LEAP_SECONDS = ((0, 0), (46828800, 7), (78364801, 8), (109900802, 9), (173059203, 10),
                (252028804, 11), (315187205, 12), (346723206, 13), (820108813, 14),
                (914803214, 15), (1025136015, 16), (1119744016, 17), (1167264017, 18))


class RecordingError(InputError):
    """A recording that cannot be turned into a contract log, with what and where."""


@dataclass
class Recording:
    """A foreign recording in SI units.

    imu_ns: IMU stamps, integer ns since the UNIX epoch (N,), strictly increasing;
    w: angular rate, rad/s, IMU sensor axes (N, 3); f: specific force, m/s^2 (N, 3);
    reference: optional external trajectory {ns, lat, lon (rad), h (m), v_ned (m/s, (M, 3)),
      optional q_nb (M, 4) wxyz vehicle FRD -> NED (NaN rows: unknown)}, described by
      `reference_meta` {source, independent ("yes"/"no: why"), position_sigma_m, ...};
    fixes: optional GNSS fixes {ns, lat, lon, h, status (int8 as
      in NavSatStatus), covariance (M, 9) m^2 ENU}; real / assumed: what the metadata says
      is measured and what this import assumed;
    reference_imu: optional second IMU flown with it that serves as the reference IMU
      (/fog/imu: the sensor level of the diagnosis) {ns, w rad/s, f m/s^2 (its sensor axes),
      mounting (`Mounting`), model, optional accuracy (`diagnosis.reference.Accuracy` keys)}."""
    name: str
    description: str
    imu_ns: np.ndarray
    w: np.ndarray
    f: np.ndarray
    mounting: Mounting
    model: str = "unknown"
    reference: dict | None = None
    reference_meta: dict = field(default_factory=dict)
    fixes: dict | None = None
    real: dict = field(default_factory=dict)
    assumed: dict = field(default_factory=dict)
    reference_imu: dict | None = None

    def __post_init__(self):
        self.imu_ns = np.asarray(self.imu_ns, dtype=np.int64)
        n = len(self.imu_ns)
        for name in ("w", "f"):
            x = np.asarray(getattr(self, name), dtype=float)
            if x.shape != (n, 3):
                raise RecordingError(f"{self.name}: IMU {name} has shape {x.shape}, expected "
                                   f"({n}, 3)")
            setattr(self, name, x)
        if n < 2:
            raise RecordingError(f"{self.name}: fewer than two IMU samples")
        if np.any(np.diff(self.imu_ns) <= 0):
            k = int(np.argmax(np.diff(self.imu_ns) <= 0))
            raise RecordingError(f"{self.name}: IMU stamps do not increase at sample {k + 1}"
                                 + _wrap_hint(self.imu_ns[k + 1] - self.imu_ns[k]))
        bad = ~np.isfinite(np.hstack([self.w, self.f])).all(axis=1)
        if bad.any():
            raise RecordingError(f"{self.name}: {bad.sum()} IMU samples are not finite (first at "
                               f"sample {int(np.argmax(bad))}); a log must not carry them")
        if self.reference_imu is not None:
            self.reference_imu = _checked_reference_imu(self.name, self.reference_imu)

    @property
    def sample_rate_hz(self):
        return float(1e9 / np.median(np.diff(self.imu_ns)))


@contextlib.contextmanager
def text_file(path):
    """Turn a UnicodeDecodeError while reading `path` as text into a RecordingError naming
    the file (a binary or damaged file where a text one belongs)."""
    try:
        yield
    except UnicodeDecodeError as exc:
        raise RecordingError(f"{path}: not a text file (byte {exc.object[exc.start]:#04x} at "
                             f"offset {exc.start} is not UTF-8): is it the right file, or "
                             "damaged?") from None


def _checked_reference_imu(name, ref):
    """The reference IMU dict with ns int64, w and f (N, 3) float, its stamps increasing and
    its values finite - else a RecordingError naming it."""
    ref = dict(ref)
    ref["ns"] = np.asarray(ref["ns"], dtype=np.int64)
    n = len(ref["ns"])
    for key in ("w", "f"):
        ref[key] = np.asarray(ref[key], dtype=float)
        if ref[key].shape != (n, 3):
            raise RecordingError(f"{name}: reference IMU {key} has shape {ref[key].shape}, "
                                 f"expected ({n}, 3)")
    if n < 2 or np.any(np.diff(ref["ns"]) <= 0):
        raise RecordingError(f"{name}: the reference IMU's stamps do not increase (or fewer "
                             "than two samples)")
    bad = ~np.isfinite(np.hstack([ref["w"], ref["f"]])).all(axis=1)
    if bad.any():
        raise RecordingError(f"{name}: {bad.sum()} reference IMU samples are not finite (first "
                             f"at sample {int(np.argmax(bad))})")
    return ref


# counters that loggers stamp with, and the jump back their wrap makes (ns)
COUNTER_WRAPS = {"a 32-bit microsecond counter": 2**32 * 1000, "a 32-bit millisecond counter":
                 2**32 * 1_000_000, "a 16-bit millisecond counter": 2**16 * 1_000_000}


def _wrap_hint(step_ns):
    """': ... wrapped' when a step back of step_ns (< 0) is a known counter's wrap, else ''."""
    for what, span in COUNTER_WRAPS.items():
        if abs(-int(step_ns) - span) < 0.01 * span:
            return (f" (back by {-int(step_ns) / 1e9:.6g} s: {what} wrapped there; unwrap the "
                    f"time column by adding {span / 1e9:.6g} s after each wrap)")
    return ""


def gps_to_unix_s(gps_s):
    """UNIX (UTC) seconds of GPS times (s since 1980-01-06), the leap seconds then in force
    removed."""
    gps_s = np.asarray(gps_s, dtype=float)
    starts, leaps = np.array(LEAP_SECONDS).T
    return gps_s + GPS_EPOCH_UNIX_S - leaps[np.searchsorted(starts, gps_s, side="right") - 1]


def attitude_at(t, t_att, wxyz):
    """Attitudes (M, 4) wxyz at times t (M,) by slerp between the recorded attitudes wxyz
    (K, 4) at increasing times t_att (K,) (same time unit); NaN outside their span."""
    from scipy.spatial.transform import Rotation, Slerp
    q = np.full((len(t), 4), np.nan)
    inside = (t >= t_att[0]) & (t <= t_att[-1])
    xyzw = Slerp(t_att, Rotation.from_quat(np.asarray(wxyz)[:, [1, 2, 3, 0]]))(
        np.asarray(t, float)[inside]).as_quat()
    q[inside] = xyzw[:, [3, 0, 1, 2]]
    return q


# Hz: an IMU stream read slower than this is a status snapshot (PX4's sensor_accel and
# sensor_gyro topics logged at 1 Hz), not the interval means a strapdown navigator needs -
# a vehicle turns and vibrates faster; consumer IMUs are logged at 50-1000 Hz
MIN_IMU_RATE_HZ = 10.0


def _check_rate(name, which, ns):
    """Refuse an IMU whose median sample rate is below MIN_IMU_RATE_HZ."""
    rate = 1e9 / float(np.median(np.diff(ns)))
    if rate < MIN_IMU_RATE_HZ:
        raise RecordingError(f"{name}: the {which} has {len(ns)} samples at {rate:.3g} Hz (median "
                             f"interval); below {MIN_IMU_RATE_HZ:g} Hz they are status snapshots, "
                             "not increments a navigator can integrate: choose the IMU's "
                             "full-rate stream (or check the stamps' time unit)")


def check_recording(rec):
    """Refuse a recording whose IMU cannot be in the units and axes the import says: a
    rate below MIN_IMU_RATE_HZ (either IMU); the
    median |specific force| far from 1 g (g read as m/s^2 or the reverse); with a reference
    attitude, the 1 s mean specific force turned into NED by the mounting and that attitude
    not pointing up (axes, mounting or quaternion convention wrong), or the gyro's rates a
    factor of ten or more from the attitude's own rate (deg/s read as rad/s)."""
    _check_overlap(rec)             # first: stamps in the wrong unit fail it, and it says so
    _check_rate(rec.name, "IMU", rec.imu_ns)
    if rec.reference_imu is not None:
        _check_rate(rec.name, "reference IMU", rec.reference_imu["ns"])
        _check_reference_imu(rec)
    g = float(np.median(np.linalg.norm(rec.f, axis=1)))
    if not 0.5 * G0 < g < 2 * G0:
        raise RecordingError(f"{rec.name}: the median |specific force| is {g:.3g} m/s^2; a "
                             "vehicle on Earth feels about 9.8: is the accelerometer's unit "
                             "(g or m/s^2) right?")
    ref = rec.reference
    q = None if ref is None else ref.get("q_nb")
    if q is None or np.isfinite(q).all(axis=1).sum() < 10:
        _check_against_course(rec)
        return
    ok = np.isfinite(q).all(axis=1)
    t_ref = ref["ns"][ok]
    k = np.clip(np.searchsorted(rec.imu_ns, t_ref), 0, len(rec.imu_ns) - 1)
    q_ns = quaternion.from_float_array(q[ok]) * rec.mounting.q_vs
    f_n = np.median(attitude.rotate(q_ns, _local_mean(rec.f, k)), axis=0)
    if f_n[2] > -0.8 * g or np.hypot(f_n[0], f_n[1]) > 0.3 * g:
        raise RecordingError(f"{rec.name}: the specific force turned into NED by the mounting and "
                             f"the reference attitude is {np.round(f_n, 2).tolist()} m/s^2 in the "
                             f"median, not [0, 0, -{g:.1f}]: the sensor axes, the mounting or "
                             "the attitude quaternion's convention (body -> NED or ECEF) is wrong")
    rate = attitude.turn_rate(t_ref / 1e9, quaternion.from_float_array(q[ok]))
    ref_rate = float(np.percentile(rate, 99))
    imu_rate = float(np.percentile(np.linalg.norm(_local_mean(rec.w, k), axis=1), 99))
    if ref_rate > 0.05 and not 0.1 < imu_rate / ref_rate < 10:
        raise RecordingError(f"{rec.name}: the gyro's rates reach {imu_rate:.3g}, the reference "
                             f"attitude turns at up to {ref_rate:.3g} rad/s: is the gyro's unit "
                             "(deg/s or rad/s) right?")


def _check_reference_imu(rec):
    """The reference IMU must feel 1 g, overlap the IMU in time over at least half the IMU's
    span, and - where either turns - see the same size of rotation in its 1 s means (|w|
    does not depend on the mounting: a ratio beyond 0.5-2 is a unit, deg/s read as rad/s,
    or another vehicle's topic); its stamps must agree with the IMU's within
    REFERENCE_IMU_MAX_OFFSET_S (`reference_imu_offset_s`: a larger clock offset is beyond
    the diagnosis' linear time_skew term - 50 ms came out as 41 ms with spurious scale
    factors beside it); and the two mountings must bring both IMUs' 1 s mean rates and
    specific forces to the vehicle frame within REFERENCE_IMU_MAX_TURN_DEG of each other
    (a reference 10 deg off in yaw gave the misalignment and cos 10 deg - 1 as scale
    factors; 90 deg crashed the diagnosis; its axes forgotten, gravity pointed up)."""
    ref = rec.reference_imu
    g = float(np.median(np.linalg.norm(ref["f"], axis=1)))
    if not 0.5 * G0 < g < 2 * G0:
        raise RecordingError(f"{rec.name}: the reference IMU's median |specific force| is "
                             f"{g:.3g} m/s^2, not about 9.8: is its accelerometer's unit right?")
    lo, hi = max(rec.imu_ns[0], ref["ns"][0]), min(rec.imu_ns[-1], ref["ns"][-1])
    if hi - lo < 0.5 * (rec.imu_ns[-1] - rec.imu_ns[0]):
        raise RecordingError(f"{rec.name}: the reference IMU ({_utc(ref['ns'][0])} .. "
                             f"{_utc(ref['ns'][-1])}) covers less than half of the IMU's span "
                             f"({_utc(rec.imu_ns[0])} .. {_utc(rec.imu_ns[-1])}): do the two "
                             "share a time base?")
    mids = np.arange(lo + 500_000_000, hi - 500_000_000, 1_000_000_000) / 1e9
    if len(mids) < 10:
        return
    means = [[alignment.means_around(ns / 1e9, x, mids, 0.5) for x in (w, f)]
             for ns, w, f in ((rec.imu_ns, rec.w, rec.f), (ref["ns"], ref["w"], ref["f"]))]
    ok = np.isfinite(np.hstack([m for pair in means for m in pair])).all(axis=1)
    if ok.sum() < 10:
        return
    size = [np.linalg.norm(pair[0][ok], axis=1) for pair in means]
    spread = [float(np.std(x)) for x in size]
    if max(spread) > COURSE_CHECK_RATE:
        ratio = spread[0] / max(spread[1], 1e-12)
        if not 0.5 < ratio < 2.0:
            raise RecordingError(f"{rec.name}: the IMU's rotation rate varies {ratio:.3g} times "
                                 "as much as the reference IMU's (1 s means of |w|): is one "
                                 "gyro's unit (deg/s or rad/s) wrong, or the topic another "
                                 "vehicle's?")
        offset = reference_imu_offset_s(rec)
        if abs(offset) > REFERENCE_IMU_MAX_OFFSET_S:
            raise RecordingError(
                f"{rec.name}: the reference IMU's stamps are {offset * 1e3:+.1f} ms off the "
                f"IMU's (|w| of the two best aligned so): shift them with "
                f"--reference-imu-time-offset {-offset:.4f} (the diagnosis' time_skew is a "
                f"small-offset term)")
    mine = [attitude.rotate(rec.mounting.q_vs, x[ok]) for x in means[0]]
    theirs = [attitude.rotate(ref["mounting"].q_vs, x[ok]) for x in means[1]]
    from scipy.spatial.transform import Rotation
    turn, _ = Rotation.align_vectors(np.vstack(mine), np.vstack(theirs))
    angle = math.degrees(turn.magnitude())
    if angle > REFERENCE_IMU_MAX_TURN_DEG:
        x, y, z, w = turn.as_quat()
        fixed = np.quaternion(w, x, y, z) * ref["mounting"].q_vs
        yaw, pitch, roll = (_angle_text(a) for a in attitude.as_euler(fixed))
        raise RecordingError(
            f"{rec.name}: the reference IMU's rates and specific forces, turned into the vehicle "
            f"frame by its mounting, lie {angle:.1f} deg from the IMU's: is its mounting (axes) "
            f"right? They would agree with --reference-imu-rpy-deg {roll} {pitch} {yaw} (the "
            "diagnosis finds mounting misalignments of a few degrees at most)")


def _angle_text(rad):
    """An angle in deg to 0.1 for a command line: -180 written 180, no -0.0."""
    deg = round(math.degrees(float(rad)), 1)
    return f"{180.0 if deg == -180.0 else deg + 0.0:.1f}"


REFERENCE_IMU_MAX_OFFSET_S = 0.01      # s between the two IMUs' stamps the diagnosis takes
REFERENCE_IMU_MAX_TURN_DEG = 3.0       # deg between their vehicle frames (a small-angle term)


def reference_imu_offset_s(rec, search_s=1.0, step_s=0.001):
    """How late (s) the reference IMU's stamps are on the IMU's, as the stamps of interval
    means: the shift of the reference's |w| (which does not depend on either mounting) that
    best matches the IMU's over their common span, on a grid of step_s within +-search_s
    refined by a parabola."""
    ref = rec.reference_imu
    # each sample is the mean over the interval its stamp ends: compare interval centres
    # (a 100 Hz and a 400 Hz IMU on one clock are 3.75 ms apart by their stamps alone)
    t, t_r = (ns / 1e9 - 0.5 * np.median(np.diff(ns)) / 1e9 for ns in (rec.imu_ns, ref["ns"]))
    grid = np.arange(max(t[0], t_r[0]) + search_s, min(t[-1], t_r[-1]) - search_s, 0.01)
    a = np.interp(grid, t, np.linalg.norm(rec.w, axis=1))
    size_r = np.linalg.norm(ref["w"], axis=1)
    shifts = np.arange(-search_s, search_s + 1e-9, step_s)
    cost = np.array([np.mean((a - np.interp(grid + d, t_r, size_r)) ** 2) for d in shifts])
    i = int(np.clip(np.argmin(cost), 1, len(shifts) - 2))
    lo, mid, hi = cost[i - 1:i + 2]
    curve = lo - 2 * mid + hi
    return float(shifts[i] + (0.5 * step_s * (lo - hi) / curve if curve > 0 else 0.0))


def _utc(ns):
    return np.datetime_as_string(np.datetime64(int(ns), "ns"), unit="s") + "Z"


def _check_overlap(rec):
    """Refuse a reference or GNSS fixes whose time span does not overlap the IMU's: two
    time bases (boot time, GPS week seconds, UNIX time) read as one."""
    lo, hi = int(rec.imu_ns[0]), int(rec.imu_ns[-1])
    for what, src in (("reference's", rec.reference), ("GNSS fixes'", rec.fixes)):
        if src is None or not len(src["ns"]):
            continue
        a, b = int(np.min(src["ns"])), int(np.max(src["ns"]))
        if b < lo or a > hi:
            ratio = (hi - lo) / max(b - a, 1)
            unit = (f"; the IMU's span is {ratio:.3g} times the {what}: is the IMU's time "
                    "unit right (s, ms, us)?"
                    if ratio > 300 or ratio < 1 / 300 else "")
            raise RecordingError(
                f"{rec.name}: the IMU's stamps span {_utc(lo)} - {_utc(hi)}, the {what} "
                f"{_utc(a)} - {_utc(b)}: they do not overlap, so the two are on different time "
                "bases (time since boot, GPS week seconds, UNIX time): give both the same"
                + unit)


def velocity_from_positions(ns, lat, lon, h):
    """NED velocity (m/s, (M, 3)), each epoch's in its own local NED, of geodetic positions
    (rad, rad, m) at stamps ns (int ns): central differences of the ECEF positions over the
    neighbouring epochs (one-sided at the ends), turned into the epoch's NED; NaN where a
    neighbour lies more than VELOCITY_GAP_EPOCHS median epoch intervals and VELOCITY_GAP_S
    away (no velocity across a gap: the rows to leave out of a reference). (Differences in
    the first epoch's NED had tilted the velocity by the distance travelled over the Earth's
    radius: 0.1 m/s north and down at 25 km of a 25 m/s drive east.)"""
    t = (np.asarray(ns, np.int64) - int(ns[0])) / 1e9
    v_e = np.gradient(earth.geodetic_to_ecef(lat, lon, h), t, axis=0)
    v = np.einsum("kji,kj->ki", earth.ned_to_ecef_matrix(lat, lon), v_e)
    dt = np.diff(t)
    wide = dt > max(VELOCITY_GAP_EPOCHS * np.median(dt), VELOCITY_GAP_S)
    v[np.concatenate([[False], wide]) | np.concatenate([wide, [False]])] = np.nan
    return v


def velocity_lag_s(ref, search_s=1.0, step_s=0.005):
    """How late (s) the reference's own velocity is against the velocity of its positions
    (central differences: zero phase): the shift minimising their rms horizontal difference
    over epochs faster than alignment.COURSE_SPEED, refined by a parabola; None with fewer
    than 50 such epochs. A filtered velocity state lags (RTKLIB's on the drive_0708 solution:
    115 ms), and a lag found against the reference is then one against that velocity's
    timing."""
    v = np.asarray(ref["v_ned"], float)
    v_pos = velocity_from_positions(ref["ns"], ref["lat"], ref["lon"], ref["h"])
    t = (np.asarray(ref["ns"], np.int64) - int(ref["ns"][0])) / 1e9
    ok = np.isfinite(v_pos).all(axis=1) & np.isfinite(v).all(axis=1) & \
        (np.hypot(v[:, 0], v[:, 1]) > alignment.COURSE_SPEED) & \
        (t > t[0] + search_s) & (t < t[-1] - search_s)
    if ok.sum() < 50:
        return None
    good = np.isfinite(v_pos).all(axis=1)
    taus = np.arange(-search_s, search_s + 1e-9, step_s)
    cost = np.array([np.mean([(v[ok, i] - np.interp(t[ok] - tau, t[good], v_pos[good, i])) ** 2
                              for i in range(2)]) for tau in taus])
    i = int(np.clip(np.argmin(cost), 1, len(taus) - 2))
    a, b, c = cost[i - 1:i + 2]
    curve = a - 2 * b + c
    return float(taus[i] + (0.5 * step_s * (a - c) / curve if curve > 0 else 0.0))


COURSE_CHECK_RATE = 0.02       # rad/s: the course must turn this much (std) to judge a gyro
COURSE_CHECK_ACCEL = 0.3        # m/s^2: horizontal acceleration (std) to judge the axes
COURSE_CHECK_YAW = math.radians(45.0)   # a forward axis this far off is a wrong mounting


def _check_against_course(rec):
    """Without a reference attitude, the GNSS track of a land vehicle still judges the IMU
    (epochs faster than alignment.COURSE_SPEED, the IMU's 1 s means turned into the vehicle
    frame by the mounting): its yaw rate (FRD z) must follow the course rate with a ratio
    within 0.1-10 (deg/s read as rad/s is 57) and the same sense, and its horizontal specific
    force the track's acceleration (along: d speed/dt, across: speed x course rate) within
    45 deg of yaw (a forward axis that points sideways). Judged only where the track turns
    and accelerates enough to show it, and the two agree in shape (correlation, coherence)."""
    epoch = int(rec.imu_ns[0])
    track = _track(rec, epoch)
    if track is None:
        return
    t = track["t"]
    speed, course_rate, z_track = alignment.track_acceleration(t, track["v_ned"])
    t_imu = (rec.imu_ns - epoch) / 1e9
    sel = (speed > alignment.COURSE_SPEED) & (t > t_imu[0] + 0.5) & (t < t_imu[-1] - 0.5) \
        & np.isfinite(course_rate) & np.isfinite(z_track)
    if sel.sum() < 20:
        return
    k = np.searchsorted(t_imu, t[sel])
    half = max(1, int(round(0.5 * rec.sample_rate_hz)))
    w_v = attitude.rotate(rec.mounting.q_vs, _local_mean(rec.w, k, half))
    f_v = attitude.rotate(rec.mounting.q_vs, _local_mean(rec.f, k, half))
    rate = course_rate[sel]
    if np.std(rate) > COURSE_CHECK_RATE:
        corr = float(np.corrcoef(w_v[:, 2], rate)[0, 1])
        ratio = float(np.std(w_v[:, 2]) / np.std(rate))
        if abs(corr) > 0.7 and not (corr > 0 and 0.1 < ratio < 10):
            raise RecordingError(
                f"{rec.name}: the gyro's yaw rate (vehicle z by the mounting) follows the GNSS "
                f"course rate {'reversed, ' if corr < 0 else ''}at {ratio:.3g} times its size "
                f"(correlation {corr:+.2f}): " + ("is the gyro's unit (deg/s or rad/s) right?"
                                                  if not 0.1 < ratio < 10 else
                                                  "the sensor axes or the mounting turn the "
                                                  "yaw axis upside down"))
        if abs(corr) < 0.5:
            _check_time_offset(rec, t_imu, t[sel], rate, corr, half)
    z_ref = z_track[sel]
    if np.std(z_ref) > COURSE_CHECK_ACCEL:
        gain, coherence = alignment.acceleration_match(f_v[:, 0] + 1j * f_v[:, 1], z_ref)
        yaw = float(np.angle(gain))
        if coherence > 0.5:
            # said even when small. The specific force seen turned by yaw is the IMU turned
            # by -yaw about the vehicle's down axis from the mounting given, the sign the
            # diagnosis' `vector_vehicle` z gives (the RTKLIB drive: +6.1 deg here, +6.06
            # [5.05, 7.07] there)
            rec.real["mounting_yaw_against_course"] = (
                f"{-math.degrees(yaw):+.1f} deg about the vehicle's down axis: the IMU turned "
                "so from the mounting given (positive: its forward axis to the right of the "
                "vehicle's), from the accelerometers' horizontal specific force against the "
                f"GNSS track's acceleration (coherence {coherence:.2f}, size ratio "
                f"{abs(gain):.2f}; a car's body slip and lean take a few degrees): beyond "
                f"{math.degrees(COURSE_CHECK_YAW):.0f} deg it is refused, a smaller one "
                "`mimunav diagnose` measures with its interval (mounting_misalignment); "
                f"--mounting-rpy-deg {_turned_back(rec, yaw, square=False)} would turn it back")
        if coherence > 0.5 and abs(yaw) > COURSE_CHECK_YAW:
            raise RecordingError(
                f"{rec.name}: the accelerometers' horizontal specific force matches the GNSS "
                f"track's acceleration with the IMU turned {-math.degrees(yaw):+.0f} deg about "
                f"the vehicle's down axis from the mounting given (coherence {coherence:.2f}): "
                "the sensor axes or the mounting's yaw are off by that much; "
                f"the mounting turned back would be --mounting-rpy-deg {_turned_back(rec, yaw)}"
                + (" - unless the vehicle drives in reverse most of the time (then import a "
                   "forward stretch)" if abs(yaw) > math.radians(135.0) else ""))


def _turned_back(rec, yaw, square=True):
    """'R P Y' (deg) of the recording's mounting turned by -yaw about the vehicle's down axis,
    yaw rounded to a quarter turn when within 15 deg of one and `square` (mountings are made
    square)."""
    quarter = round(math.degrees(yaw) / 90.0) * 90.0
    turn = quarter if square and abs(math.degrees(yaw) - quarter) < 15.0 else math.degrees(yaw)
    q = quaternion.from_rotation_vector([0.0, 0.0, -math.radians(turn)]) * rec.mounting.q_vs
    z, y, x = (round(float(np.degrees(a))) + 0 for a in attitude.as_euler(q))
    return f"{x} {y} {z}"


TIME_OFFSET_SEARCH_S = 60.0     # s: the yaw rate is looked for this far either side


def _check_time_offset(rec, t_imu, t_ref, rate, corr0, half):
    """The course turns but the gyro's yaw rate does not follow it at the stamps given: if it
    follows it well (correlation > 0.7) at a shift of the IMU's stamps of 1 s or more within
    +-TIME_OFFSET_SEARCH_S, the two time bases differ by that shift (GPS time read as UTC is
    18 s): refused, naming it. No shift that fits: left to the other checks and the
    diagnosis (a noisy course)."""
    w_z = attitude.rotate(rec.mounting.q_vs, rec.w)[:, 2:]
    smooth = _local_mean(w_z, np.arange(len(w_z)), half)[:, 0]     # once, not per shift
    best, best_lag = -1.0, 0.0
    for lag in np.arange(-TIME_OFFSET_SEARCH_S, TIME_OFFSET_SEARCH_S + 1e-9, 0.5):
        at = t_ref + lag
        inside = (at > t_imu[0] + 0.5) & (at < t_imu[-1] - 0.5)
        if inside.sum() < 20:
            continue
        k = np.searchsorted(t_imu, at[inside])
        c = np.corrcoef(smooth[k], rate[inside])[0, 1]
        if c > best:
            best, best_lag = float(c), float(lag)
    if best > 0.7 and abs(best_lag) >= 1.0:
        raise RecordingError(
            f"{rec.name}: the gyro's yaw rate follows the GNSS course rate only with the IMU's "
            f"stamps shifted by {-best_lag:+.1f} s (correlation {best:.2f}, {corr0:+.2f} as "
            "stamped): the IMU's and the reference's time bases differ by that much (GPS time "
            "read as UTC is 18 s off)")


def _local_mean(x, k, half=5):
    """Means of x over the samples k - half .. k + half (noise averaged, motion kept)."""
    return alignment.span_means(x, np.clip(k - half, 0, len(x)),
                                np.clip(k + half + 1, 0, len(x)))


def write_log(rec, path, force=False):
    """Write `rec` as a contract log at `path` (atomically; an existing file only with
    force), after `check_recording`. Returns the initial alignment (`alignment.Alignment`)."""
    check_recording(rec)
    epoch = int(rec.imu_ns[0])
    t = (rec.imu_ns - epoch) / 1e9
    ref = rec.reference
    align = alignment.initial_alignment(t, rec.w, rec.f, rec.mounting, _track(rec, epoch))
    initial = {"t": float(align.t), "latitude": float(align.lat), "longitude": float(align.lon),
               "height": float(align.h), "velocity_ned": list(map(float, align.v_ned)),
               "attitude_wxyz": list(map(float, align.q_nb))}
    assumed = dict(rec.assumed)
    assumed["initial_state"] = align.method
    rate = rec.sample_rate_hz
    with LogWriter(path, force=force) as log:
        log.metadata("flight", {
            "format": "mimunav-log/1", "name": rec.name, "description": rec.description,
            "epoch_unix_ns": str(epoch), "source": "recording", "initial_state": initial})
        log.metadata("sensor/mimu", {
            "model": rec.model, "sample_rate_hz": f"{rate:.6g}",
            "mounting": rec.mounting.as_dict()})      # range: unknown, not written
        log.metadata("recording", {"real": json.dumps(rec.real), "assumed": json.dumps(assumed),
                                   "gyro_bias_static_rad_s": list(map(float, align.gyro_bias)),
                                   "accel_bias_m_s2":
                                       list(map(float, align.accel_bias)),
                                   "static_s": (None if np.isnan(align.static[0]) else
                                                [float(align.static[0]), float(align.static[1])]),
                                   "observed_max": {"gyro_rad_s": float(np.abs(rec.w).max()),
                                                    "accel_m_s2": float(np.abs(rec.f).max())}})
        channels = [("/mimu/imu", S.IMU, "mimu", rec.imu_ns, S.imu_fields(rec.w, rec.f))]
        if rec.reference_imu is not None:
            ref_imu = rec.reference_imu
            fog = {"model": ref_imu.get("model", "unknown"),
                   "sample_rate_hz": f"{1e9 / np.median(np.diff(ref_imu['ns'])):.6g}",
                   "mounting": ref_imu["mounting"].as_dict()}
            if ref_imu.get("accuracy"):
                fog["accuracy"] = ref_imu["accuracy"]
            log.metadata("sensor/fog", fog)
            channels.append(("/fog/imu", S.IMU, "fog", ref_imu["ns"],
                             S.imu_fields(ref_imu["w"], ref_imu["f"])))
        if ref is not None:
            q = ref.get("q_nb")
            known = q is not None and np.isfinite(q).all(axis=1).any()
            meta = {"source": rec.real.get("reference", "external"),
                    "attitude": ("given by the reference (" +
                                 rec.reference_meta.get("source", "its source") + ")"
                                 if known else "unknown"),
                    "velocity": "given by the reference"}
            meta.update({k: str(v) for k, v in rec.reference_meta.items()})
            lag = velocity_lag_s(ref)
            if lag is not None:
                meta["velocity_lag_s"] = f"{lag:.4f}"   # positive: its velocity lags positions
            log.metadata("reference", meta)
            channels.append(("/truth/state", S.NAV_STATE, "vehicle", ref["ns"], dict(
                latitude=ref["lat"], longitude=ref["lon"], height=ref["h"],
                velocity_ned=ref["v_ned"],
                attitude_wxyz=q if known else np.tile(UNKNOWN_ATTITUDE, (len(ref["ns"]), 1)))))
        if rec.fixes is not None:
            fx = rec.fixes
            log.metadata("gnss", {"latitude_longitude": "rad (log contract conventions)",
                                  "position_covariance": "m^2, ENU"})
            channels.append(("/gnss/fix", S.NAV_SAT_FIX, "gnss", fx["ns"], dict(
                status=fx["status"], service=np.ones(len(fx["ns"]), np.uint16),
                latitude=fx["lat"], longitude=fx["lon"], altitude=fx["h"],
                position_covariance=fx["covariance"],
                position_covariance_type=np.full(len(fx["ns"]), 2, np.uint8))))
        _write_interleaved(log, channels)
    return align


def _write_interleaved(log, channels, block_s=WRITE_BLOCK_S):
    """Write each channel (topic, schema, frame, stamps ns, fields) block_s of time at a time,
    all channels per block, so that a log cut short (a full disk, a copy stopped) keeps the
    reference and fixes up to the cut, not only the IMU."""
    lo = min(int(c[3][0]) for c in channels if len(c[3]))
    step = int(block_s * 1e9)
    # only the blocks that hold a sample (channels far apart in time leave long empty spans)
    blocks = np.unique(np.concatenate([(np.asarray(c[3], np.int64) - lo) // step
                                       for c in channels]))
    for start in (lo + blocks * step).tolist():
        for topic, schema, frame, ns, fields in channels:
            a, b = np.searchsorted(ns, [start, start + step])
            if b > a:
                log.write(topic, schema, frame, ns[a:b], **{k: v[a:b] for k, v in fields.items()})


def _track(rec, epoch):
    """The trajectory the alignment takes heading from (t s since epoch, lat, lon, h,
    v_ned): the reference, else the GNSS fixes (their velocity when recorded, else central
    differences of their positions), else None."""
    src = rec.reference
    if src is None or len(src["ns"]) < 3:
        src = rec.fixes
    if src is None or len(src["ns"]) < 3:
        return None
    t = (np.asarray(src["ns"], np.int64) - epoch) / 1e9
    v = src.get("v_ned")
    if v is None:
        v = velocity_from_positions(src["ns"], src["lat"], src["lon"], src["h"])
    ok = np.isfinite(v).all(axis=1)                 # no differenced velocity across a gap
    q = src.get("q_nb")
    return dict(t=t[ok], lat=src["lat"][ok], lon=src["lon"][ok], h=src["h"][ok], v_ned=v[ok],
                q_nb=None if q is None else np.asarray(q)[ok],
                attitude_source=rec.reference_meta.get("source", "the reference"))
