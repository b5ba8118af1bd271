"""A GNSS track's velocity from its positions (central differences in NED, m/s), its white
noise, and the epochs where its positions step off its own velocity (`position_jumps`).
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


JUMP_Z = 8.0        # robust sigmas of the track's own steps off its velocity: by chance
#                     once in 1e15 epochs of Gaussian noise; a heavy tail's (an RTK fix lost
#                     and regained) steps beyond it are what a window should not span
JUMP_FLOOR_M = 0.01     # m: a finer step is no jump whatever its sigmas - a simulated or
#                     exact track's steps are 1e-6 m and smaller (trapezoid on 100 Hz), and a
#                     centimetre is below what any free-inertial window of a MEMS unit resolves
JUMP_SPAN_S = 0.5     # s either side of a step: the net miss judged over it (at least a step)
JUMP_GAP_STEPS = 2.5    # a step longer than this many median steps is a missed epoch, not
#                     judged (`flightlog.stamps.missed_spans` leaves windows off them)


def position_jumps(t, lat, lon, h, v_ned):
    """[(t s, m)]: the epochs where a track's position steps off what its own velocity
    carries it - the step's miss of the velocity's Hermite quadrature over it,
        dp - (v0 + v1) dt / 2 - (a0 - a1) dt^2 / 12,    a = dv/dt (central differences),
    its end accelerations from the velocities' central differences - far closer than the
    trapezoid alone in smooth motion (which misses dt^3 jerk / 12: 0.3 m on a 1 Hz track
    braking; tests/motion/test_position_jumps.py), per NED axis against its robust sigma over the track (1.4826
    MAD; the horizontal and the vertical of a GNSS fix err differently), beyond JUMP_Z of it
    and beyond JUMP_FLOOR_M in size. An INS's position jumping back to its fixes after an
    outage, with a velocity that never jumped, steps by the whole jump (an independent trial's
    2.3 m at one 100 Hz epoch); a velocity differenced from the positions
    (`velocity_from_positions`) halves it. t s; lat, lon rad; h m; v_ned m/s (M, 3), each
    epoch's in its own NED; steps across a missed epoch (JUMP_GAP_STEPS) or with a
    non-finite end are not judged; [] for fewer than 10 steps judged."""
    t, v_ned = np.asarray(t, float), np.asarray(v_ned, float)
    if len(t) < 12:
        return []
    to_ecef = earth.ned_to_ecef_matrix(lat, lon)
    v = np.einsum("kij,kj->ki", to_ecef, v_ned)
    a = np.gradient(v, t, axis=0)
    dt = np.diff(t)[:, None]
    miss = np.diff(earth.geodetic_to_ecef(lat, lon, h), axis=0) \
        - (v[1:] + v[:-1]) * dt / 2 - (a[:-1] - a[1:]) * dt ** 2 / 12
    miss = np.einsum("kji,kj->ki", to_ecef[1:], miss)          # in the step's end's NED
    judged = np.isfinite(miss).all(axis=1) & \
        (dt[:, 0] <= JUMP_GAP_STEPS * float(np.median(dt)))
    if judged.sum() < 10:
        return []
    miss[~judged] = 0.0
    # the net miss of the steps within JUMP_SPAN_S either side: a stamp late by d misses by
    # v d into its epoch and by -v d out of it (an independent trial's 1 % of stamps 4-6.5 ms
    # late: 0.1 m each at 20 m/s), a noisy fix off and back (a light aircraft's altitude
    # +-2 m epoch to epoch), and the track does not stay off; a jump does
    m = max(1, round(JUMP_SPAN_S / float(np.median(dt))))
    total = np.vstack([np.zeros(3), np.cumsum(miss, axis=0)])
    net = np.zeros_like(miss)
    if len(miss) > 2 * m:
        net[m:-m] = total[2 * m + 1:] - total[:-2 * m - 1]
    size = np.linalg.norm(miss, axis=1)
    jump = judged & _beyond(miss, judged) & _beyond(net, judged)
    # one jump, one step: the largest miss within the span (a late stamp beside it is not)
    widest = np.lib.stride_tricks.sliding_window_view(
        np.pad(size, m, constant_values=0.0), 2 * m + 1).max(axis=1)
    jump &= size >= widest
    return [(float(t[k + 1]), float(size[k])) for k in np.flatnonzero(jump)]


def _beyond(x, judged):
    """(K,) bool: the rows of x (K, 3) off the median of the `judged` rows by more than JUMP_Z
    of their robust sigma (1.4826 MAD) on an axis, and by more than JUMP_FLOOR_M in size."""
    centre = np.median(x[judged], axis=0)
    sigma = 1.4826 * np.median(np.abs(x[judged] - centre), axis=0)
    off = np.abs(x - centre) > JUMP_Z * sigma           # an exact track's sigma is 0
    return off.any(axis=1) & (np.linalg.norm(x - centre, axis=1) > JUMP_FLOOR_M)
