"""A reference IMU of MEMS grade: its own white noise enters the residual (through the
prediction, `reference.predicted_at`) and the regressors made of the same prediction - errors
in variables. Where the reference is far quieter than the MIMU (a FOG) the bias this makes is
negligible; where the two are alike it is not: a lever arm's and a proof-mass offset's
regressors hold the reference's angular acceleration, a time skew's its derivative, and a
simulated flight whose reference carried a consumer part's noise (0.002 rad/s, 0.04 m/s^2 per
1 kHz sample) had a size_effect accel.x found beside nothing missing.

The check is one step of SIMEX (simulation-extrapolation: Cook & Stefanski, JASA 89, 1994):
the reference's outputs with as much white noise again, the found terms refitted on the same
held-out blocks. A bias linear in the noise's variance doubles, so 2 b - b' reads the
estimate back to a noiseless reference; the noise added per sample is the largest the
residual allows - all of each sensor's white residual variance (`white_per_sample`) charged
to the reference -, so the truth lies between b and that read-back, and the finding's
interval is widened to hold both (by 1 + |b' - b| / its half-width, the largest over the
term's axes), then judged as the halves' widening is: set aside where it holds zero (on
that null flight, a size_effect of -0.022 m read -0.27 with the noise doubled: far from
linear, and nothing). A tractor's two autopilot IMUs' true lever arm of 1.8 cm stays, its
interval four times wider, now holding the truth it had missed by 0.2 mm.
"""
from dataclasses import replace

import numpy as np

from . import library
from .confirmation import judged_wider, position_of
from .design import CHANNELS, white_per_bin
from .fitting import Fitter

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


def noisier(flight, sigma):
    """The flight with white noise of sigma ({"gyro", "accel"}, SI, per sample) added to its
    reference IMU's outputs (a fixed draw, `SEED`)."""
    rng = np.random.default_rng(SEED)
    return replace(flight,
                   fog_w=flight.fog_w + rng.normal(0.0, sigma["gyro"], flight.fog_w.shape),
                   fog_f=flight.fog_f + rng.normal(0.0, sigma["accel"], flight.fog_f.shape))


def read_back(design, again, findings, held_of):
    """(kept, set aside) of the library's `findings` on `design` given `again`, the design of
    the flight with the reference's noise doubled (`noisier`): each term refitted with the
    others on the held-out rows (`held_of(design)`) of both; its interval widened to hold
    the estimate read back to a noiseless reference too (module doc), judged as the halves'
    widening is (`confirmation.judged_wider`: set aside where it then holds zero or its
    held-out p misses its limit); each carries `errors_in_variables` {"noisier",
    "read_back", "widened_by"}."""
    first = [position_of(design, f) for f in findings]
    second = _index(again, [f["label"] for f in findings])
    if None in second:
        return findings, []
    fits = [Fitter(d, held_of(d)).fit(idx) for d, idx in ((design, first), (again, second))]
    kept, aside = [], []
    for f, j1, j2 in zip(findings, first, second):
        (b, cov), (b2, _) = fits[0].of(j1), fits[1].of(j2)
        sd = np.sqrt(np.diag(cov))
        # b2 - b holds the draw's own scatter, about the fit's sd (the noise doubled: var b2
        # ~ 2 var b, cov ~ var b): a shift within SHIFT_Z of it is no bias shown - no widening
        shift = float(np.max(np.abs(b2 - b) / sd))
        if shift <= SHIFT_Z:
            kept.append(dict(f, errors_in_variables={"noisier": b2.tolist(),
                                                     "shift_z": shift, "widened_by": 1.0}))
            continue
        # the truth lies between the fit (the reference's noise as recorded, none charged)
        # and the read-back (all of the residual's white noise the reference's): widened so
        factor = 1.0 + float(np.max(np.abs(b2 - b) / (1.96 * sd)))
        record = {"noisier": b2.tolist(), "read_back": (2 * b - b2).tolist(), "shift_z": shift}
        why = (f"the reference's own noise moves it (errors in variables): with as much "
               f"again it reads {_said(b2)} against {_said(b)}, read back to a noiseless "
               f"reference {_said(2 * b - b2)}")
        ok, judged = judged_wider(f, factor, len(b), why, "errors_in_variables", record,
                                  f.get("halves", {}).get("p_heldout_widened"))
        (kept if ok else aside).append(judged)
    return kept, aside


def _index(design, labels):
    """`confirmation.position_of` of each label in `design`, None where it has no such term
    (the noisier flight's design is made anew)."""
    names = [library.label(t) for t in design.terms]
    return [names.index(x) if x in names else None for x in labels]


def _said(x):
    return ", ".join(f"{v:.3g}" for v in np.atleast_1d(x))
