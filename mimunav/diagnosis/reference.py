"""What the MIMU should have output: the reference IMU's motion moved to the MIMU's mounting.

Both IMUs sit on one rigid vehicle, so they feel the same inertial angular rate, and their
specific forces differ by the rigid-body terms of their separation (vehicle axes):
    w_v   = C_vf w_fog
    f_v   = C_vf f_fog + w x (w x dr) + dw/dt x dr,     dr = r_mimu - r_fog
and the MIMU reads them in its own axes, w_s = C_sv w_v, f_s = C_sv f_v.
Samples are interval means (log contract): the reference's running integral
(`intervals.RunningIntegral`) at the MIMU's interval ends, differenced - exact when the
stamps coincide, to fourth order in smooth motion when they do not (its cubic spline).
"""
import numpy as np
import quaternion

from ..frames import attitude
from ..frames.mounting import runs_against
from ..compensation.effects import derivative
from .design import CHANNELS, white_per_bin
from .outputs import noise_sigma_of
from ..errors import InputError
from ..evaluation.replay import resample
from ..importers.same_data import SAME_DATA, follows
from ..motion.intervals import RunningIntegral, intervals
from ..motion.truth import Kinematics, body_rate_and_specific_force

DERIVATIVE_WINDOW_S = 0.1       # d/dt of reference rates: quartic Savitzky-Golay over 100 ms,
# exact for motion up to 4th order in time (close to it inside the profiles' ramps), and
# long enough that the reference's output quantization (FOG: 5 urad per pulse) turns into
# little angular-acceleration noise where the count moves every sample (where it stands still
# for many, not: `pulse_counted`). That noise is shared by the lever-arm transfer (x dr) and
# the size-effect regressor (x r) - errors in variables: over 20 ms it faked centimetre
# proof-mass offsets on null recordings, over 50 ms it still raised 2 false size effects in
# 40 nulls (reports/diagnosis-proof.md, seed 200 run); over 100 ms none in the cases tried.


TRANSFER_WINDOW_S = 0.03        # d/dt of the reference rate in the lever-arm transfer
# dw/dt x dr: short, because where the angular acceleration changes (the start and end of a
# roll) a 100 ms window is off by up to 2.4 mg at 0.33 m - a systematic error a proof-mass
# offset (size_effect) fits at z 3-5 on null recordings; over 30 ms the transfer error of
# an ideal reference is 0.2 mg at most. The reference's quantization through so short a
# derivative is not small where the rates are slow: a FOG's raw 1 arcsec count at 1 kHz on a
# quiet flight gave 0.5-0.6 mg rms in 10 ms bins, near the MIMU's own noise there, and the
# regressors (DERIVATIVE_WINDOW_S) share it however their windows differ (errors in
# variables: a lever arm of minus the declared one) - hence the count smoothed first
# (`pulse_counted`), which takes that error down 2-3x where the count stands still.


def predicted_mimu(flight):
    """(f m/s^2, w rad/s, inside) the MIMU should have read at its stamps, MIMU sensor axes,
    from the flight's reference IMU (`/fog/imu`, `counted_outputs`) and both mountings
    (`predicted_lagged`); inside (N,) bool: the stamps inside the reference's span."""
    inside = inside_reference(flight)
    fog_t = flight.fog_t
    return (*predicted_lagged(flight.mimu_t, fog_t,
                              counted_outputs(flight, fog_t, flight.fog_w),
                              counted_outputs(flight, fog_t, flight.fog_f), flight), inside)


def predicted_lagged(t, fog_t, fog_w, fog_f, flight):
    """`predicted_at`, each triad's at its stamps t less its lag (flight.mimu_lag_s: the
    accelerometers', the gyros'; s): what a triad lagging so behind its stamps reads -
    the interval means over (t[k-1] - lag, t[k] - lag]."""
    lag_f, lag_w = flight.mimu_lag_s
    f, w = predicted_at(t - lag_f, fog_t, fog_w, fog_f, flight)
    if lag_w != lag_f:
        w = predicted_at(t - lag_w, fog_t, fog_w, fog_f, flight)[1]
    return f, w


def inside_reference(flight):
    """(N,) bool: the MIMU's stamps inside the reference IMU's span, each triad's lag
    (flight.mimu_lag_s) taken off them; an InputError when fewer than two are."""
    t = flight.mimu_t
    inside = (t - max(flight.mimu_lag_s) > flight.fog_t[0]) & \
        (t - min(flight.mimu_lag_s) <= flight.fog_t[-1])
    if inside.sum() < 2:
        raise InputError(f"{flight.path}: the reference IMU does not cover the MIMU's samples")
    return inside


def across_gaps(t, fog_t):
    """(N,) bool over the MIMU's stamps t (s): the samples whose interval (t[k-1], t[k]] comes
    within DERIVATIVE_WINDOW_S of a gap of either IMU - a step of its stamps (s) longer than
    DERIVATIVE_WINDOW_S and three of its median steps. Across a gap the reference's interval
    mean is its one sample after it and its derivative spans both sides: a reference IMU
    silent for 60 s had been bridged, and the flight's turns read as excursions of z 1400
    (the sensor level leaves these samples out; it navigates nothing across a gap)."""
    t, edges = np.asarray(t, float), np.zeros(len(t) + 1, int)
    for s in (t, np.asarray(fog_t, float)):
        step = np.diff(s)
        if len(step) < 2:
            continue
        k = np.flatnonzero(step > max(DERIVATIVE_WINDOW_S, 3.0 * np.median(step)))
        # sample i is near (t[i] > gap start - margin and t[i-1] < gap end + margin): the
        # samples from the first after the start to the one after the last before the end
        first = np.searchsorted(t, s[k] - DERIVATIVE_WINDOW_S, "right")
        last = np.searchsorted(t, s[k + 1] + DERIVATIVE_WINDOW_S, "left")
        np.add.at(edges, first, 1)
        np.add.at(edges, np.minimum(last, len(t) - 1) + 1, -1)
    return np.cumsum(edges[:-1]) > 0


def counted_outputs(flight, fog_t, x):
    """The reference IMU's outputs x (N, k) at its stamps fog_t (s) with a pulse count's
    staircase smoothed where the flight's reference counts pulses (a simulation's:
    `pulse_counted`), else as they are. Each column on its own: a column at a time gives
    the same."""
    return pulse_counted(fog_t, x) if flight.source == "simulation" else x


def predicted_at(t, fog_t, fog_w, fog_f, flight):
    """(f m/s^2, w rad/s) the MIMU should have read at stamps t (s), MIMU sensor axes, from
    the reference IMU's samples fog_t (s), fog_w (rad/s), fog_f (m/s^2) (its sensor axes,
    through `counted_outputs`; covering t - all of the flight's, or those around a block:
    `samples`) and the mountings of `flight`."""
    w_v = attitude.rotate(flight.fog_mounting.q_vs, fog_w)
    f_v = attitude.rotate(flight.fog_mounting.q_vs, fog_f)
    reference = RunningIntegral(intervals(fog_t)[2], np.hstack([w_v, f_v]))
    w_v, f_v = reference.means(t, smooth=True).reshape(len(t), 2, 3).transpose(1, 0, 2)
    dr = flight.mimu_mounting.lever_arm_m - flight.fog_mounting.lever_arm_m
    if np.any(dr):
        w_dot = derivative(t, w_v, TRANSFER_WINDOW_S)
        f_v = f_v + np.cross(w_v, np.cross(w_v, dr)) + np.cross(w_dot, dr)
    q_sv = np.conjugate(flight.mimu_mounting.q_vs)
    return attitude.rotate(q_sv, f_v), attitude.rotate(q_sv, w_v)


TRANSFER_SHARE = 0.1    # the transfer's unfollowed error, as a share of the accelerometers'
# white residual variance per bin, beyond which the diagnosis cannot conclude: a structured
# error of that size over 10^5 bins is significant for every term it resembles (a tractor's
# engine lines at 27-60 Hz across 2.2 cm: 0.02 m/s^2 per bin, 0.42 of that variance, had read
# as accel.z <- f_x, f_y couplings of 0.02-0.04 holding 47-68 % of the residual; the foreign
# flight with the longest lever arm, 31 cm, holds 0.0002 m/s^2 of it, 3e-4 of the variance)


SHOCK_SIGMA = 5.0   # a bin's transfer miss beyond this many of its own robust scatter over
                    # the record (the reference's noise through the derivatives) is motion the
                    # transfer does not follow, not that noise
SHOCK_SHARE = 0.01  # a shock is rare: misses in more of the bins are the motion's own (an
                    # engine's lines, which `unfollowed_vibration` judges), not left out


def transfer_shocks(t, measured, predicted, lever, bins_of, usable):
    """(N,) bool: the MIMU samples of the bins where the lever-arm transfer (`predicted_at`:
    dw/dt smoothed over TRANSFER_WINDOW_S) misses the reference's angular acceleration -
    whole bins' own (fourth-order central) difference of their mean rates less the bin mean
    of the transfer's derivative, x `lever` (m, MIMU axes) - by more than SHOCK_SIGMA of
    that miss's robust scatter and more than the accelerometers' own white noise over a bin
    (`outputs.noise_sigma_of` measured - predicted over the `usable` samples, robust to the
    shocks themselves): a shock (a rocket's landing at
    9 g, a plane's catapult or the hands that carry it) whose bins tell nothing of the
    accelerometers' terms - a rocket's landing across 22 cm had held the library 4x above
    its chance level and set aside its true g-sensitivity. Bins amid their four neighbours
    only (not across a gap); none when more than SHOCK_SHARE of them miss. Bin means, not
    samples: a sample's difference follows its stamp's error. t s; measured, predicted
    (N, 6) read a column at a time; bins_of: (m, start) of `design.bins`."""
    m, start = bins_of
    out = np.zeros(len(t), bool)
    if not np.any(lever) or len(t) < start + 4 * m:
        return out
    k = np.full(len(t), -1)
    k[start:] = (np.arange(len(t) - start)) // m
    ok = (k >= 0) & usable
    count = np.bincount(k[ok], minlength=k.max() + 1).astype(float)
    full = count == m                   # whole bins: a part bin's mean is off its centre

    def mean(x):
        return np.bincount(k[ok], x[ok], minlength=len(count))[full] / count[full]
    t_b = mean(t)
    # a column at a time (a long flight's spilled columns; `samples.Columns`)
    w_b = np.column_stack([mean(predicted[:, c]) for c in (3, 4, 5)])
    smooth_b = np.column_stack([mean(derivative(t, predicted[:, c][:, None],
                                                TRANSFER_WINDOW_S)[:, 0]) for c in (3, 4, 5)])
    # the bins' own derivative: the fourth-order central difference of their means (the
    # second-order one errs by (2 pi f h)^2 / 6: 0.07 rad/s^2 on a 2 Hz, 2 rad/s swing)
    h = float(np.median(np.diff(t_b)))
    miss = np.zeros_like(w_b)
    miss[2:-2] = np.cross((w_b[:-4] - 8 * w_b[1:-3] + 8 * w_b[3:-1] - w_b[4:]) / (12 * h)
                          - smooth_b[2:-2], lever)
    ids = np.flatnonzero(full)
    next_to = np.zeros(len(ids), bool)          # a bin amid its four neighbours, no gap
    next_to[2:-2] = ids[4:] - ids[:-4] == 4
    if next_to.sum() < 10:
        return out
    inner = miss[next_to]
    # the scatter: the MAD's, floored by the central 98 %'s spread - a reference logged in
    # steps (0.01 rad/s; a FOG's count) makes most misses equal and the MAD zero
    lo, hi = np.percentile(inner, [1, 99], axis=0)
    scatter = np.maximum(1.4826 * np.median(np.abs(inner - np.median(inner, axis=0)), axis=0),
                         np.std(np.clip(inner, lo, hi), axis=0))
    white = noise_sigma_of(lambda c: np.where(usable, measured[:, c] - predicted[:, c],
                                              np.nan), 3) / np.sqrt(m)
    beyond = next_to & np.any(np.abs(miss) > np.maximum(SHOCK_SIGMA * scatter, white), axis=1)
    if beyond.sum() > SHOCK_SHARE * next_to.sum():
        return out                  # no shock: the motion's own (`unfollowed_vibration`)
    shock = np.zeros(len(count), bool)
    shock[ids[beyond]] = True
    out[ok] = shock[k[ok]]
    return out


def _undeclared_arm(rates):
    """Words on a lever arm between two IMUs left undeclared, at the record's largest 1 s
    mean |w| (rates (M, 3) rad/s): its w x (w x r) per cm (a rocket's undeclared 18 mm at
    23 rad/s of spin had made 9.5 m/s^2 the clause did not name)."""
    peak = float(np.max(np.linalg.norm(rates, axis=1))) if len(rates) else 0.0
    return (f", or a lever arm between them is not declared (w x (w x r): at {peak:.3g} "
            f"rad/s, 1 cm makes {peak ** 2 * 0.01:.2g} m/s^2; declared at import: `mimunav "
            "import` --reference-imu-lever-arm-m, or a table spec's lever_arm_m)")


def unfollowed_vibration(fog_t, fog_w, dr, bin_s, mimu_rate):
    """(m/s^2, Hz) or None: the rms over a bin (bin_s s) of the lever-arm transfer's error
    that the reference's angular vibration leaves - the lines of its rates' spectrum that
    stand out of its own floor (an engine's, a rotor's; noise and a count's steps are
    flat) in most of the record, as angular acceleration (2 pi f)^2 P, times the share of it the transfer's
    derivative (`derivative` over TRANSFER_WINDOW_S at the MIMU's rate mimu_rate Hz) misses,
    through a bin's mean (sinc), times dr (m, the two IMUs apart) - and the frequency that
    holds most of it; None without a lever arm or without such lines. fog_t s, fog_w rad/s
    (N, 3) the reference's."""
    from scipy.signal import welch
    if not np.any(dr) or len(fog_t) < 1024:
        return None
    rate = 1.0 / float(np.median(np.diff(fog_t)))
    f, p = welch(fog_w - fog_w.mean(axis=0), fs=rate, nperseg=1024, axis=0)
    band = (f > 0.1 / TRANSFER_WINDOW_S) & (f < 0.5 * mimu_rate)
    if band.sum() < 8:
        return None
    # a line is told by the segments' median spectrum: a vibration is what persists, and a
    # shock's few segments (a rocket's ignition, chute openings, landing; their bins are
    # the scan's excursions) are none - the mean had made a rocket's white reference
    # 'vibrate' at 62 Hz; its power is the mean spectrum's (the median's correction for
    # noise overstates a sinusoid's by 1 / ln 2)
    typical = welch(fog_w - fog_w.mean(axis=0), fs=rate, nperseg=1024, axis=0,
                    average="median")[1][band]
    # it stands 5 of the floor's own relative errors (1 / sqrt(segments): Welch's half-
    # overlapping segments of 1024; the median of exponential ordinates 1 / ln 2 times a
    # mean's) above it - a white spectrum's scatter is no line
    spread = 1.0 / (np.log(2.0) * np.sqrt(max(len(fog_t) // 512 - 1, 1)))
    lines = typical > np.median(typical, axis=0) * (1.0 + 5.0 * spread)
    floor = np.median(p[band], axis=0)
    excess = np.where(lines, np.maximum(p[band] - floor, 0.0), 0.0).sum(axis=1)
    missed = _missed_share(f[band], mimu_rate) * np.sinc(f[band] * bin_s)
    alpha = (2 * np.pi * f[band] * missed) ** 2 * excess * (f[1] - f[0])
    if not alpha.sum() > 0:
        return None
    return (float(np.sqrt(alpha.sum()) * np.linalg.norm(dr)),
            float(f[band][np.argmax(alpha)]))


def _missed_share(f, rate):
    """(F,) the rms error of the transfer's derivative (`derivative` over TRANSFER_WINDOW_S
    at `rate` Hz) on a unit sinusoid of each frequency f (Hz), over its true derivative's
    rms: ~0 within its band, ~1 where it smooths the motion away."""
    t = np.arange(0.0, 1.0, 1.0 / rate)
    x = np.sin(2 * np.pi * np.outer(t, f))
    d = derivative(t, x, TRANSFER_WINDOW_S)
    true = 2 * np.pi * f * np.cos(2 * np.pi * np.outer(t, f))
    inner = slice(len(t) // 4, 3 * len(t) // 4)          # away from the ends' fits
    return np.sqrt(np.mean((d - true)[inner] ** 2, axis=0)
                   / np.maximum(np.mean(true[inner] ** 2, axis=0), 1e-300))


def has_attitude(trajectory, t0, t1):
    """Whether `trajectory` carries an attitude (finite q_nb) at every sample that the span
    t0-t1 (s) interpolates between, and covers that span."""
    if len(trajectory) < 2 or trajectory.t[0] > t0 + 1e-9 or trajectory.t[-1] < t1 - 1e-9:
        return False
    k = np.searchsorted(trajectory.t, [t0, t1])
    q = quaternion.as_float_array(trajectory.q_nb[max(k[0] - 1, 0):k[1] + 1])
    return bool(np.isfinite(q).all())


def trajectory_outputs(trajectory, edges, mounting):
    """(f m/s^2, w rad/s), each (N, 3) in MIMU sensor axes: what an ideal MIMU at `mounting`
    (a `frames.mounting.Mounting`) read, as means over the N intervals between `edges` (s,
    (N+1,)), on `trajectory` (a Trajectory with attitude, vehicle frame, covering the edges).
    The NED velocity and the attitude differenced over each interval give dv/dt and the body
    rate w_nb; then w_ib = w_nb + C_bn (w_ie + w_en), f = C_bn (dv/dt - g + (2 w_ie + w_en)
    x v) (Titterton & Weston eq. 3.12, 3.70: `motion.truth.body_rate_and_specific_force`),
    plus w x (w x r) + dw/dt x r at the lever arm r. A reference independent of the MIMU
    gives regressors free of the MIMU's own noise (errors in variables, `navigation`)."""
    edges = np.asarray(edges, float)
    dt = np.diff(edges)[:, None]
    at = resample(trajectory, edges)
    mid = resample(trajectory, 0.5 * (edges[1:] + edges[:-1]))
    turn = attitude.short_way(np.conjugate(at.q_nb[:-1]) * at.q_nb[1:])
    kinematics = Kinematics(mid.v_ned, np.diff(at.v_ned, axis=0) / dt, mid.q_nb,
                            quaternion.as_rotation_vector(turn) / dt, np.zeros_like(dt * mid.v_ned))
    w_v, f_v = body_rate_and_specific_force(mid.lat, mid.h, kinematics)
    r = np.asarray(mounting.lever_arm_m, float)
    if np.any(r):
        w_dot = derivative(mid.t, w_v, TRANSFER_WINDOW_S)
        f_v = f_v + np.cross(w_v, np.cross(w_v, r)) + np.cross(w_dot, r)
    q_sv = np.conjugate(mounting.q_vs)
    return attitude.rotate(q_sv, f_v), attitude.rotate(q_sv, w_v)


def pulse_counted(t, x):
    """A pulse-counting reference's interval means (t s (N,), x (N, 3): rad/s or m/s^2, one
    rate: the count is taken per sample) with its count's staircase replaced by the line
    through the middles of its runs, where the data show the counting: this project's
    simulated reference (FOG: 1 arcsec and 0.1 mm/s a pulse; `counted_outputs` passes only a
    log whose source is "simulation") reports round(true running sum / quantum) - its error
    never accumulates,
    but at a slow rate its count stands still for many samples and then moves a whole
    quantum, and the derivative of that staircase (the lever-arm transfer's dw/dt, the
    size-effect and lever-arm regressors) is the quantization's, not the motion's: on a long
    quiet flight it fitted a lever arm of minus the declared one (bench/false_alarms.py,
    gentle.toml). The true running sum crosses the middle between two counts inside the
    sample where the count steps, so the middle of each run of one count is where the true
    sum stands at that count, to a fraction of a quantum. An axis whose samples are not whole
    multiples of their smallest step (a continuous reference) is left as it is, and so is a
    rate fast enough that the count moves every sample (each run one sample long: the line is
    the staircase); a recording's outputs, rounded rather than counted, are not passed here.
    The line also takes part of a real oscillation smaller than a few quanta (a 30 Hz rate of
    1 quantum's angle: about a fifth), which the raw count keeps."""
    t = np.asarray(t, float)
    out = np.array(x, float, copy=True)
    if len(t) < 3:
        return out
    for i in range(out.shape[1]):
        step = _smallest_step(out[:, i])
        if not step:
            continue
        pulses = out[:, i] / step
        if np.max(np.abs(pulses - np.round(pulses))) > 1e-6:   # not whole pulses: leave it
            continue
        edges = np.flatnonzero(np.round(pulses[1:])) + 1    # samples where the count moves
        starts, ends = np.r_[0, edges], np.r_[edges - 1, len(pulses) - 1]
        # in sample numbers, not seconds: the count is per sample, and a gap in the stamps
        # would otherwise pour the line's rise across it into the one sample after it
        middle = 0.5 * (starts + ends)
        running = np.cumsum(out[:, i])                      # the count, in rate x samples
        out[1:, i] = np.diff(np.interp(np.arange(len(pulses)), middle, running[starts]))
    return out


def _smallest_step(x):
    """The smallest spacing of the distinct values of x (above round-off), or None."""
    levels = np.unique(x[np.isfinite(x)])
    gaps = np.diff(levels)
    gaps = gaps[gaps > 1e-9 * max(float(np.abs(levels).max(initial=0.0)), 1e-300)]
    return float(gaps.min()) if len(gaps) else None


# ---- does the reference predict the MIMU at all? ---------------------------------------
AGREEMENT_BIN_S = 1.0       # the check's means: long enough that white noise averages out,
                            # short enough to follow a manoeuvre (a turn, a pull)
AGREEMENT_CORRELATION = 0.9     # a moving channel's recorded and predicted means correlate at
                                # least this much, else the reference does not predict it (the
                                # model explains < 81 % of the motion: the track level's rule)
MOVING_SPREAD = {"accel": 0.3, "gyro": 0.02}    # m/s^2, rad/s: spread of a channel's predicted
                                # 1 s means from which a correlation can be judged: 30x the
                                # white noise of a seed S1 Table 1 MEMS part's 1 s mean (0.01
                                # m/s^2, 7e-4 rad/s) and 10x a consumer part's
BIAS_CLASS = 0.1 * 9.80665     # m/s^2 per axis: an accelerometer bias a MEMS part may carry
#                                (a consumer part's 0.1 g): a constant difference beyond it
#                                on an axis is no bias
GRAVITY_ANGLE_DEG = 5.0     # the 1 s mean specific forces differ in direction by at most
                            # this (the median over the seconds: a clipped boost does not move
                            # it): a tilt larger than the diagnosis' small-angle terms (a few
                            # degrees) shows here, at rest too


def _alike(measured, predicted, keep, channels):
    """[the labels of the channels whose outputs go sample by sample with the reference
    IMU's prediction (`importers.same_data.follows`: its rounding, up to an offset and a
    scale) over the usable samples `keep`]."""
    if not keep.any():
        return []
    return [f"{sensor}.{axis}" for c, (sensor, axis) in enumerate(channels)
            if follows(measured[:, c][keep], predicted[:, c][keep])]


def agreement(t, measured, predicted, usable, channels):
    """Whether the reference's prediction follows the recorded MIMU: {"bin_s", "channels":
    {label: {"correlation", "predicted_spread"}}, "gravity_angle_deg", "failures": [why],
    "failed": [the sensor of each failure: "accel" or "gyro"], "alike": [the channels whose
    residual is their rounding] (`_alike`; absent where none is)} from
    the AGREEMENT_BIN_S means of the usable samples (t s; measured and predicted (N, 6):
    accel m/s^2 then gyro rad/s, MIMU axes; read as x[:, c]). A channel that moves (its
    predicted means spread by MOVING_SPREAD) must correlate to AGREEMENT_CORRELATION; the
    specific forces' means must point within GRAVITY_ANGLE_DEG of each other (the median
    over the seconds). A clock offset of seconds, a mounting turned by tens of degrees,
    another vehicle's topic fail one of them; a quiet channel is judged only for a sign
    (`frames.mounting.runs_against`: its means and their differences run against the
    prediction) - else its correlation is its noise's."""
    sec = np.floor((t - t[0]) / AGREEMENT_BIN_S).astype(int)
    keep = usable.copy()                # a column at a time: x[:, c] (`samples.Columns`)
    for c in range(6):
        keep &= np.isfinite(measured[:, c]) & np.isfinite(predicted[:, c])
    count = np.bincount(sec[keep], minlength=sec.max() + 1)
    full = count >= 0.5 * np.median(count[count > 0]) if count.any() else count > 0
    means = [np.column_stack([np.bincount(sec[keep], x[:, c][keep], minlength=len(count))
                              for c in range(6)])[full] / count[full, None]
             for x in (measured, predicted)]
    out = {"bin_s": AGREEMENT_BIN_S, "channels": {}, "failures": [], "failed": []}
    alike = _alike(measured, predicted, keep, channels)
    if alike:
        out["alike"] = alike
        out["failed"] += sorted({label.split(".")[0] for label in alike})
        out["failures"].append(
            f"the MIMU's {'outputs' if len(alike) == 6 else ', '.join(alike)} go sample by "
            "sample with the reference IMU's prediction (their changes equal to within "
            f"{SAME_DATA:g} of their rms, up to an offset and a scale) - the numbers' rounding, "
            "no sensor's error: one sensor's data twice? The residual holds nothing to "
            "diagnose there")
    for c, (sensor, axis) in enumerate(channels):
        m, p = means[0][:, c], means[1][:, c]
        spread = float(np.std(p)) if len(p) >= 5 else 0.0
        r = float(np.corrcoef(m, p)[0, 1]) if len(p) >= 5 and np.std(m) > 0 and spread > 0 \
            else float("nan")
        label = f"{sensor}.{axis}"
        out["channels"][label] = {"correlation": r, "predicted_spread": spread}
        if spread < MOVING_SPREAD[sensor] and runs_against(m, p):
            out["failed"].append(sensor)
            out["failures"].append(
                f"the MIMU's {label} runs against the reference IMU's prediction: the "
                f"{AGREEMENT_BIN_S:g} s means correlate {r:.2f}, their differences too, where "
                f"the predicted ones spread by only {spread:.3g} - a column's sign or the axes' "
                "order differs between the two IMUs (a reflection, which no mounting turns)")
        if spread >= MOVING_SPREAD[sensor] and not r >= AGREEMENT_CORRELATION:
            out["failed"].append(sensor)
            out["failures"].append(
                f"the reference IMU does not predict the MIMU's {label}: the {AGREEMENT_BIN_S:g} "
                f"s means correlate {r:.2f} (at least {AGREEMENT_CORRELATION:g} needed) where the "
                f"predicted ones spread by {spread:.3g} - the two IMUs' clocks, mountings or "
                "units disagree, or they are not on one vehicle" + (
                    _undeclared_arm(means[1][:, 3:]) if sensor == "accel" else ""))
    _gravity_angle(out, means)
    return out


def _gravity_angle(out, means):
    """Into `agreement`'s out: the median angle between the two IMUs' 1 s mean specific
    forces (means: measured, predicted (n, 6)), and beyond GRAVITY_ANGLE_DEG a failure - or
    a note where a small turn and a MEMS bias carry the difference."""
    f_m, f_p = means[0][:, :3], means[1][:, :3]
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.einsum("ij,ij->i", f_m, f_p) / (np.linalg.norm(f_m, axis=1) *
                                                  np.linalg.norm(f_p, axis=1))
    angle = float(np.degrees(np.arccos(np.clip(np.nanmedian(cos), -1.0, 1.0)))) \
        if np.isfinite(cos).any() else float("nan")
    out["gravity_angle_deg"] = angle
    if not angle <= GRAVITY_ANGLE_DEG:
        said = (f"the specific forces of the MIMU and of the reference IMU (turned by both "
                f"mountings) are {angle:.1f} deg apart (median of the {AGREEMENT_BIN_S:g} s "
                f"means; at most {GRAVITY_ANGLE_DEG:g})")
        turn = free_turn(means[0], means[1])
        free = None if turn is None else float(np.degrees(turn.magnitude()))
        d, down = np.nanmedian(f_m - f_p, axis=0), np.nanmedian(f_p, axis=0)
        down = down / np.linalg.norm(down)
        across = np.linalg.norm(d - (d @ down) * down)
        # the constant left once the turn is taken: a tilt's gravity leak is not a bias
        rows = np.isfinite(f_m).all(axis=1) & np.isfinite(f_p).all(axis=1)
        const = None if turn is None else np.median(f_m[rows] - turn.apply(f_p[rows]), axis=0)
        bias = None if const is None else float(np.linalg.norm(const))
        if free is not None and free <= GRAVITY_ANGLE_DEG and \
                np.max(np.abs(const)) <= BIAS_CLASS:
            out["gravity_note"] = (f"{said}, but about their means they turn onto each other "
                                   f"by {free:.2f} deg (a turn the diagnosis' small-angle "
                                   f"terms fit), and beside that turn differ by a constant "
                                   f"{bias:.3g} m/s^2 (a MEMS accelerometer's bias, which "
                                   "the bias terms fit)")
        else:
            out["failed"].append("accel")
            out["failures"].append(
                f"{said}: a mounting or an axis is wrong" + (
                    "" if free is not None else
                    f" - or an accelerometer bias of {across:.3g} m/s^2 across gravity, which "
                    "reads the same (the motion holds too little of a second direction to "
                    "tell them)"))


def free_turn(mine, theirs):
    """The turn (scipy Rotation) of theirs onto mine, two IMUs' 1 s means (M, 6: accel
    m/s^2 then gyro rad/s, one set of axes) about their own means, where no bias of either
    enters - each kind scaled to unit rms, as `importers.pairing` measures it - or None
    where they do not span two directions (second singular value under a tenth of the
    first) or move too little (MOVING_SPREAD): an IMU whose accelerometers are 80 mg off had
    been refused as 5.8 deg of tilt its mounting did not have."""
    from scipy.spatial.transform import Rotation
    rows = np.isfinite(mine).all(axis=1) & np.isfinite(theirs).all(axis=1)
    stacks = [[], []]
    for cols, spread in ((slice(0, 3), MOVING_SPREAD["accel"]),
                         (slice(3, 6), MOVING_SPREAD["gyro"])):
        a, b = (x[rows, cols] - x[rows, cols].mean(axis=0) for x in (mine, theirs))
        rms = float(np.sqrt(np.mean(b ** 2))) if len(b) else 0.0
        if rms >= spread:
            stacks[0].append(a / rms)
            stacks[1].append(b / rms)
    if not stacks[0]:
        return None
    a, b = np.vstack(stacks[0]), np.vstack(stacks[1])
    singular = np.linalg.svd(a.T @ b, compute_uv=False)
    if not singular[1] >= 0.1 * singular[0]:
        return None
    return Rotation.align_vectors(a, b)[0]


def transfer_doubt(flight, design, findings):
    """Why the accelerometers' findings cannot stand where the lever-arm transfer misses
    the reference's angular vibration (`reference.unfollowed_vibration`) by more than
    TRANSFER_SHARE of their white residual variance per bin, or '' (a recording's only).
    The lever arm: the mountings' and a found one's (vehicle frame; its columns are the
    transfer's - a hexacopter's undeclared 12 cm, found, missed its 52 Hz rotor lines by
    0.026 m/s^2 a bin, and the null twin's verdict named an accel.z scale of -0.027 and a
    coupling of -0.014 as missing physics, truth +0.004 and -0.002)."""
    dr = flight.mimu_mounting.lever_arm_m - flight.fog_mounting.lever_arm_m + sum(
        (np.asarray(f["vector"], float) for f in findings if f["effect"] == "lever_arm"),
        np.zeros(3))
    if flight.fog_w is None or flight.source != "recording":
        # a simulated FOG's pulse count rings at tones no IMU beside it feels (a repeated-
        # blocks flight: 341 Hz, 40 times the share), which its spectrum cannot tell from
        # motion; a recording's reference is taken as moving where it has lines
        return ""
    missed = unfollowed_vibration(flight.fog_t, flight.fog_w, dr, design.bin_s,
                                  1.0 / float(np.median(np.diff(flight.mimu_t))))
    white = max(float(v) for v, (sensor, _) in zip(white_per_bin(design.residual), CHANNELS)
                if sensor == "accel")
    if missed is None or not missed[0] ** 2 > TRANSFER_SHARE * white:
        return ""
    return (f"the lever-arm transfer cannot follow the reference's angular vibration at "
            f"{missed[1]:.0f} Hz (its derivative is smoothed over {TRANSFER_WINDOW_S:g} s): "
            f"across the {np.linalg.norm(dr) * 100:.3g} cm between the two IMUs it leaves "
            f"about {missed[0]:.2g} m/s^2 per bin out of the prediction, "
            f"{missed[0] ** 2 / white:.2g} of the accelerometers' white residual variance "
            f"(at most {TRANSFER_SHARE:g}) - terms on the accelerometers may be its shadow")
