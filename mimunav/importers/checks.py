"""A recording checked against itself before it is written: sample rate, the reference's
and the fixes' overlap with the IMU, units, the IMU against the GNSS course
(`course_check`), a reference IMU's clock and mounting (`pairing`) and the vibration its
instantaneous samples fold (`aliasing`).
"""
import math

import numpy as np

from ..navigation import alignment
from ..navigation.rest_biases import level
from ..navigation.strapdown import MAX_RATE
from ..frames import attitude
from ..flightlog.stamps import burst_clock, rounded_clock
from .aliasing import aliased
from .attitude_check import check_rates_along, mounting_against_attitude
from .course_check import REFUSED_OFFSET_S, check_against_course, local_mean, not_a_car, \
    offset_advice
from .imu_clock import GRID_S, late_or_early, trajectory_clock
from .lever import lever_force_samples
from .pairing import pair
from .same_data import check_distinct
from .trajectory_point import check_trajectory_point
from .recording import G0, RecordingError, utc_text
from .vehicle_check import check_declared_vehicle
from .velocity_check import check_acceleration_scale, check_velocity, positions_velocity
from ..motion.carrier import ALONG_COURSE, EITHER_END, car_tests, course_keys
from ..motion.track import velocity_from_positions


# Hz: an IMU stream read slower than this is a status snapshot (PX4's sensor_accel and
# sensor_gyro topics logged at 1 Hz), not the interval means a strapdown navigator needs -
# a vehicle turns and vibrates faster; consumer IMUs are logged at 50-1000 Hz
MIN_IMU_RATE_HZ = 10.0
RATE_TOLERANCE = 0.01       # a stream at that rate whose stamps jitter passes (KITTI's 10 Hz
#                             synced rows: median interval 0.100003 s had been refused)


def _check_rate(name, which, ns):
    """Refuse an IMU whose median sample rate is below MIN_IMU_RATE_HZ (less
    RATE_TOLERANCE)."""
    rate = 1e9 / float(np.median(np.diff(ns)))
    if rate < MIN_IMU_RATE_HZ * (1 - RATE_TOLERANCE):
        raise RecordingError(f"{name}: the {which} has {len(ns)} samples at {rate:.3g} Hz (median "
                             f"interval); below {MIN_IMU_RATE_HZ:g} Hz they are status snapshots, "
                             "not increments a navigator can integrate: choose the IMU's "
                             "full-rate stream - ulog and dataflash: --imu-instance or "
                             "--reference-imu-instance; ros2: --imu-topic or "
                             "--reference-imu-topic; table: the spec's columns - or check the "
                             "stamps' time unit")


ATTITUDE_AS = "quaternion's convention (body -> NED or ECEF)"   # what may be wrong of it


def check_recording(rec):
    """Refuse a recording whose IMU cannot be in the units and axes the import says: a
    rate below MIN_IMU_RATE_HZ (either IMU); the
    median |specific force| far from 1 g (g read as m/s^2 or the reverse); with a reference
    attitude, the 1 s mean specific force turned into NED by the mounting and that attitude
    not pointing up (axes, mounting or quaternion convention wrong), or the gyro's rates a
    factor of ten or more from the attitude's own rate (deg/s read as rad/s)."""
    _check_overlap(rec)             # first: stamps in the wrong unit fail it, and it says so
    _check_rate(rec.name, "IMU", rec.imu_ns)
    _uniform_clocks(rec)
    check_velocity(rec)
    check_declared_vehicle(rec, reference_track(rec, int(rec.imu_ns[0])))
    if rec.reference_imu is not None:
        _check_rate(rec.name, "reference IMU", rec.reference_imu["ns"])
        check_distinct(rec)
        pair(rec)
        rec.aliased = aliased(rec)
    _check_gravity_felt(rec)
    _check_rates_unit(rec)
    ref = rec.reference
    q = None if ref is None else ref.get("q_nb")
    if q is None or np.isfinite(q).all(axis=1).sum() < 10:
        check_against_course(rec, reference_track(rec, int(rec.imu_ns[0])))
        return
    ok = np.isfinite(q).all(axis=1)
    t_ref = ref["ns"][ok]
    k = np.clip(np.searchsorted(rec.imu_ns, t_ref), 0, len(rec.imu_ns) - 1)
    q_ns = attitude.from_wxyz(q[ok]) * rec.mounting.q_vs
    f_ned = attitude.rotate(q_ns, local_mean(rec.f, k))
    check_down(rec, f_ned)
    rate = attitude.turn_rate(t_ref / 1e9, attitude.from_wxyz(q[ok]))
    ref_rate = float(np.percentile(rate, 99))
    imu_rate = float(np.percentile(np.linalg.norm(local_mean(rec.w, k), axis=1), 99))
    if ref_rate > 0.05 and not 0.1 < imu_rate / ref_rate < 10:
        raise RecordingError(f"{rec.name}: the gyro's rates reach {imu_rate:.3g}, the reference "
                             f"attitude turns at up to {ref_rate:.3g} rad/s: is the gyro's unit "
                             "(deg/s or rad/s) right?")
    # of the trajectory's point: the IMU's lever arm from it removed (an IMU 0.2 m off a rate
    # table's axis, its arm declared, had been refused as beside a reference held still)
    arm = lever_force_samples(rec.imu_ns, attitude.rotate(rec.mounting.q_vs, rec.w),
                              rec.mounting.lever_arm_m)
    check_acceleration_scale(rec, t_ref / 1e9, ref["v_ned"][ok],
                             f_ned - attitude.rotate(attitude.from_wxyz(q[ok]), local_mean(arm, k)))
    _check_heading_against_course(rec, q, ok)
    check_rates_along(rec, _check_reference_clock(rec))     # after the clock: seconds off
    #                                                         refuse as such first
    mounting_against_attitude(rec)
    check_trajectory_point(rec)     # once the attitude and its clock hold


def check_down(rec, f_ned):
    """Refuse (RecordingError) a recording whose specific force turned into NED by the
    mounting and the reference attitude (f_ned (M, 3), m/s^2, at the reference's epochs)
    does not point down in the median: gravity's, for any vehicle whose acceleration
    averages out - G0, not the IMU's median |f| (a swinging foot's reads 13.3, centripetal,
    and a right mounting had been refused against it)."""
    g, f_n = G0, np.median(f_ned, axis=0)
    if f_n[2] > -0.8 * g or np.hypot(f_n[0], f_n[1]) > 0.3 * g:
        raise RecordingError(f"{rec.name}: the specific force turned into NED by the mounting and "
                             f"the reference attitude is {np.round(f_n, 2).tolist()} m/s^2 in the "
                             f"median, not [0, 0, -{g:.1f}]: the sensor axes, the mounting or "
                             "the attitude's " + rec.reference_meta.get("attitude_as",
                                                                         ATTITUDE_AS) + " is wrong"
                             + ("; or the attitude is not the reference IMU's own (attitude_of "
                                "= \"reference_imu\" turned it by that IMU's mounting onto the "
                                "vehicle: is it the vehicle's, attitude_of = \"vehicle\"?)"
                                if rec.reference_meta.get("attitude_of") == "reference_imu"
                                else "") + _upside_down(rec, f_n, g))


def _uniform_clocks(rec):
    """The IMU's and the reference IMU's stamps, where they are whole ticks of a uniform
    clock (`stamps.rounded_clock`) or a host's reads of bursts of samples
    (`stamps.burst_clock`), replaced by that clock's times and said so."""
    ns, said = _uniform(rec.imu_ns)
    if ns is not None:
        rec.imu_ns, rec.real["imu_stamps"] = ns, said
    if rec.reference_imu is not None:
        ns, said = _uniform(rec.reference_imu["ns"])
        if ns is not None:
            rec.reference_imu["ns"], rec.real["reference_imu_stamps"] = ns, said


def _uniform(ns):
    """`stamps.rounded_clock`'s clock of the stamps ns, else `stamps.burst_clock`'s."""
    clock = rounded_clock(ns)
    return clock if clock[0] is not None else burst_clock(ns)


HEADING_OFF_COURSE_DEG = 10.0   # deg: a car's reference heading from its own course, the
                                # mean over its epochs faster than FAST_S: in ordinary
                                # driving a car slips a few degrees (beyond ~5 its tyres
                                # slide), and a wrong yaw convention is off by tens (KITTI's
                                # yaw from east read as a heading: 90)
JUDGED_OFF_COURSE_DEG = 30.0    # deg: the same for a recording judged a car, not declared one
                                # (`motion.carrier`'s tests also pass a light aircraft in
                                # gentle flight, which crabs 15-20 deg in a strong crosswind)
FAST_S = 5.0                    # m/s: a course from differenced fixes holds to a few degrees


def _check_heading_against_course(rec, q, ok):
    """What moves along its forward axis - declared a car, a train or a two-wheeler
    (`motion.carrier.ALONG_COURSE`), or judged a car - must have its reference heading
    follow its own course (no side slip), in the mean over its fast epochs: refused beyond
    HEADING_OFF_COURSE_DEG (JUDGED_OFF_COURSE_DEG for a recording judged a car, not
    declared one) - a yaw in another convention; a car reversing for most of its fast
    epochs reads 180 and is refused too, saying so; a train runs either end first, so its
    mean is taken modulo 180 deg (`carrier.EITHER_END`); said in rec.real otherwise. Not
    judged for anything else (it may fly sideways). A train's heading counted
    counter-clockwise had been taken (trial: not judged, "declared: train")."""
    declared = rec.vehicle in ALONG_COURSE
    if not declared and not_a_car(rec, (np.asarray(rec.reference["ns"], np.int64)
                                        - int(rec.imu_ns[0])) / 1e9, rec.reference["v_ned"]):
        return
    v = rec.reference["v_ned"][ok]
    fast = np.hypot(v[:, 0], v[:, 1]) > FAST_S
    if fast.sum() < 20:
        return
    heading = attitude.as_euler(attitude.from_wxyz(q[ok][fast]))[0]
    ends = 2 if rec.vehicle in EITHER_END else 1    # an axial mean: 0 and 180 deg alike
    off = heading - np.arctan2(v[fast, 1], v[fast, 0])
    mean = round(math.degrees(float(np.angle(np.mean(np.exp(1j * ends * off))))) / ends,
                 1) + 0.0       # no -0.0
    said = (f"the reference's heading lies {mean:+.1f} deg from its own course (circular "
            f"mean over {int(fast.sum())} epochs faster than {FAST_S:g} m/s"
            + (", modulo 180 deg: it runs either end first)" if ends == 2 else ")"))
    what = f"a {rec.vehicle}" if declared else "a car"
    if abs(mean) > (HEADING_OFF_COURSE_DEG if declared else JUDGED_OFF_COURSE_DEG):
        raise RecordingError(
            f"{rec.name}: {said}, and {what} moves along its heading: is the attitude's yaw in "
            "the convention the import reads (a heading from north, clockwise; a yaw from "
            "east, counter-clockwise, is heading = 90 deg - yaw: `scale` and `offset` in a "
            "table spec, the offset in the column's unit - 1.5707963 in rad)?"
            + (f" Or is its {rec.reference_meta['attitude_as']} wrong?"
               if "attitude_as" in rec.reference_meta else "")
            + (" Or does it drive in reverse most of the time?" if abs(mean) > 150 else "")
            + ("" if declared else " (Judged a car from its track; if it is not "
               "one, declare what it is: --vehicle, or the spec's `vehicle`.)"))
    rec.real["reference_heading"] = said


def _check_reference_clock(rec):
    """The reference trajectory's clock against the IMU's (`imu_clock.trajectory_clock`:
    its attitude's turn rate, else its specific force along the vehicle's x axis), said in
    rec.real["reference_clock"]: a decided lag of REFUSED_OFFSET_S or more refused,
    naming the shift that puts it back (the light aircraft's VN-300 solution: 2.5 s); one of
    two grid steps (GRID_S) or more said with that option, not applied: the data cannot tell
    the clocks' offset (a mocap pose 0.3 s late) from the IMU's latency (a phone's 40 ms,
    erased when shifted at import), physics the diagnosis reports as a time skew. Not
    decided, the data peaking among rivals none of which lies at the stamps (within a lobe
    of them: `imu_clock.rate_lag`'s zero_lag_s): rec.reference_clock_open (a ship's MEMS
    0.7 s off, its rolls repeating every 10 s, had the navigation level conclude on a lever
    arm, the clock unnamed); a motion that repeats exactly, stamped right, peaks anywhere
    among rivals, one of them at the stamps: not open. Returns the lags (s) the reference's
    stamps may be late by: the decided one, else 0 and the data's best lags near the stamps
    and anywhere."""
    clock = trajectory_clock(rec)
    rec.real["reference_clock"] = clock["said"]
    late = clock["offset_s"]
    near = clock.get("zero_lag_s", clock.get("peak_lag_s"))    # the best lag within a
    if late is None and near is not None and abs(near) > GRID_S:  # lobe of the stamps
        rec.reference_clock_open = clock["said"]    # the data peak away from the stamps
        #                                             among rivals: the navigation and track
        #                                             levels stop short (`diagnosis.levels`)
    if late is not None and 0 < abs(late) < 2 * GRID_S:
        rec.real["reference_clock"] += (f"; within two steps of the {GRID_S:g} s grid: not "
                                        "applied - left as the IMU's time skew, which "
                                        + skew_measured_by(rec))
    if late is not None and 2 * GRID_S <= abs(late) < REFUSED_OFFSET_S:
        rec.reference_clock_unapplied_s = late
        rec.real["reference_clock"] += ("; not applied: left as the IMU's latency (physics "
                                        "to report), which the track level measures as a "
                                        "time skew and the navigation level cannot (it stops "
                                        "short on it); if it is the two clocks' offset, "
                                        + offset_advice(
                                            rec, rec.reference_shift_s - late, ".2f")[2:])
    if late is not None and abs(late) >= REFUSED_OFFSET_S:
        raise RecordingError(
            f"{rec.name}: the reference's trajectory moves as the IMU does only with its stamps "
            f"{late_or_early(late)} ({clock['said']}): the two time bases differ by that much"
            + offset_advice(rec, rec.reference_shift_s - late, ".2f"))
    if late is not None:
        return [late]
    rivals = (clock.get(key) for key in ("zero_lag_s", "peak_lag_s"))
    return [0.0] + sorted({x for x in rivals if x is not None and abs(x) > GRID_S})


def skew_measured_by(rec):
    """Which level measures the IMU's time skew against the reference, in words: not the
    sensor level where the import timed the reference IMU against the IMU by the same
    motions (`pairing`: such a latency went into that clock - the diagnosis then says it
    is not tested, where the import had said the sensor level measures it finer)."""
    track = "the track level's yaw-rate lag may not resolve it, the navigation level cannot"
    if rec.reference_imu is not None and rec.reference_imu_clock_se_s:
        return ("no level tests here: the import timed the reference IMU against the IMU by "
                "these same motions (measured reference imu clock), which takes such a "
                f"latency into that clock ({track} test it)")
    return f"the sensor level measures finer ({track} test it)"


def _upside_down(rec, f_n, g):
    """Where the specific force turned into NED reads down (f_n m/s^2, g its size), which of
    the two turns it: the IMU as mounted, when its own median specific force in the vehicle
    frame reads the vehicle upside down - the mounting that turns its z half a turn about
    its x (a ROS topic's FRD IMU read by REP-103's FLU had been refused naming no option) -,
    or the reference's attitude, when the IMU reads the vehicle upright (a FLU body's
    rotation matrix read as FRD: following the mounting hint had made a clean log of an
    upside-down car, an independent check); both where it reads neither."""
    if f_n[2] < 0.8 * g:
        return ""
    q_vs = rec.mounting.q_vs * np.quaternion(0.0, 1.0, 0.0, 0.0)
    yaw, pitch, roll = (round(float(np.degrees(x)), 1) + 0.0 for x in attitude.as_euler(q_vs))
    mounting = (f"if the IMU's z points down where up was taken (FRD read as FLU), "
                f"--mounting-rpy-deg {roll:g} {pitch:g} {yaw:g}")
    attitude_axes = ("the reference attitude's body is turned: its axes are not the "
                     "vehicle's FRD (a table spec's body_axes = \"FLU\" for a ROS or KAIST "
                     "body) or it rotates the other way (NED or grid to body)")
    up = attitude.rotate(rec.mounting.q_vs, np.median(rec.f, axis=0))[2]
    if up < -0.8 * g:
        return (f" - it reads down, and the IMU as mounted reads the vehicle upright (its "
                f"specific force {up:+.2f} m/s^2 along the vehicle's down): {attitude_axes}")
    if up > 0.8 * g:
        return f" - it reads down, as the IMU as mounted reads the vehicle: {mounting}"
    return f" - it reads down: {mounting}; or {attitude_axes}"


FELT_GRAVITY_SHARE = 0.05   # of the recording's 1 s means: at least this share (and 3 s)
                            # feels gravity's size - a vehicle spends some time on the ground,
                            # hovering, cruising or under a parachute; a coast is no unit error


def _check_gravity_felt(rec):
    """Refuses (RecordingError) an IMU whose 1 s means of |specific force| lie between 0.5
    and 2 g for fewer than FELT_GRAVITY_SHARE of them (or 3 s): g read as m/s^2 (all near
    1) or m/s^2 read as g (near 96) - not a free fall or a boost between rests."""
    t = (rec.imu_ns - rec.imu_ns[0]) / 1e9
    sec = np.floor(t).astype(int)
    count = np.bincount(sec)
    means = np.column_stack([np.bincount(sec, rec.f[:, i]) for i in range(3)])[count > 0] / \
        count[count > 0, None]
    size = np.linalg.norm(means, axis=1)
    felt = (size > 0.5 * G0) & (size < 2 * G0)
    if felt.sum() < 3 and felt.all():
        raise RecordingError(f"{rec.name}: the IMU's record is {t[-1]:.2f} s long: its units "
                             "are checked on at least 3 s (1 s means of |specific force| near "
                             "1 g), and an import needs more than that to align")
    if felt.sum() < max(3, FELT_GRAVITY_SHARE * len(size)):
        raise RecordingError(f"{rec.name}: {felt.sum()} of {len(size)} 1 s means of |specific "
                             f"force| lie between 0.5 and 2 g (their median "
                             f"{float(np.median(size)):.3g} m/s^2); a vehicle on Earth feels "
                             "about 9.8 for a part of its record: is the accelerometer's unit "
                             "(g or m/s^2) right?")


RATE_SHARE = 0.999      # of the samples: a gyro's rates beyond MAX_RATE on more of them are
#                         no wild value's (one sample) but the unit's (deg/s read as rad/s)


def _check_rates_unit(rec):
    """Refuses (RecordingError) an IMU (or reference IMU) whose |angular rate| exceeds the
    navigator's MAX_RATE (rad/s: above any navigation gyro's range) on more than
    1 - RATE_SHARE of its samples: deg/s read as rad/s - a Shimmer's hand-waved gyro so
    declared had been imported at peaks of 729 rad/s, and refused only at `diagnose` in
    words of angle increments."""
    for whose, w in (("IMU", rec.w), ("reference IMU", (rec.reference_imu or {}).get("w"))):
        if w is None or not len(w):
            continue
        top = float(np.quantile(np.linalg.norm(w, axis=1), RATE_SHARE))
        if top > MAX_RATE:
            raise RecordingError(
                f"{rec.name}: the {whose}'s angular rates reach {top:.4g} rad/s "
                f"({math.degrees(top):.4g} deg/s; {100 * RATE_SHARE:g} % of its samples lie "
                f"below that), beyond any navigation gyro's range ({MAX_RATE:g} rad/s): are "
                "they in deg/s? (a table spec's unit = \"deg/s\")")


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
                f"{rec.name}: the IMU's stamps span {utc_text(lo)} - {utc_text(hi)}, the {what} "
                f"{utc_text(a)} - {utc_text(b)}: they do not overlap, so the two are on different time "
                "bases (time since boot, GPS week seconds, UNIX time): give both the same"
                + unit)


def differenced(ref, v_pos=None):
    """Whether a reference's velocity is its positions' central differences (an importer's
    `velocity_from_positions` where the source has none), to 1 mm/s: no lag to measure, and
    the metadata says so (a phone's positions-only reference had been written 'velocity
    given by the reference', its lag 0.0000 +- 0.0000)."""
    v = np.asarray(ref["v_ned"], float)
    v_pos = positions_velocity(ref) if v_pos is None else v_pos
    ok = np.isfinite(v).all(axis=1) & np.isfinite(v_pos).all(axis=1)
    return bool(ok.any()) and bool(np.abs(v[ok] - v_pos[ok]).max() < 1e-3)


def velocity_lag_s(ref, search_s=1.0, v_pos=None):
    """How late (s) the reference's own velocity is against the velocity of its positions
    (central differences: zero phase), over epochs faster than alignment.COURSE_SPEED; None
    with fewer than 50 such epochs. A filtered velocity state lags (RTKLIB's on the
    drive_0708 solution: 115 ms), and a lag found against the reference is then one against
    that velocity's timing.

    Searched over shifts of whole epochs (median interval), where the positions' velocity is
    read at its own epochs: between them the interpolation averages two differences' noise,
    and noisy positions pulled the minimum half an epoch off (+50 ms at 10 Hz and 5 cm of
    noise, truth 0). Then refined by regressing the residual on the reference velocity's own
    rate of change (v(t) - v_pos(t - s) = -(lag - s) a, to first order), whose noise is not
    the positions', and stepped by whole epochs until it lies within an epoch of its shift.
    Returns (lag, its standard error: a jackknife over LAG_BLOCKS blocks of the epochs), or
    None."""
    v = np.asarray(ref["v_ned"], float)[:, :2]
    v_pos = (positions_velocity(ref) if v_pos is None else v_pos)[:, :2]
    t = (np.asarray(ref["ns"], np.int64) - int(ref["ns"][0])) / 1e9
    ok = np.isfinite(v_pos).all(axis=1) & np.isfinite(v).all(axis=1) & \
        (np.hypot(v[:, 0], v[:, 1]) > alignment.COURSE_SPEED) & \
        (t > t[0] + search_s) & (t < t[-1] - search_s)
    if ok.sum() < 50:
        return None
    good = np.isfinite(v_pos).all(axis=1)
    dt = float(np.median(np.diff(t)))
    steps = np.arange(-int(search_s / dt), int(search_s / dt) + 1) * dt

    def residual(shift):
        return v[ok] - np.column_stack([np.interp(t[ok] - shift, t[good], v_pos[good, i])
                                        for i in range(2)])
    best = steps[int(np.argmin([np.mean(residual(s) ** 2) for s in steps]))]
    a = np.gradient(v, t, axis=0)[ok]
    if not np.isfinite(a).all() or np.sum(a * a) == 0.0:
        return float(best), math.inf
    for step in range(LAG_STEPS + 1):   # the grid's noisy minimum may be epochs off: step on
        ea, aa = (np.add.reduceat(np.sum(x, axis=1), _blocks(len(x), LAG_BLOCKS))
                  for x in (residual(best) * a, a * a))
        refine = -float(np.sum(ea) / np.sum(aa))
        if abs(refine) <= dt:
            break
        if step == LAG_STEPS:           # no shift settles it: no lag to give
            return None
        best += round(refine / dt) * dt
    rest = np.sum(aa) - aa
    if not np.all(rest > 0):            # one block holds all the acceleration: no jackknife
        return float(best + np.clip(refine, -dt, dt)), math.inf
    leave_one_out = -(np.sum(ea) - ea) / rest
    se = math.sqrt((LAG_BLOCKS - 1) * np.mean((leave_one_out - leave_one_out.mean()) ** 2))
    return float(best + np.clip(refine, -dt, dt)), se


LAG_STEPS = 5       # whole-epoch steps of the refinement at most (it converges in 1-2;
#                    one that does not gives no lag)
LAG_BLOCKS = 10     # contiguous blocks of the jackknife: the positions' differenced noise is
#                    blue (it nearly cancels against a smooth acceleration), so a white-noise
#                    standard error overstated it 100-fold; the blocks' spread measures it


def _blocks(n, k):
    """Start indices of k contiguous blocks of n items."""
    return (np.arange(k) * n) // k


def reference_track(rec, epoch):
    """The trajectory the alignment takes heading from (t s since epoch, lat, lon, h,
    v_ned; `what` it is, for messages; heading_known; `faces_course`: False for a declared
    vehicle that need not face its course, `motion.carrier.ALONG_COURSE` - a walker's
    phone, a copter; `vehicle`), the reference, else the GNSS fixes (their velocity when
    recorded, else central differences of their positions), else None."""
    src, what = rec.reference, "the reference"
    if src is None or len(src["ns"]) < 3:
        src, what = rec.fixes, "the GNSS fixes (no reference trajectory)"
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
                attitude_source=rec.reference_meta.get("source", "the reference"), what=what,
                heading_known=rec.reference_heading_known,
                **course_keys(rec.vehicle, faces_course(rec, t[ok], v[ok])))


def faces_course(rec, t, v_ned):
    """Whether the vehicle's course may stand for its heading: as declared
    (`motion.carrier.course_keys`: None), else judged by its track (velocities v_ned m/s at
    t s from the IMU's first stamp) and IMU - not where they show it no car
    (`motion.carrier.car_tests`; a multicopter's figure eights, judged no car, had still
    been given its course as heading, 90 deg off), its speed aside: a slow robot or a
    walker still moves along its forward axis."""
    if rec.vehicle is not None:
        return None
    return not car_tests(t, v_ned, (rec.imu_ns - rec.imu_ns[0]) / 1e9, rec.f, rec.w,
                         moving=False)[0]


UPRIGHT_DEG = 60.0      # deg: a car, a train, a two-wheeler on its stand (5-10 deg), an
#                        aircraft, a ship or a copter at rest is within this of level (a
#                        tail-dragger's 10-15 deg of pitch, a moored hull's roll); beyond
#                        it the mounting given has the IMU's axes turned - a z axis up
#                        taken as down reads a roll of 180
RESTS_UPRIGHT = ("car", "train", "two-wheeler", "aircraft", "multicopter", "ship")
ON_GRADES_DEG = {"car": 20.0, "train": 20.0}    # deg: where it can rest - the steepest public
#                        road 35 % (19.3 deg); rails far less (a phone holder 30 deg off passed)


def resting_upright(rec, align):
    """A vehicle that rests upright must level at its rest through the mounting given: a
    declared car, train, aircraft, ship or copter beyond UPRIGHT_DEG (a car's or a
    train's ON_GRADES_DEG) of roll or pitch is refused with the mounting that levels it
    (the yaw as given); an undeclared one is said in rec.real["resting_tilt"] (it may be a
    rocket on its rail or a hand-held unit). Judged on the IMU's own specific force there
    (a reference's level, which the alignment may take, had let a phone 30 deg off through
    as 0.5 g of accelerometer bias), only where a rest starts the recording (a moving
    vehicle banks: an aircraft's log starting in a 70 deg bank, its rest later, had been
    refused as mounted 70 deg off)."""
    if not align.at_rest_start or np.isnan(align.static[0]) or \
            rec.vehicle in ("rocket", "pedestrian", "other"):
        return                  # the attitude at t0 is its rest's only when a rest starts it
    up = (getattr(align, "bias_basis", None) or {}).get("gravity_sensor_axes")  # its own
    if up is None:              # level, not the reference's the alignment may have taken
        _, pitch, roll = attitude.as_euler(attitude.from_wxyz(align.q_nb))
    else:
        roll, pitch = level(attitude.rotate(rec.mounting.q_vs, np.asarray(up, float)))
    limit = ON_GRADES_DEG.get(rec.vehicle, UPRIGHT_DEG)
    if max(abs(roll), abs(pitch)) <= math.radians(limit):
        return
    tilt = attitude.from_euler(np.array(0.0), np.array(pitch), np.array(roll))
    yaw_l, pitch_l, roll_l = attitude.as_euler(tilt * rec.mounting.q_vs)
    said = (f"at its rest {align.static[0]:.1f}-{align.static[1]:.1f} s the IMU, through the "
            f"mounting given, rests at roll {math.degrees(roll):+.1f}, pitch "
            f"{math.degrees(pitch):+.1f} deg; the mounting that levels it (the yaw as given): "
            "--mounting-rpy-deg " + " ".join(f"{round(math.degrees(a), 1) + 0.0:.1f}"
                                             for a in (roll_l, pitch_l, yaw_l))
            + " (a table spec's mounting_rpy_deg)")
    if rec.vehicle in RESTS_UPRIGHT:
        article = "an" if rec.vehicle[0] in "aeiou" else "a"
        raise RecordingError(f"{rec.name}: {article} {rec.vehicle} rests upright (within "
                             f"{limit:g} deg of level), but {said}")
    rec.real["resting_tilt"] = (f"{said}: a vehicle that rests upright is not so mounted "
                                "(declare it with --vehicle to have this refused)")
