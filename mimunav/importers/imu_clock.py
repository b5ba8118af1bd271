"""A reference IMU's clock against the IMU's (`pairing.pair`), and a reference attitude's
(`trajectory_clock`).

Clock: the two rotation rates' magnitudes |w| do not depend on either mounting. Their
normalised cross-correlation over every lag at which the two overlap for at least half the
shorter record (masked: each lag's correlation over its own overlap) must peak once -
at least PEAK_CORRELATION, and every lag beyond the peak's own lobe (where the correlation
stays above SECOND_PEAK_SHARE of it, at most LOBE_MAX_S either side) at most that share,
or the peak above the best of them by DISTINCT_Z standard errors (`peak_margin`); the peak
is then refined to a millisecond with the two gyro triads' biases and scales fitted beside
it (`_refined`), its standard error said (widened by what their misalignment could move).
Each tenth of the overlap gives its own offset: a straight line through them, weighted by
their own variances, measures a drift (a crystal's tens of ppm), taken when beyond
DISTINCT_Z of its standard error and worth SMALL_OFFSET_S over the overlap - the stamps
then corrected along the line. A recording whose IMUs hardly turn (|w| spread below
TURNING_RATE) cannot be timed so: said, and left as recorded. A reference trajectory's
|w| that leaves its clock undecided (a train's or a car's turns repeat) is tried again by
the specific force along the vehicle's x axis (`_along_force_lag`).
"""
import math

import numpy as np

from ..frames import attitude
from .attitude_check import attitude_means
from .series import masked_correlation, on_grid, parabola_min, peak_margin, window_means

SMALL_OFFSET_S = 0.001      # s: the refinement's step; a measured offset beyond it is
                            # corrected (whatever the user's own shift was: the result must
                            # not depend on it), a smaller one left to the time_skew term
GRID_S = 0.02               # s: the coarse search's grid (50 Hz: |w| of a vehicle's motion)
REFINE_WINDOW_S = 0.1       # s: |w|^2 as means over windows this long, not interpolated
JACKKNIFE_BLOCKS = 30       # the refined offset's standard error by the jackknife over this
                            # many blocks: with 10, its spread over 20 seeds of a gentle
                            # flight (information in a few turns) reached 7 standard errors
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
DISTINCT_Z = 4.0            # a rival peak above that share is no rival when the peak
#                             stands above it by this many standard errors (`peak_margin`):
#                             the rival is the best of some hundreds of lobes within the
#                             search, and 0.01 shared among 500 of them is z = 4.1 one-sided
#                             (a robot's 1.5 Hz bumps: 0.88 a bump away, 8.3 errors below the
#                             peak; a steady wave's next period: 1.0 below)



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
        np.linalg.norm(ref["w"], axis=1), "the two IMUs (|w|)", "the reference's stamps"))
    if found.get("lag_s") is None:
        return dict(found, offset_s=None)
    offset, se, (drift, drift_se, centre, at_centre) = _refined(rec, found["lag_s"])
    if not math.isfinite(offset + se):
        return {"offset_s": None, "peak_lag_s": found["lag_s"],
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
    steps over twice the median left out), by the module doc's rule; where that leaves it
    undecided, the specific force along the vehicle's x axis (`_along_force_lag`) by the
    same rule."""
    ref = rec.reference
    ok = np.isfinite(ref["q_nb"]).all(axis=1)
    t = ref["ns"][ok] / 1e9
    rate = attitude.turn_rate(t, attitude.from_wxyz(ref["q_nb"][ok]))
    step = np.diff(t)
    keep = step <= 2 * np.median(step)
    found = rate_lag(_centres(rec.imu_ns), np.linalg.norm(rec.w, axis=1),
                     (0.5 * (t[1:] + t[:-1]))[keep], rate[keep],
                     "the IMU's and the reference attitude's turn rates (|w|)",
                     "the reference's stamps")
    if found.get("lag_s") is None:
        along = _along_force_lag(rec)
        if along.get("lag_s") is not None:
            found = dict(along, said=f"{along['said']}, where their turn rates left it "
                                     f"{found['said']}")
    return dict(found, offset_s=found.get("lag_s"))


FORCE_STEP_S = 0.1      # s: the 1 s means of `_along_force_lag` slide this far a step


def _along_force_lag(rec):
    """`rate_lag` of the IMU's specific force along the vehicle's x axis (turned by its
    mounting) against what the reference's attitude and velocity make of it
    (`attitude_check.attitude_means`), both 1 s means every FORCE_STEP_S: a train's or a
    car's starts and stops happen once, where its turns repeat (a reference trajectory
    stamped in GPS time, 18 s from its IMU's UTC, had been left "not decided" - the |w| of
    a train's curves peaking there at 1.00 and 0.93 10 s on - and taken as stamped)."""
    ref_s, imu_s = rec.reference["ns"] / 1e9, rec.imu_ns / 1e9
    mids_ref = np.arange(ref_s[0] + 0.5, ref_s[-1] - 0.5, FORCE_STEP_S)
    mids_imu = np.arange(imu_s[0] + 0.5, imu_s[-1] - 0.5, FORCE_STEP_S)
    predicted = attitude_means(rec.reference, mids_ref)
    if predicted is None or len(mids_ref) < 3 or len(mids_imu) < 3:
        return {"lag_s": None}
    mine = attitude.rotate(rec.mounting.q_vs, window_means(rec.imu_ns, rec.f, mids_imu))
    return rate_lag(mids_imu, mine[:, 0], mids_ref, predicted[1][:, 0],
                    "the IMU's and the reference's specific force along the vehicle's x axis "
                    "(1 s means)", "the reference's stamps")


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


def late_or_early(seconds):
    """How late (positive) or early stamps are, in words: "0.05 s late", "3.22 s early" (a
    helicopter's reference "-3.22 s late" had read as late)."""
    return f"{abs(seconds):.2f} s {'early' if seconds < 0 else 'late'}"


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
    said = (f"{whose} correlate {peak:.2f} with {late} {late_or_early(lags[k] * GRID_S)}, "
            f"{second:.2f} at best beyond the peak's lobe (+-{width:.2g} s)")
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
                           zero_said=f"{whose} correlate {r[i]:.2f} with {late} "
                                     f"{late_or_early(lags[i] * GRID_S)}, {peak:.2f} at best")
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


def _refined(rec, coarse_s, search_s=2 * GRID_S, step_s=0.001, blocks=10,
             jackknife_blocks=JACKKNIFE_BLOCKS):
    """(offset s, its standard error s, `_drift`'s line through the blocks' own offsets):
    the offset that best matches the two |w|^2 (means over REFINE_WINDOW_S) within
    +-search_s of coarse_s, on a grid of step_s refined by a parabola, with what the two
    gyros' own errors make of |w|^2 fitted at each shift first (`_gyro_error_columns`:
    biases and scales); the error by the jackknife over `jackknife_blocks` consecutive
    blocks of the overlap, widened by how far a misalignment's products move the offset;
    the drift from `blocks` of them; NaN where the least cost, of the whole or of a
    jackknife part, is at the search's edge (not bracketed)."""
    ref, half = rec.reference_imu, REFINE_WINDOW_S / 2
    t, t_r = rec.imu_ns / 1e9, ref["ns"] / 1e9
    lo = max(t[0], t_r[0] - coarse_s) + search_s + half
    hi = min(t[-1], t_r[-1] - coarse_s) - search_s - half
    grid = np.arange(lo, hi, 0.01)
    w = window_means(rec.imu_ns, rec.w, grid, half)
    size = window_means(rec.imu_ns, np.sum(rec.w ** 2, axis=1)[:, None], grid, half)[:, 0]
    columns, products = _gyro_error_columns(rec.imu_ns, rec.w, grid, half)
    with_products = np.column_stack([columns, products])
    size_r = np.sum(ref["w"] ** 2, axis=1)[:, None]
    shifts = coarse_s + np.arange(-search_s, search_s + 1e-9, step_s)
    block, fine = (np.minimum(np.arange(len(grid)) * n // len(grid), n - 1)
                   for n in (blocks, jackknife_blocks))
    rows = [block == b for b in range(blocks)]

    def left(d):                # what the columns leave of the difference, fitted over
        y = window_means(ref["ns"], size_r, grid + d, half)[:, 0] - size       # all, and
        r2 = (y - columns @ np.linalg.lstsq(columns, y, rcond=None)[0]) ** 2  # block by block
        alone = [np.sum((y[k] - columns[k] @ np.linalg.lstsq(
            columns[k], y[k], rcond=None)[0]) ** 2) for k in rows]
        return (np.bincount(fine, r2, minlength=jackknife_blocks), alone,
                np.sum((y - with_products @ np.linalg.lstsq(with_products, y, rcond=None)[0])
                       ** 2))
    cost, own_cost, cost_products = (np.array(x) for x in zip(*[left(d) for d in shifts]))
    whole = parabola_min(shifts, cost.sum(axis=1))
    parts = np.array([parabola_min(shifts, cost.sum(axis=1) - cost[:, b])
                      for b in range(jackknife_blocks)])
    se = math.hypot(math.sqrt((jackknife_blocks - 1) / jackknife_blocks
                              * np.sum((parts - parts.mean()) ** 2)),
                    parabola_min(shifts, cost_products) - whole)
    # each block's own offset from its own fit (a block's share of the overall fit moves
    # with the others': still blocks had 'placed' 40.11 ms to 0.02 ms and bent a clock
    # without drift by 25 ms), and only where the IMU turns in it
    turning = np.array([_turns(np.linalg.norm(w[k], axis=1)) for k in rows])
    own = np.array([parabola_min(shifts, own_cost[:, b]) if turning[b] else math.nan
                    for b in range(blocks)])
    mids = np.array([grid[k].mean() for k in rows])
    count = np.bincount(block, minlength=blocks)
    return whole, se, _drift(mids, own, _offset_variances(own_cost, count, step_s))


def _gyro_error_columns(ns, w, grid, half):
    """((len(grid), 7), (len(grid), 3)) what the two gyro triads' own errors make of
    |w_r|^2 - |w|^2, as window means (half-width half, s) about the grid's times (s) of the
    IMU's rates w (rad/s, stamps ns). With w_r = C w (any mounting C) and the IMU's
    w' = S w + b (its scale and misalignment S, bias b), the difference is
    w'.A w' + 2 c.w' + const: first the squares w_i^2 (A's diagonal: the scales), the
    rates and 1, then apart the products w_x w_y, w_x w_z, w_y w_z (a misalignment). A
    shift mimics part of each: a MEMS pair's 0.3 deg/s had made a fixed wing's offset 0.3 ms
    late, a 2 % scale a gentle flight's 2 ms late (standard error 1.2), its 1 %
    misalignment 1.2 ms late. But on a car the products are the shift's own signature (its
    roll rate follows its lateral acceleration's rate of change: w_x w_z ~ v w_z dw_z/dt;
    a phone beside an INS read 2.5 ms off with them, 5 standard errors): the offset is
    taken without them, and how far they move it is counted into its error."""
    i, j = np.triu_indices(3, 1)
    return (np.column_stack([window_means(ns, w ** 2, grid, half),
                             window_means(ns, w, grid, half), np.ones(len(grid))]),
            window_means(ns, w[:, i] * w[:, j], grid, half))


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
    # a variance under a picosecond squared is rounding (two IMUs' exact samples: 0)
    t, y, weight = t[ok], offsets[ok], 1.0 / np.maximum(variances[ok], 1e-24)
    centre = float(np.sum(weight * t) / np.sum(weight))
    x = t - centre
    slope = float(np.sum(weight * x * y) / np.sum(weight * x * x))
    intercept = float(np.sum(weight * y) / np.sum(weight))
    chi2 = float(np.sum(weight * (y - intercept - slope * x) ** 2)) / (len(t) - 2)
    return slope, math.sqrt(max(chi2, 1.0) / np.sum(weight * x * x)), centre, intercept
