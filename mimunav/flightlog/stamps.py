"""Stamps of a channel: runs at one sample rate, and the samples missing from them.
"""
import math

import numpy as np

from ..kernels import njit


RATE_RUN = 200          # steps: a different sampling period held this long is a new rate
RATE_CHANGE = 0.05      # relative change of the period that makes a new rate (a logger


def rate_segments(t: np.ndarray) -> list[tuple[int, int, float]]:
    """[(first stamp index, last stamp index, period ns)] of a channel whose sampling rate
    may change (a logger switched from 100 to 50 Hz): runs of at least RATE_RUN steps whose
    running-median period differs from the previous run's by more than RATE_CHANGE. One
    segment when the rate holds (jitter and gaps do not make a new rate)."""
    step = np.diff(np.asarray(t, np.int64)).astype(float)
    n = len(step)
    if n < 2 * RATE_RUN:
        return [(0, n, _period(step))]
    size = RATE_RUN // 2                      # medians of blocks of steps: jitter-proof
    blocks = np.median(step[:n // size * size].reshape(-1, size), axis=1)
    bounds, ref = [0], blocks[0]
    for j in range(1, len(blocks)):
        if abs(blocks[j] / ref - 1) > RATE_CHANGE and j * size - bounds[-1] >= RATE_RUN:
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
    `rate_segments` run (a change of rate is no gap); each stamp is put in the next free
    slot of the sampling grid, whose phase is tracked as a running mean (weight
    `smoothing`) of the stamps' offsets from it, so a late stamp followed by an early one
    (jitter of 6-9 ms on a 10 ms period) stays in its slot and a clock slightly off is
    followed; slots left empty are the missing samples."""
    t = np.asarray(t, np.int64)
    out = []
    for a, b, period in rate_segments(t):
        if period <= 0:
            continue
        rel = (t[a:b + 1] - int(t[a])).astype(float)
        gaps = _empty_slots(rel, period, smoothing)
        # the period again as the span over its slots, until the slots hold: the median of
        # 100-step means takes lost samples into the period (2 % lost: 10.2 ms for 10, and
        # half of them missed); the span's steps cancel each other's jitter
        for _ in range(5):
            slots = len(rel) - 1 + int(gaps.sum())
            again = _empty_slots(rel, rel[-1] / slots, smoothing)
            if np.array_equal(again, gaps):
                break
            gaps = again
        out += [(int(a + k), int(gaps[k])) for k in np.flatnonzero(gaps)]
    return out


@njit()
def _empty_slots(rel, period, smoothing):
    """Per step k -> k + 1, the empty grid slots between the two stamps."""
    gaps = np.zeros(len(rel) - 1, np.int64)
    slot, phase = 0, 0.0
    for k in range(1, len(rel)):
        step = max(1, int(round((rel[k] - phase) / period)) - slot)
        gaps[k - 1] = step - 1
        slot += step
        phase += smoothing * (rel[k] - period * slot - phase)
    return gaps
