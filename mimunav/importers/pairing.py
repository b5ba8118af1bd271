"""A reference IMU flown beside the IMU (a better IMU on the same vehicle, often on its own
clock and in its own axes): its clock offset and its mounting measured against the IMU's and
corrected when the data decide them, refused with the measured values when they do not.

Clock: measured and corrected first (`imu_clock.clock_offset`).

Mounting: after the clock, the two IMUs' 1 s mean rates and specific forces in the vehicle
frame (each through its own mounting) are turned onto each other (Wahba's problem, scipy's
`align_vectors`): first about their own means, where no bias of either IMU enters, and the
turn is applied at any size when they span two directions (their second singular value at
least SPAN_SHARE of the first); else with gravity among them (the rates about their means
beside the specific forces as recorded), the turn applied beyond SMALL_TURN_DEG and kept
within it (an accelerometer bias difference across gravity reads as tilt: the diagnosis
fits both); refused with the measured turn where gravity alone is seen (it leaves the yaw
about it open). A triad mirrored against the other IMU's (a column's sign, an axis order: no
turn holds it) is refused naming it: a moving axis whose 1 s means run against the IMU's, as
given or after the best turn (`_runs_against`). The turn goes to the IMU's mounting instead
where the reference's attitude is the reference IMU's own (`attitude_of`) or holds it and
not the IMU's (`attitude_check`).
"""
import math

import numpy as np
import quaternion

from ..frames import attitude
from ..frames.mounting import AGAINST, Mounting, runs_against
from .recording import G0, RecordingError, at_range, utc_text
from .attitude_check import (angle_text, turn_both, turn_the_imu, turned_back, wahba,
                             whose_turn)
from .imu_clock import DISTINCT_Z, GRID_S, SMALL_OFFSET_S, TURNING_RATE, clock_offset
from .lever import arm_cov, lever_force, unit_forces
from .series import window_means

SMALL_TURN_DEG = 3.0        # deg: within this its mounting_misalignment term carries a turn
SPAN_SHARE = 0.05           # second singular value over the first: two directions seen
ARM_ROUNDS = 3              # a lever arm not given, fitted in turn with the mounting's turn
TURN_BLOCKS = 20            # blocks of the seconds a measured turn's error is jackknifed over
#                             (longer than the motion stays correlated on a drive or a flight)

def pair(rec):
    """Check the recording's reference IMU against its IMU and correct its clock and
    mounting where they are measured (module doc); say what was measured and done in
    rec.real (`reference_imu_clock`, `reference_imu_mounting`). Refuses (RecordingError) a
    reference IMU that does not feel 1 g, overlaps the IMU over less than half its span,
    turns a different amount (a unit: deg/s read as rad/s), or whose clock or mounting
    beyond the diagnosis' small terms cannot be decided from the data."""
    ref = rec.reference_imu
    g = float(np.median(np.linalg.norm(ref["f"], axis=1)))
    if not 0.5 * G0 < g < 2 * G0:
        raise RecordingError(f"{rec.name}: the reference IMU's median |specific force| is "
                             f"{g:.3g} m/s^2, not about 9.8: is its accelerometer's unit right?")
    _check_units(rec)
    clock = clock_offset(rec)
    rec.real["reference_imu_clock"] = clock["said"]
    if clock["offset_s"] is None and not abs(clock.get("peak_lag_s", math.inf)) <= GRID_S:
        rec.reference_imu_clock_open = clock["said"]    # the stamps are not where the data
        #                                                 peak: the sensor level stops short
    if "drift" in clock:
        rec.shift_reference_imu(-clock["offset_s"], "measured: " + clock["said"],
                                drift=-clock["drift"], at_s=clock["at_s"] + clock["offset_s"])
    elif clock["offset_s"] is not None and abs(clock["offset_s"]) > SMALL_OFFSET_S:
        rec.shift_reference_imu(-clock["offset_s"], "measured: " + clock["said"])
    if rec.reference_imu_offset_given and clock["offset_s"] is not None and \
            abs(clock["offset_s"]) > SMALL_OFFSET_S:
        late = clock["offset_s"] > 0        # the reference IMU's stamps late on the IMU's
        rec.real["reference_imu_clock"] += (
            f"; the data put the reference IMU's stamps {abs(clock['offset_s']) * 1e3:.1f} ms "
            f"{'late' if late else 'early'} beside the offset given: it is that far off, or "
            f"the IMU {'leads' if late else 'lags'} the reference IMU by that much - a "
            "latency the diagnosis cannot test once the clock is shifted")
    _check_overlap(rec)
    clock_se = clock.get("offset_se_s", math.inf) if clock["offset_s"] is not None else math.inf
    rec.reference_imu_clock_se_s = clock_se if math.isfinite(clock_se) else None
    _pair_mountings(rec, clock_se)


def _check_overlap(rec):
    ref = rec.reference_imu
    lo, hi = max(rec.imu_ns[0], ref["ns"][0]), min(rec.imu_ns[-1], ref["ns"][-1])
    if hi - lo < 0.5 * (rec.imu_ns[-1] - rec.imu_ns[0]):
        raise RecordingError(f"{rec.name}: the reference IMU ({utc_text(ref['ns'][0])} .. "
                             f"{utc_text(ref['ns'][-1])}) covers less than half of the IMU's span "
                             f"({utc_text(rec.imu_ns[0])} .. {utc_text(rec.imu_ns[-1])}): do the "
                             "two share a time base?")


def _check_units(rec):
    """The two gyros must see the same spread of |w| (a ratio beyond 0.5-2: a unit)."""
    size = [np.linalg.norm(w, axis=1) for w in (rec.w, rec.reference_imu["w"])]
    spread = [float(np.std(s)) for s in size]
    if max(spread) > TURNING_RATE:
        ratio = spread[0] / max(spread[1], 1e-12)
        if not 0.5 < ratio < 2.0:
            raise RecordingError(f"{rec.name}: the IMU's rotation rate varies {ratio:.3g} times "
                                 "as much as the reference IMU's (|w|): is one gyro's unit "
                                 "(deg/s or rad/s) wrong, or the topic another vehicle's?")


def _second_means(rec):
    """([[IMU w, f, `_lever_force`], [reference w, f]] 1 s means over the overlap (rad/s,
    m/s^2, sensor axes; the lever force's vehicle frame), (M,) bool: the seconds both fill and
    no clipped sample lies in (a rate table's 300 deg/s steps on a 250 deg/s gyro), (M,) their
    mid-times (s)."""
    ref = rec.reference_imu
    lo, hi = max(rec.imu_ns[0], ref["ns"][0]), min(rec.imu_ns[-1], ref["ns"][-1])
    mids = np.arange(lo + 500_000_000, hi - 500_000_000, 1_000_000_000) / 1e9
    means = [[window_means(ns, x, mids) for x in (w, f)]
             for ns, w, f in ((rec.imu_ns, rec.w, rec.f), (ref["ns"], ref["w"], ref["f"]))]
    means[0].append(_lever_force(rec, mids))
    if len(mids) < 10:
        return means, np.zeros(len(mids), bool), mids
    ok = np.isfinite(np.hstack([m for p in means for m in p])).all(axis=1)
    clipped = at_range(rec.w, rec.f, rec.range).astype(float)[:, None]
    return means, ok & ~(window_means(rec.imu_ns, clipped, mids)[:, 0] > 0), mids


def _turn_said(angle, how, rpy, hint, se=math.inf):
    """The measured turn in words: angle (deg, its standard error se where known), how
    (`_measured_turn`), the mounting (roll, pitch, yaw text; None: not said) that would hold
    it and the option that gives it."""
    roll, pitch, yaw = rpy or (None,) * 3
    return (f"{angle:.1f} deg " + (f"(standard error {se:.2g}) " if math.isfinite(se) else "")
            + "from the mounting given (1 s mean rates and specific forces in the "
            "vehicle frame" + (", about their own means: no bias of either IMU in it"
                               if how == "free" else
                               f"; the IMU's own gyros and accelerometers turn onto the "
                               f"reference's more than {TRIADS_AGREE_DEG:g} deg apart: both "
                               "together" if how == "triads differ" else "") + ")" + (
                "; the two would agree with the reference IMU at roll, pitch, yaw "
                f"{roll}, {pitch}, {yaw} deg" if rpy else "") +
            (f" ({hint.format(roll=roll, pitch=pitch, yaw=yaw)})" if rpy and hint else ""))


def _pair_mountings(rec, clock_se):
    """Turn the reference IMU's mounting onto the IMU's where the 1 s means decide it (module
    doc; `_turn_mountings`), a lever arm not given fitted first (`_fit_arm`) and said in the
    vehicle frame the IMU ends in (a ship's MEMS turned 90 deg from its mounting given had
    its arm read in the frame before the turn: [0.0, -11.8, -8.0] m for [12, 0, -8])."""
    means, ok, mids = _second_means(rec)
    if ok.sum() < 10:
        rec.real["reference_imu_mounting"] = "not measured: under 10 s of common samples"
        return
    arm = _fit_arm(rec, means, ok, mids)
    before = rec.mounting.q_vs
    _turn_mountings(rec, clock_se, means, ok, mids)
    if arm is not None:
        _say_arm(rec, *arm, rec.mounting.q_vs * np.conjugate(before))


def _turn_mountings(rec, clock_se, means, ok, mids):
    """Turn the reference IMU's mounting onto the IMU's where the 1 s means (`_second_means`)
    decide it, a small turn only beyond what the clock's standard error clock_se (s) can make
    of the rates (`_clock_turn_deg`); say what was measured."""
    ref = rec.reference_imu
    turn, angle, how, apart, se = _measured_turn(rec, means, ok)
    if in_theirs := _arm_in_their_frame(rec, means, ok, mids, turn):   # the IMU's frame off
        turn, angle, how, apart, se = _measured_turn(rec, means, ok)
    seen = bool(how)
    # a mirrored triad (a sign, an axis order) is no turn: after the best turn an axis runs
    # against the other IMU's, named as given where one does there too (a mirrored accel turns
    # the gyros against) - as given alone, 180 deg runs two against (a FOG, a Shimmer's export)
    vehicle = [(attitude.rotate(rec.mounting.q_vs, means[0][k][ok]),
                attitude.rotate(ref["mounting"].q_vs, means[1][k][ok])) for k in range(2)]
    said = {when: [why for (mine, theirs), sensor in zip(vehicle, ("gyro", "accel"))
                   for why in [_runs_against(sensor, mine, turned(theirs), when,
                                             columns.format(sensor), _axis_names(rec))] if why]
            for when, columns, turned in (
                ("with the mountings given", "{} columns", lambda x: x),
                ("after the best turn between them (fitted on both triads)",
                 "gyro and the accelerometer columns", turn.apply))}
    given, after = said.values()
    if after or apart:
        raise RecordingError(f"{rec.name}: {(given or after)[0] if after else apart}")
    fixed = attitude.from_scipy(turn) * ref["mounting"].q_vs
    yaw, pitch, roll = (angle_text(a) for a in attitude.as_euler(fixed))
    hint = ref.get("mounting_hint")
    said = _turn_said(angle, how, (roll, pitch, yaw), hint, se)
    if rec.reference_meta.get("attitude_of") == "reference_imu" and seen or in_theirs:
        # the reference's attitude is of the reference IMU's axes, or the arm given holds in
        # them: they stay, the IMU turns
        turn_the_imu(rec, _for_the_imu(rec, turn, means, ok, mids),
                     _turn_said(angle, how, None, None),
                     "the lever arm given fits the IMU's forces only in the reference IMU's "
                     "frame (turned by the turn between the two)" if in_theirs else
                     "the reference's attitude is the reference IMU's (attitude_of)")
        return
    # an accelerometer bias difference b across gravity tilts the mean specific force by
    # b / g: a small measured tilt may be that, not the boxes' turn (the diagnosis fits both)
    bias_alike = f"{G0 * math.tan(math.radians(angle)):.2g} m/s^2"
    if angle <= SMALL_TURN_DEG and not seen:
        rec.real["reference_imu_mounting"] = (
            f"measured {angle:.1f} deg of tilt from the mounting given (or an accelerometer "
            f"bias difference of {bias_alike} across gravity, which reads the same); the turn "
            "about gravity is not seen (beside gravity, the 1 s means hold too little of a "
            f"second direction - under {SPAN_SHARE:g} of it: a still or gently driven "
            "vehicle): the yaw given is taken for it - check it")
        return
    timing = _clock_turn_deg(means[0][0][ok], clock_se)
    if angle <= SMALL_TURN_DEG and (how != "free" or
                                    not angle > DISTINCT_Z * max(timing, se)):
        rec.real["reference_imu_mounting"] = (
            f"measured {said}: kept (the diagnosis fits a turn this small; "
            f"{_why_kept(how, angle, bias_alike, (clock_se, timing), se)})")
        return
    if not seen:
        raise RecordingError(
            f"{rec.name}: the reference IMU's rates and specific forces, turned into the vehicle "
            f"frame by its mounting, lie {angle:.1f} deg from the IMU's, and beside gravity "
            f"their 1 s means hold too little of a second direction (under {SPAN_SHARE:g} of "
            "it: a still or gently driven vehicle), which leaves a turn about it open: "
            f"give its mounting (its tilt as the data show it, the yaw as given: roll, "
            f"pitch, yaw {roll}, {pitch}, {yaw} deg"
            + (f": {hint.format(roll=roll, pitch=pitch, yaw=yaw)})" if hint else ")"))
    if how == "free" and _halves_apart(rec, means, ok, said):
        return
    _check_placed(rec, angle, se, (roll, pitch, yaw), hint)
    imus = [(vehicle[0][0], vehicle[1][0] - means[0][2][ok]), (vehicle[0][1], vehicle[1][1])]
    whose, held, turns = whose_turn(rec.reference, mids[ok], imus, angle,
                                    (TURNING_RATE, MOVING_FORCE), SPAN_SHARE)
    if whose == "both":     # the attitude holds neither mounting given: each onto it
        turn_both(rec, turns, f"measured {_turn_said(angle, how, None, None)}; {held}")
        return
    if whose == "imu":      # the reference's attitude holds the reference IMU, not the IMU
        turn_the_imu(rec, _for_the_imu(rec, turn, means, ok, mids),
                     _turn_said(angle, how, None, None), held)
        return
    ref["mounting"] = Mounting(attitude.as_wxyz(fixed), ref["mounting"].lever_arm_m)
    rec.real["reference_imu_mounting"] = f"measured {said}: turned so" + (f" ({held})" if held
                                                                          else "")


def _check_placed(rec, angle, se, rpy, hint):
    """Refuses (RecordingError) a turn between the two IMUs (angle, its standard error se,
    deg) that the data do not place within SMALL_TURN_DEG: no mounting to take (two feet of
    a walker: 45 deg, se 20, had been 'turned so'); rpy: the best turn's roll, pitch, yaw
    texts."""
    if se <= SMALL_TURN_DEG:
        return
    roll, pitch, yaw = rpy
    raise RecordingError(
        f"{rec.name}: the reference IMU's mounting lies {angle:.1f} deg from the IMU's "
        f"(standard error {se:.2g} deg), which the data do not place within the "
        f"{SMALL_TURN_DEG:g} deg the diagnosis' mounting terms fit: do the two share one "
        f"motion? If so, give its mounting from the installation (the data's best turn, "
        f"as uncertain: roll, pitch, yaw {roll}, {pitch}, {yaw} deg" + (
            f": {hint.format(roll=roll, pitch=pitch, yaw=yaw)})" if hint else ")"))


ARM_FRAME_DEG = 5.0      # deg: the gyros' own turn from which the lever arm given is asked
#                          which IMU's frame it holds in (a smaller turn moves its force
#                          less than the misfit's noise)
ARM_FRAME_SHARE = 0.5    # the arm in the reference IMU's frame must leave at most this share
#                          of the accelerometers' misfit that it leaves in the IMU's


def _arm_in_their_frame(rec, means, ok, mids, both):
    """Whether the lever arm given holds in the reference IMU's frame rather than in the
    IMU's (the IMU's mounting the one off): where the gyros' own turn between the two (rates
    hold no arm; where they span one direction only, `both` - the turn measured on both
    triads) reaches ARM_FRAME_DEG, the arm's force computed with the arm turned by it
    leaves at most ARM_FRAME_SHARE of the accelerometers' misfit (after each one's best turn)
    that the arm as given leaves; its force then replaces `means[0][2]`. A mounting given
    far off puts the IMU's rates on other axes than the arm's, and their force turns its
    accelerometers' triad away from its gyros' (a ship's MEMS turned 90 or 180 deg in yaw,
    its 14.4 m arm given: refused as triads 26-29 deg apart - "a reflection"; the proof
    flight's IMU 90 deg off, 9.4 m away: the reference IMU turned instead, 8.5 deg of pitch
    in its turn)."""
    r = rec.mounting.lever_arm_m - rec.reference_imu["mounting"].lever_arm_m
    if not np.any(r):
        return False
    q_mine, q_ref = rec.mounting.q_vs, rec.reference_imu["mounting"].q_vs
    mine, theirs = (attitude.rotate(q, x[0][ok]) for q, x in ((q_mine, means[0]),
                                                                (q_ref, means[1])))
    gyros = wahba(mine - mine.mean(axis=0), theirs - theirs.mean(axis=0), SPAN_SHARE) or both
    if math.degrees(gyros.magnitude()) < ARM_FRAME_DEG:
        return False
    forces = [means[0][2], _lever_force(rec, mids, gyros.apply(r))]
    misfit = []
    for force in forces:
        turn = _measured_turn(rec, [[means[0][0], means[0][1], force], means[1]], ok)[0]
        gap = attitude.rotate(q_mine, means[0][1][ok]) - force[ok] - \
            turn.apply(attitude.rotate(q_ref, means[1][1][ok]))
        misfit.append(float(np.sqrt(np.mean((gap - gap.mean(axis=0)) ** 2))))
    if not misfit[1] <= ARM_FRAME_SHARE * misfit[0]:
        return False
    means[0][2] = forces[1]
    return True


def _halves_apart(rec, means, ok, said):
    """Whether the free turns of the recording's first and second halves of seconds
    (`_measured_turn`) lie apart beyond DISTINCT_Z of their standard errors together and
    beyond SMALL_TURN_DEG - one unit moved against the other during the recording, and no
    one mounting holds it (a phone that turned 15 deg in its holder halfway had been given
    the mean of its two mountings, true at no time); if so, the mountings given are kept
    and the import says why beside the whole turn (`said`)."""
    half = np.flatnonzero(ok)[ok.sum() // 2]
    turns = [_measured_turn(rec, means, ok & side) for side in
             (np.arange(len(ok)) < half, np.arange(len(ok)) >= half)]
    if any(how != "free" for _, _, how, _, _ in turns):
        return False
    (first, a1, *_, se1), (second, a2, *_, se2) = turns
    apart = math.degrees((first.inv() * second).magnitude())
    se = math.hypot(se1, se2)
    if not (apart > DISTINCT_Z * se and apart > SMALL_TURN_DEG):
        return False
    rec.reference_imu_moved = (
        f"the first half's turn between the two IMUs ({a1:.1f} deg) and the second half's "
        f"({a2:.1f} deg) lie {apart:.1f} deg apart (standard error {se:.2g}): one unit moved "
        "against the other during the recording, and no one mounting holds both halves "
        "(import the spans where each holds one apart)")
    rec.real["reference_imu_mounting"] = (f"measured {said}, but not taken: "
                                          f"{rec.reference_imu_moved} - the mountings given "
                                          "are kept, and the sensor level sets its findings "
                                          "aside")
    return True


def _for_the_imu(rec, turn, means, ok, mids):
    """`turn` measured again once the IMU's mounting takes it: the lever force between the
    two (`_lever_force`) is the IMU's rates in the vehicle frame of its mounting, which a
    mounting tens of degrees off puts on the wrong axes (an AUV's 0.85 m arm beside a
    mounting given 91 deg off had left 2.15 deg of pitch in the turn; 0.02 deg given right).
    The same turn without a lever arm."""
    if not np.any(rec.mounting.lever_arm_m - rec.reference_imu["mounting"].lever_arm_m):
        return turn
    given = rec.mounting
    rec.mounting = turned_back(given, turn)[0]
    try:
        again = [means[0][0], means[0][1], _lever_force(rec, mids)]
        rest = _measured_turn(rec, [again, means[1]], ok)[0]
    finally:
        rec.mounting = given
    return turn * rest


def _why_kept(how, angle, bias_alike, clock, se):
    """Why a small measured turn (deg, decided `how`: `_measured_turn`, its standard error
    se) is not taken; clock: (the clock's standard error, s; the turn it makes, deg)."""
    clock_se, timing = clock
    if how == "triads differ":
        return ("the IMU's gyros and accelerometers turn onto the reference's by more than "
                f"{TRIADS_AGREE_DEG:g} deg apart: its own triads differ")
    if how != "free":
        return (f"its tilt may be an accelerometer bias difference across gravity: "
                f"{bias_alike} reads as {angle:.1f} deg")
    if se >= timing:
        return (f"it lies within {DISTINCT_Z:g} of its standard errors ({se:.2g} deg, "
                f"jackknifed over {TURN_BLOCKS} blocks of the seconds)")
    if math.isfinite(timing):
        return f"a clock known to {clock_se * 1e3:.2g} ms turns the rates by up to {timing:.2g} deg"
    return ("the clock between the two is not measured: a small turn of the rates is not told "
            "from a time offset")


def _clock_turn_deg(w, clock_se):
    """deg: how far a clock error of clock_se (s) turns the 1 s mean rates w (N, 3 rad/s, 1 s
    apart) - a rate vector that changes direction at dw/dt moves by dw/dt clock_se - as the
    rms of their change over the rms of their spread (5 ms between two IMUs' interval stamps
    had turned a conical motion's rates 0.4 deg); inf for a clock not measured."""
    if not math.isfinite(clock_se):
        return math.inf
    spread = float(np.sqrt(np.mean((w - w.mean(axis=0)) ** 2)))
    change = float(np.sqrt(np.mean(np.gradient(w, axis=0) ** 2)))
    return math.degrees(change / max(spread, 1e-12) * clock_se)


def _axis_names(rec):
    """[for the vehicle's x, y, z: the sensor axis of each IMU along it, in words] - a
    reflection named about the vehicle's axis alone had left a user to turn it back through
    a 93 deg mounting to find the column (a motorcycle's MIMU y)."""
    names = []
    for axis in np.eye(3):
        each = []
        for whose, mounting in (("the IMU's", rec.mounting),
                                ("the reference IMU's", rec.reference_imu["mounting"])):
            along = attitude.rotate(mounting.q_vs.inverse(), axis)
            i = int(np.argmax(np.abs(along)))
            each.append(f"{whose} {'+-'[int(along[i] < 0)]}{'xyz'[i]}")
        names.append(f"{each[0]} and {each[1]} sensor axis along it")
    return names


def _runs_against(sensor, mine, theirs, when, columns, names=None):
    """Why the triads are a reflection (naming the triad and axis - with `names`, each
    IMU's sensor axis along it: `_axis_names` -, and the `columns` to check), or '': a
    moving axis - 1 s means spread by 0.02 rad/s or 0.3 m/s^2 (`reference.MOVING_SPREAD`'s
    sizes) - whose means (vehicle frame) run against the other
    IMU's: correlation below AGAINST; a quieter one where `mounting.runs_against`
    (its differences too)."""
    spread = 0.02 if sensor == "gyro" else 0.3
    for i, axis in enumerate("xyz"):
        if min(np.std(mine[:, i]), np.std(theirs[:, i])) < spread and \
                not runs_against(mine[:, i], theirs[:, i]):     # a quiet axis: a sign only
            continue
        r = float(np.corrcoef(mine[:, i], theirs[:, i])[0, 1])
        if r < AGAINST:
            where = f" ({names[i]})" if names else ""
            return (f"{when}, the two IMUs' {sensor}s about the vehicle's {axis} axis{where} run "
                    f"against each other (1 s means correlate {r:.2f}): a column's sign or the "
                    f"axes' order differs between the two IMUs - a reflection, which no "
                    f"mounting can turn: check the {columns}")
    return ""


def _measured_turn(rec, means, ok):
    """(the turn of the reference's vehicle-frame vectors onto the IMU's, its angle in deg,
    how it was decided, why the two triads' own turns lie too far apart for any mounting
    (`_triads_apart`) or '', its standard error (deg, `_turn_se_deg`; inf but "free"); how:
    "free" - by the 1 s means about their own means, where
    no bias of either IMU enters (a constant difference), each kind scaled to unit rms;
    "triads differ" - so, but the triads' own turns lie apart beyond their errors (the
    turn of both, kept for the diagnosis: which triad is the unit's is not told by the data
    - an independent review: gyros turned 1 deg against their own accelerometers had turned
    an exact mounting 1 deg when the gyros' turn was taken); "with gravity"
    - the rates about their means beside the specific forces as recorded, gravity among
    them (an accelerometer bias difference across it then reads as tilt); "" - only one
    direction seen: the smallest turn of the mean specific force onto the IMU's, the yaw
    about it left open). Two directions are seen where the second singular value of the
    vectors' cross-covariance is at least SPAN_SHARE of the first."""
    from scipy.spatial.transform import Rotation
    q_mine, q_ref = rec.mounting.q_vs, rec.reference_imu["mounting"].q_vs
    w_mine, f_mine = (attitude.rotate(q_mine, x[ok]) for x in means[0][:2])
    w_ref, f_ref = (attitude.rotate(q_ref, x[ok]) for x in means[1])
    f_mine = f_mine - means[0][2][ok]
    # each gyro's bias is a constant the turn must not fit: the rates about their means (a
    # MEMS pair's 0.3 deg/s bias difference, weighted up to g beside the specific forces,
    # had turned a fixed wing's two aligned IMUs 1.1 deg apart; w - mean = C (w_r - mean));
    # so the specific forces where they vary enough (a rate table's six positions: their
    # 15-19 mg bias differences had read as 4.6 deg of tilt)
    centred = [x - x.mean(axis=0) for x in (w_mine, w_ref, f_mine, f_ref)]
    rms_w, rms_f = (float(np.sqrt(np.mean(x ** 2))) for x in (centred[0], centred[2]))
    kinds = [(centred[0] / rms_w, centred[1] / rms_w)] if rms_w >= TURNING_RATE else []
    kinds += [(centred[2] / rms_f, centred[3] / rms_f)] if rms_f >= MOVING_FORCE else []
    # each triad alone, where it decides the turn: a MEMS unit's gyros turned against its
    # own accelerometers take a compromise that fits neither (1 deg of gyro triad had turned
    # an exact mounting 0.7 deg); both weighed by how tightly each holds its own
    each = [_own_turn(k) for k in kinds] if len(kinds) == 2 else []
    kinds = _weighed(kinds, [se for _, se in each])
    if kinds:
        turn = wahba(np.vstack([k[0] for k in kinds]), np.vstack([k[1] for k in kinds]),
                     SPAN_SHARE)
        if turn is not None:
            if any(e is not None and math.degrees((e.inv() * turn).magnitude())
                   > max(TRIADS_AGREE_DEG, DISTINCT_Z * se) for e, se in each):
                return turn, math.degrees(turn.magnitude()), "triads differ", \
                    _triads_apart(each, kinds), math.inf
            return turn, math.degrees(turn.magnitude()), "free", "", _turn_se_deg(kinds, turn)
    mine = np.vstack([centred[0] * (G0 / rms_w), f_mine]) if rms_w >= TURNING_RATE else f_mine
    theirs = np.vstack([centred[1] * (G0 / rms_w), f_ref]) if rms_w >= TURNING_RATE else f_ref
    turn = wahba(mine, theirs, SPAN_SHARE)
    if turn is not None:
        return turn, math.degrees(turn.magnitude()), "with gravity", "", math.inf
    turn, _ = Rotation.align_vectors([f_mine.mean(axis=0)], [f_ref.mean(axis=0)])
    return turn, math.degrees(turn.magnitude()), "", "", math.inf


def _turn_se_deg(kinds, turn):
    """deg: the standard error of the free `turn` fitted to `kinds` ([(mine, theirs)], rows
    the seconds), jackknifed over TURN_BLOCKS consecutive blocks of the seconds, each left
    out in turn - all three axes of the turn together (a glider's two aligned IMUs had read
    0.1 deg and been turned; the measured turn needs its own noise beside the clock's)."""
    n = len(kinds[0][0])
    block = np.minimum(np.arange(n) * TURN_BLOCKS // n, TURN_BLOCKS - 1)
    parts = []
    for b in range(TURN_BLOCKS):
        keep = block != b
        part = wahba(*(np.vstack([k[i][keep] for k in kinds]) for i in (0, 1)), SPAN_SHARE)
        if part is None:
            return math.inf
        parts.append((part * turn.inv()).as_rotvec())
    parts = np.array(parts)
    spread = (TURN_BLOCKS - 1) / TURN_BLOCKS * np.sum((parts - parts.mean(axis=0)) ** 2)
    return math.degrees(math.sqrt(spread))


def _own_turn(kind):
    """(one triad's own turn of theirs onto mine, its standard error in deg: `_turn_se_deg`),
    (None, inf) where its vectors hold one direction only (`wahba`)."""
    turn = wahba(*kind, SPAN_SHARE)
    return (None, math.inf) if turn is None else (turn, _turn_se_deg([kind], turn))


def _weighed(kinds, se):
    """The triads' vectors `kinds` [(mine, theirs)] each scaled by the inverse of its own
    turn's standard error (deg; as they are where one is not finite): the turn fitted to
    them weighs each by its precision (a car's gyro triad, its roll rates a quarter of its
    yaw rates and a third of them noise, had pulled an exact accelerometer triad's turn
    1.6 deg)."""
    if len(se) != 2 or not all(math.isfinite(e) and e > 0 for e in se):
        return kinds
    scale = [min(se) / e for e in se]
    return [(mine * k, theirs * k) for (mine, theirs), k in zip(kinds, scale)]


def _triads_apart(each, kinds):
    """Why the two IMUs' gyro triads turn onto each other otherwise than their accelerometer
    triads do, by more than TRIADS_APART_DEG, or '' (`each`: each triad's `_own_turn`, None
    where it is not decided - then the other's turn must take that
    direction onto its own; `kinds`: the triads' vectors (mine, theirs)): no mounting turns
    one triad of a rigid unit without the other - one triad's column sign or axis order
    differs (a glider's gyro z signed wrong had been turned 70 deg as a 'mounting', then
    refused as a specific force not pointing up; a gyro triad's x and y swapped, 67 deg)."""
    # a triad decides its turn where its error cannot make TRIADS_APART_DEG (a car's gyro
    # triad, roll rates a quarter of its yaw rates and a third of them noise, had read 8
    # deg apart from an exact accelerometer triad and been refused)
    turns = [e if e is not None and DISTINCT_Z * se < TRIADS_APART_DEG else None
             for e, se in each]
    decided = [e for e in turns if e is not None]
    if len(each) != 2 or not decided:
        return ""
    if len(decided) == 2:
        apart = math.degrees((turns[0].inv() * turns[1]).magnitude())
    else:                       # the undecided triad's one direction, turned by the other's
        mine, theirs = kinds[turns.index(None)]
        u, _, vt = np.linalg.svd(mine.T @ theirs)
        apart = math.degrees(math.acos(np.clip(u[:, 0] @ decided[0].apply(vt[0]), -1, 1)))
    if apart <= TRIADS_APART_DEG:
        return ""
    said = (f"the two IMUs' gyros and their accelerometers turn onto each other {apart:.0f} deg "
            "apart: no mounting turns one triad of a unit without the other - ")
    if apart >= SIGN_APART_DEG:
        return said + ("a column's sign or the axes' order differs between one IMU's gyros and "
                       "its accelerometers: check the gyro and the accelerometer columns of "
                       "both IMUs")
    return said + ("too little for a column's sign or the axes' order (they turn a triad by "
                   f"{SIGN_APART_DEG:g} deg or more); one IMU's triads were aligned apart - a "
                   "calibration that turned one triad and not the other (a logger's raw and "
                   "calibrated exports), or two units' triads given as one IMU: check which "
                   "columns each IMU's triads come from")


def _fit_arm(rec, means, ok, mids):
    """Where no lever arm between the two IMUs is given and the motion moves them both,
    the arm r (m, vehicle frame) that, with the turn, fits the IMU's 1 s mean specific
    forces about their means (least squares, alternating with `_measured_turn` ARM_ROUNDS
    times): where its size stands beyond DISTINCT_Z of its error along it (`lever.arm_cov`),
    its force replaces the lever force of the means (`means[0][2]`) and it is returned with
    its covariance (m^2; else None) - the turn is fitted free of it (a motorcycle's 40 cm,
    not given, had pulled an exact mounting 0.3 deg, charged to the unit as a
    cross-coupling of its gyros). The diagnosis fits the arm itself (`lever_arm`)."""
    if np.any(rec.mounting.lever_arm_m - rec.reference_imu["mounting"].lever_arm_m):
        return None
    unit = unit_forces(rec.imu_ns, attitude.rotate(rec.mounting.q_vs, rec.w), mids)
    design = (unit[ok] - unit[ok].mean(axis=0)).reshape(-1, 3)
    mine, theirs = (attitude.rotate(q, x[ok]) for q, x in (
        (rec.mounting.q_vs, means[0][1]), (rec.reference_imu["mounting"].q_vs, means[1][1])))
    if np.linalg.matrix_rank(design) < 3:
        return None
    given, arm = means[0][2], np.zeros(3)
    for _ in range(ARM_ROUNDS):
        turn = _measured_turn(rec, means, ok)[0]
        gap = mine - turn.apply(theirs)
        arm, *_ = np.linalg.lstsq(design, (gap - gap.mean(axis=0)).ravel(), rcond=None)
        means[0][2] = np.einsum("mij,j->mi", unit, arm)
    cov = arm_cov(design, (gap - gap.mean(axis=0)).ravel())
    size = float(np.linalg.norm(arm))
    along = arm / max(size, 1e-12)          # its error along itself: a 20-block jackknife's
    if not size > DISTINCT_Z * math.sqrt(float(along @ cov @ along)):   # full chi-square
        means[0][2] = given                 # had taken a light aircraft's 0.24 +- 0.2 m
        return None
    return arm, cov


def _say_arm(rec, arm, cov, turn):
    """Say the arm fitted (`_fit_arm`: arm m, cov m^2, in the IMU's vehicle frame as it was
    given) in rec.real["reference_imu_lever_arm"], turned into the IMU's vehicle frame as it
    ends (`turn`: quaternion from the one to the other)."""
    arm = attitude.rotate(turn, arm)
    c = quaternion.as_rotation_matrix(turn)
    cov = c @ cov @ c.T
    rec.real["reference_imu_lever_arm"] = (
        f"none given; the IMU's 1 s mean specific forces fit one of "
        f"[{', '.join(f'{x:+.3f}' for x in arm)}] m (vehicle frame, from the reference IMU; "
        f"jackknifed standard errors {', '.join(f'{x:.2g}' for x in np.sqrt(np.diag(cov)))}, "
        "which leave out the model's own errors - a motorcycle's read 2.6 cm off at 0.5 mm): "
        "a first reading, its force only kept out of the mounting's measurement - the "
        "diagnosis measures the arm (lever_arm); give it if it is known (a table spec's "
        "lever_arm_m; --reference-imu-lever-arm-m, or --lever-arm-m for the IMU)")


def _lever_force(rec, mids, r=None):
    """(M, 3) m/s^2, vehicle frame: the 1 s means of what the IMU feels beyond the reference
    IMU (`lever.lever_force` at the IMU's rates), r from it (m, vehicle frame; None: the
    mountings' lever arms)."""
    if r is None:
        r = rec.mounting.lever_arm_m - rec.reference_imu["mounting"].lever_arm_m
    return lever_force(rec.imu_ns, attitude.rotate(rec.mounting.q_vs, rec.w), mids, r)


TRIADS_APART_DEG = 5.0      # deg: a unit's two triads lie within their few mrad of each
#                             other; turns this far apart are no mounting, but a sign
SIGN_APART_DEG = 45.0       # deg: a column's sign or two axes swapped in one triad turn its
#                             best fit by this or more (a glider's gyro z: 70; x and y swapped:
#                             67); a Shimmer's calibration turned its gyros 8 deg off its accels
TRIADS_AGREE_DEG = 0.2      # deg: a triad's own turn within this of both triads' (a unit's
#                             agree to its 1-3 mrad misalignments), else they differ: no turn
MOVING_FORCE = 0.3          # m/s^2: 1 s mean specific forces' spread that turns the boxes
