"""The specific force a lever arm adds between two points of one rigid vehicle, and the arm
fitted to it: dw/dt x r + w x (w x r) (r from the point that feels the less to the one that
feels the more, vehicle frame), in the 1 s means the import's checks compare (`pairing`:
two IMUs; `trajectory_point`: an IMU and its reference trajectory's point).
"""
import numpy as np

from .series import window_means

ARM_BLOCKS = 20     # consecutive blocks of the seconds an arm's error is jackknifed over


def lever_force(ns, w_v, mids, r, half=0.5):
    """(M, 3) m/s^2, vehicle frame: means over [mid - half, mid + half] (s, `mids`) of
    dw/dt x r + w x (w x r) at an IMU's rates w_v (rad/s, vehicle frame, at its stamps ns)
    sample by sample (dw/dt's mean: the rate's change across), r in m. Of 1 s mean rates, a
    foot's strides (+-10 rad/s, 6 cm) lost w x (w x r) and turned an exact mounting 6.6 deg."""
    r = np.asarray(r, float)
    if not np.any(r):
        return np.zeros((len(mids), 3))
    t = ns / 1e9
    edges = [np.column_stack([np.interp(mids + side, t, w_v[:, i]) for i in range(3)])
             for side in (-half, half)]
    return np.cross((edges[1] - edges[0]) / (2 * half), r) + \
        window_means(ns, np.cross(w_v, np.cross(w_v, r)), mids, half)


def unit_forces(ns, w_v, mids):
    """(M, 3, 3): `lever_force` of the three unit arms (the last axis), m/s^2 per m - the
    design an arm is fitted on (the force is linear in r)."""
    return np.stack([lever_force(ns, w_v, mids, r) for r in np.eye(3)], axis=2)


def arm_cov(design, gap):
    """(k, k): the covariance of the least-squares arm (m^2) of `gap` (3 M,) on `design` (3 M,
    k: the arm's 3 columns, then any others; rows the seconds' three axes), jackknifed over
    ARM_BLOCKS consecutive blocks of the seconds (the 1 s means' misfit is correlated over
    seconds: its white formula had given a motorcycle's arm 0.5 mm where it lay 26 mm
    off)."""
    n = len(gap) // 3
    block = np.repeat(np.minimum(np.arange(n) * ARM_BLOCKS // n, ARM_BLOCKS - 1), 3)
    parts = np.array([np.linalg.lstsq(design[block != b], gap[block != b], rcond=None)[0]
                      for b in range(ARM_BLOCKS)])
    centred = parts - parts.mean(axis=0)
    return (ARM_BLOCKS - 1) / ARM_BLOCKS * centred.T @ centred + 1e-12 * np.eye(len(centred.T))


def lever_force_samples(ns, w_v, r):
    """(N, 3) m/s^2, vehicle frame: dw/dt x r + w x (w x r) at each of an IMU's samples (rates
    w_v rad/s, vehicle frame, at its stamps ns; dw/dt their central differences), r in m -
    for means over a few samples (`course_check.local_mean`)."""
    r = np.asarray(r, float)
    if not np.any(r) or len(ns) < 2:
        return np.zeros((len(ns), 3))
    dw = np.gradient(w_v, ns / 1e9, axis=0)
    return np.cross(dw, r) + np.cross(w_v, np.cross(w_v, r))
