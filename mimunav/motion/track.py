"""A GNSS track's velocity from its positions (central differences in NED, m/s).
"""
import numpy as np

from ..frames import earth


# a position difference across a longer gap is no velocity (a car turns in 2 s; a few lost
# epochs at 4-10 Hz still difference well)
VELOCITY_GAP_EPOCHS, VELOCITY_GAP_S = 5, 2.0


def velocity_from_positions(ns, lat, lon, h):
    """NED velocity (m/s, (M, 3)), each epoch's in its own local NED, of geodetic positions
    (rad, rad, m) at stamps ns (int ns): central differences of the ECEF positions over the
    neighbouring epochs (one-sided at the ends), turned into the epoch's NED; NaN where a
    neighbour lies more than VELOCITY_GAP_EPOCHS median epoch intervals and VELOCITY_GAP_S
    away (no velocity across a gap: the rows to leave out of a reference). (Differences in
    the first epoch's NED had tilted the velocity by the distance travelled over the Earth's
    radius: 0.1 m/s north and down at 25 km of a 25 m/s drive east.)"""
    t = (np.asarray(ns, np.int64) - int(ns[0])) / 1e9
    v_e = np.gradient(earth.geodetic_to_ecef(lat, lon, h), t, axis=0)
    v = np.einsum("kji,kj->ki", earth.ned_to_ecef_matrix(lat, lon), v_e)
    dt = np.diff(t)
    wide = dt > max(VELOCITY_GAP_EPOCHS * np.median(dt), VELOCITY_GAP_S)
    v[np.concatenate([[False], wide]) | np.concatenate([wide, [False]])] = np.nan
    return v


def white_noise(x):
    """The white noise (1 sigma) of a series x (N,) or of each of its columns together
    (N, k), epoch to epoch: its second differences' MAD, each column less its median
    (1.4826 MAD; a second difference of white noise has 6 times its variance) - a slow
    motion cancels in them, so what is left is the noise (an upper bound where the motion
    turns sharply between epochs); 0 for fewer than 5 epochs."""
    x = np.asarray(x, float)
    if len(x) < 5:
        return 0.0
    d2 = x[2:] - 2 * x[1:-1] + x[:-2]
    return 1.4826 * float(np.median(np.abs(d2 - np.median(d2, axis=0)))) / 6 ** 0.5
