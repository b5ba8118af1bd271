"""Which of two IMUs a reference's attitude holds. A turn measured between a recording's
IMU and its reference IMU (`pairing`) says only that one of the two mountings given is off;
where the reference trajectory carries an attitude, the vehicle-frame angular rate and
specific force that it and the velocity make are compared with each IMU's, turned into the
vehicle frame by its mounting, so that the turn goes onto the IMU the attitude contradicts
(a car's consumer IMU given 3.9 deg off its true mounting had turned its OXTS reference IMU
instead, and the words sent the user to the reference's section), and onto both where it
holds neither. And whether the attitude holds its own IMU at all, axis by axis
(`check_rates_along`): a sign of its angles read wrong turns it against the gyro.
"""
import math

import numpy as np
import quaternion
from scipy.spatial.transform import Rotation

from ..flightlog.stamps import missed_spans
from ..frames import attitude
from ..frames.mounting import Mounting
from ..sensors.mimu import G0
from .lever import lever_force
from .recording import RecordingError
from .series import window_means

# an IMU the attitude holds lies within this share of the turn measured between the two
# from it (a mounting given right lies a reference attitude's own error from it: 0.0 deg on
# the trials' cars and quadrotor); one beyond it is off. The turn goes to the one that is
# off; where both are, each is turned onto the attitude (their turn between them then the
# one measured, the attitude's own error in both)
HOLDS_SHARE = 0.25


def attitude_means(reference, mids):
    """(w rad/s, f m/s^2) (M, 3): means over [mid - 0.5, mid + 0.5] s (`mids`, s) of the
    angular rate and the specific force, vehicle axes (FRD), that the reference's attitude
    q_nb (vehicle -> NED) and NED velocity make: the rate of the turn between successive
    attitudes (the Earth's and the transport rate in it: near constants, which the
    comparison's centring removes) and C_bn (dv/dt - g_n), g_n = (0, 0, G0) down; None
    without an attitude."""
    q, v = reference.get("q_nb"), reference.get("v_ned")
    if q is None or v is None:
        return None
    ok = np.isfinite(q).all(axis=1) & np.isfinite(v).all(axis=1)
    if ok.sum() < 3:
        return None
    ns, q_nb, v = reference["ns"][ok], attitude.from_wxyz(q[ok]), v[ok]
    step = np.diff(ns / 1e9)[:, None]
    # conj(q_k) q_k+1: the turn over the step in the body frame at its start
    turn = attitude.rotation_vector_error(np.conjugate(q_nb[:-1]), np.conjugate(q_nb[1:]))
    f_ned = np.diff(v, axis=0) / step - np.array([0.0, 0.0, G0])
    # the step's mean force in the body at its middle, half the turn on (its end's had
    # turned a glider's circles at 14 deg/s by half a 25 Hz step, 0.3 deg, onto both IMUs)
    f = attitude.rotate(np.conjugate(q_nb[:-1] * quaternion.from_rotation_vector(0.5 * turn)),
                        f_ned)
    return window_means(ns[1:], turn / step, mids), window_means(ns[1:], f, mids)


def turn_from_attitude(predicted, imu, spreads, span_share):
    """The turn (scipy Rotation) that best takes the attitude's vehicle-frame vectors
    `predicted` (w, f) onto an IMU's `imu` (w, f), both (M, 3) 1 s means: about their own
    means (no bias of either enters), each kind scaled to the attitude's rms, a kind left
    out where the attitude's spread is under `spreads` (rad/s, m/s^2); None where the rows
    hold too little of a second direction (second singular value under span_share of the
    first)."""
    a, b = [], []
    for mine, theirs, least in zip(imu, predicted, spreads):
        x, y = theirs - theirs.mean(axis=0), mine - mine.mean(axis=0)
        rms = float(np.sqrt(np.mean(x ** 2)))
        if rms >= least:
            a.append(y / rms)
            b.append(x / rms)
    if not a:
        return None
    return wahba(np.vstack(a), np.vstack(b), span_share)


def wahba(mine, theirs, span_share):
    """The turn of `theirs` (N, 3) onto `mine` (scipy Rotation: Wahba's problem) where the
    vectors span two directions (second singular value of their cross-covariance at least
    span_share of the first), else None."""
    singular = np.linalg.svd(mine.T @ theirs, compute_uv=False)
    if not singular[1] >= span_share * singular[0]:
        return None
    return Rotation.align_vectors(mine, theirs)[0]


def whose_turn(reference, mids, imus, turn_deg, spreads, span_share):
    """("imu" | "reference" | "both" | None, words, [the turn of the attitude's vectors onto
    each IMU's]): which mounting a turn of turn_deg (deg) measured between the IMU and the
    reference IMU belongs to, as the reference's attitude holds it: the one whose
    vehicle-frame 1 s means (`imus`: [(w, f) of the IMU, of the reference IMU] at `mids`, s)
    lie beyond HOLDS_SHARE of the turn from the attitude's, the other within, over the
    seconds all hold (at least 10); "both" where both lie beyond it; None (the words say
    why) where the attitude is missing or does not decide it."""
    predicted = attitude_means(reference, mids) if reference is not None else None
    if predicted is None:
        return None, "", []
    rows = np.isfinite(np.hstack([*predicted, *(x for imu in imus for x in imu)])).all(axis=1)
    turns = [turn_from_attitude([x[rows] for x in predicted], [x[rows] for x in imu],
                                spreads, span_share) if rows.sum() >= 10 else None
             for imu in imus]
    if None in turns:
        return None, "the reference's attitude does not turn enough to tell which is off", []
    angles = [float(np.degrees(turn.magnitude())) for turn in turns]
    said = (f"the reference's attitude lies {angles[0]:.1f} deg from the IMU and "
            f"{angles[1]:.1f} deg from the reference IMU")
    within = [a <= HOLDS_SHARE * turn_deg for a in angles]
    whose = {(False, True): "imu", (True, False): "reference",
             (False, False): "both"}.get(tuple(within))
    return whose, said + ("" if whose else ": it does not tell which is off"), turns


def turn_both(rec, turns, said):
    """Turn each IMU's mounting onto the reference's attitude (`whose_turn`'s "both": it
    holds neither mounting given; `turns`: the attitude's vectors onto each IMU's), saying
    so in rec.real / rec.assumed (`said`: how far the attitude lies from each)."""
    rec.mounting, mine = turned_back(rec.mounting, turns[0])
    rec.reference_imu["mounting"], theirs = turned_back(rec.reference_imu["mounting"], turns[1])
    rec.real["reference_imu_mounting"] = (
        f"{said}: it holds neither mounting given, so each was turned onto it - the IMU's "
        f"to roll, pitch, yaw {mine} deg, the reference IMU's to {theirs} deg")
    rec.assumed["mounting"] = f"measured against the reference's attitude: roll, pitch, " \
                              f"yaw {mine} deg"


def turn_the_imu(rec, turn, measured, why):
    """Put a turn measured between the IMU and the reference IMU (`turn`: scipy Rotation of
    the reference's vehicle-frame vectors onto the IMU's) on the IMU's mounting, the
    reference IMU's kept, saying so in rec.real / rec.assumed: `measured` the turn in words,
    `why` the IMU's (the reference's attitude is its own, or holds it)."""
    rec.mounting, rpy = turned_back(rec.mounting, turn)
    rec.real["reference_imu_mounting"] = (
        f"measured {measured}: {why}, so the IMU's mounting was turned instead, to roll, "
        f"pitch, yaw {rpy} deg")
    rec.assumed["mounting"] = f"measured against the reference IMU: roll, pitch, yaw {rpy} deg"


def turned_back(mounting, turn):
    """(the `Mounting` that takes back `turn` - a scipy Rotation of other vectors onto this
    IMU's vehicle-frame ones -, its roll, pitch, yaw in words, deg)."""
    q_vs = np.conjugate(attitude.from_scipy(turn)) * mounting.q_vs
    yaw, pitch, roll = (angle_text(x) for x in attitude.as_euler(q_vs))
    return Mounting(attitude.as_wxyz(q_vs), mounting.lever_arm_m), f"{roll}, {pitch}, {yaw}"


def angle_text(rad):
    """An angle in deg to 0.1 for a command line: -180 written 180, no -0.0."""
    deg = round(float(np.degrees(float(rad))), 1)
    return f"{180.0 if deg == -180.0 else deg + 0.0:.1f}"


# a vehicle axis about which the attitude's 1 s mean rate and the gyro's correlate below minus
# this runs against it: where an axis turns, a mounting and a convention read right correlate
# near +1 (the Earth's rate and the gyro's bias are constants, centred out; comma2k19's car
# 0.98-1.00 on all three, the VN-300's light aircraft 1.00); an angle read as its negative,
# or a mounting 180 deg off about another axis, near -1. Over 20 s or more, white noise
# reaches -0.5 with odds under 1 %
RUNS_AGAINST = 0.5
MIN_SECONDS = 20
TURNS = 0.002   # rad/s: an axis is judged where the attitude's 1 s mean rate spreads this much
#   (its std): 40 times a MEMS gyro's bias wander over minutes (10 deg/h), 8 times what a
#   tactical INS's attitude noise (0.01 deg an epoch) makes of it; a noisier axis correlates
#   near 0, not -1. A car's bumps turn its roll axis 0.004 (comma2k19; a noise test on the
#   series' own differences had passed over all three axes there, a car's 1 s means varying
#   as fast as they spread)
AXES = "xyz"


SPAN_S = 1.0    # s: the rates are compared over spans between attitude epochs this long or
#   more, the gyro's mean over exactly each span: means over whole seconds beside a 1 Hz
#   attitude's turns between epochs had folded a car's bumps (1.4 s) into a correlation of
#   -0.57 about x (an independent review)

MAX_STEP_RAD = 1.0  # rad: a step between attitude epochs turning more than this is not told
#   from its turn the other way round (pi: either way); the first order of a step's rotation
#   vector as the integral of its rates holds to a few per cent below it


def rates_along(reference, ns, w, mounting, late_s=0.0):
    """{axis: (correlation, gain, spans)} of the vehicle axes (FRD) about which the
    reference's attitude turns (TURNS, over MIN_SECONDS spans or more): over successive
    spans between its epochs k and k + n (n the fewest steps spanning SPAN_S; the epochs
    moved late_s s earlier, how late its stamps are), the turn conj(q_k) q_k+n as a rotation
    vector per second against an IMU's mean rate over exactly that span (w rad/s at stamps
    ns, sensor axes, turned into the vehicle frame by `mounting`), both about their own
    means; the gain is the IMU's rate per the attitude's (1 for the two read alike, -1 for a
    sign read wrong). The span's turn is the sum of its steps' (conj(q_j) q_j+1, each in the
    body frame at its start): one rotation over a second had wrapped a 400 deg/s roll. Spans
    over a gap (longer than 1.5 times the median) or with a step over MAX_STEP_RAD are left
    out."""
    q = reference.get("q_nb")
    ok = np.zeros(0, bool) if q is None else np.isfinite(q).all(axis=1)
    if ok.sum() < MIN_SECONDS:
        return {}
    t, q_nb = reference["ns"][ok] / 1e9 - late_s, attitude.from_wxyz(q[ok])
    n = max(1, int(np.ceil(SPAN_S / float(np.median(np.diff(t))) - 1e-6)))
    k = np.arange(0, len(t) - n, n)
    span = t[k + n] - t[k]
    # conj(q_j) q_j+1: each step's turn in the body frame at its start, summed over a span
    step = attitude.rotation_vector_error(np.conjugate(q_nb[:-1]), np.conjugate(q_nb[1:]))
    turned = np.vstack([np.zeros(3), np.cumsum(step, axis=0)])
    predicted = (turned[k + n] - turned[k]) / span[:, None]
    mine = attitude.rotate(mounting.q_vs, window_means(ns, w, t[k] + span / 2, span / 2))
    steep = np.concatenate([[0], np.cumsum(np.linalg.norm(step, axis=1) > MAX_STEP_RAD)])
    steep = steep[k + n] > steep[k]
    rows = (np.isfinite(predicted).all(axis=1) & np.isfinite(mine).all(axis=1)
            & (span <= 1.5 * np.median(span)) & ~steep)
    out = {}
    for i, axis in enumerate(AXES):
        x, y = predicted[rows, i], mine[rows, i]
        x, y = x - x.mean(), y - y.mean()
        if rows.sum() < MIN_SECONDS or not np.std(x) >= TURNS:
            continue
        out[axis] = (float(np.corrcoef(x, y)[0, 1]), float(x @ y / (x @ x)), int(rows.sum()))
    return out


def check_rates_along(rec, lags_s=(0.0,)):
    """Refuse (RecordingError) a reference attitude that turns against the gyro of its own
    IMU - the reference IMU where there is one, else the IMU - about a vehicle axis
    (`rates_along`; correlation below -RUNS_AGAINST) at every lag of lags_s (s, how late
    its stamps may be: the clock check's decided lag, else the stamps and its best rival -
    a motion that repeats runs against itself half a period off: a car's 1.4 s bounce, its
    reference 0.7 s late, had been refused as a sign read wrong): an angle's sign read
    wrong (an INS's roll and pitch: x and y; a yaw counted counter-clockwise: z, and y
    where it pitches; the quaternion's conjugate: z at least), or that IMU's mounting 180
    deg off about the axis that follows. An IMU's trial on a train, its INS's roll and
    pitch read as their negatives, had been taken, and the windows then charged the MEMS
    with 6-40 times its error. Said in rec.real["reference_attitude_rates"] otherwise."""
    own = rec.reference_imu
    whose, ns, w, mounting = (("the IMU's", rec.imu_ns, rec.w, rec.mounting) if own is None else
                              ("the reference IMU's", own["ns"], own["w"], own["mounting"]))
    tried = [(late, rates_along(rec.reference, ns, w, mounting, late)) for late in lags_s]
    tried = [(late, along) for late, along in tried if along]
    if not tried:
        return
    words = [(late, along, _rates_said(whose, late, along)) for late, along in tried]
    holds = [(late, said) for late, along, said in words
             if not any(r < -RUNS_AGAINST for r, *_ in along.values())]
    if holds:
        rec.real["reference_attitude_rates"] = holds[0][1]
        return
    _, along, said = words[0]
    against = [axis for axis, (r, *_) in along.items() if r < -RUNS_AGAINST]
    raise RecordingError(
        f"{rec.name}: {said}: it turns against that gyro about {' and '.join(against)}"
        + (f" (and with its stamps taken {', '.join(f'{x:+.2f}' for x, *_ in words[1:])} s "
           "late too)" if len(words) > 1 else "") + ": is a "
        "sign of the attitude's angles read wrong (roll and pitch as their negatives turn "
        "it against about x and y; a yaw counted counter-clockwise about z; the "
        "quaternion's conjugate about z at least - `scale = -1` on an angle's column in a "
        f"table spec), or is {whose} mounting 180 deg off about an axis that follows?")


def _rates_said(whose, late, along):
    """The words of `rates_along`'s correlations and gains, its stamps taken late s late."""
    said = "; ".join(f"{axis}: correlation {r:+.2f}, gain {gain:+.2f}"
                     for axis, (r, gain, _) in along.items())
    return (f"the reference's attitude against {whose} gyro, mean rates over spans of "
            f"{SPAN_S:g} s or more between its epochs"
            + (f" (its stamps taken {late:+.2f} s late: the clock's)" if late else "")
            + f", about the vehicle axes that turn ({TURNS:g} rad/s or more), "
            f"{max(n for *_, n in along.values())} spans ({said})")


# deg: without a reference IMU, the IMU's mounting is turned onto the reference's attitude
# where its rates and forces lie further than this from it (and TURN_Z of its standard
# error): a reference attitude's own error (0.1-0.5 deg) and an IMU's scale and misalignment
# (0.5-1 % of the rates: 0.3-0.6 deg of turn) stay within it
ATTITUDE_TURN_DEG = 1.0
TURN_Z = 4.0                # standard errors (the clock's and the pairing's DISTINCT_Z)
TURN_SPAN_SHARE = 0.05      # second singular value over the first: two directions seen
SPREADS = (0.02, 0.3)       # rad/s, m/s^2: a kind of 1 s means that spreads less is left out
#                             (the pairing's TURNING_RATE and MOVING_FORCE)
RATES_ALONE_SPREAD = 0.005  # rad/s: the rates alone, about three directions, spread at least
#                             this - 30 times a MEMS gyro's noise over 1 s (0.01 deg/s/rtHz:
#                             1.7e-4 rad/s), whose turn the jackknife then weighs (a survey
#                             ship's waves, 0.0195 rad/s over 1318 s, had been left out at 0.02)
JACKKNIFE_BLOCKS = 10


def mounting_against_attitude(rec):
    """Without a reference IMU, the IMU's mounting measured against the reference's
    attitude: the turn of the vehicle-frame 1 s mean rates that the attitude makes
    (`attitude_means`) onto the IMU's (turned by the mounting given), both about their own
    means (no bias enters; `turn_from_attitude`) - with the specific forces too (the lever
    arm's transfer taken out, `lever.lever_force`) only where the rates span fewer than two
    directions (a car's: its forces' lever transfer is small; a quadrotor's, an arm given
    0.1-0.2 m wrong had turned an exact mounting 1.2-4.5 deg) -, its standard error
    jackknifed over JACKKNIFE_BLOCKS blocks. Turned onto it beyond ATTITUDE_TURN_DEG and
    TURN_Z standard errors, said in rec.real / rec.assumed; kept otherwise, said too. The
    reference's stamps taken as late as the clock check measured and left
    (`reference_clock_unapplied_s`: a phone's 2 deg yaw against an INS 0.5 s off had read a
    0.4 deg pitch with it), not measured where that clock is undecided. A
    quadrotor's IMU given 10 deg off its mocap body had passed with the rates' gains at
    0.88, and its 3.8 deg off been charged to the accelerometers as 0.3 m/s^2 of bias."""
    ref = rec.reference
    if rec.reference_imu is not None or ref is None or ref.get("q_nb") is None:
        return
    if rec.reference_clock_open:
        rec.real["mounting_against_attitude"] = (
            "not measured: the reference's clock against the IMU's is not decided (measured "
            "clock offset) - the mounting as given")
        return
    late = rec.reference_clock_unapplied_s or 0.0      # measured, left as the IMU's latency
    lo = max(rec.imu_ns[0] / 1e9, ref["ns"][0] / 1e9 - late) + 1.0
    hi = min(rec.imu_ns[-1] / 1e9, ref["ns"][-1] / 1e9 - late) - 1.0
    mids = np.arange(lo, hi, 1.0)
    predicted = attitude_means(ref, mids + late) if len(mids) >= MIN_SECONDS else None
    if predicted is None:
        return
    w_v = attitude.rotate(rec.mounting.q_vs, rec.w)
    mine = (window_means(rec.imu_ns, w_v, mids),
            attitude.rotate(rec.mounting.q_vs, window_means(rec.imu_ns, rec.f, mids))
            - lever_force(rec.imu_ns, w_v, mids, rec.mounting.lever_arm_m))
    rows = np.isfinite(np.hstack([*predicted, *mine])).all(axis=1) & \
        ~_over_gaps(*missed_spans(ref["ns"] / 1e9 - late), mids)
    change = np.gradient(predicted[0], mids, axis=0)[rows]     # rad/s^2: the rates' change
    theirs, mine = [x[rows] for x in predicted], [x[rows] for x in mine]
    turn = _rate_turn(mine[:1], theirs[:1], change)     # the rates alone, where they span
    if turn is not None:                                # two directions
        theirs, mine = theirs[:1], mine[:1]
    else:
        turn = _rate_turn(mine, theirs, change)
    if rows.sum() < MIN_SECONDS or turn is None:
        rec.real["mounting_against_attitude"] = (
            "not measured: the reference's attitude and velocity make 1 s means that spread "
            f"about fewer than two directions (second singular value under {TURN_SPAN_SHARE:g} "
            f"of the first; its rates alone {_spread_said(theirs[0])}) or over under "
            f"{MIN_SECONDS} s ({int(rows.sum())} s)")
        return
    block = np.arange(len(theirs[0])) * JACKKNIFE_BLOCKS // len(theirs[0])
    parts = [_rate_turn([x[block != b] for x in mine], [x[block != b] for x in theirs],
                        change[block != b])
             for b in range(JACKKNIFE_BLOCKS)]
    if any(p is None for p in parts):
        rec.real["mounting_against_attitude"] = (
            f"not measured: without one of {JACKKNIFE_BLOCKS} blocks of the record the 1 s "
            "means spread too little to place a turn, so its error is not known - the "
            "mounting as given")
        return
    # the lag's column moves the turn by the model's own error (its rates' change over 1 s
    # means is coarse): counted into the error (a 5 ms skew's 0.16 deg left 0.1 at 3.5 se)
    plain = _rate_turn(mine, theirs, None)
    se, axis_se = _jackknifed(turn, parts, np.zeros(3) if plain is None else
                              (plain * turn.inv()).as_rotvec())
    _turn_or_keep(rec, turn, math.degrees(turn.magnitude()), se,
                  _turn_said(len(mine) > 1, turn, se, axis_se, late))


def _turn_or_keep(rec, turn, angle, se, said):
    """The IMU's mounting turned by `turn` (scipy Rotation, `angle` deg, standard error `se`
    deg; `said`: its words) beyond ATTITUDE_TURN_DEG and TURN_Z standard errors, kept as
    given otherwise - said, with the mounting it would turn to where it is measured beyond
    TURN_Z standard errors (rec.mounting_off_kept)."""
    kept, rpy = turned_back(rec.mounting, turn)
    if angle <= max(ATTITUDE_TURN_DEG, TURN_Z * se):
        rec.real["mounting_against_attitude"] = (
            f"{said}: within {ATTITUDE_TURN_DEG:g} deg or {TURN_Z:g} standard errors - the "
            "mounting as given")
        if angle > TURN_Z * se:     # measured, within what the reference's attitude may err
            rec.mounting_off_kept = (
                f"the import measured the IMU {angle:.2f} deg (standard error {se:.2g}) off "
                f"its mounting given against the reference's attitude and kept the one given "
                f"(within {ATTITUDE_TURN_DEG:g} deg, which a reference attitude's own error "
                f"may reach); where that attitude is better, --mounting-rpy-deg {rpy.replace(',', '')} "
                "at import turns it")
            rec.real["mounting_against_attitude"] += (
                f" (turned, it would be roll, pitch, yaw {rpy} deg: --mounting-rpy-deg where "
                "the reference's attitude is known to better than that)")
        return
    rec.mounting = kept
    rec.real["mounting_against_attitude"] = (
        f"{said}: turned onto the attitude, to roll, pitch, yaw {rpy} deg (the IMU against "
        "the frame the reference's attitude is of; if that is the vehicle's, the mounting "
        "given is off)")
    rec.assumed["mounting"] = (f"measured against the reference's attitude: roll, pitch, "
                               f"yaw {rpy} deg")


def _rate_turn(mine, theirs, change):
    """The turn (scipy Rotation) of the attitude's vehicle-frame 1 s means `theirs` onto the
    IMU's `mine` (lists of (M, 3): the rates, and the specific forces where given), about
    their own means, or None. Rates alone that span three directions: the rotation of the
    polar decomposition of the least-squares map between them (w_imu = R S w_att: a gyro
    triad's scales and non-orthogonality S, symmetric, left out of the turn - Wahba's fit
    of the rates, `turn_from_attitude`, had turned an exact mounting by a cheap gyro's
    unequal scales), fitted beside the rates' change `change` (rad/s^2; None: not): an
    IMU's lag d adds -d dw/dt, whose cross-covariance with the rates is antisymmetric - a
    turn (a 5 ms skew had read 0.16 deg at 8 standard errors); else `turn_from_attitude`."""
    if len(mine) == 1:
        x, y = (v[0] - v[0].mean(axis=0) for v in (theirs, mine))
        spread = np.linalg.svd(x, compute_uv=False)
        if len(x) >= 10 and spread[2] >= TURN_SPAN_SHARE * spread[0] and \
                np.sqrt(np.mean(x ** 2)) >= RATES_ALONE_SPREAD:
            lagged = x if change is None else np.column_stack([x, change - change.mean(axis=0)])
            u, _, vt = np.linalg.svd(np.linalg.lstsq(lagged, y, rcond=None)[0][:3].T)
            return Rotation.from_matrix(u @ np.diag([1, 1, np.linalg.det(u @ vt)]) @ vt)
    return turn_from_attitude(theirs, mine, SPREADS[:len(theirs)], TURN_SPAN_SHARE)


def _spread_said(rates):
    """How the attitude's 1 s mean rates (M, 3) rad/s spread about their mean: rms and the
    singular values over the first, against what the rates alone need (`_rate_turn`)."""
    x = rates - rates.mean(axis=0)
    if len(x) < 3:
        return "too few"
    spread = np.linalg.svd(x, compute_uv=False)
    return (f"spread {np.sqrt(np.mean(x ** 2)):.3g} rad/s rms (at least {RATES_ALONE_SPREAD:g} "
            f"needed), singular values 1 : {spread[1] / spread[0]:.2g} : "
            f"{spread[2] / spread[0]:.2g} (three directions needed)")


def _over_gaps(starts, ends, mids, half=0.5):
    """(M,) bool: the seconds [mid - half, mid + half] (`mids`, s) that meet a span the
    reference missed epochs in (`flightlog.stamps.missed_spans`, s) - its turn over a
    dropout is spread over the step (a mocap's 0.5-2 s dropouts had doubled the turn's
    standard error)."""
    return np.array([bool(np.any((ends > m - half) & (starts < m + half))) for m in mids])


def _jackknifed(turn, parts, model):
    """(deg, (3,) deg): the standard error of `turn` (scipy Rotation), as a whole and about
    each axis: the jackknife's from its fits without each block (`parts`), and the turn a
    choice of model moves it by (`model`, a rotation vector, rad) beside it."""
    off = np.array([(p * turn.inv()).as_rotvec() for p in parts])
    var = (len(parts) - 1) / len(parts) * np.sum((off - off.mean(axis=0)) ** 2, axis=0) \
        + np.asarray(model) ** 2
    return math.degrees(math.sqrt(var.sum())), np.degrees(np.sqrt(var))


def _turn_said(forces, turn, se, axis_se, late):
    """The words of `mounting_against_attitude`'s measure: the turn (scipy Rotation) with its
    standard errors (deg; about each vehicle axis), from the rates (and the forces where
    `forces`), the reference taken late s late."""
    return (f"the IMU's 1 s mean rates{' and specific forces' if forces else ''}, turned by "
            f"the mounting given, lie {math.degrees(turn.magnitude()):.2f} deg (standard error "
            f"{se:.2g}: jackknifed, with what a lag would turn; the IMU turned from its "
            "mounting given about the vehicle's forward, right, down axes by "
            # `turn` takes the attitude's means onto the IMU's: the IMU's own turn is its
            # inverse (an IMU turned -1 deg about down had read +1.00, and a user acting on
            # it doubled the error)
            + ", ".join(f"{a:+.2f} +- {e:.2g}" for a, e in
                        zip(np.degrees(turn.inv().as_rotvec()), axis_se))
            + " deg) from those of the reference's attitude and velocity"
            + (f" (its stamps taken {abs(late) * 1e3:.0f} ms {'late' if late > 0 else 'early'}:"
               " the clock's)" if late else ""))
