"""IMU outputs as interval means - the log contract's meaning of a sample: the mean over the
interval that ends at its stamp. Their intervals' edges (`intervals`) and the exact running
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

    def means(self, times):
        """The outputs re-expressed as means over the intervals (times[k-1], times[k]] (s,
        (M,) increasing; the first repeats the second): exact where times and edges meet,
        the interval-mean meaning kept where they do not."""
        area = self.once(np.asarray(times, float))
        out = np.diff(area, axis=0) / np.diff(times)[:, None]
        return np.vstack([out[:1], out])
