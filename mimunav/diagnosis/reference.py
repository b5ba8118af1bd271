"""What the MIMU should have output: the reference IMU's motion moved to the MIMU's mounting.

Both IMUs sit on one rigid vehicle, so they feel the same inertial angular rate, and their
specific forces differ by the rigid-body terms of their separation (vehicle axes):
    w_v   = C_vf w_fog
    f_v   = C_vf f_fog + w x (w x dr) + dw/dt x dr,     dr = r_mimu - r_fog
and the MIMU reads them in its own axes, w_s = C_sv w_v, f_s = C_sv f_v.
Samples are interval means (log contract): the reference's cumulative increments are
interpolated at the MIMU's interval ends and differenced, which is exact when the stamps
coincide and keeps the interval-mean meaning when they do not.
"""
import numpy as np

from .. import attitude
from ..effects import derivative

DERIVATIVE_WINDOW_S = 0.1       # d/dt of reference rates: quartic Savitzky-Golay over 100 ms,
# exact for the profiles' smootherstep ramps (rate quintic in time) away from their ends, and
# long enough that the reference's output quantization (FOG: 5 urad per pulse) does not turn
# into angular-acceleration noise. That noise is shared by the lever-arm transfer (x dr) and
# the size-effect regressor (x r) - errors in variables: over 20 ms it faked centimetre
# proof-mass offsets on null recordings, over 50 ms it still raised 2 false size effects in
# 40 nulls (reports/diagnosis-proof.md, seed 200 run); over 100 ms none in the cases tried.


def on_intervals(t_src, x_src, t):
    """Interval means x_src (N, k) over (t_src[k-1], t_src[k]] re-expressed as interval means
    over (t[k-1], t[k]] (the first output repeats the second interval)."""
    dt_src = np.diff(t_src, prepend=t_src[0] - (t_src[1] - t_src[0]))
    edges = np.concatenate([[t_src[0] - dt_src[0]], t_src])
    cum = np.vstack([np.zeros((1, x_src.shape[1])), np.cumsum(x_src * dt_src[:, None], axis=0)])
    at = np.column_stack([np.interp(t, edges, cum[:, j]) for j in range(x_src.shape[1])])
    out = np.diff(at, axis=0) / np.diff(t)[:, None]
    return np.vstack([out[:1], out])


def predicted_mimu(flight):
    """(f m/s^2, w rad/s) the MIMU should have read at its stamps, MIMU sensor axes, from the
    flight's reference IMU (`/fog/imu`) and both mountings."""
    t = flight.mimu_t
    inside = (t > flight.fog_t[0]) & (t <= flight.fog_t[-1])
    if inside.sum() < 2:
        raise ValueError(f"{flight.path}: the reference IMU does not cover the MIMU's samples")
    w_v = attitude.rotate(flight.fog_mounting.q_vs, flight.fog_w)
    f_v = attitude.rotate(flight.fog_mounting.q_vs, flight.fog_f)
    w_v, f_v = on_intervals(flight.fog_t, np.hstack([w_v, f_v]), t).reshape(len(t), 2, 3) \
        .transpose(1, 0, 2)
    dr = flight.mimu_mounting.lever_arm_m - flight.fog_mounting.lever_arm_m
    if np.any(dr):
        w_dot = derivative(t, w_v, DERIVATIVE_WINDOW_S)
        f_v = f_v + np.cross(w_v, np.cross(w_v, dr)) + np.cross(w_dot, dr)
    q_sv = np.conjugate(flight.mimu_mounting.q_vs)
    return attitude.rotate(q_sv, f_v), attitude.rotate(q_sv, w_v), inside
