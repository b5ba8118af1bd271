"""A land vehicle's IMU checked against its GNSS track without a reference attitude: the
gyro's yaw rate against the course rate (its unit, its sense, the IMU's clock) and the
horizontal specific force against the track's acceleration (the mounting's yaw; a mirrored
triad). Both series are 1 s means: the IMU's over its samples, the track's over its epochs
(a 10 Hz track's course rate, differenced epoch by epoch, is mostly noise: a tractor's
correlated 0.16 with its yaw rate, and 2 s of clock offset had passed as "follows as
stamped"; `motion.carrier.epoch_means`).
"""
import math

import numpy as np
import quaternion

from ..navigation import alignment
from ..navigation.rests import span_means
from ..navigation.travel import (TRACK_FORCE_RATIO, acceleration_match, along_across_gains,
                                 follows_track, match_angle_se, track_acceleration)
from ..frames import attitude
from .recording import RecordingError
from ..motion.carrier import ALONG_COURSE, LAND, car_tests, epoch_means


def not_a_car(rec, t_track, v_ned):
    """[why the recording is not a car] - declared another vehicle, or the tests
    `motion.carrier.car_tests` fails on its track's velocities v_ned (m/s) at t_track (s
    from the IMU's first stamp) and its specific force and rate - or [] for a car."""
    if rec.vehicle:
        return [] if rec.vehicle == LAND else [f"declared: {rec.vehicle}"]
    return car_tests(t_track, v_ned, (rec.imu_ns - rec.imu_ns[0]) / 1e9, rec.f, rec.w)[0]


COURSE_CHECK_RATE = 0.02       # rad/s: the course must turn this much (std) to judge a gyro
COURSE_CHECK_ACCEL = 0.3        # m/s^2: horizontal acceleration (std) to judge the axes
COURSE_CHECK_YAW = math.radians(45.0)   # a forward axis this far off is a wrong mounting

BODY_SLIP = math.radians(3.0)   # a car's side slip and its lever arm's forces (an
#   independent trial's two drives, mountings exact: -2.2 and -2.3 deg at 2.8 sigma)
DIAGNOSED_YAW = math.radians(20.0)      # the diagnosis' small-angle mounting term holds no
                                        # more (diagnosis.library.PHYSICAL_RANGE, 0.35 rad)


MIRROR_MARGIN = 0.1     # coherence a mirrored force must gain over the best turn (a car's
#                         direct fit reads 0.9-1.0, its mirror less by the share of turning)


def check_against_course(rec, track):
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
    if track is None:
        return
    failed = not_a_car(rec, track["t"], track["v_ned"])
    if failed:
        rec.real["course_checks"] = (f"not made: not a car ({'; '.join(failed)}), so " + (
            "its lean or cant tilts its sideways force out of the level plane the checks "
            "assume, though its course is its heading (the initial state takes it)"
            if rec.vehicle in ALONG_COURSE else "it need not move along its forward axis")
            + ", and its course judges neither the IMU's axes nor its clock - but a yaw rate "
            "that follows it at 0.1-10 times its size still checks the gyro's unit")
    t = track["t"]
    speed, course_rate, z_track = (epoch_means(t, x[:, None], 0.5)[:, 0]   # as the IMU's
                                   for x in track_acceleration(t, track["v_ned"]))
    t_imu = (rec.imu_ns - epoch) / 1e9
    sel = (speed > alignment.COURSE_SPEED) & (t > t_imu[0] + 0.5) & (t < t_imu[-1] - 0.5) \
        & np.isfinite(course_rate) & np.isfinite(z_track)
    if sel.sum() < 20:
        return
    k = np.searchsorted(t_imu, t[sel])
    half = max(1, int(round(0.5 * rec.sample_rate_hz)))
    w_v = attitude.rotate(rec.mounting.q_vs, local_mean(rec.w, k, half))
    f_v = attitude.rotate(rec.mounting.q_vs, local_mean(rec.f, k, half))
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
    COURSE_CHECK_YAW, and refused as a reflection where the IMU's force mirrored (one
    horizontal axis's sign turned) follows the track clearly better than turned by any yaw
    (a tractor's IMU with its z signed wrong, turned over by the mounting that levelled it,
    had been imported as driving in reverse 85 % of the time)."""
    gain, coherence = acceleration_match(z_imu, z_ref)
    gain_m, mirrored = acceleration_match(np.conj(z_imu), z_ref)
    along_m, across_m = along_across_gains(np.conj(z_imu) * np.exp(-1j * np.angle(gain_m)),
                                           z_ref)
    # mirrored, it follows the track as a car's does: alike along and across (a vehicle that
    # banks into its turns feels less across, even against them: a train 0.94 and -0.17)
    if mirrored > 0.5 and mirrored > coherence + MIRROR_MARGIN and along_m > 0 and \
            0.5 < across_m / along_m < 2.0:
        raise RecordingError(
            f"{rec.name}: the accelerometers' horizontal specific force follows the GNSS "
            f"track's acceleration only mirrored (coherence {mirrored:.2f}; {coherence:.2f} "
            "turned by any yaw): one of the IMU's axes runs against the vehicle's - a "
            "column's sign or the axes' order (a mounting that turns the IMU over to level a "
            "z axis signed wrong flips another) - a reflection, which no mounting turns: "
            "check the IMU's columns")
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
            + (f"; within twice its standard error or a car's body slip "
               f"({math.degrees(BODY_SLIP):.0f} deg) of the mounting given, the import turns "
               "nothing: the diagnosis tells a mounting's yaw from the slip"
               if abs(yaw) < max(2 * se, BODY_SLIP) else
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
FOLLOWS = 0.7                   # a yaw rate that correlates above this with the course rate
#                                 as stamped follows it; below, the clock is not checked
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
    smooth = local_mean(w_z, np.arange(len(w_z)), half)[:, 0]     # once, not per shift
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
    shifted = best > FOLLOWS and unexplained >= CLEARLY_BETTER and best_lag != 0.0
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
        "`mimunav diagnose`'s to measure: the track level's time lag)" if corr0 > FOLLOWS else
        f"not measured: the gyro's yaw rate follows the GNSS course rate at no shift "
        f"(correlation {corr0:+.2f} as stamped, {best:+.2f} at best at {-best_lag:+.1f} s; "
        f"{grid}): the course does not time the IMU's clock, which is taken as stamped "
        "unchecked") + (
        f" - the reference as shifted by the --reference-time-offset {rec.reference_shift_s:+g} "
        "given" if rec.reference_shift_s else "")
    if shifted and abs(best_lag) >= REFUSED_OFFSET_S:
        raise RecordingError(
            f"{rec.name}: the gyro's yaw rate follows the GNSS course rate only with the IMU's "
            f"stamps shifted by {-best_lag:+.1f} s (correlation {best:.2f}, {corr0:+.2f} as "
            "stamped): the IMU's and the reference's time bases differ by that much"
            + (" (GPS time read as UTC is 18 s off)" if abs(best_lag) > 10 else "")
            + offset_advice(rec, rec.reference_shift_s + best_lag, ".1f"))


def offset_advice(rec, total_s, form):
    """'; --reference-time-offset TOTAL would shift the reference back' - the whole shift
    from the recording's stamps, in place of any the command line gave (a given shift is
    in the stamps checked: the correction alone would undo it)."""
    given = rec.reference_shift_s
    if given and abs(total_s) < 0.05:
        return f"; without the --reference-time-offset {given:+g} given, the reference is right"
    return (f"; --reference-time-offset {total_s:+{form}} would shift the reference back"
            + (f" (in place of the {given:+g} s given)" if given else ""))


def local_mean(x, k, half=5):
    """Means of x over the samples k - half .. k + half (noise averaged, motion kept)."""
    return span_means(x, np.clip(k - half, 0, len(x)),
                                np.clip(k + half + 1, 0, len(x)))
