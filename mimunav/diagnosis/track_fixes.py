"""The reference track's fixes the IMU's own forces refute. A fix off its neighbours (an RTK
float fix 1.5 m from the fixed ones, a multipath jump) bends the track's course, and the
vehicle model simulated from it turns where the vehicle did not: an independent trial's
drive read "unexplained residual gyro.z 174.0-176.0 s (z -13.4)" at a 1 Hz fix 1.5 m off -
the reference's error charged to the gyro.

The test: a fix's second divided difference of the horizontal positions is the vehicle's
horizontal acceleration averaged under a hat over the two epoch steps around it, exactly;
the IMU's horizontal specific force (its mounting, then the track's course: no side slip)
averaged under the same hat is the same acceleration. Where their difference spikes at a
fix against its neighbours' (`_spikes`) beyond OFF_Z of the spikes' scale over the track
and beyond FIX_FLOOR_M, the fix is refuted and left out of the track the vehicle model
is made of (as an importer drops float fixes).
"""
import numpy as np

from ..frames import attitude, earth
from ..motion.vehicle import TRUSTED_SPEED

OFF_Z = 6.0         # of the spikes' Rayleigh scale (median / 1.1774, a 2-D miss): by
# chance once in 7e7 fixes (exp(-18))
FIX_FLOOR_M = 0.3   # a fix is refuted only off by more than an RTK fix can be: 6 x its 5 cm
# (1 sigma, horizontal) - the RTKLIB drive's 4 Hz RTK track spikes by 0.13 m at most (its
# IMU's jerks and vibration), an independent trial's float fixes (1.5 m) by 0.6-2.8 m
RAYLEIGH_MEDIAN = 1.1774    # sqrt(2 ln 2): a Rayleigh variable's median over its scale
MAX_STEP_S = 2.0        # a longer step between fixes is an outage: no difference across it
MAX_HAT_S = 1.0     # s: a wider hat's half is not judged - the spike of the IMU's own errors
# grows with its square (an independent review: 0.5 Hz fixes, an accelerometer scale of 5 %,
# an 8 m/s^2 stop: an exact fix refuted "0.35 m off")
RELATIVE_SHARE = 0.1    # of the acceleration under the hat: the spike the IMU's own errors can
# make where it changes - a scale of a few %, a mounting yaw up to 5 deg, a lag of 0.1 s
# against the hat (the review's 1 Hz stop, scale 1.10 and 0.1 s late: 0.27 m at most)
HAT_S = 0.5     # s: a hat's half at least, so that the IMU's samples resolve it (25 of a
# 50 Hz IMU) - the vehicle's jerk over it the IMU feels as well


def refuted_fixes(flight):
    """[(t s, how far off m)] of the fixes of flight.truth the IMU's forces refute (module doc),
    each differenced with the fixes `_hat_epochs` (m) away, over those whose steps there are
    within MAX_STEP_S inside the IMU's record; [] for a recording without an imported
    /mimu/imu or with fewer than 10 such fixes."""
    tr, t_imu = flight.truth, flight.mimu_t
    m = _hat_epochs(tr.t) if tr is not None else 0
    if tr is None or flight.mimu_imu is None or len(tr.t) < 4 * m + 10:
        return []
    t = tr.t
    r_n, r_e = earth.radii(float(tr.lat[0]))
    position = np.column_stack([(tr.lat - tr.lat[0]) * (r_n + tr.h),
                                (tr.lon - tr.lon[0]) * (r_e + tr.h) * np.cos(tr.lat)])
    p, k, q = np.arange(len(t) - 2 * m), np.arange(m, len(t) - m), np.arange(2 * m, len(t))
    track = 2 * ((position[q] - position[k]) / (t[q] - t[k])[:, None]
                 - (position[k] - position[p]) / (t[k] - t[p])[:, None]) / (t[q] - t[p])[:, None]
    f = attitude.rotate(flight.mimu_mounting.q_vs, flight.mimu_imu[1])[:, :2]
    turned = _hat_means(t_imu, _turned(f, _course(tr, t_imu)), t[p], t[k], t[q])
    own = _hat_means(t_imu, f, t[p], t[k], t[q])
    longest = np.lib.stride_tricks.sliding_window_view(np.diff(t), 2 * m).max(axis=1)
    usable = (longest <= MAX_STEP_S) & (t[p] >= t_imu[0]) & (t[q] <= t_imu[-1]) & \
        np.isfinite(turned).all(axis=1)
    speed = np.hypot(tr.v_ned[:, 0], tr.v_ned[:, 1])
    slow = np.minimum.reduce([speed[p], speed[k], speed[q]]) <= TRUSTED_SPEED
    miss, judged = _spikes(track - turned, np.hypot(*track.T) - np.hypot(*own.T), slow,
                           usable, m)
    if judged.sum() < 10:
        return []
    half = (t[q] - t[p]) / 2
    judged &= half <= MAX_HAT_S
    off = miss * half ** 2 / 3                      # m: a fix off by e spikes 3 e / H^2
    own = RELATIVE_SHARE * np.hypot(*track.T) * half ** 2 / 3   # what the IMU's own
    limit = max(OFF_Z * np.median(off[judged]) / RAYLEIGH_MEDIAN, FIX_FLOOR_M)  # errors make
    return [(float(t[k[j]]), float(off[j]))
            for j in np.flatnonzero(judged & (off > np.maximum(limit, own)))]


def _spikes(apart, sizes, slow, usable, m):
    """(|spike| m/s^2, judged) per fix: the track's acceleration less the IMU's (`apart`,
    (K, 2) north, east), less the mean of its neighbours' m fixes either side - one fix off
    by e makes e, -2 e, e there (a spike of 3 e), where the IMU's own errors (a mounting's
    tilt leaking gravity, its bias, its scale) and the vehicle's motion change smoothly and
    leave none (the RTKLIB drive's IMU, 6 deg pitched, read 1 m/s^2 beside its track).
    Where the vehicle is slower than TRUSTED_SPEED about a fix its course is no heading:
    the sizes of the two forces (`sizes`: the track's less the IMU's in its own frame),
    whose spike a fix off by e makes 1 to 3 times smaller: a fix is refuted there less
    readily."""
    both = usable[:-2 * m] & usable[m:-m] & usable[2 * m:]
    slow3 = slow[:-2 * m] | slow[m:-m] | slow[2 * m:]
    spike = apart[m:-m] - (apart[:-2 * m] + apart[2 * m:]) / 2
    size_spike = sizes[m:-m] - (sizes[:-2 * m] + sizes[2 * m:]) / 2
    miss = np.where(slow3, np.abs(size_spike), np.hypot(*spike.T))
    pad = np.zeros(m, bool)
    return np.concatenate([pad * 1.0, miss, pad * 1.0]), np.concatenate([pad, both, pad])


def _hat_epochs(t):
    """Epoch steps each side of a fix's hat: the fewest that span HAT_S (s) - at a track's
    100 Hz the IMU's own samples (50 Hz) cannot resolve a hat of two steps, and the second
    difference of its positions amplifies their noise by 1/dt^2 (a 100 Hz ground truth had
    7 of 24000 epochs refuted, none off)."""
    return max(1, int(np.ceil(HAT_S / float(np.median(np.diff(t))) - 1e-9)))


def _turned(f, course):
    """(N, 2): the vehicle frame's horizontal force f (forward, right; (N, 2)) north and
    east, the vehicle heading along `course` (rad, clockwise from north: no side slip)."""
    c, s = np.cos(course), np.sin(course)
    return np.column_stack([c * f[:, 0] - s * f[:, 1], s * f[:, 0] + c * f[:, 1]])


def _course(tr, t):
    """rad from north, clockwise: the track's course at times t (s), its velocities
    interpolated (at rest, whatever their noise says: the force there is small)."""
    return np.arctan2(np.interp(t, tr.t, tr.v_ned[:, 1]), np.interp(t, tr.t, tr.v_ned[:, 0]))


def _hat_means(t, x, p, m, q):
    """(K, 2): the means of x (samples at stamps t, s, each its interval's) under the hats
    from p up to m and down to q (s, (K,) each), area 1 - the weight the second divided
    difference of positions at those times puts on the acceleration."""
    dt = np.diff(t, prepend=t[0] - (t[1] - t[0]))
    a0 = np.vstack([np.zeros(2), np.cumsum(x * dt[:, None], axis=0)])
    a1 = np.vstack([np.zeros(2), np.cumsum(x * ((t - dt / 2) * dt)[:, None], axis=0)])
    edges = np.concatenate([[t[0] - dt[0]], t])

    def at(cumulative, s):
        return np.column_stack([np.interp(s, edges, cumulative[:, j]) for j in range(2)])
    p, m, q = p[:, None], m[:, None], q[:, None]
    rising = (at(a1, m[:, 0]) - at(a1, p[:, 0])) - p * (at(a0, m[:, 0]) - at(a0, p[:, 0]))
    falling = q * (at(a0, q[:, 0]) - at(a0, m[:, 0])) - (at(a1, q[:, 0]) - at(a1, m[:, 0]))
    half = (q - p) / 2
    return rising / ((m - p) * half) + falling / ((q - m) * half)


def worst_of_runs(fixes):
    """Of `refuted_fixes`, the one off most in each run of neighbouring ones (within
    MAX_STEP_S): a fix off by e spikes its neighbours' differences too, by half as much."""
    runs = []
    for fix in fixes:
        if runs and fix[0] - runs[-1][-1][0] <= MAX_STEP_S:
            runs[-1].append(fix)
        else:
            runs.append([fix])
    return [max(run, key=lambda f: f[1]) for run in runs]


def without_refuted(tr, fixes, differenced):
    """The trajectory `tr` without the fixes (`worst_of_runs`), its velocities differenced
    again where they were central differences of the positions (`differenced`): the
    neighbours' had been made with the fix left out."""
    from ..motion.track import velocity_from_positions
    if not fixes:
        return tr
    kept = tr[~np.isin(tr.t, [t for t, _ in fixes])]
    if differenced and len(kept.t) >= 3:
        kept.v_ned = velocity_from_positions(np.round((kept.t - kept.t[0]) * 1e9).astype(
            np.int64), kept.lat, kept.lon, kept.h)
    return kept
