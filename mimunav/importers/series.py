"""Numbers over sampled series the importers' checks share: a correlation over every lag
with gaps masked, how far its peak stands above a rival (jackknifed), the least of a cost on
a grid refined by a parabola, window means read off a running integral, a series on a grid."""
import math

import numpy as np


def masked_correlation(x, y, min_overlap):
    """(lags in samples, normalised correlation of x and y(. + lag) over each lag's overlap)
    of two series on one grid with NaN where a series has no value; lags whose overlap is
    shorter than min_overlap samples are NaN. By FFT: sums of products, of each series and
    of its square, over the overlap of the two masks."""
    mx, my = np.isfinite(x), np.isfinite(y)
    x0, y0 = np.where(mx, x, 0.0), np.where(my, y, 0.0)
    n = len(x) + len(y)
    size = 1 << (n - 1).bit_length()

    def corr(a, b):             # sum_i a[i] b[i + lag] for lag -len(a)+1 .. len(b)-1
        full = np.fft.irfft(np.conj(np.fft.rfft(a, size)) * np.fft.rfft(b, size), size)
        return np.concatenate([full[-(len(a) - 1):], full[:len(b)]]) if len(a) > 1 else \
            full[:len(b)]
    m = mx.astype(float), my.astype(float)
    count = np.rint(corr(*m))
    sx, sy = corr(x0, m[1]), corr(m[0], y0)
    sxx, syy, sxy = corr(x0 * x0, m[1]), corr(m[0], y0 * y0), corr(x0, y0)
    with np.errstate(invalid="ignore", divide="ignore"):
        cov = sxy - sx * sy / count
        var = (sxx - sx * sx / count) * (syy - sy * sy / count)
        r = cov / np.sqrt(var)
    r[(count < min_overlap) | ~(var > 0)] = np.nan
    lags = np.arange(-(len(x) - 1), len(y)) if len(x) > 1 else np.arange(len(y))
    return lags, r


def parabola_min(x, y):
    """Abscissa of the minimum of y(x) on a uniform grid x, refined by a parabola through the
    smallest value and its neighbours; NaN when the smallest value is at either end of the
    grid (the minimum is not bracketed: a parabola through the end and its two neighbours had
    put a straight stretch's lag at -14.6 s for a +-0.5 s search)."""
    j = int(np.argmin(y))
    if j in (0, len(y) - 1):
        return math.nan
    a, b, c = y[j - 1], y[j], y[j + 1]
    den = a - 2 * b + c
    return float(x[j] + (0.5 * (a - c) / den if den > 0 else 0.0) * (x[1] - x[0]))


def window_means(ns, x, mids, half=0.5):
    """(M, 3) the means of x (each sample the mean over the interval its stamp ns ends) over
    [mid - half, mid + half] s exactly, by its running integral (NaN beyond the record): whole
    samples about an edge 17 us apart had read a turn of 0.1 deg where none was."""
    t = ns / 1e9
    step = np.diff(t, prepend=t[0] - np.median(np.diff(t)))
    running = np.vstack([np.zeros(x.shape[1]), np.cumsum(x * step[:, None], axis=0)])
    edges = np.concatenate([[t[0] - step[0]], t])
    lo, hi = mids - half, mids + half
    out = np.column_stack([(np.interp(hi, edges, running[:, i]) -
                            np.interp(lo, edges, running[:, i])) / (2 * half)
                           for i in range(x.shape[1])])
    out[(lo < edges[0]) | (hi > edges[-1])] = np.nan
    return out


def on_grid(t, x, grid):
    """x (at times t, s) at the grid times (s); NaN outside t's span."""
    out = np.interp(grid, t, x)
    out[(grid < t[0]) | (grid > t[-1])] = np.nan
    return out


def peak_margin(a, b, lag, rival, blocks=20):
    """(how much higher the correlation of a and b(. + lag) is than at lag `rival`, its
    standard error): a and b on one grid (NaN: no value), lags in samples; the error by the
    jackknife over `blocks` consecutive blocks of a's grid, each left out in turn (blocks
    of the recording, longer than its motion stays correlated)."""
    def pairs(shift):
        i = np.arange(len(a))
        i = i[(i + shift >= 0) & (i + shift < len(b))]
        i = i[np.isfinite(a[i]) & np.isfinite(b[i + shift])]
        return i, a[i], b[i + shift]
    (i_p, x_p, y_p), (i_r, x_r, y_r) = pairs(lag), pairs(rival)
    block_p, block_r = (np.minimum(i * blocks // len(a), blocks - 1) for i in (i_p, i_r))

    def margin(out=-1):
        keep_p, keep_r = block_p != out, block_r != out
        return (np.corrcoef(x_p[keep_p], y_p[keep_p])[0, 1]
                - np.corrcoef(x_r[keep_r], y_r[keep_r])[0, 1])
    parts = np.array([margin(q) for q in range(blocks)])
    se = math.sqrt((blocks - 1) / blocks * np.sum((parts - parts.mean()) ** 2))
    return float(margin()), se


STAMP_JITTER = 1e-4     # the stamped intervals' rms spread over their median below which
#                         they are taken as they are: nothing to decide (a crystal's steps)
STEADY_SPAN = 250      # intervals either side whose mean is a sample's steady interval: a
#                        logger's 100 us of jitter averages to 4 us (0.1 % at 200 Hz), and a
#                        rate switched mid-record (200 -> 250 Hz) blurs over 2.5 s only
BURST_SPAN = 100     # samples whose mean interval is a logger's typical one: bursts of up
#                      to a few samples (0.1 ms apart, then the rest) vary it by a few %
BURST_SHARE = 0.1    # share of intervals under half a typical one above which the stamps
#                      come in bursts (2 of 3 in bursts of three; a clock's glitch is rare)
NEIGHBOURS = 5       # samples either side whose mean |dv| a gap's increment is held against
STAMP_NOISE_SHARE = 0.5     # the increments' |dv| / dt scatters this much less with a steady
#                             interval than with the stamped ones: the stamps are the noise


def increment_intervals(t, dv):
    """(the intervals (s, (N,)) velocity increments dv (m/s, (N, 3)) stamped at t (s) span,
    what was decided, or ''): where the stamps jitter, whether the increments follow them
    (`_jitter_judged`); after a gap in the stamps, whether the increment spans the gap or
    its own interval only (`_gaps_judged`). A logger reading a steady IMU in bursts (stamps
    0.1 ms apart, then 9.9 ms) has no typical interval to tell a gap by (its median, 0.1 ms,
    had made every other increment 50 times its rate, without a word): its increments are
    each taken as one interval's, and the words say so. Bursts are told by intervals under
    half a typical one (`_typical_interval`) in more than BURST_SHARE of them; rows dropped
    leave none."""
    step = _typical_interval(t)
    stamped = np.diff(t, prepend=t[0] - step)
    # read in bursts: many intervals far shorter than a typical one (dropped rows make
    # only longer ones: 10 % of them dropped had been taken for bursts, every increment
    # divided by a mean over the gaps, -12 % on every axis - an independent review)
    bursts = np.mean((stamped > 0) & (stamped < 0.5 * step)) > BURST_SHARE
    if not bursts:          # gaps: the median interval, which rows dropped do not move
        step = float(np.median(stamped[stamped > 0]))
    near = stamped > 0 if bursts else np.abs(stamped - step) < 0.5 * step
    size = np.linalg.norm(dv, axis=1)
    intervals, said = _jitter_judged(stamped, near, size, step, bursts)
    if step <= 0 or bursts:
        return intervals, said
    intervals, gaps = _gaps_judged(stamped, intervals, near, size)
    return intervals, "; ".join(x for x in (said, gaps) if x)


def _jitter_judged(stamped, near, size, step, bursts):
    """(intervals s, words) - whether increments of sizes |dv| `size` (m/s) follow their
    stamped intervals where these jitter: an IMU sampled at jittered instants integrates
    over the jittered intervals (|dv| ~ |f| dt: the stamps are right), a logger that stamps a
    steady IMU on its own read jitters its stamps alone (|dv| does not follow: dividing by
    them makes rate noise - a glider's 100 us of stamp jitter at 200 Hz had hidden a
    g-sensitivity behind rate noise). Judged on the scatter of |dv| / dt between
    neighbouring samples (motion nearly cancels; gravity makes |dv| large on any vehicle),
    stamped against a steady interval; where the steady one scatters under
    STAMP_NOISE_SHARE of the stamped, the mean of the STEADY_SPAN intervals either side
    (weighted by a triangle) is taken between samples `near` a typical interval `step` (a
    gap keeps its stamped length here; one global mean had read a rate switched from 200 to
    250 Hz 11 % off, an independent review); over all of them where they come in `bursts`."""
    spread = float(np.std(stamped[near])) / step if near.sum() > 10 else 0.0
    if spread < STAMP_JITTER or step <= 0:
        return stamped, ""
    jitter = (f"the stamped intervals come in bursts ({spread:.2g} of a typical one, "
              f"{step * 1e3:.4g} ms, in rms)" if bursts else
              f"the stamped intervals jitter by {spread:.1e} of their typical one")

    def scatter(dt):            # robust sigma of |dv| / dt between neighbours, where near
        x = np.diff(size / dt)[near[1:] & near[:-1]]
        return 1.4826 * float(np.median(np.abs(x - np.median(x))))
    half = STEADY_SPAN // 2     # twice a box of half the span: a burst's ripple falls as 1/n^2
    smooth = _local_mean(_local_mean(stamped, near, half), near, half)
    steady = np.where(near, smooth, stamped)   # its clock's
    as_stamped, as_steady = scatter(stamped), scatter(steady)
    if not as_steady < STAMP_NOISE_SHARE * as_stamped:
        return stamped, (f"{jitter} and the velocity increments follow them (|dv|/dt scatters "
                         f"{as_stamped:.3g} m/s^2 with them, {as_steady:.3g} with a steady "
                         "interval): each increment divided by its stamped interval")
    return steady, (f"{jitter}, but the velocity increments do not follow them (|dv|/dt "
                    f"scatters {as_stamped:.3g} m/s^2 with them, {as_steady:.3g} with a steady "
                    "one): the stamps' jitter is the logger's, each increment divided by the "
                    f"mean interval of the {2 * STEADY_SPAN + 1} around it "
                    f"({np.median(steady[near]) * 1e3:.4g} ms in the median" +
                    ("; a dropped sample cannot be told from the bursts: its increment is "
                     "taken as one interval's" if bursts else "") + "), the stamps kept")


def _gaps_judged(stamped, intervals, near, size):
    """(intervals s, words): where the stamps leave a gap (an interval beyond half a typical
    one longer: not `near`), whether the increment after it spans the gap (an IMU that
    accumulates until read: |dv| about the gap's intervals times its neighbours') or its own
    interval only (a logger that dropped rows: about once) - judged on the median over the
    gaps of log(|dv| / its neighbours') / log(gap / steady interval), 1 or 0. Divided by
    the gap or by the steady interval around it (a helicopter's 0.5 % of dropped rows,
    each increment after one divided by the gap, had halved those samples' rates and read
    as gyro scale factors of -0.2 %, p 5e-113)."""
    gap = ~near & (stamped > 0) & (stamped > np.median(stamped[near]))
    if not gap.any() or near.sum() < 10:
        return intervals, ""
    steady = _local_mean(intervals, near, STEADY_SPAN)
    neighbours = _local_mean(size, near, NEIGHBOURS)
    span = stamped[gap] / steady[gap]
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.log(size[gap] / neighbours[gap]) / np.log(span)
    share = float(np.nanmedian(share)) if np.isfinite(share).any() else 1.0
    seen = (f"{int(gap.sum())} gaps in the stamps ({float(np.median(span)):.3g} intervals "
            f"long in the median); the increment after each is "
            f"{float(np.median(size[gap] / neighbours[gap])):.3g} times its neighbours' in the "
            "median")
    if share > 0.5:
        return intervals, f"{seen}: it spans the gap, divided by it"
    out = intervals.copy()
    out[gap] = steady[gap]
    return out, (f"{seen}: it holds its own interval only (the rows were dropped), divided by "
                 "the steady interval - the motion in the gaps is not recorded")


def _typical_interval(t):
    """(s) the median over the record of the mean interval across BURST_SPAN samples (all
    of them on a short record): a logger's bursts even out over it, a gap stays rare."""
    k = max(min(BURST_SPAN, (len(t) - 1) // 4), 1)
    return float(np.median((t[k:] - t[:-k]) / k))


def _local_mean(x, keep, span):
    """(N,) the mean of x over the `keep` entries within `span` either side of each."""
    c = np.concatenate([[0.0], np.cumsum(np.where(keep, x, 0.0))])
    n = np.concatenate([[0], np.cumsum(keep)])
    i = np.arange(len(x))
    lo, hi = np.maximum(i - span, 0), np.minimum(i + span + 1, len(x))
    return (c[hi] - c[lo]) / np.maximum(n[hi] - n[lo], 1)
