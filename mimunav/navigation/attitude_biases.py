"""The biases of an IMU without a rest, from a reference that carries the vehicle's attitude
(a fused pose, an autopilot's estimate): what the IMU measured over windows between the
reference's epochs less what the reference's attitude and velocity say it should have
(Titterton & Weston 2004, eq. 3.70), with the lever arm's terms and gravity averaged over
each window; `navigation.alignment` takes them where a recording has no rest.
"""
import math

import numpy as np
from scipy.spatial.transform import Rotation

from ..frames import attitude, earth


ATTITUDE_BIAS_WINDOW_S = 1.0    # s: windows of the gyro bias from a reference attitude
MIN_ATTITUDE_BIAS_WINDOWS = 10
WINDOW_TURN = 0.35      # rad the IMU's attitude spans in a window, at most (a car's 20
#                         deg/s turn; `_turned`): the window's attitude at mid-window stands
#                         for its others to half that, and its rates' axis holds - a swinging
#                         foot turns
#                         3 rad a second, and its 'biases' had read 8 deg/s and 4.6 m/s^2 with
#                         standard errors of 1 deg/s and 22 mg


def biases_from_attitude(t, w, f, mounting, track, window=ATTITUDE_BIAS_WINDOW_S):
    """The gyro and accelerometer biases (rad/s, m/s^2, sensor axes) of a recording without
    a rest whose reference carries the vehicle attitude (a fused pose, an autopilot's
    estimate): per window [a, b] between the reference's own epochs (about `window` s), the
    IMU's mean rate w and specific force f (sensor axes, stamps t s: the samples ending in
    (a, b]) less what the reference says they were:
        rate   C_sb (rotvec(q_nb(a)^-1 q_nb(b)) / (b - a) + C_bn (w_ie^n + w_en^n))
        force  C_sb C_bn ((v(b) - v(a)) / (b - a) + (2 w_ie^n + w_en^n) x v - g^n)
    (T&W eq. 3.70; C_bn at mid-window); the median over the windows and its standard error
    (1.2533 x the MAD-based sigma / sqrt n), over the windows the IMU turns through less
    than WINDOW_TURN in. Returns ((gyro bias, se), (accel bias, se), windows) or None without
    MIN_ATTITUDE_BIAS_WINDOWS windows of known attitude."""
    q = track.get("q_nb")
    if q is None:
        return None
    inside = np.isfinite(q).all(axis=1) & (track["t"] >= t[0]) & (track["t"] <= t[-1])
    t_q = track["t"][inside]
    if len(t_q) < 2:
        return None
    # windows between the reference's own epochs (no interpolated attitude)
    step = max(1, int(round(window / np.median(np.diff(t_q)))))
    a, b = slice(0, len(t_q) - step, step), slice(step, len(t_q), step)
    rot = attitude.as_scipy(attitude.from_wxyz(np.asarray(q)[inside]))
    r_a, span = rot[a], t_q[b] - t_q[a]
    w_nb = (r_a.inv() * rot[b]).as_rotvec() / span[:, None]      # vehicle axes
    edges = t_q[a]
    mid = 0.5 * (edges + t_q[b])
    lat, h = (np.interp(mid, track["t"], track[k]) for k in ("lat", "h"))
    v = np.column_stack([np.interp(mid, track["t"], track["v_ned"][:, i]) for i in range(3)])
    w_ie, w_en = earth.earth_rate_ned(lat), earth.transport_rate_ned(lat, h, v)
    if not track.get("heading_known", True):    # its north is not true north: the Earth
        w_ie[..., :2] = 0.0                     # rate's horizontal part is left in
    # C_nb(mid) = C_nb(a) R(w_nb span / 2) (body-frame turn), so C_bn(mid) = R(-..) C_bn(a)
    c_bn_mid = Rotation.from_rotvec(-0.5 * w_nb * span[:, None]) * r_a.inv()
    rate = w_nb + c_bn_mid.apply(w_ie + w_en)
    v_ref = np.asarray(track["v_ned"], float)[inside]
    force = c_bn_mid.apply((v_ref[b] - v_ref[a]) / span[:, None]
                           + np.cross(2 * w_ie + w_en, v)) \
        - _mean_gravity_body(rot, t_q, step, earth.gravity_ned(lat, h))
    k0, k1 = np.searchsorted(t, edges, side="right"), np.searchsorted(t, t_q[b], side="right")
    use = (k1 - k0 >= 2) & (_turned(t, w, k0, k1) <= WINDOW_TURN)
    if use.sum() < MIN_ATTITUDE_BIAS_WINDOWS:
        return None
    q_sv = np.conjugate(mounting.q_vs)

    def window_means(x):
        c = np.vstack([np.zeros((1, 3)), np.cumsum(x, axis=0)])
        return (c[k1[use]] - c[k0[use]]) / (k1[use] - k0[use])[:, None]

    def median_difference(x, predicted):
        d = window_means(x) - attitude.rotate(q_sv, predicted[use])
        bias = np.median(d, axis=0)
        sigma = 1.4826 * np.median(np.abs(d - bias), axis=0)
        return bias, 1.2533 * sigma / math.sqrt(len(d))
    # the IMU sits at the lever arm r from the reference's point: it also feels
    # dw/dt x r + w x (w x r) (vehicle axes, from the IMU's own rates: the window's mean
    # dw/dt is the rate's change across it) - a boat rolling 11 deg with r 1.4 m had left
    # 0.013 m/s^2 on accel.z, the centripetal mean, and the tangential's median over
    # windows of a roll does not vanish either
    w_v = attitude.rotate(mounting.q_vs, w)
    r = mounting.lever_arm_m
    force = np.array(force)
    turn = (_rate_at(t, w_v, t_q[b][use]) - _rate_at(t, w_v, edges[use])) / span[use, None]
    force[use] += window_means(np.cross(w_v, np.cross(w_v, r))) + np.cross(turn, r)
    return median_difference(w, rate), median_difference(f, force), int(use.sum())


def _turned(t, w, k0, k1):
    """(n,) rad: how far the attitude strays within each window of samples (k0, k1]: twice
    the largest angle of the rates w (N, 3, rad/s, stamps t s) integrated from the window's
    mean attitude (small angles) - a steady turn's whole angle, a vibration's few mrad (the
    mean |w| had counted an engine's 0.3 rad/s rms of vibration, 0.8 mrad of angle, as a
    turn and every window had been left out); nan for an empty window."""
    dt = np.diff(t, prepend=t[0] - (t[1] - t[0] if len(t) > 1 else 0.0))
    angle = np.cumsum(w * dt[:, None], axis=0)
    out = np.full(len(k0), np.nan)
    size = k1 - k0
    full = np.flatnonzero(size > 0)
    if not len(full):
        return out
    window = np.repeat(full, size[full])
    rows = np.concatenate([np.arange(k0[j], k1[j]) for j in full])
    sums = np.zeros((len(k0), 3))
    np.add.at(sums, window, angle[rows])
    stray = np.linalg.norm(angle[rows] - sums[window] / size[window, None], axis=1)
    most = np.zeros(len(k0))
    np.maximum.at(most, window, stray)
    out[full] = 2.0 * most[full]
    return out


def _mean_gravity_body(rot, t_q, step, g_n):
    """(n, 3) m/s^2: gravity g_n (n, 3, NED) in the body axes averaged over each window of
    `step` reference epochs t_q (s; attitudes rot, body -> NED), over its epochs - by
    Simpson's rule where they are even in number of steps and evenly spaced, else the
    trapezoid's: at the window's mid-rotation alone a hull rolling 2.6 deg at 6 s was off by
    g phi'' span^2 / 12 = 0.04 m/s^2 in 1 s windows, by the trapezoid over 10 Hz epochs
    4e-4."""
    starts = np.arange(0, len(t_q) - step, step)[:len(g_n)]
    times = t_q[starts[:, None] + np.arange(step + 1)]
    steps = np.diff(times, axis=1)
    if step % 2 == 0 and np.allclose(steps, steps[:, :1], rtol=1e-3):
        weights = np.tile(np.r_[1.0, np.tile([4.0, 2.0], step // 2)[:-1], 1.0] / (3 * step),
                          (len(starts), 1))
    else:
        padded = np.pad(steps, ((0, 0), (1, 1)))
        weights = 0.5 * (padded[:, :-1] + padded[:, 1:]) / steps.sum(axis=1, keepdims=True)
    out = np.zeros((len(starts), 3))
    for j in range(step + 1):
        out += rot[starts + j].inv().apply(g_n) * weights[:, j:j + 1]
    return out


def _rate_at(t, w, epochs, reach=2):
    """The rates w (N, 3) at the epochs (s): the mean of the 2 reach + 1 samples of stamps t
    (s) nearest each (an interval mean's stamp ends its interval: half a sample late)."""
    k = np.clip(np.searchsorted(t, epochs), reach, len(t) - reach - 1)
    return np.mean([w[k + d] for d in range(-reach, reach + 1)], axis=0)
