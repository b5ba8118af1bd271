"""Wild values and saturation in the MIMU's outputs: clipped samples, the noise a sample is
judged against, and seed S1's wild-value filter (a sample replaced where it leaves the local
curvature), with the per-sample flags it sets.
"""
import math
from dataclasses import dataclass

import numpy as np


# Sample flags (bit mask) set by `compensate`
REPLACED = 1       # a wild (outlier) or non-finite raw value replaced by its neighbours' median
SATURATED = 2      # compensated output at or beyond the unit's range on some axis, or a raw
                   # output clipped (stuck at its extreme, `clipped`)
CLIP_RUN = 5       # identical consecutive samples at a channel's extreme: clipped
UNUSABLE = 4       # could not be repaired (non-finite across the whole filter window)


def clipped(x: np.ndarray, extremes: np.ndarray | None = None) -> np.ndarray:
    """Samples (N,) bool where some axis of x (N, 3) sits at that axis's extreme value in a
    run of at least CLIP_RUN identical consecutive samples: an output clipped by its ADC or
    amplifier, whatever the declared range says. A live sensor's noise moves a quantized
    output every sample; a channel that never moves (ptp 0) is left alone. extremes: the
    (max, min) (2, 3) of the whole record's finite values when x is a block of it (NaN
    where a column has fewer than CLIP_RUN finite values or never moves)."""
    x = np.asarray(x, dtype=float)
    out = np.zeros(len(x), dtype=bool)
    if extremes is None:
        extremes = column_extremes(x)
    for col, top, bottom in zip(x.T, *extremes):
        if not np.isfinite(top):
            continue
        for extreme in (top, bottom):
            at = np.concatenate([[0], (col == extreme).astype(np.int8), [0]])
            edges = np.flatnonzero(np.diff(at))
            for a, b in zip(edges[::2], edges[1::2]):
                if b - a >= CLIP_RUN:
                    out[a:b] = True
    return out


def column_extremes(x: np.ndarray) -> np.ndarray:
    """(max, min) (2, 3) of each column's finite values for `clipped`; NaN where a column
    has fewer than CLIP_RUN finite values or never moves."""
    out = np.full((2, x.shape[1]), np.nan)
    for j, col in enumerate(np.asarray(x, dtype=float).T):
        finite = col[np.isfinite(col)]
        if len(finite) >= CLIP_RUN and np.ptp(finite) > 0:
            out[:, j] = finite.max(), finite.min()
    return out


def noise_sigma(sub: np.ndarray) -> np.ndarray:
    """The wild-value filter's noise standard deviation per column from a subsample of the
    record (every step-th sample, step = max(1, N // 20000)): 1.4826 MAD of the second
    difference, divided by sqrt(1.5); at least 1e-12 of the largest value; 0 for a column
    without finite values."""
    # an all-NaN channel (UNUSABLE later) gets sigma 0 without nanmedian's warning: a
    # process-wide warnings filter would also silence the threads navigating meanwhile
    with np.errstate(all="ignore"):
        d2 = np.abs(sub[1:-1] - 0.5 * (sub[:-2] + sub[2:])) if len(sub) >= 3 else np.abs(sub)
        sigma, top = np.full(sub.shape[1], np.nan), np.full(sub.shape[1], np.nan)
        some = np.isfinite(d2).any(axis=0)
        sigma[some] = 1.4826 * np.nanmedian(d2[:, some], axis=0) / math.sqrt(1.5)
        some = np.isfinite(sub).any(axis=0)
        top[some] = np.nanmax(np.abs(sub[:, some]), axis=0)
        floor = np.maximum(1e-12 * top, _step_noise(sub))
    return np.where(np.isfinite(sigma), np.maximum(sigma, floor), 0.0) + 1e-300


def _step_noise(sub):
    """Per column, the rms of the quantization noise q / sqrt(12) of a column whose values
    sit on a few levels (fewer distinct values than half its samples; q the smallest
    spacing of the distinct values), else 0: a quantized output whose noise is below its
    step has second differences that are mostly 0, and a MAD of 0 would call every step of
    it wild."""
    out = np.zeros(sub.shape[1])
    for j in range(sub.shape[1]):
        col = sub[:, j][np.isfinite(sub[:, j])]
        levels = np.unique(col)
        if 3 <= len(levels) < 0.5 * len(col):
            out[j] = float(np.min(np.diff(levels))) / math.sqrt(12.0)
    return out


def subsample_step(n: int) -> int:
    """The stride of the subsample `noise_sigma` reads from a record of n samples."""
    return max(1, n // 20000)


@dataclass
class RecordStats:
    """What `compensate` needs from a whole record when it sees a block of it: the
    wild-value filter's noise sigma of each raw channel (accel volts, gyro volts,
    temperature, frequency; `noise_sigma`), and the (max, min) of the filtered voltages
    (accel, gyro) for `clipped` (`column_extremes`)."""
    sigma: list
    extremes: list = None
    min_step_ns: int = 0        # the shortest sample interval of the record (margins)

    @classmethod
    def sigma_of_blocks(cls, blocks, n, names):
        """The sigmas from blocks (structured arrays holding the fields `names`) of a record
        of n samples, read once: the same numbers as on the whole record."""
        step, seen, min_step, last = subsample_step(n), 0, None, None
        subs = [[] for _ in names]
        for block in blocks:
            first = (-seen) % step
            for k, name in enumerate(names):      # a copy: a field's strided view would
                # keep the whole block alive (a 2-hour 1 kHz record's every message)
                subs[k].append(np.asarray(block[name], dtype=float)[first::step].copy())
            seen += len(block)
            stamps = block["log_time"].astype(np.int64)
            steps = np.diff(stamps if last is None else np.r_[last, stamps])
            steps = steps[steps > 0]
            if len(steps):
                min_step = int(steps.min()) if min_step is None else min(min_step, int(steps.min()))
            last = int(stamps[-1])
        return cls([noise_sigma(np.concatenate(sub)) for sub in subs],
                   min_step_ns=min_step or 10**6)

    def add_extremes(self, filtered):
        """Fold the filtered voltages of one block (accel, gyro, each (N, 3)) into the
        record's extremes; `finish_extremes` turns them into `column_extremes`' form."""
        if not hasattr(self, "_top"):
            self._top, self._bottom = np.full((2, 3), -np.inf), np.full((2, 3), np.inf)
            self._count = np.zeros((2, 3), int)
        for k, x in enumerate(filtered):
            finite = np.isfinite(x)
            self._top[k] = np.maximum(self._top[k], np.where(finite, x, -np.inf).max(axis=0))
            self._bottom[k] = np.minimum(self._bottom[k], np.where(finite, x, np.inf).min(axis=0))
            self._count[k] += finite.sum(axis=0)

    def finish_extremes(self):
        moving = (self._count >= CLIP_RUN) & (self._top > self._bottom)
        self.extremes = [np.where(moving[k], np.stack([self._top[k], self._bottom[k]]), np.nan)
                         for k in range(2)]


CURVE_REACH = 5      # the wild-value filter's curvature: second differences up to 5 samples away


def wild_value_filter(x: np.ndarray, flags: np.ndarray, n_sigma: float = 6.0,
                      sigma: np.ndarray | None = None) -> np.ndarray:
    """Wild-value (outlier) filter, seed S1 section 3.2 step 1.

    A sample is wild when it is non-finite, or when it disagrees with both linear
    extrapolations from its neighbours, 2 x[k-1] - x[k-2] from the left and 2 x[k+1] - x[k+2]
    from the right (only the available one at the record's ends), by more than
    n_sigma * sqrt(6) noise standard deviations (the extrapolation difference of white noise
    has variance 6 sigma^2), plus twice the local curvature seen without the sample (the
    largest second difference centred 2 to CURVE_REACH samples away on either side), so a
    smooth but fast-changing signal with little noise - a manoeuvre, or an airframe vibration
    sampled a few times a period - is not mistaken for spikes. An isolated spike disagrees with both sides; a
    step or a ramp agrees with one; a spike's neighbours agree with their clean side. Wild samples are
    flagged REPLACED and replaced by linear interpolation between the nearest good samples;
    a channel with no good sample is flagged UNUSABLE.

    The noise standard deviation of each channel is robust and global: 1.4826 MAD of the
    second difference x[k] - (x[k-1] + x[k+1])/2 over the record, divided by sqrt(1.5).
    x (N, 3); returns a filtered copy; flags are updated in place. sigma: the record's
    noise sigma (`noise_sigma`) when x is a block of it."""
    x = np.ascontiguousarray(x, dtype=float)
    out = x.copy()
    if sigma is None:
        sigma = noise_sigma(x[::subsample_step(len(x))])
    wild = find_wild(x, n_sigma * sigma * math.sqrt(6.0))
    for j in np.nonzero(wild.any(axis=0))[0]:
        good = ~wild[:, j]
        if not good.any():
            flags[:] |= UNUSABLE
            continue
        idx = np.arange(len(x))
        out[~good, j] = np.interp(idx[~good], idx[good], x[good, j])
        flags[~good] |= REPLACED
    return out


def find_wild(x: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """The wild samples of x (N, k) as `wild_value_filter` defines them, (N, k) bool, for
    per-column limits (k,): n_sigma * sqrt(6) noise sigmas. Plain numpy, so that `compensate`
    does not pay numba's start-up (about 1 s a process): the rule is evaluated only at the
    candidates - samples whose second difference |x[k] - (x[k-1] + x[k+1]) / 2| exceeds
    limit / 2 (the tolerance is at least the limit), the record's ends, non-finite samples.
    Non-finite second differences of the curvature are left out of its maximum (NaN) or
    make it infinite (inf), and an infinite curvature leaves the tolerance at the limit."""
    n, cols = x.shape
    limit = np.broadcast_to(np.asarray(limit, dtype=float), (cols,))
    wild = ~np.isfinite(x)
    with np.errstate(invalid="ignore", over="ignore"):
        mid = np.full(x.shape, np.inf)                  # the ends are never quiet
        mid[1:-1] = np.abs(x[1:-1] - 0.5 * (x[:-2] + x[2:]))
        k, j = np.nonzero(~(mid <= 0.5 * limit) & ~wild)
        curvature = _curvature_of_all if len(k) > DENSE_CANDIDATES * x.size else _curvature_at
        curve = curvature(x, k, j)
        tol = np.where(np.isfinite(curve), limit[j] + 2.0 * curve, limit[j])

        def at(d):                                      # x[k + d, j], clipped to the record
            return x[np.clip(k + d, 0, n - 1), j]
        v = x[k, j]
        from_left = np.where(k >= 2, 2.0 * at(-1) - at(-2), np.nan)
        from_right = np.where(k <= n - 3, 2.0 * at(1) - at(2), np.nan)
        agree = (np.abs(v - from_left) <= tol) | (np.abs(v - from_right) <= tol)
        some_side = np.isfinite(from_left) | np.isfinite(from_right)
        wild[k, j] = ~(mid[k, j] <= 0.5 * tol) & some_side & ~agree
    return wild


DENSE_CANDIDATES = 1 / 16   # above this share of samples, the curvature of every sample


def _curvature_at(x, k, j):
    """Local curvature seen without x[k, j], at the candidates (k, j): the largest second
    difference centred at k-2 .. k-CURVE_REACH and k+2 .. k+CURVE_REACH - half a period of a
    vibration at a tenth of the sample rate, so a sampled vibration's curvature is seen
    whatever its phase at k - each summed from the sample nearer k outwards; 0 when none
    is finite. From the 2 CURVE_REACH + 3 samples around each candidate."""
    n, cols = x.shape
    r = CURVE_REACH + 1                                 # near[:, r] is the candidate
    near = x.ravel()[np.clip(k[:, None] + np.arange(-r, r + 1), 0, n - 1) * cols + j[:, None]]
    c = np.arange(2, CURVE_REACH + 1)
    left = np.abs(near[:, r + 1 - c] - 2.0 * near[:, r - c] + near[:, r - 1 - c])
    right = np.abs(near[:, r - 1 + c] - 2.0 * near[:, r + c] + near[:, r + 1 + c])
    left[k[:, None] < c + 1] = np.nan                   # centres outside the record
    right[k[:, None] > n - c - 2] = np.nan
    return np.fmax.reduce(np.fmax(left, right), axis=1, initial=0.0)


def _curvature_of_all(x, k, j):
    """`_curvature_at`, from the second differences of the whole record (a record where
    most samples are candidates: a vibrating one), padded with NaN beyond its ends."""
    pad = np.full((CURVE_REACH + 1, x.shape[1]), np.nan)
    inward = np.concatenate([pad, np.abs(x[2:] - 2.0 * x[1:-1] + x[:-2]), pad])
    outward = np.concatenate([pad, np.abs(x[:-2] - 2.0 * x[1:-1] + x[2:]), pad])
    # centre i sits at row i + CURVE_REACH; the window of CURVE_REACH - 1 centres starting
    # at k - CURVE_REACH (left) or k + 2 (right)
    w = CURVE_REACH - 1

    def window_max(d):
        m = d[:len(d) - w + 1]
        for i in range(1, w):
            m = np.fmax(m, d[i:len(d) - w + 1 + i])
        return m
    left = window_max(inward)[k, j]
    right = window_max(outward)[k + CURVE_REACH + 2, j]
    return np.fmax(np.fmax(left, right), 0.0)


def flag_counts(flags: np.ndarray) -> dict[str, int]:
    """Samples flagged REPLACED, SATURATED, UNUSABLE by `compensate`: {name: count}."""
    return {name: int(np.sum(flags & bit > 0)) for name, bit in
            (("replaced", REPLACED), ("saturated", SATURATED), ("unusable", UNUSABLE))}
