"""Rests and stillness in a recording: spans where the reference shows a vehicle at rest,
quiet stretches of the IMU (with |f| near g and |w| small), a track's acceleration, and the
direction of travel (forward or reversing) from 1 s means.
"""
import math

import numpy as np

from ..frames import earth
from ..motion.track import white_noise


STATIC_SPEED = 0.2          # m/s: GNSS speed below which the vehicle is taken to be at rest
STATIC_MARGIN_S = 1.0       # s cut from the end of the rest period (the car starts to roll)
STATIC_AVERAGE_S = 1.0      # s: the track's velocity is averaged over this before the rest test
                            # (central differences of 2 cm fixes at 10 Hz scatter 0.14 m/s per
                            # axis, and a 30 s rest broke into pieces under STATIC_SPEED; over
                            # 1 s they scatter 0.03)
MIN_STATIC_S = 2.0          # s: a shorter rest cannot give a level and a gyro bias
                            # (1 cm/s RTK velocity noise -> 0.2 deg course noise)
STILL_TOLERANCE = 0.5       # m/s: a noisy reference shows rest when its speed's 2-sigma upper
                            # bound - a line fitted through its positions (`track_still`) -
                            # lies below this


def rest_intervals(t_track, v_ned, t_first, t_last, h=None):
    """Rest periods of a track, [(t0, t1)] s: runs of epochs slower than STATIC_SPEED (m/s)
    in their mean horizontal velocity over STATIC_AVERAGE_S (the displacement over it: a
    moving vehicle's is not noise) and vertically within STATIC_SPEED or
    VERTICAL_NOISE_TIMES that mean's own noise (`_mean_noise`), and of these the longest
    part that does not climb (`_level_part`: by the heights h, m, when given), each end that
    meets motion moved STATIC_MARGIN_S into the rest
    from the neighbouring moving epoch; a run that starts the track starts at t_first (the
    IMU's first stamp), one that ends it ends at t_last. Only rests of at least MIN_STATIC_S
    are returned."""
    t_track = np.asarray(t_track, float)
    v_d = np.asarray(v_ned, float)[:, 2]
    mean = means_around(t_track, np.asarray(v_ned, float), t_track, STATIC_AVERAGE_S / 2)
    still = (np.hypot(mean[:, 0], mean[:, 1]) <= STATIC_SPEED) & \
        (np.abs(mean[:, 2]) <= max(STATIC_SPEED, VERTICAL_NOISE_TIMES *
                                   _mean_noise(t_track, v_d)))
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(int), [0]])))
    out = []
    for a, b in zip(edges[::2], edges[1::2]):          # still[a:b]
        a, b = _level_part(t_track, v_d, h, a, b)
        if b - a < 2:
            continue
        t0 = t_first if a == 0 else float(t_track[a - 1]) + STATIC_MARGIN_S
        t1 = t_last if b == len(still) else float(t_track[b]) - STATIC_MARGIN_S
        t0, t1 = max(t0, t_first), min(t1, t_last)
        if t1 - t0 >= MIN_STATIC_S:
            out.append((float(t0), float(t1)))
    return out


REST_BRIDGE_S = 2 * STATIC_MARGIN_S + 2 * STATIC_AVERAGE_S   # s: one noisy epoch's speed,
#                            averaged and trimmed either side, breaks a rest by about this much
#                            (a train's 90 s in a station had broken at 4.5, 19.5, 26.5 s);
#                            `steady_runs` then judges the bridged span on the IMU


def _bridged(rests):
    """The rests [(t0, t1)] with those REST_BRIDGE_S or less apart joined."""
    out = []
    for t0, t1 in rests:
        if out and t0 - out[-1][1] <= REST_BRIDGE_S:
            out[-1] = (out[-1][0], t1)
        else:
            out.append((t0, t1))
    return out


VERTICAL_NOISE_TIMES = 4.0  # a vertical velocity differenced from noisy heights (1-3 m at
#                            1 Hz: metres per second) judges a rest only beyond this many of
#                            its own standard errors: a train's 90 s in a station had broken
#                            into 2-6 s pieces by it, and its gyro bias came from one


def _level_run(heights, t0, t1):
    """The rest (t0, t1) s cut to its longest part that does not climb by the reference's
    `heights` (t s, h m; None: as it is) - `_level_part` on the epochs inside it: a steady
    climb the IMU does not feel (its start and end split the run, REST_HEAVE) is cut out."""
    if heights is None:
        return t0, t1
    t_h, h = (np.asarray(x, float) for x in heights)
    a, b = np.searchsorted(t_h, t0), np.searchsorted(t_h, t1, side="right")
    if b - a < 3:
        return t0, t1
    a2, b2 = _level_part(t_h, h, h, a, b)
    if b2 - a2 < 2:
        return t0, t0
    return (t0 if a2 == a else float(t_h[a2])), (t1 if b2 == b else float(t_h[b2 - 1]))


def _level_part(t, v_d, h, a, b):
    """(a, b): the longest part of the still run [a, b) of epochs t (s) that starts or ends
    it and does not climb - its heights' least-squares slope (m/s, with `h`; else its mean
    vertical velocity v_d) within STATIC_SPEED or VERTICAL_NOISE_TIMES its standard error
    (`motion.track.white_noise` per epoch). Epoch by epoch a vertical from noisy heights
    hides a climb, over a stretch it does not: a copter rising straight up at 2 m/s under 2 m heights at
    1 Hz had been a 60 s rest, its climb's 2/60 m/s^2 read as an accelerometer bias.
    (a, a) when no part holds."""
    y = np.asarray(v_d if h is None else h, float)[a:b]
    x = np.asarray(t, float)[a:b] - float(t[a])
    sigma = white_noise(np.asarray(v_d if h is None else h, float))

    def level(sx, sy, sxx, sxy, count):
        if h is None:                   # the mean vertical velocity
            size, se = np.abs(sy / count), sigma / np.sqrt(count)
        else:                           # the heights' slope
            spread = np.maximum(sxx - sx ** 2 / count, 1e-12)
            size, se = np.abs((sxy - sx * sy / count) / spread), sigma / np.sqrt(spread)
        return (size <= np.maximum(STATIC_SPEED, VERTICAL_NOISE_TIMES * se)) & (count >= 2)
    sums = [np.concatenate([[0.0], np.cumsum(z)]) for z in (x, y, x * x, x * y)]
    n = np.arange(1, b - a + 1)
    head = np.flatnonzero(level(*(c[1:] for c in sums), n))                  # [a, a + n)
    tail = np.flatnonzero(level(*(c[-1] - c[:-1] for c in sums), n[::-1]))  # [a + k, b)
    first = int(n[head[-1]]) if len(head) else 0
    last = int(n[::-1][tail[0]]) if len(tail) else 0
    if max(first, last) == 0:
        return a, a
    return (a, a + first) if first >= last else (b - last, b)


def _mean_noise(t, x):
    """The white noise (1 sigma) of x's mean over STATIC_AVERAGE_S at epochs t: from the
    second differences' MAD (a second difference of white noise has 6 times its variance),
    over the root of the epochs averaged; 0 for fewer than 5 epochs."""
    if len(x) < 5:
        return 0.0
    epochs = max(1.0, STATIC_AVERAGE_S / float(np.median(np.diff(t))))
    return white_noise(x) / math.sqrt(epochs)


def felt_at_rest(t, w, f, rests, heights=None):
    """The rests [(t0, t1)] s (a reference's, `rest_intervals`) where the IMU feels one too:
    its mean specific force gravity's size (within REST_GRAVITY) and its mean rate about the
    Earth's (within REST_RATE) - a reference that stands still while the IMU falls freely or
    spins (a rocket's apogee under a stalled GNSS velocity) is no rest - and, within them,
    the runs where it holds still (`steady_runs`: a moored boat rocking on its mooring is
    still to its GNSS, and its mean rate is small, but its gyro bias from that 'rest' had
    been 20 times the truth) - reference rests a noisy epoch's speed split joined first
    (`_bridged`), the IMU judging the gap, and each run cut to where the reference's
    `heights` (t s, h m) do not climb (`_level_run`); ([kept], [(t0, t1, why not)])."""
    kept, refused = [], []
    for t0, t1 in _bridged(rests):
        k = (t >= t0) & (t <= t1)
        if not k.any():
            continue
        g_err = float(np.linalg.norm(f[k].mean(axis=0))) - G0
        rate = float(np.linalg.norm(w[k].mean(axis=0)))
        if abs(g_err) > REST_GRAVITY or rate > REST_RATE:
            refused.append((t0, t1, f"the reference stands still {t0:.2f}-{t1:.2f} s but the IMU "
                                    f"feels |f| {g_err + G0:.2f} m/s^2 and |w| "
                                    f"{math.degrees(rate):.1f} deg/s there: no rest"))
            continue
        runs, tilt, turn = steady_runs(t, w, f, t0, t1)
        cut = [_level_run(heights, a, settled_until(t, w, f, a, b)) for a, b in runs]
        kept += [(a, b) for a, b in cut if b - a >= MIN_STATIC_S]
        if runs and not any(b - a >= MIN_STATIC_S for a, b in cut):
            refused.append((t0, t1, f"the reference stands still {t0:.2f}-{t1:.2f} s and the "
                                    "IMU holds still there, but under "
                                    f"{MIN_STATIC_S:g} s of it before the IMU starts to move "
                                    "or the reference's heights climb: no rest"))
        if not runs:
            refused.append((t0, t1, f"the reference stands still {t0:.2f}-{t1:.2f} s but the IMU "
                                    f"does not: its 1 s means tilt up to {math.degrees(tilt):.2f} "
                                    f"deg and turn up to {math.degrees(turn):.2f} deg/s about "
                                    f"their means (a rest holds within "
                                    f"{math.degrees(REST_TILT):g} deg and "
                                    f"{math.degrees(REST_TURN):g} deg/s for {MIN_STATIC_S:g} s): "
                                    "it rocks or moves, no rest"))
    return kept, refused


REST_TILT = math.radians(1.0)   # rad: a rest's 1 s means of specific force stay this close to
#                                 their mean direction - 3 x the idling RTKLIB drive's worst
#                                 (0.31 deg, its occupants aboard; its stops 0.01-0.22), where
#                                 a moored hull rolling 2.6 deg, or a car braking at 0.2 m/s^2
#                                 (1.2 deg), lies beyond
REST_TURN = math.radians(1.0)   # rad/s: its 1 s mean rates this close to their mean - 4 x
#                                 that drive's worst (0.23 deg/s), where a hull rocking at
#                                 2.5 deg/s lies beyond
STEADY_WINDOW_S = 1.0           # s: the means judged
REST_HEAVE = 0.15               # m/s^2: and their size this close to its mean - 3.5 x the
#                                 idling RTKLIB drive's worst (0.043; a moored boat rocking
#                                 0.13), where a copter lifting off at 1 m/s^2 lies beyond: a
#                                 vertical start the direction of g does not show (its climb
#                                 at a steady 2 m/s had been taken into its rest)


def steady_runs(t, w, f, t0, t1):
    """([(a, b)] s: the runs of at least MIN_STATIC_S within [t0, t1] where the IMU holds
    still - consecutive STEADY_WINDOW_S means of specific force (m/s^2) within REST_TILT of
    the run's mean direction so far and REST_HEAVE of its mean size, and of rate (rad/s)
    within REST_TURN of its mean rate so far, a window beyond any starting the next run -, the worst tilt (rad) and turn
    (rad/s) of the span's means about their mean). Run by run, so that a steady turn beside
    a rest is a run of its own (judged by its rate where that matters), not a share of one
    mean that neither holds. A span shorter than two windows is judged as one window."""
    n = max(int((t1 - t0) // STEADY_WINDOW_S), 1)
    filled, f_mean, w_mean = _window_means(t, (f, w), t0, t1, n)
    size = np.linalg.norm(f_mean, axis=1)
    up = f_mean / size[:, None]
    index = np.flatnonzero(filled)
    runs, first = [], 0
    for k in range(1, len(index) + 1):
        if k < len(index) and index[k] == index[k - 1] + 1 and \
                _holds(up[first:k], w_mean[first:k], up[k], w_mean[k]) and \
                abs(size[k] - size[first:k].mean()) <= REST_HEAVE:
            continue
        start = t0 + index[first] * STEADY_WINDOW_S
        end = t1 if index[k - 1] == n - 1 else t0 + (index[k - 1] + 1) * STEADY_WINDOW_S
        if end - start >= MIN_STATIC_S:
            runs.append((float(start), float(end)))
        first = k
    middle = up.mean(axis=0)
    tilt = np.arccos(np.clip(up @ (middle / np.linalg.norm(middle)), -1.0, 1.0))
    turn = np.linalg.norm(w_mean - w_mean.mean(axis=0), axis=1)
    return runs, float(tilt.max()), float(turn.max())


SETTLED_Z = 5.0     # a rest's last window whose mean lies this many times the scatter of the
#                    rest's other window means from their median has started to move: a
#                    robot setting off 0.4 s before a reference's rest ended had moved its gyro
#                    bias by 0.006 deg/s (6 of its standard errors) within REST_TURN's 1 deg/s;
#                    6 channels at 5 sigma: a still rest's end cut by chance once in ~10^5


# the least scatter of a window's mean (rad/s x 3, m/s^2 x 3): below a navigation-grade
# unit's 1 s noise (0.002 deg/h^0.5: 6e-7 rad/s; 0.01 m/s/h^0.5: 1.7e-4 m/s^2), above a
# simulation's rounding - an ideal IMU's still windows agree to 1e-15 and had cut 6 s of rest,
# and its quietest windows' spread of 0 had left no window quiet (no rest at all)
SETTLED_FLOOR = np.array([1e-7] * 3 + [1e-6] * 3)


def settled_until(t, w, f, t0, t1):
    """The end (s) of the rest [t0, t1] before its IMU starts to move: STEADY_WINDOW_S
    windows counted back from t1 are cut, the last first, while one's mean rate (rad/s) or
    specific force (m/s^2) lies more than SETTLED_Z times from the median of the windows
    before it, in the robust scatter of those (or the samples' own noise over a window, when
    larger). The rest's start is a reference's, trimmed by STATIC_MARGIN_S, or the
    recording's."""
    n = int((t1 - t0) // STEADY_WINDOW_S)
    if n < 4:
        return t1
    k = np.flatnonzero((t > t1 - n * STEADY_WINDOW_S) & (t <= t1))
    back = np.minimum(((t1 - t[k]) // STEADY_WINDOW_S).astype(int), n - 1)   # 0: the last
    counts = np.bincount(back, minlength=n)
    if (counts < 2).any():
        return t1
    x = np.hstack([w[k], f[k]])
    means = np.column_stack([np.bincount(back, x[:, i], n) for i in range(6)]) / counts[:, None]
    own = np.sqrt(np.column_stack([np.bincount(back, (x[:, i] - means[back, i]) ** 2, n)
                                   for i in range(6)])) / counts[:, None]
    cut = 0
    while n - cut > 3:
        before = means[cut + 1:]
        centre = np.median(before, axis=0)
        scatter = np.maximum.reduce([1.4826 * np.median(np.abs(before - centre), axis=0),
                                     np.median(own[cut + 1:], axis=0), SETTLED_FLOOR])
        if not (np.abs(means[cut] - centre) > SETTLED_Z * scatter).any():
            break
        cut += 1
    return t1 - cut * STEADY_WINDOW_S


def _holds(up, rate, next_up, next_rate):
    """Whether a window's direction of specific force (unit) and rate (rad/s) lie within
    REST_TILT and REST_TURN of a run's means (its windows' `up`, `rate`)."""
    middle = up.mean(axis=0)
    tilt = math.acos(min(1.0, float(next_up @ middle) / float(np.linalg.norm(middle))))
    return tilt <= REST_TILT and float(np.linalg.norm(next_rate - rate.mean(axis=0))) <= REST_TURN


def yaw_turned(t, w_v, t0, t1):
    """Yaw (rad) a level vehicle turned between t0 and t1 from vehicle-axis rates (rad/s):
    the integral of the rate about down (small-tilt approximation of the Euler rate)."""
    k = (t > t0) & (t <= t1)
    dt = np.diff(t, prepend=t[0])
    return float(np.sum(w_v[k, 2] * dt[k]))


QUIET_WINDOW_S = 0.5        # s: windows the IMU-only rest test looks at
QUIET_SPREAD = 3.0          # x the quietest twentieth's spread: still quiet (the RTKLIB drive's
                            # idling start rest 0.040 rad/s, its quietest stops 0.014, driving
                            # 0.082 in the median)
QUIET_SPREAD_TRACKED = 4.0  # the same where a reference track also judges each stretch
QUIET_HOLE = 2              # windows: a louder moment inside a rest does not split it
QUIET_RATE = math.radians(1.0)      # rad/s: a resting consumer gyro's mean rate over a run (its bias) stays below
#                                     it - or the data show it is no turn (`_no_turn`: an
#                                     ADIS16448's 4.3 deg/s across gravity, EuRoC's)
TURN_SHOWN = 4.0            # a steady rate across gravity turns the specific force by its rate
#                             times the run's span: beyond this many times the turn the run
#                             shows (its first and last fifths' mean directions), it is none
G0 = 9.80665                # m/s^2, standard gravity (a resting IMU feels about this)
REST_GRAVITY = 0.2 * G0     # m/s^2: | |mean f| - g | at a rest a reference shows, at most: beyond
                            # any MEMS part's bias (a consumer accelerometer's 0.05 g), far below
                            # a coasting rocket's free fall (|f| near 0)
REST_RATE = math.radians(10.0)  # rad/s: |mean w| there, at most: beyond a consumer gyro's
                            # uncalibrated bias (a few deg/s), below a spinning body's rate


def quiet_stretches(t, w, f, track=None):
    """Rests judged from the IMU, [(t0, t1)] s of at least MIN_STATIC_S: runs of
    QUIET_WINDOW_S windows whose gyro and specific-force-magnitude scatter are within
    QUIET_SPREAD (QUIET_SPREAD_TRACKED with a track) times
    the quietest twentieth of the recording's windows, whose mean rate is below QUIET_RATE -
    or, where no such run is found, is no turn the data show (`_no_turn`: taken as bias) -
    and whose mean specific force is gravity's size (REST_GRAVITY: a phone's 45 mg bias had
    failed 0.3 m/s^2 and lost a minute on a table), and which the reference
    `track` (when it covers them) does not show moving: a run the reference shows at rest
    (`track_still`: a noisy plain GNSS fix, metres apart epoch to epoch, hid a 33 s rest
    behind its differenced speed), else its windows where the reference's speed is below
    STATIC_SPEED. For the biases when
    the reference shows no rest (it may not cover one); outside the reference, a drive that
    never stops can pass the relative test, so the note says the rest was judged from the
    IMU alone. Each run is first cut to where the IMU holds still (`steady_runs`): a smooth
    braking is quiet but tilts the specific force (a phone's bias 'at rest' had been taken
    over 3 s of a car still braking from 3.7 m/s either side of its stop), and a quiet run
    that went on into smooth driving had failed the track's test whole, losing a parked
    minute at its start."""
    n = max(int(round(QUIET_WINDOW_S / np.median(np.diff(t)))), 4)
    m = len(t) // n
    if m < 2:
        return []
    cut = lambda x: x[:m * n].reshape(m, n, *x.shape[1:])          # noqa: E731
    w_s, f_norm = cut(w), np.linalg.norm(cut(f), axis=2)
    spread_w = np.linalg.norm(w_s.std(axis=1), axis=1)
    spread_f = f_norm.std(axis=1)
    # a track judges each stretch below (its positions show it still), so the spread may
    # be looser with one: the RTKLIB drive's idling start rest is 3.4 x its quietest stops
    loose = QUIET_SPREAD_TRACKED if track is not None and len(track["t"]) >= 2 else QUIET_SPREAD
    steady = _close((spread_w <= max(loose * np.quantile(spread_w, 0.05), SETTLED_FLOOR[0]))
                    & (spread_f <= max(loose * np.quantile(spread_f, 0.05), SETTLED_FLOOR[3])),
                    QUIET_HOLE)
    # gravity judges every window, filled or not; a steady turn is no rest: the mean rate
    # judges each run (a hand-held phone's tremor had lifted half its 0.5 s windows of a
    # 30 s rest past QUIET_RATE, 0.67-1.08 deg/s about a 0.39 deg/s bias, and lost the rest)
    quiet = steady & (np.abs(np.linalg.norm(cut(f).mean(axis=1), axis=1) - G0) < REST_GRAVITY)
    runs = [run for t0, t1 in _runs(quiet, cut(t)[:, 0], cut(t)[:, -1])
            for run in steady_runs(t, w, f, t0, t1)[0]]
    # a run whose gyro reads QUIET_RATE or more is a bias only where no rest reads less
    # (a turntable's 5 deg/s after a true rest had been the longer 'rest')
    judged = [(run, _no_turn(t, w, f, *run)) for run in runs]
    runs = [run for run, how in judged if how == "still"] or \
        [run for run, how in judged if how == "bias"]
    if track is None or len(track["t"]) < 2:
        return runs
    mid = cut(t).mean(axis=1)
    covered = (mid >= track["t"][0]) & (mid <= track["t"][-1])
    speed = np.interp(mid, track["t"], np.linalg.norm(track["v_ned"], axis=1))
    slow = ~covered | (speed <= STATIC_SPEED)
    out = []
    for t0, t1 in runs:         # the IMU still: its positions, else its speed must agree
        if track_still(track, t0, t1):
            out.append((t0, t1))
        else:
            inside = (mid >= t0) & (mid <= t1)
            out += _runs(inside & slow, cut(t)[:, 0], cut(t)[:, -1])
    return out


REST_GRAVITY_BIAS = 0.05 * G0   # m/s^2: | |mean f| - g | at most where a gyro's reading of
#                                 QUIET_RATE or more is taken as bias: a consumer
#                                 accelerometer's bias; a coordinated turn banked 18 deg or
#                                 more, whose specific force holds still in the body as a
#                                 rest's does, reads beyond (1/cos: 0.05 g)


def _no_turn(t, w, f, t0, t1):
    """How the IMU's mean rate over [t0, t1] (rad/s, samples w at stamps t s) reads: "still"
    below QUIET_RATE; "bias" where it is no steady turn the data show - across the mean
    down below REST_RATE and TURN_SHOWN times beyond what the specific force f turned
    (EuRoC's first 5 s: a gyro reading 4.3 deg/s across gravity, f's direction moved 0.02
    deg where that rate turns it 13 - the rest had been refused), along it below REST_RATE
    (which f cannot show: taken as bias, and said so, `vertical_rate_said`), |f| within
    REST_GRAVITY_BIAS of g, and no steady level turn would read that rate and f alike
    (`_level_turn`: a coordinated turn holds f still in the body as a rest does, a
    turntable turns about f); else "turn"."""
    k = (t >= t0) & (t <= t1)
    mean, down, along = vertical_rate(w[k], f[k])
    if float(np.linalg.norm(mean)) < QUIET_RATE:
        return "still"
    across = float(np.linalg.norm(mean - along * down))
    size = float(np.linalg.norm(f[k].mean(axis=0)))
    if max(abs(along), across) >= REST_RATE or abs(size - G0) > REST_GRAVITY_BIAS or \
            _level_turn(across, along, size):
        return "turn"
    fifth = max(int(k.sum()) // 5, 1)
    first, last = (x / np.linalg.norm(x) for x in (f[k][:fifth].mean(axis=0),
                                                   f[k][-fifth:].mean(axis=0)))
    shown = math.acos(min(1.0, float(first @ last)))
    # the fifths' centres lie 0.8 of the run apart
    return "bias" if across < QUIET_RATE or across * (t1 - t0) * 0.8 > TURN_SHOWN * shown \
        else "turn"


def _level_turn(across, along, size):
    """Whether a mean rate (rad/s, `across` and `along` the mean specific force's axis) could
    be a steady level turn: turning at a rate about the vertical, a vehicle feels its
    centripetal acceleration a beside g, its specific force tilted from the vertical by
    atan(a / g) - the angle between its rate and f - and its size g / cos of that angle (a
    coordinated turn banked 15 deg, a car circling, a turntable at 0). It is one unless f's
    size lies 2 REST_GRAVITY_BIAS (the accelerometer's bias, both ways) below that: EuRoC's
    rest at 67 deg reads 1.00 g where a turn reads 2.6."""
    turn_size = G0 * math.hypot(across, along) / max(abs(along), 1e-12)
    return size > turn_size - 2 * REST_GRAVITY_BIAS


def vertical_rate_said(t, w, f, t0, t1):
    """'' or, where the IMU's mean rate about its mean down over the rest [t0, t1] reaches
    QUIET_RATE, that it is taken as the gyro's bias though a steady turn about the vertical
    would read alike (the specific force does not show one)."""
    k = (t >= t0) & (t <= t1)
    along = vertical_rate(w[k], f[k])[2]
    if abs(along) < QUIET_RATE:
        return ""
    return (f"; its {math.degrees(along):+.2f} deg/s about the vertical (positive: turning "
            "right, seen from above) taken as the gyro's bias: a steady turn about the "
            "vertical reads alike - the specific force does not show one, and the IMU alone "
            "cannot tell them")


def vertical_rate(w, f):
    """(mean rate (rad/s), mean down (unit, from the mean specific force f), the mean rate's
    component along it) of a rest's samples w, f: what a steady turn about the vertical
    would read, which the specific force cannot tell from a bias."""
    mean = w.mean(axis=0)
    down = -f.mean(axis=0) / np.linalg.norm(f.mean(axis=0))
    return mean, down, float(mean @ down)


def _runs(mask, starts, ends):
    """[(t0, t1)] s of the runs of True in the windows' mask (their first and last stamps
    starts, ends) at least MIN_STATIC_S long."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return [(float(starts[a]), float(ends[b - 1])) for a, b in zip(edges[::2], edges[1::2])
            if ends[b - 1] - starts[a] >= MIN_STATIC_S]


def _close(mask, hole):
    """`mask` with runs of at most `hole` False between two True filled (one rest the odd
    window of an idling engine had split into 2.5-3 s pieces, each too short to judge)."""
    out = mask.copy()
    idx = np.flatnonzero(mask)
    for a, b in zip(idx[:-1], idx[1:]):
        if 1 < b - a <= hole + 1:
            out[a:b] = True
    return out


def track_still(track, t0, t1):
    """Whether the reference over [t0, t1] s (at least 5 epochs) shows, positively, a vehicle
    at rest under noise: the slope of a straight line through its positions (its mean
    velocity when it has none) plus 2 of its standard errors (from the fit's own residuals)
    at most STILL_TOLERANCE - a short or noisy stretch that cannot show rest is not one."""
    k = (track["t"] >= t0) & (track["t"] <= t1)
    if k.sum() < 5:
        return False
    if "lat" not in track:
        v = np.asarray(track["v_ned"], float)[k, :2]
        se_v = np.hypot(*(v.std(axis=0, ddof=1) / math.sqrt(len(v))))
        return float(np.hypot(*v.mean(axis=0))) + 2 * float(se_v) <= STILL_TOLERANCE
    lat, lon, h = track["lat"][k], track["lon"][k], track["h"][k]
    ned = earth.ned_difference(lat, lon, h, lat[0], lon[0], h[0])[:, :2]
    x = np.column_stack([np.ones(k.sum()), track["t"][k] - track["t"][k].mean()])
    coef, *_ = np.linalg.lstsq(x, ned, rcond=None)
    resid = ned - x @ coef
    se = np.sqrt(np.sum(resid ** 2, axis=0) / (len(x) - 2) / np.sum(x[:, 1] ** 2))
    return float(np.hypot(*coef[1])) + 2 * float(np.hypot(*se)) <= STILL_TOLERANCE


def means_around(t, x, epochs, half):
    """Means of the samples x (N, k) at stamps t (s, increasing) within +-half s of each
    epoch (nan where none)."""
    return span_means(x, np.searchsorted(t, epochs - half), np.searchsorted(t, epochs + half))


def span_means(x, lo, hi):
    """Means of the rows lo[i] .. hi[i] - 1 of x (N, k) by one cumulative sum (nan where a
    span is empty)."""
    c = np.vstack([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])
    with np.errstate(invalid="ignore", divide="ignore"):
        return (c[hi] - c[lo]) / (hi - lo)[:, None]


def velocity_noise(track):
    """The reference velocity's white noise per horizontal axis (m/s), from the second
    differences of its north and east velocities (`motion.track.white_noise`); the
    vehicle's own motion between epochs adds to it, so it is an upper bound. None for fewer
    than 5 epochs."""
    v = np.asarray(track["v_ned"], float)[:, :2]
    return white_noise(v) if len(v) >= 5 else None


def rate_mean_se(t, w, t0, t1):
    """((3,) rad/s, 1): the standard error of the IMU's mean rate w (rad/s, stamps t s) over
    [t0, t1] from the scatter of its STEADY_WINDOW_S means (their sd over sqrt n), and how
    many times that scatter exceeds what the samples' own noise within the windows predicts
    (their pooled sd over sqrt of a window's samples; the largest axis'): about 1 where the
    IMU is still, far above where it moves (a moored hull rocking: its 5 s 'rest' 0.2 deg/s,
    the ratio in the tens); (NaN, NaN) with fewer than 3 windows."""
    n = int((t1 - t0) // STEADY_WINDOW_S)
    if n < 3:
        return np.full(3, np.nan), math.nan
    k = np.flatnonzero((t >= t0) & (t <= t1))
    which = np.minimum(((t[k] - t0) // STEADY_WINDOW_S).astype(int), n - 1)
    counts = np.bincount(which, minlength=n)
    filled = counts > 0
    window_mean = np.column_stack([np.bincount(which, w[k, i], n) for i in range(3)]) \
        / np.maximum(counts, 1)[:, None]
    inside = w[k] - window_mean[which]            # each sample less its window's mean
    means = window_mean[filled]
    pooled = np.sum(inside ** 2, axis=0) / max(int(np.sum(counts[filled] - 1)), 1)
    # a noise-free (simulated) IMU predicts 0: its round-off is the floor
    predicted = np.maximum(np.sqrt(pooled / np.mean(counts[filled])), 1e-12)
    scatter = means.std(axis=0, ddof=1)
    return scatter / math.sqrt(len(means)), float(np.max(scatter / predicted))


def _window_means(t, series, t0, t1, n):
    """(filled (n,) bool, then each of `series` (N, 3) averaged over the filled ones of n
    STEADY_WINDOW_S windows from t0 - the samples of [t0, t1] at stamps t (s), those past
    the last window's end in it)."""
    k = np.flatnonzero((t >= t0) & (t <= t1))
    which = np.minimum(((t[k] - t0) // STEADY_WINDOW_S).astype(int), n - 1)
    counts = np.bincount(which, minlength=n)
    filled = counts > 0
    return (filled,) + tuple(
        np.column_stack([np.bincount(which, x[k, i], n) for i in range(3)])[filled]
        / counts[filled, None] for x in series)
