"""A reference IMU flown beside the IMU (a better IMU on the same vehicle, often on its own
clock and in its own axes): its clock offset and its mounting measured against the IMU's and
corrected when the data decide them, refused with the measured values when they do not.

Clock: the two rotation rates' magnitudes |w| do not depend on either mounting. Their
normalised cross-correlation over every lag at which the two overlap for at least half the
shorter record (masked: each lag's correlation over its own overlap) must peak once -
at least PEAK_CORRELATION, and every lag beyond the peak's own lobe (where the correlation
stays above SECOND_PEAK_SHARE of it, at most LOBE_MAX_S either side) at most that share,
or the peak above the best of them by DISTINCT_Z standard errors (`peak_margin`); the peak
is then refined to a millisecond with each gyro's bias fitted beside it (`_refined`), its
standard error said. Each tenth of the overlap gives its own offset: a straight line through
them, weighted by their own variances, measures a drift (a crystal's tens of ppm), taken
when beyond DISTINCT_Z of its standard error and worth SMALL_OFFSET_S over the overlap - the
stamps then corrected along the line. A recording whose IMUs hardly turn (|w| spread below
TURNING_RATE) cannot be timed so: said, and left as recorded.

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

from ..frames import attitude
from ..frames.mounting import AGAINST, Mounting, runs_against
from .recording import G0, RecordingError, at_range, utc_text
from .attitude_check import angle_text, turn_both, turn_the_imu, wahba, whose_turn
from .series import masked_correlation, on_grid, parabola_min, peak_margin, window_means

SMALL_OFFSET_S = 0.001      # s: the refinement's step; a measured offset beyond it is
                            # corrected (whatever the user's own shift was: the result must
                            # not depend on it), a smaller one left to the time_skew term
SMALL_TURN_DEG = 3.0        # deg: within this its mounting_misalignment term carries a turn
GRID_S = 0.02               # s: the coarse search's grid (50 Hz: |w| of a vehicle's motion)
REFINE_WINDOW_S = 0.1       # s: |w|^2 as means over windows this long, not interpolated
#                             (noise halved midway between samples had read 43.0 ms 44.0)
PEAK_CORRELATION = 0.5      # the |w| correlation at the peak, at least
SECOND_PEAK_SHARE = 0.8     # the peak's lobe ends where the correlation falls below this
#                             share of the peak; no lag beyond it may reach it again
LOBE_MAX_S = 30.0           # s: a lobe wider than this either side is no peak (the motion
#                             hardly changes over the record: nothing to time it by)
TURNING_RATE = 0.02         # rad/s: 1 s mean rates' spread below which the rates do not
#                             turn the mounting
MOTION_SNR = 5.0            # |w| times the two clocks where its spread is beyond this many
#                             of its own noise (`_turns`; white noise alone reads 1): a fixed
#                             0.02 rad/s had left a ship's 0.32 s unmeasured, its seas
#                             rolling it 5 deg/s but |w| spread 0.018 rad/s, and the lag then
#                             read as a gyro scale of -0.04 (cos(2 pi 0.32 s / 8 s) - 1)
SPAN_SHARE = 0.05           # second singular value over the first: two directions seen
DISTINCT_Z = 4.0            # a rival peak above that share is no rival when the peak
#                             stands above it by this many standard errors (`peak_margin`):
#                             the rival is the best of some hundreds of lobes within the
#                             search, and 0.01 shared among 500 of them is z = 4.1 one-sided
#                             (a robot's 1.5 Hz bumps: 0.88 a bump away, 8.3 errors below the
#                             peak; a steady wave's next period: 1.0 below)


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
    if "drift" in clock:
        rec.shift_reference_imu(-clock["offset_s"], "measured: " + clock["said"],
                                drift=-clock["drift"], at_s=clock["at_s"] + clock["offset_s"])
    elif clock["offset_s"] is not None and abs(clock["offset_s"]) > SMALL_OFFSET_S:
        rec.shift_reference_imu(-clock["offset_s"], "measured: " + clock["said"])
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


def _centres(ns):
    """The interval centres (s) of samples stamped at the end of their intervals (a 100 Hz
    and a 400 Hz IMU on one clock are 3.75 ms apart by their stamps alone)."""
    return ns / 1e9 - 0.5 * np.median(np.diff(ns)) / 1e9


def _turns(x):
    """Whether the series x (its NaNs aside) moves beyond MOTION_SNR of its own noise: its
    standard deviation against the robust sigma of its first differences over sqrt 2 (a
    quantized series whose differences are mostly 0: any spread)."""
    x = x[np.isfinite(x)]
    if len(x) < 3:
        return False
    noise = float(np.median(np.abs(np.diff(x)))) / (0.6745 * math.sqrt(2.0))
    return float(np.std(x)) > MOTION_SNR * noise


def clock_offset(rec):
    """{"offset_s": how late (s) the reference IMU's stamps are on the IMU's, or None when
    the data do not decide it, "said": what was measured} (module doc)."""
    ref = rec.reference_imu
    found = _given_lobe(rec, rate_lag(
        _centres(rec.imu_ns), np.linalg.norm(rec.w, axis=1), _centres(ref["ns"]),
        np.linalg.norm(ref["w"], axis=1), "the two IMUs", "the reference's stamps"))
    if found.get("lag_s") is None:
        return dict(found, offset_s=None)
    offset, se, (drift, drift_se, centre, at_centre) = _refined(rec, found["lag_s"])
    if not math.isfinite(offset + se):
        return {"offset_s": None,
                "said": f"{found['said']}; not refined: the |w|^2 fit's least cost lies at the "
                        f"edge of its +-{2 * GRID_S * 1e3:.0f} ms search about that peak (with "
                        "the whole overlap or without one of its tenths), so the two do not "
                        "agree on it: left as recorded"}
    said = f"{found['said']}; refined to {{:+.1f}} ms (standard error {se * 1e3:.2g} ms)"
    span = (min(rec.imu_ns[-1], ref["ns"][-1]) - max(rec.imu_ns[0], ref["ns"][0])) / 1e9
    if abs(drift) > DISTINCT_Z * drift_se and abs(drift) * span > SMALL_OFFSET_S:
        return {"offset_s": at_centre, "offset_se_s": se, "drift": drift, "drift_se": drift_se,
                "at_s": centre, "said": said.format(at_centre * 1e3 + 0.0)
                + f" at {centre - rec.imu_ns[0] / 1e9:.1f} s of the IMU's record, drifting "
                f"{drift * 1e6:+.1f} ppm (standard error {drift_se * 1e6:.2g} ppm, its blocks' "
                f"own offsets): {drift * span * 1e3:+.1f} ms over the {span:.0f} s they share"}
    said = said.format(offset * 1e3 + 0.0)
    small = abs(drift) > DISTINCT_Z * drift_se        # beyond its errors, but under 1 ms
    return {"offset_s": offset, "offset_se_s": se,
            "said": said + (f"; a drift of {drift * 1e6:+.2g} ppm (se {drift_se * 1e6:.2g}): "
                            f"{abs(drift) * span * 1e3:.2g} ms over the {span:.0f} s they "
                            f"share, under {SMALL_OFFSET_S * 1e3:g} ms - not corrected"
                            if small else
                            f"; no drift beyond {DISTINCT_Z:g} standard errors "
                            f"({drift * 1e6:+.2g} ppm, se {drift_se * 1e6:.2g})"
                            if math.isfinite(drift_se) else
                            "; no drift measured: fewer than 5 tenths of the overlap turn enough to place "
                            f"an offset of their own (a crystal's 30 ppm would move it "
                            f"{30e-6 * span * 1e3:.0f} ms over the {span:.0f} s they share)")}


def trajectory_clock(rec):
    """{"offset_s": how late (s) the reference trajectory's stamps are on the IMU's, to
    GRID_S, or None when the data do not decide it, "said"}: the IMU's |w| against the turn
    rate of the reference's attitude (between successive attitudes, at their mid-times;
    steps over twice the median left out), by the module doc's rule."""
    ref = rec.reference
    ok = np.isfinite(ref["q_nb"]).all(axis=1)
    t = ref["ns"][ok] / 1e9
    rate = attitude.turn_rate(t, attitude.from_wxyz(ref["q_nb"][ok]))
    step = np.diff(t)
    keep = step <= 2 * np.median(step)
    found = rate_lag(_centres(rec.imu_ns), np.linalg.norm(rec.w, axis=1),
                     (0.5 * (t[1:] + t[:-1]))[keep], rate[keep],
                     "the IMU's and the reference attitude's turn rates", "the reference's stamps")
    return dict(found, offset_s=found.get("lag_s"))


def _given_lobe(rec, found):
    """`rate_lag`'s `found` taken at its best lag within a lobe of zero, where the data alone
    leave the peak among rivals (a swinging payload's |w| repeats every half swing, a rate
    table's at each repeat of its steps) and an offset was given: the offset chooses the
    lobe, the data then refine it and measure a drift (`clock_offset`), and the words say
    which chose what; else `found`, its words naming the option with the peak's value."""
    if "peak_lag_s" not in found:
        return found
    if rec.reference_imu_offset_given:
        if "zero_lag_s" not in found:
            return dict(found, said=f"{found['said']}; nor does the offset given put one of "
                                    "its rivals within a lobe of zero")
        return {"lag_s": found["zero_lag_s"],
                "said": f"{found['zero_said']}: the data alone set no lag apart - the lobe "
                        f"taken is the one the offset given picks ({found['said']})"}
    return dict(found, said=f"{found['said']}; where the recording's own notes confirm the "
                f"peak, --reference-imu-time-offset {-found['peak_lag_s'] + 0.0:+.3g} (or "
                "time_offset_s in a table spec's [reference_imu]) picks its lobe, and the "
                "import then refines it and measures a drift")


def rate_lag(t_a, rate_a, t_b, rate_b, whose, late):
    """{"lag_s": how late (s) series b's times are on a's, to GRID_S, or None, "said",
    "ambiguous" when a peak is there but not alone}: two rotation-rate magnitudes (rad/s at
    times s, interval centres) correlated over every lag at which they overlap for half the
    shorter (module doc); `whose`, `late`: what the sentence calls the series and b's
    stamps."""
    lo, hi = min(t_a[0], t_b[0]), max(t_a[-1], t_b[-1])
    grid = np.arange(lo, hi, GRID_S)
    a, b = on_grid(t_a, rate_a, grid), on_grid(t_b, rate_b, grid)
    if not (_turns(a) or _turns(b)):
        return {"lag_s": None, "said": f"not measured: neither turns (|w| spread within "
                                       f"{MOTION_SNR:g} times its own noise); the stamps taken "
                                       "as recorded"}
    shorter = min(np.isfinite(a).sum(), np.isfinite(b).sum())
    need = max(0.5 * shorter, 10.0 / GRID_S)
    lags, r = masked_correlation(a, b, need)
    if not np.isfinite(r).any():
        return {"lag_s": None, "said": f"not measured: a lag is judged on {need * GRID_S:.3g} s "
                                       "of overlap (half the shorter record, at least 10 s), "
                                       f"the shorter holds {shorter * GRID_S:.3g} s"}
    k = int(np.nanargmax(r))
    peak = float(r[k])
    lobe, width = _lobe(r, k, SECOND_PEAK_SHARE * peak)
    away = np.ones(len(r), bool)
    away[lobe] = False
    j = int(np.nanargmax(np.where(away, r, np.nan))) if np.isfinite(r[away]).any() else None
    second = float(r[j]) if j is not None else -1.0
    said = (f"{whose} (|w|) correlate {peak:.2f} with {late} {lags[k] * GRID_S:+.2f} s "
            f"late, {second:.2f} at best beyond the peak's lobe (+-{width:.2g} s)")
    rival = second > SECOND_PEAK_SHARE * peak
    if rival and peak >= PEAK_CORRELATION and width <= LOBE_MAX_S:
        margin, se = peak_margin(a, b, lags[k], lags[j])
        said += (f" at {lags[j] * GRID_S:+.2f} s, {margin:.3f} below the peak (standard "
                 f"error {se:.2g}, block jackknife)")
        rival = not margin > DISTINCT_Z * se
    if peak < PEAK_CORRELATION or rival or width > LOBE_MAX_S:
        out = {"lag_s": None, "said": f"not decided ({said}: at least {PEAK_CORRELATION:g} "
                                      f"at one lag, at most {SECOND_PEAK_SHARE:g} of it "
                                      f"beyond a lobe of at most +-{LOBE_MAX_S:g} s needed)",
               "ambiguous": True}
        if peak >= PEAK_CORRELATION and width <= LOBE_MAX_S:     # a peak among rivals
            out["peak_lag_s"] = float(lags[k] * GRID_S)
            near = np.abs(lags * GRID_S) <= width       # the best lag within a lobe of zero
            i = int(np.flatnonzero(near)[np.nanargmax(r[near])]) \
                if np.isfinite(r[near]).any() else k
            if r[i] > SECOND_PEAK_SHARE * peak:         # one of the rivals lies there
                out.update(zero_lag_s=float(lags[i] * GRID_S),
                           zero_said=f"{whose} (|w|) correlate {r[i]:.2f} with {late} "
                                     f"{lags[i] * GRID_S:+.2f} s late, {peak:.2f} at best")
        return out
    return {"lag_s": float(lags[k] * GRID_S), "said": said}


def _lobe(r, k, floor):
    """(slice, s): the lags about the peak k where the correlation r stays above floor, and
    on down to the first minimum either side (NaN ends it), and the half width (s) above
    the floor - the peak's own lobe, as wide as
    the motion stays correlated with itself (a
    car's |w| over its turns of 6-20 s: a fixed 1 s had counted its shoulder, 0.89, as a
    second peak and left a 2.5 s offset measured at 1.00 undecided)."""
    r = np.nan_to_num(r, nan=-np.inf)
    lo = hi = k
    while lo > 0 and r[lo - 1] > floor:
        lo -= 1
    while hi < len(r) - 1 and r[hi + 1] > floor:
        hi += 1
    width = (hi - lo) * GRID_S / 2
    # and on down its flanks to their first minimum: a second peak rises again beyond it
    while lo > 0 and -np.inf < r[lo - 1] < r[lo]:
        lo -= 1
    while hi < len(r) - 1 and -np.inf < r[hi + 1] < r[hi]:
        hi += 1
    return slice(lo, hi + 1), width


def _refined(rec, coarse_s, search_s=2 * GRID_S, step_s=0.001, blocks=10):
    """(offset s, its standard error s, `_drift`'s line through the blocks' own offsets):
    the offset that best matches the two |w|^2 (means over REFINE_WINDOW_S) within
    +-search_s of coarse_s, on a grid of step_s refined by a parabola; the error by the
    jackknife over `blocks` consecutive blocks of the overlap; NaN where the least cost, of
    the whole or of a jackknife part, is at the search's edge (not bracketed). Each gyro's
    bias b moves its
    |w|^2 by 2 b.w + |b|^2, which a shift can partly mimic (a MEMS pair's 0.3 deg/s had made
    a fixed wing's offset 0.3 ms late): at each shift the difference is fitted on [the IMU's
    rates, 1] first - with w_r = C w, |w_r + b_r|^2 - |w + b|^2 = 2 (C'b_r - b).w + const,
    whatever the mounting C - and the cost is what that fit leaves."""
    ref, half = rec.reference_imu, REFINE_WINDOW_S / 2
    t, t_r = rec.imu_ns / 1e9, ref["ns"] / 1e9
    lo = max(t[0], t_r[0] - coarse_s) + search_s + half
    hi = min(t[-1], t_r[-1] - coarse_s) - search_s - half
    grid = np.arange(lo, hi, 0.01)
    w = window_means(rec.imu_ns, rec.w, grid, half)
    size = window_means(rec.imu_ns, np.sum(rec.w ** 2, axis=1)[:, None], grid, half)[:, 0]
    bias_columns = np.column_stack([w, np.ones(len(grid))])
    size_r = np.sum(ref["w"] ** 2, axis=1)[:, None]
    shifts = coarse_s + np.arange(-search_s, search_s + 1e-9, step_s)
    block = np.minimum(np.arange(len(grid)) * blocks // len(grid), blocks - 1)

    rows = [block == b for b in range(blocks)]

    def left(d):                # per block, what the bias columns leave of the difference:
        y = window_means(ref["ns"], size_r, grid + d, half)[:, 0] - size      # fitted over all,
        coef = np.linalg.lstsq(bias_columns, y, rcond=None)[0]            # and block by block
        alone = [np.sum((y[k] - bias_columns[k] @ np.linalg.lstsq(
            bias_columns[k], y[k], rcond=None)[0]) ** 2) for k in rows]
        return np.bincount(block, (y - bias_columns @ coef) ** 2, minlength=blocks), alone
    cost, own_cost = (np.array(x) for x in zip(*[left(d) for d in shifts]))  # (shifts, blocks)
    whole = parabola_min(shifts, cost.sum(axis=1))
    parts = np.array([parabola_min(shifts, cost.sum(axis=1) - cost[:, b])
                      for b in range(blocks)])
    se = math.sqrt((blocks - 1) / blocks * np.sum((parts - parts.mean()) ** 2))
    # each block's own offset from its own fit (a block's share of the overall fit moves
    # with the others': still blocks had 'placed' 40.11 ms to 0.02 ms and bent a clock
    # without drift by 25 ms), and only where the IMU turns in it
    turning = np.array([_turns(np.linalg.norm(w[k], axis=1)) for k in rows])
    own = np.array([parabola_min(shifts, own_cost[:, b]) if turning[b] else math.nan
                    for b in range(blocks)])
    mids = np.array([grid[k].mean() for k in rows])
    count = np.bincount(block, minlength=blocks)
    return whole, se, _drift(mids, own, _offset_variances(own_cost, count, step_s))


def _offset_variances(cost, count, step):
    """(blocks,) the variance (s^2) of each block's least-cost offset: a least-squares cost
    C(d) about its least C0 is C0 + C'' (d - d0)^2 / 2, and d0's variance 2 (C0 / n) / C''
    (n samples); inf where the least is at the grid's end or the cost not curved up."""
    out = np.full(cost.shape[1], np.inf)
    for b in range(cost.shape[1]):
        j = int(np.argmin(cost[:, b]))
        if 0 < j < len(cost) - 1:
            curve = (cost[j - 1, b] - 2 * cost[j, b] + cost[j + 1, b]) / step ** 2
            if curve > 0:
                out[b] = 2 * cost[j, b] / max(count[b], 1) / curve
    return out


def _drift(t, offsets, variances):
    """(drift: the offsets' rate of change, s/s, its standard error, the weighted mean time
    s, the offset there s) of a straight line through the blocks' own offsets (s) at their
    mid-times t (s),
    weighted by their variances - a block with little motion places its offset loosely -,
    the error scaled up by the fit's own scatter where it exceeds them; blocks without a
    least inside the search left out, (0, inf, nan, nan) with fewer than 5 left."""
    ok = np.isfinite(offsets) & np.isfinite(variances)
    if ok.sum() < 5:
        return 0.0, math.inf, math.nan, math.nan
    t, y, weight = t[ok], offsets[ok], 1.0 / variances[ok]
    centre = float(np.sum(weight * t) / np.sum(weight))
    x = t - centre
    slope = float(np.sum(weight * x * y) / np.sum(weight * x * x))
    intercept = float(np.sum(weight * y) / np.sum(weight))
    chi2 = float(np.sum(weight * (y - intercept - slope * x) ** 2)) / (len(t) - 2)
    return slope, math.sqrt(max(chi2, 1.0) / np.sum(weight * x * x)), centre, intercept


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


def _turn_said(angle, how, rpy, hint):
    """The measured turn in words: angle (deg), how (`_measured_turn`), the mounting (roll,
    pitch, yaw text; None: not said) that would hold it and the option that gives it."""
    roll, pitch, yaw = rpy or (None,) * 3
    return (f"{angle:.1f} deg from the mounting given (1 s mean rates and specific forces in the "
            "vehicle frame" + (", about their own means: no bias of either IMU in it"
                               if how == "free" else
                               f"; the IMU's own gyros and accelerometers turn onto the "
                               f"reference's more than {TRIADS_AGREE_DEG:g} deg apart: both "
                               "together" if how == "triads differ" else "") + ")" + (
                "; the two would agree with the reference IMU at roll, pitch, yaw "
                f"{roll}, {pitch}, {yaw} deg" if rpy else "") +
            (f" ({hint.format(roll=roll, pitch=pitch, yaw=yaw)})" if rpy and hint else ""))


def _pair_mountings(rec, clock_se):
    """Turn the reference IMU's mounting onto the IMU's where the 1 s means decide it
    (module doc), a small turn only beyond what the clock's standard error clock_se (s) can
    make of the rates (`_clock_turn_deg`); say what was measured."""
    ref = rec.reference_imu
    means, ok, mids = _second_means(rec)
    if ok.sum() < 10:
        rec.real["reference_imu_mounting"] = "not measured: under 10 s of common samples"
        return
    turn, angle, how = _measured_turn(rec, means, ok)
    seen = bool(how)
    # a triad mirrored (a sign, an axis order) is no turn: after the best turn one of its
    # moving axes runs against the other IMU's; named as given where an axis does so there
    # too (the turn is fitted on both: a mirrored accelerometer can turn the gyros against
    # each other) - as given alone, a turn of 180 deg runs two axes against (a FOG turned
    # 180 deg in yaw had been refused as a reflection)
    vehicle = [(attitude.rotate(rec.mounting.q_vs, means[0][k][ok]),
                attitude.rotate(ref["mounting"].q_vs, means[1][k][ok])) for k in range(2)]
    said = {when: [why for (mine, theirs), sensor in zip(vehicle, ("gyro", "accel"))
                   for why in [_runs_against(sensor, mine, turned(theirs), when,
                                             columns.format(sensor))] if why]
            for when, columns, turned in (
                ("with the mountings given", "{} columns", lambda x: x),
                ("after the best turn between them (fitted on both triads)",
                 "gyro and the accelerometer columns", turn.apply))}
    given, after = said.values()
    if after:
        raise RecordingError(f"{rec.name}: {(given or after)[0]}")
    fixed = attitude.from_scipy(turn) * ref["mounting"].q_vs
    yaw, pitch, roll = (angle_text(a) for a in attitude.as_euler(fixed))
    hint = ref.get("mounting_hint")
    said = _turn_said(angle, how, (roll, pitch, yaw), hint)
    if rec.reference_meta.get("attitude_of") == "reference_imu" and seen:
        # the reference's attitude is of the reference IMU's axes: they stay, the IMU turns
        turn_the_imu(rec, turn, _turn_said(angle, how, None, None),
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
    if angle <= SMALL_TURN_DEG and (how != "free" or not angle > DISTINCT_Z * timing):
        rec.real["reference_imu_mounting"] = (
            f"measured {said}: kept (the diagnosis fits a turn this small; "
            f"{_why_kept(how, angle, bias_alike, clock_se, timing)})")
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
    imus = [(vehicle[0][0], vehicle[1][0] - means[0][2][ok]), (vehicle[0][1], vehicle[1][1])]
    whose, held, turns = whose_turn(rec.reference, mids[ok], imus, angle,
                                    (TURNING_RATE, MOVING_FORCE), SPAN_SHARE)
    if whose == "both":     # the attitude holds neither mounting given: each onto it
        turn_both(rec, turns, f"measured {_turn_said(angle, how, None, None)}; {held}")
        return
    if whose == "imu":      # the reference's attitude holds the reference IMU, not the IMU
        turn_the_imu(rec, turn, _turn_said(angle, how, None, None), held)
        return
    ref["mounting"] = Mounting(attitude.as_wxyz(fixed), ref["mounting"].lever_arm_m)
    rec.real["reference_imu_mounting"] = f"measured {said}: turned so" + (f" ({held})" if held
                                                                          else "")


def _why_kept(how, angle, bias_alike, clock_se, timing):
    """Why a small measured turn (deg, decided `how`: `_measured_turn`) is not taken."""
    if how == "triads differ":
        return ("the IMU's gyros and accelerometers turn onto the reference's by more than "
                f"{TRIADS_AGREE_DEG:g} deg apart: its own triads differ")
    if how != "free":
        return (f"its tilt may be an accelerometer bias difference across gravity: "
                f"{bias_alike} reads as {angle:.1f} deg")
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


def _runs_against(sensor, mine, theirs, when, columns):
    """Why the triads are a reflection (naming the triad and axis, and the `columns` to
    check), or '': a moving axis - 1 s means spread by 0.02 rad/s or 0.3 m/s^2
    (`reference.MOVING_SPREAD`'s sizes) - whose means (vehicle frame) run against the other
    IMU's: correlation below AGAINST; a quieter one where `mounting.runs_against`
    (its differences too)."""
    spread = 0.02 if sensor == "gyro" else 0.3
    for i, axis in enumerate("xyz"):
        if min(np.std(mine[:, i]), np.std(theirs[:, i])) < spread and \
                not runs_against(mine[:, i], theirs[:, i]):     # a quiet axis: a sign only
            continue
        r = float(np.corrcoef(mine[:, i], theirs[:, i])[0, 1])
        if r < AGAINST:
            return (f"{when}, the two IMUs' {sensor}s about the vehicle's {axis} axis run "
                    f"against each other (1 s means correlate {r:.2f}): a column's sign or the "
                    f"axes' order differs between the two IMUs - a reflection, which no "
                    f"mounting can turn: check the {columns}")
    return ""


def _measured_turn(rec, means, ok):
    """(the turn of the reference's vehicle-frame vectors onto the IMU's, its angle in deg,
    how it was decided: "free" - by the 1 s means about their own means, where no bias of
    either IMU enters (a constant difference), each kind scaled to unit rms; "with gravity"
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
    if kinds:
        turn = wahba(np.vstack([k[0] for k in kinds]), np.vstack([k[1] for k in kinds]),
                     SPAN_SHARE)
        if turn is not None:
            # each triad alone, where it decides the turn: a MEMS unit's gyros turned against
            # its own accelerometers take a compromise that fits neither (1 deg of gyro
            # triad had turned an exact mounting 0.7 deg)
            each = [wahba(*k, SPAN_SHARE) for k in kinds] if len(kinds) == 2 else []
            if any(e is not None and math.degrees((e.inv() * turn).magnitude())
                   > TRIADS_AGREE_DEG for e in each):
                return turn, math.degrees(turn.magnitude()), "triads differ"
            return turn, math.degrees(turn.magnitude()), "free"
    mine = np.vstack([centred[0] * (G0 / rms_w), f_mine]) if rms_w >= TURNING_RATE else f_mine
    theirs = np.vstack([centred[1] * (G0 / rms_w), f_ref]) if rms_w >= TURNING_RATE else f_ref
    turn = wahba(mine, theirs, SPAN_SHARE)
    if turn is not None:
        return turn, math.degrees(turn.magnitude()), "with gravity"
    turn, _ = Rotation.align_vectors([f_mine.mean(axis=0)], [f_ref.mean(axis=0)])
    return turn, math.degrees(turn.magnitude()), ""


def _lever_force(rec, mids, half=0.5):
    """(M, 3) m/s^2, vehicle frame: means over [mid - half, mid + half] (s) of what the IMU
    feels beyond the reference IMU, r from it: dw/dt x r + w x (w x r) at its rates sample by
    sample (dw/dt's mean: the rate's change across). Of 1 s mean rates, a foot's strides
    (+-10 rad/s, 6 cm) lost w x (w x r) and turned an exact mounting 6.6 deg."""
    r = rec.mounting.lever_arm_m - rec.reference_imu["mounting"].lever_arm_m
    if not np.any(r):
        return np.zeros((len(mids), 3))
    w = attitude.rotate(rec.mounting.q_vs, rec.w)
    t = rec.imu_ns / 1e9
    edges = [np.column_stack([np.interp(mids + side, t, w[:, i]) for i in range(3)])
             for side in (-half, half)]
    return np.cross((edges[1] - edges[0]) / (2 * half), r) + \
        window_means(rec.imu_ns, np.cross(w, np.cross(w, r)), mids, half)


TRIADS_AGREE_DEG = 0.2      # deg: a triad's own turn within this of both triads' (a unit's
#                             agree to its 1-3 mrad misalignments), else they differ: no turn
MOVING_FORCE = 0.3          # m/s^2: 1 s mean specific forces' spread that turns the boxes
