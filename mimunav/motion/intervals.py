"""IMU outputs as interval means - the log contract's meaning of a sample: the mean over the
interval that ends at its stamp. Instantaneous samples made such means (`means_of_instants`);
their intervals' edges (`intervals`) and the exact running
integral of such piecewise-constant outputs (`RunningIntegral`), through which outputs are
re-expressed over another IMU's intervals (`RunningIntegral.means`) or sampled as a
velocity track samples its own.
"""
import numpy as np


def intervals(t):
    """Of an IMU's stamps t (s, (N,)): each output's interval (s; the first as the median
    step), its span in the integral (the interval, but no longer than a neighbour's: a
    gap's length is no output's interval) and the intervals' edges (N + 1,)."""
    step = np.diff(t, prepend=t[0] - float(np.median(np.diff(t))))
    around = np.maximum(np.concatenate([step[1:2], step[:-1]]),
                        np.concatenate([step[1:], step[-1:]]))
    return step, np.minimum(step, around), np.concatenate([[t[0] - step[0]], t])


def means_of_instants(t, x, raw=None):
    """Instantaneous samples x (N, k) at stamps t (s) as the means over the intervals centred
    on them: x + T^2 x'' / 24 with x'' by central differences, (x[k-1] + 22 x[k] + x[k+1])
    / 24 - exact for motion quadratic over three samples, where the sample itself is the
    mean only to second order
    (off by x'' T^2 / 24: a 2 Hz swing sampled at 200 Hz, 1.6e-4 of its amplitude, read as a
    scale factor). Rows whose neighbours are not an even step away (within 1 %), the first
    and the last, and rows beside a `raw` (N,) bool row (a clipped output: its true value is
    unknown) stay as they are."""
    out = np.array(x, float, copy=True)
    if len(t) < 3:
        return out
    step = np.diff(t)
    even = np.abs(step[1:] / step[:-1] - 1.0) < 0.01
    if raw is not None:
        even &= ~(raw[:-2] | raw[1:-1] | raw[2:])
    inner = np.flatnonzero(even) + 1
    out[inner] = (x[inner - 1] + 22.0 * x[inner] + x[inner + 1]) / 24.0
    return out


class RunningIntegral:
    """The running integral of piecewise-constant outputs x (N, k), x[j] over (edges[j],
    edges[j + 1]], from 0 at edges[0], exactly: `once` (piecewise linear) and `twice` (its
    own integral, piecewise quadratic) at any times; beyond the edges the first and the last
    output go on."""

    def __init__(self, edges, x):
        self.edges, self.x = edges, x
        step = np.diff(edges)[:, None]
        self.area = np.vstack([np.zeros(x.shape[1]), np.cumsum(x * step, axis=0)])
        self.volume = np.vstack([np.zeros(x.shape[1]), np.cumsum(
            0.5 * (self.area[:-1] + self.area[1:]) * step, axis=0)])

    def _at(self, times):
        """(segment start index j, time s since edges[j], output over the segment)."""
        j = np.clip(np.searchsorted(self.edges, times, side="right") - 1, 0,
                    len(self.edges) - 1)
        x = self.x[np.minimum(j, len(self.x) - 1)]
        return j, (times - self.edges[j])[:, None], x

    def once(self, times):
        j, s, x = self._at(times)
        return self.area[j] + x * s

    def twice(self, times):
        j, s, x = self._at(times)
        return self.volume[j] + self.area[j] * s + 0.5 * x * s * s

    def smooth_once(self, times):
        """`once` through a cubic spline of the integral's values at the edges where the
        edges around stand a regular step apart (elsewhere, and beyond them, `once`): the
        same at every edge, and between edges of smooth motion exact to fourth order where
        `once` is to second - its straight lines between edges cut a sinusoid's mean over
        an interval whose ends fall between them by w'' a (1 - a) h^2 / 2 (a 2 Hz, 250
        deg/s rate-table swing seen by a 400 Hz reference a 5th of a step off: 1.2e-4 of
        the rate, read as a scale factor)."""
        from scipy.interpolate import CubicSpline
        times = np.asarray(times, float)
        out = self.once(times)
        step = np.diff(self.edges)
        if len(step) < 4:
            return out
        regular = np.abs(step / np.median(step) - 1.0) < 0.5
        j = np.searchsorted(self.edges, times, side="right") - 1
        near = np.ones(len(times), bool)
        for k in range(-2, 3):
            i = j + k
            near &= (i >= 0) & (i < len(step)) & regular[np.clip(i, 0, len(step) - 1)]
        if near.any():
            out[near] = CubicSpline(self.edges, self.area)(times[near])
        return out

    def means(self, times, smooth=False):
        """The outputs re-expressed as means over the intervals (times[k-1], times[k]] (s,
        (M,) increasing; the first repeats the second): exact where times and edges meet,
        and between them for piecewise-constant outputs; smooth: between them through
        `smooth_once` (outputs that are means of smooth motion)."""
        times = np.asarray(times, float)
        area = self.smooth_once(times) if smooth else self.once(times)
        out = np.diff(area, axis=0) / np.diff(times)[:, None]
        return np.vstack([out[:1], out])
