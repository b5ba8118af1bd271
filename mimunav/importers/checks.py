"""A recording checked against itself before it is written: sample rate, the reference's
and the fixes' overlap with the IMU, units, the mounting's yaw against the GNSS course, the
clock offset of the IMU against the track, a reference IMU's clock and mounting.
"""
import math

import numpy as np
import quaternion

from ..navigation import alignment
from ..navigation.rest_biases import level
from ..navigation.rests import (TRACK_FORCE_RATIO, acceleration_match, along_across_gains,
                                follows_track, match_angle_se, span_means,
                                track_acceleration)
from ..frames import attitude
from ..flightlog.stamps import rounded_clock
from .aliasing import aliased
from .imu_clock import GRID_S, late_or_early, trajectory_clock
from .pairing import pair
from .recording import G0, RecordingError, utc_text
from .vehicle_check import check_declared_vehicle
from .velocity_check import check_acceleration_scale, check_velocity, positions_velocity
from ..motion.carrier import LAND, car_tests, course_keys
from ..motion.track import velocity_from_positions


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
        pair(rec)
        rec.aliased = aliased(rec)
    g = _gravity_sized(rec)
    ref = rec.reference
    q = None if ref is None else ref.get("q_nb")
    if q is None or np.isfinite(q).all(axis=1).sum() < 10:
        _check_against_course(rec)
        return
    ok = np.isfinite(q).all(axis=1)
    t_ref = ref["ns"][ok]
    k = np.clip(np.searchsorted(rec.imu_ns, t_ref), 0, len(rec.imu_ns) - 1)
    q_ns = attitude.from_wxyz(q[ok]) * rec.mounting.q_vs
    f_ned = attitude.rotate(q_ns, _local_mean(rec.f, k))
    f_n = np.median(f_ned, axis=0)
    if f_n[2] > -0.8 * g or np.hypot(f_n[0], f_n[1]) > 0.3 * g:
        raise RecordingError(f"{rec.name}: the specific force turned into NED by the mounting and "
                             f"the reference attitude is {np.round(f_n, 2).tolist()} m/s^2 in the "
                             f"median, not [0, 0, -{g:.1f}]: the sensor axes, the mounting or "
                             "the attitude's " + rec.reference_meta.get("attitude_as",
                                                                         ATTITUDE_AS) + " is wrong")
    rate = attitude.turn_rate(t_ref / 1e9, attitude.from_wxyz(q[ok]))
    ref_rate = float(np.percentile(rate, 99))
    imu_rate = float(np.percentile(np.linalg.norm(_local_mean(rec.w, k), axis=1), 99))
    if ref_rate > 0.05 and not 0.1 < imu_rate / ref_rate < 10:
        raise RecordingError(f"{rec.name}: the gyro's rates reach {imu_rate:.3g}, the reference "
                             f"attitude turns at up to {ref_rate:.3g} rad/s: is the gyro's unit "
                             "(deg/s or rad/s) right?")
    check_acceleration_scale(rec, t_ref / 1e9, ref["v_ned"][ok], f_ned)
    _check_heading_against_course(rec, q, ok)
    _check_reference_clock(rec)


def _uniform_clocks(rec):
    """The IMU's and the reference IMU's stamps, where they are whole ticks of a uniform
    clock, replaced by that clock's times (`stamps.rounded_clock`) and said so."""
    ns, said = rounded_clock(rec.imu_ns)
    if ns is not None:
        rec.imu_ns, rec.real["imu_stamps"] = ns, said
    if rec.reference_imu is not None:
        ns, said = rounded_clock(rec.reference_imu["ns"])
        if ns is not None:
            rec.reference_imu["ns"], rec.real["reference_imu_stamps"] = ns, said


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
    """A car's reference heading must follow its own course (no side slip), in the mean
    over its fast epochs: refused beyond HEADING_OFF_COURSE_DEG (JUDGED_OFF_COURSE_DEG for
    a recording judged a car, not declared one) - a yaw in another convention;
    a car reversing for most of its fast epochs reads 180 and is refused too, saying so;
    said in rec.real otherwise. Not judged for what is not a car (it may fly sideways)."""
    if _not_a_car(rec, (np.asarray(rec.reference["ns"], np.int64) - int(rec.imu_ns[0])) / 1e9,
                  rec.reference["v_ned"]):
        return
    v = rec.reference["v_ned"][ok]
    fast = np.hypot(v[:, 0], v[:, 1]) > FAST_S
    if fast.sum() < 20:
        return
    heading = attitude.as_euler(attitude.from_wxyz(q[ok][fast]))[0]
    off = np.angle(np.exp(1j * (heading - np.arctan2(v[fast, 1], v[fast, 0]))))
    mean = math.degrees(float(np.angle(np.mean(np.exp(1j * off)))))
    said = (f"the reference's heading lies {mean:+.1f} deg from its own course (circular "
            f"mean over {int(fast.sum())} epochs faster than {FAST_S:g} m/s)")
    limit = HEADING_OFF_COURSE_DEG if rec.vehicle == LAND else JUDGED_OFF_COURSE_DEG
    if abs(mean) > limit:
        raise RecordingError(
            f"{rec.name}: {said}, and a car moves along its heading: is the attitude's yaw in "
            "the convention the import reads (a heading from north, clockwise; a yaw from "
            "east, counter-clockwise, is heading = 90 deg - yaw: `scale` and `offset` in a "
            "table spec, the offset in the column's unit - 1.5707963 in rad)?"
            + (" Or does it drive in reverse most of the time?" if abs(mean) > 150 else "")
            + ("" if rec.vehicle == LAND else " (Judged a car from its track; if it is not "
               "one, declare what it is: --vehicle, or the spec's `vehicle`.)"))
    rec.real["reference_heading"] = said


def _not_a_car(rec, t_track, v_ned):
    """[why the recording is not a car] - declared another vehicle, or the tests
    `motion.carrier.car_tests` fails on its track's velocities v_ned (m/s) at t_track (s
    from the IMU's first stamp) and its specific force and rate - or [] for a car."""
    if rec.vehicle:
        return [] if rec.vehicle == LAND else [f"declared: {rec.vehicle}"]
    return car_tests(t_track, v_ned, (rec.imu_ns - rec.imu_ns[0]) / 1e9, rec.f, rec.w)[0]


def _check_reference_clock(rec):
    """The reference attitude's turn rate against the IMU's (`imu_clock.trajectory_clock`),
    said in rec.real["reference_clock"]: a decided lag of REFUSED_OFFSET_S or more refused,
    naming the shift that puts it back (the light aircraft's VN-300 solution: 2.5 s); one of
    two grid steps (GRID_S) or more said with that option, not applied: the data cannot tell
    the clocks' offset (a mocap pose 0.3 s late) from the IMU's latency (a phone's 40 ms,
    erased when shifted at import), physics the diagnosis reports as a time skew."""
    clock = trajectory_clock(rec)
    rec.real["reference_clock"] = clock["said"]
    late = clock["offset_s"]
    if late is not None and 2 * GRID_S <= abs(late) < REFUSED_OFFSET_S:
        rec.real["reference_clock"] += ("; not applied: the diagnosis takes it as the IMU's "
                                        "time skew (an IMU's latency is physics to report); "
                                        "if it is the two clocks' offset, " + _advice(
                                            rec, rec.reference_shift_s - late, ".2f")[2:])
    if late is not None and abs(late) >= REFUSED_OFFSET_S:
        raise RecordingError(
            f"{rec.name}: the reference's attitude turns as the IMU does only with its stamps "
            f"{late_or_early(late)} ({clock['said']}): the two time bases differ by that much"
            + _advice(rec, rec.reference_shift_s - late, ".2f"))


FELT_GRAVITY_SHARE = 0.05   # of the recording's 1 s means: at least this share (and 3 s)
                            # feels gravity's size - a vehicle spends some time on the ground,
                            # hovering, cruising or under a parachute; a coast is no unit error


def _gravity_sized(rec):
    """The median |specific force| (m/s^2) of the 1 s means that feel between 0.5 and 2 g;
    refused when fewer than FELT_GRAVITY_SHARE of them (or 3 s) do: g read as m/s^2 (all
    near 1) or m/s^2 read as g (near 96) - not a free fall or a boost between rests."""
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
    return float(np.median(size[felt]))


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


COURSE_CHECK_RATE = 0.02       # rad/s: the course must turn this much (std) to judge a gyro
COURSE_CHECK_ACCEL = 0.3        # m/s^2: horizontal acceleration (std) to judge the axes
COURSE_CHECK_YAW = math.radians(45.0)   # a forward axis this far off is a wrong mounting

BODY_SLIP = math.radians(3.0)   # a car's side slip and its lever arm's forces (an
#   independent trial's two drives, mountings exact: -2.2 and -2.3 deg at 2.8 sigma)
DIAGNOSED_YAW = math.radians(20.0)      # the diagnosis' small-angle mounting term holds no
                                        # more (diagnosis.library.PHYSICAL_RANGE, 0.35 rad)


def _check_against_course(rec):
    """Without a reference attitude, the GNSS track of a land vehicle still judges the IMU
    (epochs faster than alignment.COURSE_SPEED, the IMU's 1 s means turned into the vehicle
    frame by the mounting): its yaw rate (FRD z) must follow the course rate with a ratio
    within 0.1-10 (deg/s read as rad/s is 57) and the same sense, and its horizontal specific
    force the track's acceleration (along: d speed/dt, across: speed x course rate) within
    45 deg of yaw (a forward axis that points sideways). Judged only where the track turns
    and accelerates enough to show it, and the two agree in shape (correlation, coherence).
    Not for what is not a car, declared or judged (`motion.carrier`): a multicopter flies
    sideways, a walker's phone points anywhere (a course rate that fit a multicopter's yaw
    rate 9.5 s off had refused it) - but for it too a yaw rate that follows the course
    closely (correlation > 0.7) at a size ratio outside 0.1-10 is a gyro unit read wrong."""
    epoch = int(rec.imu_ns[0])
    track = reference_track(rec, epoch)
    if track is None:
        return
    failed = _not_a_car(rec, track["t"], track["v_ned"])
    if failed:
        rec.real["course_checks"] = (f"not made: not a car ({'; '.join(failed)}), so it need "
                                     "not move along its forward axis, and its course judges "
                                     "neither the IMU's axes nor its clock - but a yaw rate "
                                     "that follows it at 0.1-10 times its size still checks "
                                     "the gyro's unit")
    t = track["t"]
    speed, course_rate, z_track = track_acceleration(t, track["v_ned"])
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
        _check_yaw_rate(rec, w_v[:, 2], rate, not failed, t_imu, t[sel], half)
    if failed:
        return
    z_ref = z_track[sel]
    if np.std(z_ref) > COURSE_CHECK_ACCEL:
        _mounting_yaw(rec, f_v[:, 0] + 1j * f_v[:, 1], z_ref)


def _mounting_yaw(rec, z_imu, z_ref):
    """The mounting's yaw from the IMU's horizontal specific force z_imu (vehicle x + 1j y,
    m/s^2) against the track's acceleration z_ref (along + 1j across) at the same epochs:
    said in rec.real (with its standard error, or why it is not measured), refused beyond
    COURSE_CHECK_YAW."""
    gain, coherence = acceleration_match(z_imu, z_ref)
    yaw = float(np.angle(gain))
    if coherence > 0.5 and not follows_track(gain, coherence):
        rec.real["mounting_yaw_against_course"] = (
            f"not measured: the accelerometers' horizontal specific force is "
            f"{abs(gain):.2f}-{abs(gain) / coherence ** 2:.2f} times the GNSS track's "
            f"acceleration (the two least-squares slopes, coherence {coherence:.2f}; a "
            f"car's IMU reads it at about 1, within {1 / TRACK_FORCE_RATIO:.2f}-"
            f"{TRACK_FORCE_RATIO:.2f}): the vehicle's specific force is not its track's - "
            "a banked track (a railway's cant), a vehicle that is no car - and its angle "
            f"({-math.degrees(yaw):+.1f} deg) says nothing of the mounting")
        return
    along, across = along_across_gains(z_imu * np.exp(-1j * yaw), z_ref)
    if coherence > 0.5 and not (along > 0 and across > 0 and
                                0.5 < across / along < 2.0):
        rec.real["mounting_yaw_against_course"] = (
            f"not measured: turned by the {-math.degrees(yaw):+.1f} deg that fits best, the "
            f"accelerometers feel {along:.2f} of the GNSS track's acceleration along it and "
            f"{across:.2f} across it (a car feels both alike, within a factor of 2): the "
            "vehicle banks or leans into its turns (a railway's cant, a two-wheeler), and "
            "the angle says nothing of the mounting")
        return
    if coherence > 0.5:
        se = match_angle_se(z_imu, z_ref)
        # said even when small. The specific force seen turned by yaw is the IMU turned
        # by -yaw about the vehicle's down axis from the mounting given, the sign the
        # diagnosis' `vector_vehicle` z gives (the RTKLIB drive: +6.1 deg here, +6.06
        # [5.05, 7.07] there)
        rec.real["mounting_yaw_against_course"] = (
            f"{-math.degrees(yaw):+.1f} deg (standard error {math.degrees(se):.2g}) about "
            "the vehicle's down axis: the IMU turned "
            "so from the mounting given (positive: its forward axis to the right of the "
            "vehicle's), from the accelerometers' horizontal specific force against the "
            f"GNSS track's acceleration (coherence {coherence:.2f}, size ratio "
            f"{abs(gain):.2f}; a car's body slip and lean take a few degrees): beyond "
            f"{math.degrees(COURSE_CHECK_YAW):.0f} deg it is refused; `mimunav diagnose` "
            f"measures one within {math.degrees(DIAGNOSED_YAW):.0f} deg with its interval "
            "(mounting_misalignment, a small-angle term)"
            + ("" if abs(yaw) <= DIAGNOSED_YAW else ", not this one: import it turned back")
            + ("; within twice its standard error or a car's body slip of the mounting "
               "given: nothing to turn back" if abs(yaw) < max(2 * se, BODY_SLIP) else
               f"; --mounting-rpy-deg {_turned_back(rec, yaw, square=False)} would turn it "
               "back"))
    if coherence > 0.5 and abs(yaw) > COURSE_CHECK_YAW:
        raise RecordingError(
            f"{rec.name}: the accelerometers' horizontal specific force matches the GNSS "
            f"track's acceleration with the IMU turned {-math.degrees(yaw):+.0f} deg about "
            f"the vehicle's down axis from the mounting given (coherence {coherence:.2f}): "
            "the sensor axes or the mounting's yaw are off by that much; "
            f"the mounting turned back would be --mounting-rpy-deg {_turned_back(rec, yaw)}"
            + (" - unless the vehicle drives in reverse most of the time (then import a "
               "forward stretch)" if abs(yaw) > math.radians(135.0) else ""))


def _check_yaw_rate(rec, yaw_rate, rate, car, t_imu, t_ref, half):
    """The IMU's 1 s mean yaw rate (rad/s, vehicle axes) against the course rate at the
    track's fast epochs t_ref: its unit (a size ratio outside 0.1-10 where they correlate),
    and for a car its sense and its clock (`_check_time_offset`)."""
    corr = float(np.corrcoef(yaw_rate, rate)[0, 1])
    ratio = float(np.std(yaw_rate) / np.std(rate))
    # a yaw rate that follows the course at 57 times its size is a unit read wrong whatever
    # carried it; against it, only a car's (a multicopter may yaw against its turns)
    wrong = (abs(corr) > 0.7 and not (corr > 0 and 0.1 < ratio < 10)) if car else \
        (corr > 0.7 and not 0.1 < ratio < 10)
    if wrong:
        raise RecordingError(
            f"{rec.name}: the gyro's yaw rate (vehicle z by the mounting) follows the GNSS "
            f"course rate {'reversed, ' if corr < 0 else ''}at {ratio:.3g} times its size "
            f"(correlation {corr:+.2f}): " + ("is the gyro's unit (deg/s or rad/s) right?"
                                              if not 0.1 < ratio < 10 else
                                              "the sensor axes or the mounting turn the "
                                              "yaw axis upside down"))
    if not car:
        return
    # searched whatever the correlation as stamped: a car's turns last seconds, so
    # stamps 2 s off still correlated 0.70 on the shared drive (1.00 at the shift)
    _check_time_offset(rec, t_imu, t_ref, rate, corr, half)


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
CLEARLY_BETTER = 2.0            # a shift must leave at most half the yaw-rate variance the
                                # stamps leave unexplained (1 - r^2): over half the record a
                                # smooth turn correlates ~1 with itself shifted (0.999999
                                # against 0.9999988 as stamped: 1.2x), while the shared drive
                                # with its reference late by 0.5 / 1.0 / 1.5 s: 4.4x / 18.8x /
                                # 38.8x (r 0.981 / 0.916 / 0.818 as stamped, 0.996 at the
                                # shift). A margin of 0.1 in r had let the 1 s pass
REFUSED_OFFSET_S = 1.0          # s: a reference this far off the IMU's clock is refused; below,
                                # the diagnosis measures the lag with its interval (time_skew,
                                # the track's lag): a first-order time term holds while the
                                # motion's rates change little within it (a turn: ~1 s)


def _check_time_offset(rec, t_imu, t_ref, rate, corr0, half):
    """The course turns: if the gyro's yaw rate follows it well (correlation > 0.7, over at
    least half the epochs) at a shift of the IMU's stamps of REFUSED_OFFSET_S or more within
    +-TIME_OFFSET_SEARCH_S, and clearly better than as stamped (CLEARLY_BETTER), the two
    time bases differ by that shift (GPS time read as UTC is 18 s): refused, naming it. No
    shift that fits: left to the other checks and the diagnosis (a noisy course)."""
    w_z = attitude.rotate(rec.mounting.q_vs, rec.w)[:, 2:]
    smooth = _local_mean(w_z, np.arange(len(w_z)), half)[:, 0]     # once, not per shift
    best, best_lag = -1.0, 0.0
    for lag in np.arange(-TIME_OFFSET_SEARCH_S, TIME_OFFSET_SEARCH_S + 1e-9, 0.5):
        at = t_ref + lag
        inside = (at > t_imu[0] + 0.5) & (at < t_imu[-1] - 0.5)
        if inside.sum() < max(20, 0.5 * len(t_ref)):
            continue
        k = np.searchsorted(t_imu, at[inside])
        c = np.corrcoef(smooth[k], rate[inside])[0, 1]
        if c > best:
            best, best_lag = float(c), float(lag)
    # as stamped, a correlation below zero explains nothing (r0 = -0.9 is no near-match)
    unexplained = (1 - max(corr0, 0.0) ** 2) / max(1 - best ** 2, 1e-12)
    shifted = best > 0.7 and unexplained >= CLEARLY_BETTER and best_lag != 0.0
    grid = f"searched every 0.5 s within +-{TIME_OFFSET_SEARCH_S:g} s"
    rec.real["reference_clock"] = (
        f"the gyro's yaw rate follows the GNSS course rate best with the IMU's stamps shifted "
        f"by {-best_lag:+.1f} s (correlation {best:.2f}, {corr0:+.2f} as stamped; {grid})"
        + ("" if abs(best_lag) >= REFUSED_OFFSET_S else
           f": under {REFUSED_OFFSET_S:g} s it is imported as stamped and left to `mimunav "
           "diagnose`, which measures the lag with its interval (the track level's time lag)")
        if shifted else
        f"the gyro's yaw rate follows the GNSS course rate as stamped (correlation "
        f"{corr0:+.2f}; no shift explains clearly more, {grid}; a lag under 0.5 s is "
        "`mimunav diagnose`'s to measure: the track level's time lag)") + (
        f" - the reference as shifted by the --reference-time-offset {rec.reference_shift_s:+g} "
        "given" if rec.reference_shift_s else "")
    if shifted and abs(best_lag) >= REFUSED_OFFSET_S:
        raise RecordingError(
            f"{rec.name}: the gyro's yaw rate follows the GNSS course rate only with the IMU's "
            f"stamps shifted by {-best_lag:+.1f} s (correlation {best:.2f}, {corr0:+.2f} as "
            "stamped): the IMU's and the reference's time bases differ by that much"
            + (" (GPS time read as UTC is 18 s off)" if abs(best_lag) > 10 else "")
            + _advice(rec, rec.reference_shift_s + best_lag, ".1f"))


def _advice(rec, total_s, form):
    """'; --reference-time-offset TOTAL would shift the reference back' - the whole shift
    from the recording's stamps, in place of any the command line gave (a given shift is
    in the stamps checked: the correction alone would undo it)."""
    given = rec.reference_shift_s
    if given and abs(total_s) < 0.05:
        return f"; without the --reference-time-offset {given:+g} given, the reference is right"
    return (f"; --reference-time-offset {total_s:+{form}} would shift the reference back"
            + (f" (in place of the {given:+g} s given)" if given else ""))


def _local_mean(x, k, half=5):
    """Means of x over the samples k - half .. k + half (noise averaged, motion kept)."""
    return span_means(x, np.clip(k - half, 0, len(x)),
                                np.clip(k + half + 1, 0, len(x)))


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
                heading_known=rec.reference_heading_known, **course_keys(rec.vehicle))


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
