"""A reference IMU's own white noise enters the residual (through the prediction,
`reference.predicted_at`) and the regressors made of the same prediction - errors in variables.
Where the reference is far quieter than the MIMU (a FOG) the bias this makes is small unless
the motion hardly excites a regressor (below); where the two are alike it is not: a lever arm's
and a proof-mass offset's regressors hold the reference's angular acceleration, a time skew's
its derivative, and a simulated flight whose reference carried a consumer part's noise (0.002
rad/s, 0.04 m/s^2 per 1 kHz sample) had a size_effect accel.x found beside nothing missing.

Beside a MEMS-grade reference the check is one step of SIMEX (simulation-extrapolation: Cook &
Stefanski, JASA 89, 1994): the reference's outputs with as much white noise again, the found
terms refitted on the same held-out blocks. A bias linear in the noise's variance doubles, so 2
b - b' reads the estimate back to a noiseless reference; the noise added per sample is the
largest the residual allows - all of each sensor's white residual variance (`white_per_sample`)
charged to the reference -, so the truth lies between b and that read-back, and the finding's
interval is widened to hold both (by 1 + |b' - b| / its half-width, the largest over the term's
axes), then judged as the halves' widening is: set aside where it holds zero (on that null
flight, a size_effect of -0.022 m read -0.27 with the noise doubled: far from linear, and
nothing). A tractor's two autopilot IMUs' true lever arm of 1.8 cm stays, its interval four
times wider, now holding the truth it had missed by 0.2 mm.

Beside a reference of higher grade in a recording, the findings take the same check with the noise
added equal to the reference's own, measured (`reference_white_noise`), where its noise is
differentiated: in a lever arm's transfer (dw/dt x dr, in every accelerometer's prediction: on
a null car the columns of accel.z's scale and of accel.x <- f_z read 0.98 and 0.42 on their
training half, beyond range) or in a finding's regressors (`DIFFERENTIATED`). That noise can
hold most of a regressor where the motion hardly excites it (a car's roll and pitch: a lever
arm's vertical component), and there the bias is far from linear in the noise - a ROS car's
exact 40 cm lever arm beside a tactical IMU (0.1 deg/sqrt h, 100 Hz) read -0.235 m at p <
1e-300 on a null. The share s of a term's regressor that the added noise makes (its sum of
squares over the regressor's) reads it back exactly for one regressor whose noise both
attenuates it and biases it by c (b(m) = (beta S + c m V) / (S + m V) at m times the noise, s =
V / (S + V)): beta = (2 b - b'(1 + s)) / (1 - s); the linear read-back is its s -> 0 limit
(Fuller, Measurement Error Models, 1987, 1.1: the reliability ratio 1 - s).
"""
from dataclasses import replace

import numpy as np

from . import library
from .confirmation import judged_wider, position_of
from .design import CHANNELS, white_per_bin
from .fitting import Fitter

DIFFERENTIATED = ("lever_arm", "size_effect", "time_skew")   # regressors made of the
#                             reference's angular acceleration or its outputs' derivatives
NOISE_WINDOW_S = 5.0        # the reference's white noise is read in windows this long, ...
NOISE_DECILE = 10           # ... at their first decile: the quietest (a rest, a straight road)
#                             hold its noise alone, where a rotor's or an engine's vibration
#                             swells the rest (a hexacopter's FOG: 1.1e-4 rad/s, 7.7e-3 m/s^2
#                             per 1 kHz sample, its datasheet's ARW and noise density exactly;
#                             a car's tactical IMU at 100 Hz 0.95 of its 2.9e-4 rad/s - the
#                             decile of 500-sample variances sits ~10 % below their mean)
SHARE_MAX = 0.9             # a regressor 90 % the reference's noise: read back 10x amplified,
#                             the term is not measurable against this reference
SHARE_SMALL = 0.1           # below it a shift within SHIFT_Z is no bias shown (the bias is
#                             at most (1 + s) / (1 - s) = 1.2 times the shift); above it the
#                             read-back is made whatever the shift (at s = 0.6 the shift is a
#                             quarter of the bias)
NOT_READ_BACK = ("the findings were not read back to a noiseless reference (errors in "
                 "variables): the recording streams (its reference IMU is read block by block, "
                 "not held to add noise to), and the reference's own noise may make or bias "
                 "them (a lever arm, a proof-mass offset, a time skew; beside a lever arm any "
                 "accelerometer term; beside a MEMS-grade reference any term)")
SEED = 20240531             # the added noise's draw: fixed, so a diagnosis repeats exactly
SHIFT_Z = 3.0               # a shift of the estimate beyond 3 of its sds is a bias shown: one
#                             draw's own scatter is about one sd (an independent review's toy
#                             fit without any noise in its regressor widened every interval,
#                             median 1.35x, and set true 4-sigma effects aside 13 % of the time)


def white_per_sample(design, rate_hz):
    """{"gyro": rad/s, "accel": m/s^2}: 1 sigma per reference sample (at rate_hz) of white
    noise whose bin means carry the whole white variance of the design's residual, the
    largest over each sensor's axes: var(diff(residual)) / 2 per bin of design.bin_s, times
    the reference samples in a bin."""
    per_bin = white_per_bin(design.residual)
    n = max(design.bin_s * rate_hz, 1.0)
    return {sensor: float(np.sqrt(n * max(per_bin[c] for c, (s, _) in enumerate(CHANNELS)
                                          if s == sensor)))
            for sensor in ("gyro", "accel")}


def at_risk(flight, findings, mems_grade):
    """Whether the reference's own noise may make or bias `findings` (module doc): any
    finding beside a MEMS-grade reference; beside another in a recording, any where a lever
    arm's transfer differentiates its rates into the accelerometers' prediction, else those
    whose regressors hold derivatives (`DIFFERENTIATED`)."""
    if not findings:
        return False
    if mems_grade:
        return True
    lever = flight.mimu_mounting.lever_arm_m - flight.fog_mounting.lever_arm_m
    return flight.source == "recording" and bool(
        np.any(lever) or any(f["effect"] in DIFFERENTIATED for f in findings))


def reference_white_noise(fog_t, fog_w, fog_f):
    """{"gyro": rad/s, "accel": m/s^2}: the reference IMU's own white noise, 1 sigma per
    sample, from its outputs at stamps fog_t (s) alone: var(diff(x)) / 2 per axis over
    windows of NOISE_WINDOW_S, its NOISE_DECILE-th percentile over the windows, the largest
    over the axes (the whole record one window when it is shorter)."""
    n = max(int(round(NOISE_WINDOW_S / float(np.median(np.diff(fog_t))))), 3)
    out = {}
    for sensor, x in (("gyro", fog_w), ("accel", fog_f)):
        per_window = np.array([white_per_bin(x[a:a + n]) for a in range(0, max(len(x) - n, 0)
                                                                         + 1, n)])
        out[sensor] = float(np.sqrt(np.max(np.nanpercentile(per_window, NOISE_DECILE,
                                                            axis=0))))
    return out


def noisier(flight, sigma):
    """The flight with white noise of sigma ({"gyro", "accel"}, SI, per sample) added to its
    reference IMU's outputs (a fixed draw, `SEED`)."""
    rng = np.random.default_rng(SEED)
    return replace(flight,
                   fog_w=flight.fog_w + rng.normal(0.0, sigma["gyro"], flight.fog_w.shape),
                   fog_f=flight.fog_f + rng.normal(0.0, sigma["accel"], flight.fog_f.shape))


def read_back(design, again, findings, held_of, added, own=False):
    """(kept, set aside) of the library's `findings` on `design` given `again`, the design of
    the flight with noise added to its reference (`noisier`): each term refitted with the
    others on the held-out rows (`held_of(design)`) of both; its interval widened to hold
    the estimate read back to a noiseless reference too (module doc), judged as the halves'
    widening is (`confirmation.judged_wider`: set aside where it then holds zero or its
    held-out p misses its limit); each carries `errors_in_variables` {"noisier",
    "read_back", "widened_by", "share", "added_per_sample", "own"}. added: the noise
    added, {"gyro" rad/s, "accel" m/s^2} 1 sigma per reference sample; own: it is the
    reference's own (`reference_white_noise`), read back through each coefficient's
    regressor share (module doc) - else the residual's whole white noise
    (`white_per_sample`), read back linearly."""
    first = [position_of(design, f) for f in findings]
    second = _index(again, [f["label"] for f in findings])
    if None in second:
        return findings, []
    fits = [Fitter(d, held_of(d)).fit(idx) for d, idx in ((design, first), (again, second))]
    kept, aside = [], []
    for f, j1, j2 in zip(findings, first, second):
        (b, cov), (b2, _) = fits[0].of(j1), fits[1].of(j2)
        sd = np.sqrt(np.diag(cov))
        share = _shares(design, again, j1, j2, held_of(design)) if own else np.zeros(len(b))
        # b2 - b holds the draw's own scatter, about the fit's sd (the noise doubled: var b2
        # ~ 2 var b, cov ~ var b): a shift within SHIFT_Z of it is no bias shown - no widening
        shift = float(np.max(np.abs(b2 - b) / sd))
        record = {"noisier": b2.tolist(), "shift_z": shift, "share": share.tolist(),
                  "added_per_sample": added, "own": own}
        if shift <= SHIFT_Z and share.max() <= SHARE_SMALL:
            kept.append(dict(f, errors_in_variables=dict(record, widened_by=1.0)))
            continue
        if share.max() >= SHARE_MAX:
            aside.append(dict(f, errors_in_variables=record, rejected=(
                f"the reference's own noise ({_said_noise(added)} per sample, measured) "
                f"makes {share.max():.0%} of its regressor (errors in variables): not "
                f"measurable against this reference - inconclusive")))
            continue
        # the truth lies between the fit (the reference's noise as recorded, none charged)
        # and the read-back: widened so
        back = (2 * b - b2 * (1 + share)) / (1 - share)
        factor = 1.0 + float(np.max(np.abs(back - b) / (1.96 * sd)))
        record["read_back"] = back.tolist()
        why = (f"the reference's own noise moves it (errors in variables): with as much "
               f"again{' (' + _said_noise(added) + ', measured)' if own else ''} it "
               f"reads {_said(b2)} against {_said(b)}, read back to a noiseless "
               f"reference {_said(back)}"
               + (" (sensor axes x, y, z)" if len(np.atleast_1d(b)) == 3 else ""))
        ok, judged = judged_wider(f, factor, len(b), why, "errors_in_variables", record,
                                  f.get("halves", {}).get("p_heldout_widened"))
        (kept if ok else aside).append(judged)
    return kept, aside


def _shares(design, again, j1, j2, rows):
    """(k,) of term j1 of `design` (j2 of `again`, the same flight's with noise added to its
    reference): the sum of squares the added noise makes in each of its regressors, over
    theirs, on the bins of `rows` both designs hold."""
    _, a, b = np.intersect1d(design.t, again.t, return_indices=True)
    a, b = a[rows[a]], b[rows[a]]
    added = total = 0.0
    for c, x in design.columns[j1].items():
        if c in again.columns[j2]:
            added = added + np.sum((again.columns[j2][c][b] - x[a]) ** 2, axis=0)
            total = total + np.sum(x[a] ** 2, axis=0)
    return np.atleast_1d(added / np.maximum(total, 1e-300))


def _index(design, labels):
    """`confirmation.position_of` of each label in `design`, None where it has no such term
    (the noisier flight's design is made anew)."""
    names = [library.label(t) for t in design.terms]
    return [names.index(x) if x in names else None for x in labels]


def _said_noise(sigma):
    return f"{sigma['gyro']:.2g} rad/s, {sigma['accel']:.2g} m/s^2"


def _said(x):
    return ", ".join(f"{v:.3g}" for v in np.atleast_1d(x))
