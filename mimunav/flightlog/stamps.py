"""Stamps of a channel: runs at one sample rate, the samples missing from them, and a
uniform clock behind stamps written in whole ticks.
"""
import math
from statistics import NormalDist

import numpy as np

from ..kernels import njit


RATE_RUN = 200          # steps: a different sampling period held this long is a new rate
RATE_CHANGE = 0.05      # relative change of the period that makes a new rate (a logger


def rate_segments(t: np.ndarray) -> list[tuple[int, int, float]]:
    """[(first stamp index, last stamp index, period ns)] of a channel whose sampling rate
    may change (a logger switched from 100 to 50 Hz): runs of at least RATE_RUN steps whose
    running-median period differs from the previous run's by more than RATE_CHANGE (or
    CHANGE_SIGMAS of the block medians' own scatter, `_block_scatter`). One
    segment when the rate holds (jitter and gaps do not make a new rate)."""
    step = np.diff(np.asarray(t, np.int64)).astype(float)
    n = len(step)
    if n < 2 * RATE_RUN:
        return [(0, n, _period(step))]
    size = RATE_RUN // 2                      # medians of blocks of steps: jitter-proof
    blocks = np.median(step[:n // size * size].reshape(-1, size), axis=1)
    change = max(RATE_CHANGE, CHANGE_SIGMAS * _block_scatter(blocks))
    bounds, ref = [0], blocks[0]
    for j in range(1, len(blocks)):
        if abs(blocks[j] / ref - 1) > change and j * size - bounds[-1] >= RATE_RUN:
            bounds.append(j * size)
            ref = blocks[j]
    bounds.append(n)
    # a block astride a change holds both rates: merge runs of one rate, put each change
    # where the steps fit the two rates best, and merge again (a run astride a change
    # measured a rate between the two)
    merged = _merge_alike(step, bounds)
    log_step = np.log(np.maximum(step, 1.0))
    for i in range(1, len(merged) - 1):
        a, c, b = merged[i - 1], merged[i], merged[i + 1]
        la, lb = math.log(_period(step[a:c])), math.log(_period(step[c:b]))
        lo, hi = max(a + 1, c - RATE_RUN), min(b - 1, c + RATE_RUN)
        cost = [np.abs(log_step[lo:k] - la).sum() + np.abs(log_step[k:hi] - lb).sum()
                for k in range(lo, hi + 1)]
        merged[i] = lo + int(np.argmin(cost))
    merged = _merge_alike(step, merged)
    return [(a, b, _period(step[a:b])) for a, b in zip(merged[:-1], merged[1:])]


def mean_rate_hz(t: np.ndarray) -> float:
    """The sample rate of a channel (Hz): with one rate, the mean over its span with the
    missing samples counted (the median step of stamps rounded to the ns had read
    100.001 Hz where 60,000 samples spanned 599.99 s); with several, the median step's."""
    t = np.asarray(t, np.int64)
    if len(rate_segments(t)) > 1:
        return float(1e9 / np.median(np.diff(t)))
    missing = sum(n for _, n in missing_samples(t))
    return (len(t) - 1 + missing) / ((t[-1] - t[0]) / 1e9)


CHANGE_SIGMAS = 6.0     # a new rate's block median lies this many of the blocks' own scatter
#                         off the run's (20 % jitter with 20 % lost scatters them by 3.5 %:
#                         a 2-hour phone log had been cut into rates and read 183 Hz for 200)


def _block_scatter(blocks):
    """The relative scatter (1 sigma) of one block median of steps about its neighbours':
    the median absolute difference of neighbouring blocks' logs (a change of rate is one
    such difference, which it leaves out), over sqrt 2."""
    if len(blocks) < 3 or np.any(blocks <= 0):
        return 0.0
    d = np.diff(np.log(blocks))
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2))


def _merge_alike(step, bounds):
    """The run bounds with each pair of neighbouring runs of one rate (periods within
    RATE_CHANGE) merged, and every run shorter than RATE_RUN steps (no rate by the
    definition) merged into the run before it."""
    merged = list(bounds)
    while len(merged) > 2:
        periods = [_period(step[a:b]) for a, b in zip(merged[:-1], merged[1:])]
        alike = [i for i in range(1, len(merged) - 1)
                 if abs(periods[i] / periods[i - 1] - 1) <= RATE_CHANGE
                 or merged[i + 1] - merged[i] < RATE_RUN]
        if not alike:
            break
        del merged[alike[0]]
    return merged


def _period(step):
    """Median step over many samples (jitter averages out), ns."""
    rel = np.concatenate([[0.0], np.cumsum(step)])
    span = max(1, min(100, len(step) // 10))
    return float(np.median((rel[span:] - rel[:-span]) / span))


def missing_samples(t: np.ndarray, smoothing: float = 0.02) -> list[tuple]:
    """Gaps of a channel sampled at a nominal period T with jitter: [(index k, samples
    missing between stamps k and k + 1)]. T is the median step over many samples of each
    `rate_segments` run (a change of rate is no gap). Two kinds of jitter:
      - stamps jittered about a fixed grid (a logger stamping a sample late or early): its
        steps alternate long and short (`free_running` says not); each stamp is put in the
        next free slot of the grid, whose phase is tracked as a running mean (weight
        `smoothing`) of the stamps' offsets from it, so a late stamp followed by an early
        one (jitter of 6-9 ms on a 10 ms period) stays in its slot and a clock slightly off
        is followed; slots left empty are the missing samples;
      - a free-running sampler whose intervals jitter one by one: its phase wanders without
        bound, no grid holds it (a phone's 1.5 ms interval jitter had read as 2315 gaps
        where 7 were), and a step of n periods (rounded) is n - 1 missing samples."""
    t = np.asarray(t, np.int64)
    out = []
    for a, b, period in rate_segments(t):
        if period <= 0:
            continue
        rel = (t[a:b + 1] - int(t[a])).astype(float)
        first = _near_step(np.diff(rel), period)
        locked = _locked_grid(rel, first)
        if locked:              # a grid whose phase holds: no free-running sampler's
            gaps = _on_the_grid(rel, *locked, smoothing)
        elif free_running(np.diff(rel)):
            out += [(int(a + k), n) for k, n in _long_steps(np.diff(rel), period)]
            continue
        else:
            gaps = _refitted(rel, first, smoothing)
        if gaps is None:
            gaps = _over_the_span(rel, _empty_slots(rel, period, smoothing), smoothing)
        out += [(int(a + k), int(gaps[k])) for k in np.flatnonzero(gaps)]
    return out


LOCK_WIDTH = 0.25       # the first search of the grid's period: within this share of the
#                         median of near steps (18 % long where 30 % of a grid jittered by
#                         3 ms rms had been lost); its harmonic, half the period, lies beyond
LOCK_FIRST = 2000       # periods: the span of the first search (a grid jittered by 3 ms rms
#                         on 10 ms sums to 0.17 of its count: beyond LOCK_SIGMAS of noise's
#                         from some 900 stamps on); each next span 4 times longer
LOCK_SIGMAS = 5.0       # the stamps' phasor sum over sqrt(n): noise reaches it once in
#                         e^25 cells of the search (|z|^2 / n is exponential)
LOCK_BLOCK = 1 << 16    # stamps summed at a time (memory: block x candidates complex)


def _locked_grid(rel, period):
    """(period ns, phase ns) of the grid that stamps rel (ns from the first) lie on, or
    None: the period whose phasor sum |sum exp(2 pi i t / P)| over the stamps is largest -
    lost samples leave a grid's phase, and so its sum, whole, where the slope over the
    runs between gaps had been pulled by every gap placed a step off (20 % lost, 1 ms
    jitter: 10.06 ms for 10, 49 of 431 lost samples uncounted) - found over LOCK_FIRST
    periods within LOCK_WIDTH of `period` (`_strongest_frequency`, then to an eighth of
    the sum's resolution, 1 / span), carried over the whole span by the drift of the
    sums' phases over each LOCK_FIRST periods (`_phase_drift`), the sums over the first
    span and the whole beyond LOCK_SIGMAS of noise's, and LOCK_HELD of the stamps in spans
    whose sums hold a phase (a 100 Hz run then 118 Hz had locked to the first). The phase:
    where the whole sum's angle puts the grid's first point. None too (`_lockable`) for
    stamps that go back, too few, far sparser than `period`, or in ticks coarser than a
    period's 1 / LOCK_ALIAS."""
    if not _lockable(rel, period):
        return None
    part = rel[rel <= min(float(rel[-1]), LOCK_FIRST * period)]
    if len(part) < LOCK_MIN or part[-1] <= 0:      # 64 alike stamps first: no span
        return None
    cell = 1.0 / float(part[-1])
    fs = _strongest_frequency(part, period) + np.arange(-8, 9) * cell / 8
    z = _phasor_sums(part, fs)
    k = int(np.argmax(np.abs(z)))
    if not np.abs(z[k]) > LOCK_SIGMAS * math.sqrt(len(part)):
        return None
    f = float(fs[k])
    for _ in range(2):
        drift, held, scatter = _phase_drift(rel, f, LOCK_FIRST * period)
        f -= drift
    (whole,) = _phasor_sums(rel, np.array([f]))
    if held < LOCK_HELD or scatter > LOCK_SCATTER or \
            not abs(whole) > LOCK_SIGMAS * math.sqrt(len(rel)) \
            or np.median(np.diff(rel)) < 0.5 / f:   # most steps a fraction of the period:
        return None                                 # windows of a duty cycle, no grid
    return 1.0 / f, float(np.angle(whole)) / (2 * math.pi * f)


LOCK_MIN = 64           # stamps in the first span at least (a lone first stamp before a
#                         pause of 2000 periods had left one, and a sum's resolution of 1/0)
LOCK_ALIAS = 2.25       # stamps in whole ticks (ms) sum alike at f and 1 / tick - f, which
#                         lies beyond LOCK_WIDTH of f only for ticks under period / 2.25 (a
#                         600 Hz part stamped in ms had locked to 400 Hz)


def _lockable(rel, period):
    """Whether stamps rel (ns from the first) can be locked (`_locked_grid`): they never go
    back (a swapped pair, a clock stepped back: a chunk before the first), they hold fewer
    LOCK_FIRST-period chunks than stamps (bursts 1 ns apart read a 1 ns period and asked for
    a chunk every 2 us of a 2 min log: 2.5 GB), and they lie in no tick of LOCK_ALIAS
    periods or more."""
    if len(rel) < LOCK_MIN or rel[-1] <= 0 or np.any(np.diff(rel) < 0):
        return False
    if rel[-1] / (LOCK_FIRST * period) > len(rel):
        return False
    tick = stamp_tick(rel / 1e9)
    return tick is None or tick * 1e9 < period / LOCK_ALIAS


def _strongest_frequency(t, period):
    """The frequency (1/ns) within LOCK_WIDTH of 1 / period (ns) at which stamps t (ns) are
    most in phase: the largest of the spectrum of their counts in bins of period / 16
    (their phases to 0.6 % of a sum's), padded to an eighth of its resolution."""
    bin_ns = period / 16
    counts = np.bincount(np.round(t / bin_ns).astype(np.int64)).astype(float)
    n = 1 << int(math.ceil(math.log2(8 * len(counts))))
    freq = np.fft.rfftfreq(n, bin_ns)
    band = np.flatnonzero(np.abs(freq * period - 1) <= LOCK_WIDTH)
    return float(freq[band[np.argmax(np.abs(np.fft.rfft(counts, n)[band]))]])


CHUNK_SIGMAS = 3.0      # a chunk's sum over sqrt(n) that gives its phase to 0.24 rad rms
LOCK_SCATTER = 3.0      # the chunks' phases about their line, in their noise's rms, at most:
#                         a grid's are its jitter's (about 1); a free-running sampler's
#                         wander (3 % interval jitter had locked, its count off by 84 of 959)
LOCK_HELD = 0.9         # of the stamps: in chunks whose sums hold a phase (a grid's chunks
#                         all do, but for a short last one; a run of another rate does not)


def _phase_drift(rel, f, chunk):
    """(drift, held, scatter): how far (1/ns) f lies above the stamps' frequency - the phases
    of the stamps' sums at f over each `chunk` ns (those beyond CHUNK_SIGMAS of noise's)
    turn by 2 pi times that per ns: the slope of their unwrapped angles on the chunks' mean
    times, weighted by the sums' sizes -, the share of the stamps in those chunks, and the
    rms of their phases about that line in their own noise's (sqrt(n / 2) / |sum|, rad):
    about 1 on a grid, where a free-running sampler's phase wanders (0 and nan with fewer
    than three such chunks)."""
    at = (rel // chunk).astype(np.int64)
    phasor = np.exp(2j * math.pi * ((f * rel) % 1.0))
    z = np.bincount(at, phasor.real) + 1j * np.bincount(at, phasor.imag)
    n = np.bincount(at).astype(float)
    held = np.abs(z) > CHUNK_SIGMAS * np.sqrt(n)
    share = float(n[held].sum() / len(rel))
    if held.sum() < 3:
        return 0.0, share, math.nan
    centre = np.bincount(at, rel)[held] / n[held]
    line = np.polyfit(centre, np.unwrap(np.angle(z[held])), 1, w=np.abs(z[held]))
    off = np.angle(z[held] * np.exp(-1j * np.polyval(line, centre)))
    scatter = float(np.sqrt(np.mean((off * np.abs(z[held]) / np.sqrt(n[held] / 2)) ** 2)))
    return float(line[0]) / (2 * math.pi), share, scatter


def _phasor_sums(t, fs):
    """sum over t of exp(2 pi i f t) for each f of fs (1/ns; t ns), LOCK_BLOCK stamps at a
    time."""
    z = np.zeros(len(fs), complex)
    for a in range(0, len(t), LOCK_BLOCK):
        cycles = np.outer(fs, t[a:a + LOCK_BLOCK]) % 1.0
        z += np.exp(2j * math.pi * cycles).sum(axis=1)
    return z


def _on_the_grid(rel, period, phase, smoothing):
    """The gaps of stamps rel (ns) on a locked grid (`_locked_grid`): the slots counted
    from the grid point nearest the first stamp, as many as the span holds
    (`_held_by_the_span`, the stamps' rms off the grid as their jitter)."""
    x = rel - ((phase + period / 2) % period - period / 2)
    gaps = _empty_slots(x, period, smoothing)
    off = x - period * np.round(x / period)
    return _held_by_the_span(x, gaps, period, float(np.sqrt(np.mean(off * off))),
                             np.diff(rel))


REFIT_RANGE = 0.5       # the refitted period stays within this share of the first estimate:
#                         the median of 100-step means is long by the share of samples lost
#                         (10 % lost: 10 %), never by half; beyond it the stamps are no grid
#                         of one sample each (a host stamping a 400 Hz part's reads in bursts
#                         every 16 ms had refitted to the 20 us inside a burst: 50 kHz)


def _near_step(steps, period):
    """The median of the steps (ns) within half a period of `period` (ns), twice: a grid's
    step, which lost samples (steps of two periods and more) do not lengthen - the median
    of 100-step means is long by the share lost (10 % lost: 11.1 ms for 10)."""
    for _ in range(2):
        near = np.abs(steps - period) < 0.5 * period
        if near.any():
            period = float(np.median(steps[near]))
    return period


def _refitted(rel, first, smoothing):
    """The gaps of grid-jittered stamps rel (ns) from the first estimate of their period
    `first` (ns, `_near_step`), the period refitted as the stamps' slope on their slots
    within the runs between gaps until the slots hold - the span over the slots takes the
    gaps' own count into it (a quadruped's stamps jittered by 3.4 ms rms on 10 ms had
    settled at 9.81 ms and 45 'missed' samples where the span holds none) -, kept to as
    many as the span holds (`_held_by_the_span`); None where the refit leaves REFIT_RANGE
    of the first estimate."""
    period = first
    gaps = _empty_slots(rel, period, smoothing)
    for _ in range(5):
        period, sigma = _period_within_runs(rel, gaps)
        if not abs(period / first - 1) <= REFIT_RANGE:
            return None
        again = _empty_slots(rel, period, smoothing)
        if np.array_equal(again, gaps):
            break
        gaps = again
    return _held_by_the_span(rel, gaps, period, sigma, np.diff(rel))


def _over_the_span(rel, gaps, smoothing):
    """The gaps of stamps rel (ns) whose slot refit failed (`_refitted`): the period as the
    span over the slots, until the slots hold (the refit before the slope within runs)."""
    for _ in range(5):
        slots = len(rel) - 1 + int(gaps.sum())
        again = _empty_slots(rel, rel[-1] / slots, smoothing)
        if np.array_equal(again, gaps):
            break
        gaps = again
    return gaps


def _period_within_runs(rel, gaps):
    """(period, rms jitter) (ns) of stamps rel (ns) whose steps miss `gaps` samples: the
    least-squares slope of the stamps on their grid slots with an intercept of its own for
    each run between gaps - a gap placed wrongly moves no slope - and the rms of the
    stamps about those lines."""
    slot = np.concatenate([[0], np.cumsum(gaps + 1)]).astype(float)
    run = np.concatenate([[0], np.cumsum(gaps > 0)])
    count = np.bincount(run).astype(float)
    d_slot = slot - (np.bincount(run, slot) / count)[run]
    d_rel = rel - (np.bincount(run, rel) / count)[run]
    spread = float((d_slot * d_slot).sum())
    if spread == 0:                     # every run a single stamp: no slope
        return math.nan, math.nan
    period = float((d_slot * d_rel).sum() / spread)
    return period, float(np.sqrt(np.mean((d_rel - period * d_slot) ** 2)))


SPAN_SIGMAS = 4.0       # how far, in the end stamps' jitter, the span may place its slots


def _held_by_the_span(rel, gaps, period, sigma, steps):
    """The gaps as many as the span holds: the stamps' span over the period counts the
    grid's slots to within the end stamps' jitter (SPAN_SIGMAS times sqrt(2) sigma, ns),
    so gaps beyond that many missing samples are jitter the slots could not tell - a late
    stamp past the next slot's middle - and only the longest steps keep theirs, up to the
    span's count (none where it holds no missing sample)."""
    held = int(round(rel[-1] / period)) - (len(rel) - 1)
    if gaps.sum() <= max(held, 0) + math.ceil(SPAN_SIGMAS * math.sqrt(2) * sigma / period):
        return gaps
    kept = np.zeros_like(gaps)
    for k in np.flatnonzero(gaps)[np.argsort(-steps[gaps > 0], kind="stable")]:
        if kept.sum() + gaps[k] > held:
            break
        kept[k] = gaps[k]
    return kept


MISSED_STEPS = 2.5      # a step this many median steps long has missed epochs (one missed
#                         of a 1 Hz track, 2 s, passes: its jitter alone reaches 1.5)


def missed_spans(t, steps=MISSED_STEPS):
    """(starts, ends) (s, as t): the steps between successive stamps t longer than `steps`
    median steps - where a channel missed epochs (a reference's dropout)."""
    t = np.asarray(t, float)
    step = np.diff(t)
    k = np.flatnonzero(step > steps * float(np.median(step))) if len(step) else \
        np.zeros(0, int)
    return t[k], t[k + 1]


def longest_gap(t, gaps):
    """(k, samples missing) of the longest of `gaps` (`missing_samples`' [(k, n)]) by the
    stamps t (any unit): the step t[k] -> t[k + 1]."""
    return max(gaps, key=lambda g: t[g[0] + 1] - t[g[0]])


SCHEDULED_GAPS = 10     # gaps at least: so many at one interval are a schedule, not chance
SCHEDULED_SHARE = 0.9   # of the gaps at least on the schedule (a few lost samples beside it)


def scheduled(gaps):
    """Words on gaps (`missing_samples`' [(k, n)]) that recur like a schedule - SCHEDULED_GAPS
    or more, SCHEDULED_SHARE of them of one count and every so many samples (to one) from
    the gap before - or ''. A logger dropping samples at each buffer write (an SD card's
    flush) loses them so, and a stream that sends another message every k samples,
    stamped by a count of its messages, makes the same stamps (an
    x-IMU's packet numbers: a packet of another kind after every 128 samples read as 98 lost
    samples and 258 Hz for 256)."""
    if len(gaps) < SCHEDULED_GAPS:
        return ""
    every = np.diff([k for k, _ in gaps])
    counts = np.array([n for _, n in gaps[1:]])
    period, size = int(np.median(every)), int(np.median(counts))
    on = (np.abs(every - period) <= 1) & (counts == size)
    if on.sum() < max(SCHEDULED_GAPS, SCHEDULED_SHARE * len(every)):
        return ""
    return (f"{int(on.sum()) + 1} of the {len(gaps)} gaps recur every {period} samples, each "
            f"of {size}: a logger that drops samples at each of its buffer's writes loses "
            "them so, and stamps that count a stream's messages, another kind sent on that "
            "schedule, step alike - if so they are no times")


FREE_RUNNING_SPREAD = 1.7     # a grid's spans of SPAN_STEPS steps scatter as its single
#                               steps do (both the jitter of two end stamps), a free-running
#                               sampler's as sqrt(SPAN_STEPS) = 2.8 times them: grids 0.96-1.2
#                               (up to 10 % lost), phones 2.8-3.3; the steps' lag-1
#                               correlation had read a quadruped's late-tailed grid -0.29
#                               against a limit of -0.25, a draw of its kind above it (39
#                               'missed' samples in 2400)
SPAN_STEPS = 8


def free_running(steps):
    """Whether the steps (ns, one rate) jitter interval by interval rather than about a grid:
    the robust spread (MAD) of the spans of SPAN_STEPS steps over that of single steps
    above FREE_RUNNING_SPREAD - a grid's phase stays bounded, a free-running sampler's
    wanders -, both of steps within half a median step of it (a span over a lost sample is
    a period longer: 5 % lost had read a grid free running); False for steps that do not
    jitter, or too few spans to tell."""
    steps = np.asarray(steps, float)
    step = float(np.median(steps)) if len(steps) else 0.0
    near = np.abs(steps - step) < 0.5 * step
    whole = np.convolve(near, np.ones(SPAN_STEPS), "valid") == SPAN_STEPS
    if whole.sum() < 10 * SPAN_STEPS:
        return False
    spans = np.convolve(steps, np.ones(SPAN_STEPS), "valid")[whole]
    single = np.median(np.abs(steps[near] - np.median(steps[near])))
    if single == 0:
        return False
    return float(np.median(np.abs(spans - np.median(spans))) / single) > FREE_RUNNING_SPREAD


def _long_steps(steps, period):
    """[(k, samples missing)] of a free-running sampler's steps (ns): a step beyond both
    1.5 periods and the longest that its jitter makes among this many steps (one in ten
    runs of them: the normal quantile of 1 / (10 n) of the steps' robust sigma - a phone's
    1.5 ms jitter reaches 16 ms, 1.6 periods, 30 times in 66,000 steps) misses
    round(step / period) - 1 samples, at least one. A lone missing sample (a step of two
    periods) shorter than that is not counted: the stamps cannot tell it."""
    near = steps[np.abs(steps - period) < 0.5 * period]
    sigma = 1.4826 * float(np.median(np.abs(near - np.median(near)))) if len(near) else 0.0
    longest = period + NormalDist().inv_cdf(1 - 0.1 / len(steps)) * sigma
    long = np.flatnonzero(steps > max(1.5 * period, longest))
    return [(int(k), max(1, int(round(steps[k] / period)) - 1)) for k in long]


@njit()
def _empty_slots(rel, period, smoothing):
    """Per step k -> k + 1, the empty grid slots between the two stamps. A stamp that
    rounds past an empty slot into the one its successor rounds to is late, not after a
    missed sample: it takes the empty slot (an INS's stamps late by up to 6.5 ms on a
    10 ms grid had read as 156 missed samples and 100.6 Hz where none was missed)."""
    gaps = np.zeros(len(rel) - 1, np.int64)
    slot, phase = 0, 0.0
    for k in range(1, len(rel)):
        nearest = int(round((rel[k] - phase) / period))
        step = max(1, nearest - slot)
        if step > 1 and k + 1 < len(rel) and \
                int(round((rel[k + 1] - phase) / period)) <= nearest:
            step -= 1
        gaps[k - 1] = step - 1
        slot += step
        phase += smoothing * (rel[k] - period * slot - phase)
    return gaps


TICKS_S = (1e-3, 1e-4, 1e-5, 1e-6)     # the whole units a logger may stamp in
CLOCK_RUN = 10          # samples: a shorter run between gaps keeps its stamps
ROUNDING_SHARE = 0.55   # of a tick: how far a stamp rounded from a uniform clock lies from
                        # the line fitted through them (the rounding's half tick, and the
                        # line's own error); a stamp further off is timing, kept


def stamp_tick(t):
    """The largest of TICKS_S the stamps t (s, from their first) are whole multiples of, or
    None."""
    rel = np.asarray(t, float) - t[0]
    for tick in TICKS_S:
        if np.all(np.abs(rel / tick - np.round(rel / tick)) < 1e-3):
            return tick
    return None


def rounded_clock(ns):
    """(stamps ns (N,) int64, words) of a uniform clock behind stamps written in whole
    ticks (`stamp_tick`: a flight computer's millis() of a 501.3 Hz part), or (None, ''):
    each run between gaps is fitted by a line over its samples, and taken when every stamp
    lies within ROUNDING_SHARE of a tick of it, the steps are not all one and the runs so
    fitted hold most of the samples - the rounding's error (tick / sqrt 12 rms) made the
    lever-arm transfer's derivative jump by 0.13 rad/s^2 at each 1 ms step of a 0.5 Hz
    swing. Stamps that stray further (a scheduler's jitter) keep theirs."""
    ns = np.asarray(ns, np.int64)
    if len(ns) < CLOCK_RUN:
        return None, ""
    t = (ns - ns[0]) / 1e9
    tick, step = stamp_tick(t), np.diff(t)
    if not tick or np.ptp(step) < 0.5 * tick:
        return None, ""
    # a gap: a step beyond the rounded steps' own spread (a period of 1.2 ticks steps by
    # 1 and 2; a median step of 1 had made every 2 a gap)
    cuts = np.flatnonzero(step > float(np.median(step)) + 1.5 * tick) + 1
    uniform, rate = _lines_through_runs(ns, cuts, ROUNDING_SHARE * tick)
    return (None, "") if uniform is None else (uniform, (
        f"stamped in whole {tick * 1e3:g} ms of a uniform {rate:.6g} Hz clock (every stamp "
        f"within half a tick of it, {len(cuts) + 1} run(s) between gaps): that clock's times are "
        f"used, not the rounding's (its error {tick / math.sqrt(12) * 1e3:.2g} ms rms)"))


def _lines_through_runs(ns, cuts, within):
    """(stamps ns (N,) int64, rate Hz) of the uniform clock behind stamps ns: each run
    between the `cuts` (indices that start a run) of CLOCK_RUN samples or more replaced by
    the line fitted over its samples - (None, None) where a stamp lies beyond `within` (s)
    of its line or the runs so fitted hold under half the samples; the rate over the steps
    inside runs."""
    t = (ns - ns[0]) / 1e9
    out, fitted = t.copy(), 0
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(t)]):
        if b - a < CLOCK_RUN:
            continue
        k = np.arange(b - a, dtype=float)
        line = np.polyval(np.polyfit(k, t[a:b], 1), k)
        if np.max(np.abs(t[a:b] - line)) > within:
            return None, None
        out[a:b], fitted = line, fitted + b - a
    if fitted < 0.5 * len(t):
        return None, None
    inside = np.ones(len(t) - 1, bool)
    inside[cuts - 1] = False
    return (ns[0] + np.round(out * 1e9).astype(np.int64),
            inside.sum() / float(np.sum(np.diff(out)[inside])))


BURSTS = 4.0            # a step this many times the median step is a host's read (the
#                         samples of a read lie a few us apart: a host reading a sensor's
#                         queue k samples at a time, a phone's batched events)
BURST_STEP = 100e-6     # s: the samples of a read lie closer than any IMU samples (8 kHz:
#                         125 us) - a grid recording a few samples every few seconds
#                         (duty-cycled) steps by its own period inside its windows
READS_SHARE = 0.02      # of the steps at least: reads of 50 samples or fewer - a grid's
#                         few long gaps are no bursts (two 10 min runs 2 h apart had made
#                         the mean step 4 times the median, and been 'one read')


def burst_clock(ns):
    """(stamps ns (N,) int64, words) of a uniform clock behind stamps written in bursts -
    READS_SHARE of the steps or more BURSTS times the median step, and the mean step too,
    the median step under BURST_STEP: a host stamping each read
    of a sensor's queue, its samples a few us apart (a 400 Hz part read every 16 ms had read
    475 Hz and 4505 'missed' samples) - or (None, ''): each run between missed reads (a step
    beyond 2.5 times the reads' median interval) fitted by a line over its samples and taken
    when every stamp lies within one read interval of it and the runs so fitted hold most
    of the samples. The line lies up to a read interval off the samples' true times, a
    constant lag the clock checks against a reference measure."""
    ns = np.asarray(ns, np.int64)
    if len(ns) < 10 * CLOCK_RUN:
        return None, ""
    t = (ns - ns[0]) / 1e9
    step = np.diff(t)
    reads = step > BURSTS * float(np.median(step))
    # the samples of a read closer than their mean interval over the span (a grid that
    # loses runs of samples steps by whole periods), and the reads a share of the steps
    if reads.mean() < READS_SHARE or float(np.mean(step)) < BURSTS * float(np.median(step)) \
            or float(np.median(step)) >= BURST_STEP:
        return None, ""
    read = float(np.median(step[reads]))
    cuts = np.flatnonzero(step > 2.5 * read) + 1
    uniform, rate = _lines_through_runs(ns, cuts, read)
    return (None, "") if uniform is None else (uniform, (
        f"stamped in bursts: the stamps are a host's reads {read * 1e3:.3g} ms apart (their "
        f"median step {np.median(step) * 1e6:.3g} us), not the samples' times - a uniform "
        f"{rate:.6g} Hz clock through them is used ({len(cuts) + 1} run(s) between missed "
        f"reads, every stamp within one read of it); it lies up to {read * 1e3:.3g} ms off "
        "the samples' own times, a constant lag the clock checks against a reference "
        "measure"))
