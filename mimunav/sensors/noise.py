"""Sensor noise in physical units (IEEE Std 952-1997 terms).

white(N): rate noise of density N (e.g. rad/s/sqrt(Hz) = rad/sqrt(s), the angle random
walk); interval means at rate fs have standard deviation N sqrt(fs); Allan deviation
N / sqrt(tau).
flicker(B): bias instability with two-sided PSD S(f) = B^2 / (2 pi f) (IEEE 952 PSDs are
two-sided: white noise S = N^2 gives sigma(tau) = N / sqrt(tau)), whose Allan deviation is
flat at B sqrt(2 ln 2 / pi) = 0.664 B; generated in the frequency domain as shaped white
noise (`flicker_axes`; the PSD from 1/(4 x record length) to Nyquist, FLICKER_SPAN).
"""
import math
import os

import numpy as np

FLICKER_ADEV = math.sqrt(2 * math.log(2) / math.pi)     # 0.664: ADEV floor / B


def white(rng, n, rate_hz, density):
    """Interval means of white noise, shape (n, len(density)); density per sqrt(Hz)."""
    density = np.atleast_1d(np.asarray(density, dtype=float))
    x = rng.standard_normal((n, len(density)))
    x *= density
    x *= math.sqrt(rate_hz)
    return x


def flicker(rng, n, rate_hz, b):
    """Flicker (1/f) bias of instability coefficient b (per axis), shape (n, len(b)).

    Two-sided PSD b^2 / (2 pi f), i.e. one-sided b^2 / (pi f), for 1/(FLICKER_SPAN n dt)
    <= f <= fs/2 (`flicker_axes`)."""
    b = np.atleast_1d(np.asarray(b, dtype=float))
    out = np.empty((n, len(b)))
    for i, x in enumerate(flicker_axes(rng, n, rate_hz, b)):
        out[:, i] = x
    return out


# 1/f wander extends below any record; a record's flicker is made from 1 / (FLICKER_SPAN x
# its length) up: slower wander is a near-constant offset over it, which the sensor models
# draw as the turn-on bias and the calibration's fits absorb in their bias (their flicker
# covariance, `calibration.flicker_covariance`, starts at the same frequency)
FLICKER_SPAN = 4


def synthesis_length(n):
    """The period m of the synthesis behind a record of n samples (`flicker_axes`): the
    least even length >= 2n that the FFT takes fast (`scipy.fft.next_fast_len`: no prime
    factor above 5)."""
    from scipy import fft           # here: 0.6 s of import that commands without noise skip
    m = fft.next_fast_len(2 * max(n, 1), real=True)
    while m % 2:
        m = fft.next_fast_len(m + 1, real=True)
    return m


def flicker_axes(rng, n, rate_hz, b):
    """`flicker`, one axis at a time (an iterator of (n,) arrays): a long record needs
    about 4 x 8 n bytes of work memory per axis, not per triad.

    The first n samples of `flicker_periods` over m = `synthesis_length(n)` >= 2n samples:
    a line spectrum whose lowest line, at fs/m ~ 1/(2 T) for a record of length T, stands
    for the band from 1/(FLICKER_SPAN T) = 1/(4 T) (the midpoint rule: the line spacing is
    1/(2 T)). Why m >= 2n: the synthesis makes a process of period m, and a record that is
    nearly a whole period has its end drawn back to its start - with m = n, or the next
    power of two >= n used before (1.006 n for 16 284 samples), the bias wandered from the
    record's first tenth to its last by 0.67 of what the PSD from 1/(4 T) says (0.61 of the
    PSD extended to 0). With m ~ 2n: 1.025 of the PSD from 1/(4 T) (expected, from the line
    spectrum; 0.95 of the PSD extended to 0, whose rest is what FLICKER_SPAN leaves to the
    turn-on bias); tests/test_sensors.py checks it."""
    m = synthesis_length(n)
    for x in flicker_periods(rng, m, b):
        yield x[:n].astype(float)


def flicker_periods(rng, m, b):
    """One period of m samples (m even) of periodic flicker noise of instability b per axis
    (an iterator of (m,) float32 arrays): two-sided PSD b^2 / (2 pi f) at every frequency
    k fs/m, k = 1 .. m/2, none at 0 - the same samples at any rate fs (flicker's Allan
    deviation does not depend on the averaging time).

    The spectrum of white noise of unit one-sided PSD (variance fs/2 per sample) is drawn
    directly - its discrete Fourier transform's bins are independent complex normals of mean
    square m fs/2 (real at the Nyquist bin) - shaped by sqrt(S) and transformed back, in
    single precision (relative error ~1e-7 of a noise, far below any ADC step)."""
    if m % 2:
        raise ValueError(f"flicker_periods: m = {m} must be even (a real Nyquist bin)")
    # per part of bin k (f_k = k fs / m): sqrt(m fs/2 x S1(f_k) / 2) with the one-sided
    # S1 = b^2 / (pi f) = 2 x the two-sided PSD: m b / sqrt(4 pi k), fs cancels
    amp = np.arange(m // 2 + 1, dtype=np.float32)
    amp[0] = np.inf                                             # no power at f = 0
    np.divide(np.float32(m), np.sqrt(np.float32(4 * math.pi) * amp), out=amp)
    amp[-1] *= np.float32(math.sqrt(2))                         # the real Nyquist bin
    for b_i in np.atleast_1d(np.asarray(b, dtype=float)):
        spec = rng.standard_normal(2 * len(amp), dtype=np.float32).view(np.complex64)
        spec.imag[-1] = 0.0
        spec *= amp
        spec *= float(b_i)               # a Python float: the product stays complex64
        yield np.fft.irfft(spec, n=m)


class TriadNoise:
    """White plus flicker noise of a sensor triad over a record of n samples at rate_hz,
    taken block by block in order (`take`): the white part drawn as it is taken from its own
    generator, the flicker part shaped over the whole record once (`flicker_axes`), kept in
    files of `folder` when given (read back block by block, so a long record's noise does
    not stay in memory). The same generators give the same noise however the record is cut
    into blocks."""

    def __init__(self, rng, n, rate_hz, white_density, flicker_b, folder=None):
        white_rng, flicker_rng = rng.spawn(2)
        self.white_rng, self.rate_hz, self.n = white_rng, rate_hz, n
        self.density = np.full(3, float(white_density))
        self.pos, self.flicker, self.files = 0, None, None
        if not flicker_b:
            return
        if folder is None:
            self.flicker = flicker(flicker_rng, n, rate_hz, [flicker_b] * 3)
            return
        self.files = []
        for i, x in enumerate(flicker_axes(flicker_rng, n, rate_hz, [flicker_b] * 3)):
            path = os.path.join(folder, f"flicker-{id(self)}-{i}.f64")
            x.tofile(path)
            self.files.append(path)

    def take(self, k):
        """The next k samples' noise, (k, 3)."""
        if self.pos + k > self.n:
            raise ValueError(f"noise of a {self.n}-sample record: {self.pos + k} taken")
        x = white(self.white_rng, k, self.rate_hz, self.density)
        if self.flicker is not None:
            x += self.flicker[self.pos:self.pos + k]
        elif self.files:
            for i, path in enumerate(self.files):
                x[:, i] += np.fromfile(path, dtype=float, count=k, offset=8 * self.pos)
        self.pos += k
        return x


def quantize(x, step, out=None):
    """Round x to a multiple of step (no-op for step 0); out: the array to write (may be
    x itself), else a new one."""
    if step == 0:
        return x if out is None else np.copyto(out, x) or out
    q = np.divide(x, step, out=out)
    np.rint(q, out=q)                   # numpy's round to 0 decimals
    q *= step
    return q


def quantize_increments(x, step, carry=None):
    """Quantize interval increments as a pulse counter does: the running sum is quantized
    and the residual carried, so no quantization error accumulates. x (n, k). carry: a dict
    holding the running sum ("sum") and its quantized value ("total") between the blocks of
    one record (updated), or None for a whole record."""
    if step == 0:
        return x
    start, counted = ((np.zeros(x.shape[1]), np.zeros(x.shape[1])) if carry is None or
                      "sum" not in carry else (carry["sum"], carry["total"]))
    running = np.cumsum(np.vstack([start, x]), axis=0)[1:]    # the same sums as one cumsum
    total = np.floor(running / step + 0.5) * step
    if carry is not None and len(x):
        carry["sum"], carry["total"] = running[-1], total[-1]
    return np.diff(total, axis=0, prepend=counted[None, :])
