"""A time skew beyond the linear term: the sensor level's `time_skew` regressor is the
first-order -tau df/dt, which holds for a tau much shorter than the motion's period. A
triad that lags tens of ms reads as far less (motion at frequency nu shifted by tau projects
onto the derivative with the gain sin(2 pi nu tau) / (2 pi nu tau)) and its second-order
remainder as other terms: the proof flight's accelerometers lagging 20 ms had read 19.44 ms
[19.37, 19.50] beside an accel.y scale asymmetry and bias; a gentle flight's 80 ms, 41.4 ms
[40.3, 42.6]; the repeated blocks' 80 ms, 56.9 ms beside a lever arm of -0.78 m - all
named, none true.

Beyond LINEAR_SKEW_S the skew found is applied to the prediction itself - the triad's
reference interval means taken that much earlier (`Flight.mimu_lag_s`,
`reference.predicted_lagged`: exact, no linearisation) - and the diagnosis made again,
the linear term now fitting only the remainder, until the remainder is within
LINEAR_SKEW_S (or MAX_PASSES). The finding reported is the shift plus its remainder.

The lag so reached is checked by the data (`lag_checked`): the triad's residual against
the exactly shifted prediction, on a grid of lags, must be least at it. Where the fit's
wander takes a slow skew's signal for the bias's (a gentle flight's accelerometers 80 ms
late: 41 ms, the remainder then -1.3 ms, while the residual is least at 80 ms), the lag
is the residual's least itself (`direct_lag`), its interval jackknifed over blocks of the
record, and the diagnosis is made again at it; where that cannot place
it either, the skew and the triad's findings are set aside, saying where the residual is
least.
"""
import math
from dataclasses import replace

import numpy as np
from scipy import stats

from ..evaluation.replay import compensated_mimu
from ..importers.series import parabola_min
from . import library, sensor
from .design import MOTION_HZ
from .reference import predicted_mimu

LINEAR_SKEW_S = 0.245 / (2 * math.pi * MOTION_HZ)  # 7.8 ms: the linear term's gain on motion
# at MOTION_HZ, sin(x)/x, is 0.99 at x = 0.245 rad; a vehicle's motion lies below MOTION_HZ
MAX_PASSES = 6      # shifts: each remainder is read at a gain of 0.64 or more for motion
# below MOTION_HZ while it stays under a quarter period (x < pi/2), so six take a 0.1 s lag
# to within LINEAR_SKEW_S
TRIADS = {"accel": (1.0, 0.0), "gyro": (0.0, 1.0), "imu": (1.0, 1.0)}
CHECK_BIN_S = 1 / (2 * MOTION_HZ)   # the check's bins: the motion's band, the vibration
# above it averaged out; their first differences take out a bias's slow wander
CHECK_GRID = (0.0, 0.25, 0.5, 0.75, 0.9, 1.0, 1.1, 1.25, 1.5, 2.0)  # x the lag reached: a
# lag read at half or twice the data's shows, one within 10 % of it does not
DIRECT_BLOCKS = 8   # contiguous blocks the direct lag's interval is jackknifed over
CHECK_Z = 4.0       # a lag of the grid whose residual lies below the one reached by this many
# of the statistic's relative standard errors, sqrt(2 / bins), is where the data put it


def diagnose(flight, cal, **options):
    """`sensor.diagnose` of `flight` against `cal` (its keyword `options`), with a time skew
    found beyond LINEAR_SKEW_S applied to the prediction and refitted (module doc)."""
    diag = sensor.diagnose(flight, cal, **options)
    firsts, shifts, passes = {}, dict.fromkeys(TRIADS, 0.0), 0
    while (skew := _beyond_linear(diag)) is not None and passes < MAX_PASSES:
        firsts.setdefault(skew["sensor"], skew)
        shifts[skew["sensor"]] += skew["coefficient"]
        diag = sensor.diagnose(replace(flight, mimu_lag_s=_lags(shifts)), cal, **options)
        passes += 1
    held = firsts and flight.stream_block is None       # a streamed flight is not held
    measured = measured_outputs(flight, cal) if held else None
    unsettled = _beyond_linear(diag) or (lag_checked(flight, measured, shifts) if held else None)
    direct = None
    if unsettled is not None and "least_at_s" in unsettled:     # the data's own lag
        name = unsettled["sensor"]
        direct = direct_lag(flight, measured, name, math.copysign(      # the least's side: a lag
            2 * max(abs(unsettled["least_at_s"]), abs(shifts[name])),  # may lead (negative)
            unsettled["least_at_s"]))
        if direct is not None and not direct["ci95"][0] <= 0 <= direct["ci95"][1]:
            shifts[name], unsettled = direct["lag_s"], None
            diag = sensor.diagnose(replace(flight, mimu_lag_s=_lags(shifts)), cal, **options)
            passes += 1
    for name, first in firsts.items():
        _fold(diag, first, shifts[name], passes, unsettled,
              direct if direct is not None and unsettled is None else None)
    if firsts and flight.stream_block is not None:
        diag.inconclusive = diag.inconclusive + [
            "a time skew beyond the linear term was refitted on the shifted prediction but not "
            "checked against the exactly shifted residual: the flight streams, and that check "
            "holds it whole (a bias wander can take a slow skew's part)"]
    return diag


def _lags(shifts):
    """(accelerometers', gyros') lags (s) of the shifts per TRIADS key."""
    return tuple(sum(shifts[s] * TRIADS[s][k] for s in TRIADS) for k in (0, 1))


def measured_outputs(flight, cal):
    """(N, 6): the held flight's MIMU through `cal`, specific force m/s^2 then rate rad/s
    (sensor axes) - what `lag_checked` and `direct_lag` compare with the predictions."""
    w, f, _ = compensated_mimu(flight, cal, per_sample=True, warn=False)
    return np.hstack([f, w])


def lag_checked(flight, measured, shifts):
    """None where the residual of each triad shifted (`shifts`: s per TRIADS key) of the
    `measured_outputs` against the exactly lagged prediction is least at its lag among
    CHECK_GRID times it; else {"sensor": the triad, "least_at_s": the lag where the residual
    is least} (module doc)."""
    for name in (n for n in TRIADS if shifts[n]):
        lag = shifts[name]
        grid = lag * np.asarray(CHECK_GRID)
        cols = np.flatnonzero(np.repeat(TRIADS[name], 3))
        stat = [tuple(x.sum() for x in _residual_steps(flight, measured, cols, name, x))
                for x in grid]
        stat = [(total / n, n) for total, n in stat]
        (best, n_bins), (at, _) = min(stat), stat[CHECK_GRID.index(1.0)]
        if at > best * (1 + CHECK_Z * math.sqrt(2 / n_bins)):
            return {"sensor": name, "least_at_s": float(grid[stat.index(min(stat))])}
    return None


def _residual_steps(flight, measured, cols, name, lag, blocks=1):
    """(sum of squares of the first differences of CHECK_BIN_S means of measured -
    predicted, the number of those differences), each (blocks,) over that many contiguous
    blocks of them, over the columns `cols`, the triad `name` lagging by `lag` s."""
    lags = tuple(lag * m for m in TRIADS[name])
    f_p, w_p, inside = predicted_mimu(replace(flight, mimu_lag_s=lags))
    r = (measured - np.hstack([f_p, w_p]))[inside][:, cols]
    t = flight.mimu_t[inside]
    k = ((t - t[0]) // CHECK_BIN_S).astype(int)
    count = np.bincount(k)
    means = np.stack([np.bincount(k, r[:, c]) for c in range(len(cols))], 1)[count > 0]
    steps = np.diff(means / count[count > 0, None], axis=0)
    steps = steps[np.all(np.isfinite(steps), axis=1)]
    block = np.arange(len(steps)) * blocks // max(len(steps), 1)
    return (np.bincount(block, np.sum(steps ** 2, axis=1), blocks),
            np.bincount(block, minlength=blocks) * steps.shape[1])


def direct_lag(flight, measured, name, reach_s):
    """The lag (s) of the triad `name` where its residual (`measured`: `measured_outputs`)
    against the exactly lagged prediction is least (`_residual_steps`), searched from 0 to
    reach_s in steps of LINEAR_SKEW_S / 2 and refined by a parabola, with its 95 % interval
    by the jackknife over DIRECT_BLOCKS contiguous blocks (each left out of the summed
    residual in turn, Student t: a block in a long rest, its residual flat, moves no part -
    its own least would lie anywhere): {"sensor", "lag_s", "ci95", "jackknife_s"}; None where the whole record's or
    a part's least lies at the search's end."""
    cols = np.flatnonzero(np.repeat(TRIADS[name], 3))
    grid = np.arange(0.0, abs(reach_s) + 1e-12, LINEAR_SKEW_S / 2) * np.sign(reach_s)
    sums = np.array([_residual_steps(flight, measured, cols, name, x, DIRECT_BLOCKS)[0]
                     for x in grid])                            # (lags, blocks)
    total = sums.sum(axis=1)
    lag = parabola_min(grid, total)
    parts = np.array([parabola_min(grid, total - sums[:, b]) for b in range(DIRECT_BLOCKS)])
    if not np.isfinite(lag) or not np.isfinite(parts).all():
        return None
    se = math.sqrt((DIRECT_BLOCKS - 1) / DIRECT_BLOCKS * np.sum((parts - parts.mean()) ** 2))
    half = stats.t.ppf(0.975, DIRECT_BLOCKS - 1) * se
    return {"sensor": name, "lag_s": float(lag), "ci95": [float(lag - half), float(lag + half)],
            "jackknife_s": parts.tolist()}


def _beyond_linear(diag):
    """The time_skew finding of a triad (or the unit) beyond LINEAR_SKEW_S, the largest;
    None where there is none."""
    skews = [f for f in diag.findings if f["effect"] == "time_skew" and f["sensor"] in TRIADS
             and abs(f["coefficient"]) > LINEAR_SKEW_S]
    return max(skews, key=lambda f: abs(f["coefficient"]), default=None)


def _fold(diag, first, shift, passes, unsettled, direct=None):
    """The `shift` (s) applied for first's triad into the diagnosis: its skew finding is the
    shift plus the last pass's remainder (found, or fitted beside the findings where it is
    no longer significant) - or, where the shift is the data's own least (`direct`:
    `direct_lag`), that lag and its blocks' interval; `unsettled`: a skew still beyond
    LINEAR_SKEW_S after the passes, or a lag the residual does not put where the fit did
    (no `direct_lag` either) - then the triad's findings are set aside, the diagnosis
    inconclusive."""
    said = (f"the prediction shifted by {shift * 1e3:.4g} ms over {passes} pass(es): a time "
            f"skew beyond {LINEAR_SKEW_S * 1e3:.2g} ms is no linear term (-tau df/dt)")
    if direct is not None and direct["sensor"] == first["sensor"]:
        diag.findings = [f for f in diag.findings if f["label"] != first["label"]] + [dict(
            first, coefficient=direct["lag_s"], ci95=direct["ci95"], shifted={
                "lag_s": shift, "passes": passes, "said": said + "; the lag where the residual "
                "against the exactly shifted prediction is least, its interval jackknifed over "
                f"{DIRECT_BLOCKS} blocks (the fit's bias wander had taken part of it)"},
            ci95_method=f"the residual's least over exact shifts; jackknife over "
                        f"{DIRECT_BLOCKS} blocks, Student t")]
        return
    if unsettled is not None and unsettled["sensor"] == first["sensor"]:
        why = f"time_skew {first['sensor']}.all: {said}, " + (  # the remainder's second
            f"and its remainder {unsettled['coefficient'] * 1e3:.3g} ms still is: the lag "
            "did not settle" if "least_at_s" not in unsettled else  # order is in the triad's
            f"but the residual against the prediction shifted exactly is least near "
            f"{unsettled['least_at_s'] * 1e3:.3g} ms (of 0 to twice the shift): the fit's bias "
            "wander takes the skew's slow signal - the lag is not measured")
        near = [f["sensor"] in (first["sensor"], "imu") for f in diag.findings]
        diag.rejected = diag.rejected + [dict(f, rejected=why)
                                         for f, n in zip(diag.findings, near) if n]
        diag.findings = [f for f, n in zip(diag.findings, near) if not n]
        diag.inconclusive = diag.inconclusive + [why]
        return
    same = [f for f in diag.findings if f["label"] == first["label"]]
    finding = same[0] if same else _remainder(diag, first)
    if finding is None:
        diag.inconclusive = diag.inconclusive + [
            f"time_skew {first['sensor']}.all: {said}; its remainder could not be fitted"]
        return
    if not same:
        diag.findings = diag.findings + [finding]
    finding["coefficient"] += shift
    finding["ci95"] = [float(c) + shift for c in finding["ci95"]]
    finding["shifted"] = {"lag_s": shift, "passes": passes, "said": said}


def _remainder(diag, first):
    """The skew `first` (a finding of the first pass: its tests and effect size) with the
    last pass's remainder as its coefficient and interval - fitted beside the findings on
    every bin where it is no longer significant; None where the design has no such term."""
    labels = [library.label(t) for t in diag.design.terms]
    if first["label"] not in labels:
        return None
    j = labels.index(first["label"])
    given = [labels.index(f["label"]) for f in diag.findings if f["label"] in labels]
    b, cov = diag.fitter.fit(given + [j]).of(j)
    value, sd = float(b[0]), math.sqrt(float(cov[0, 0]))
    return dict(first, coefficient=value, ci95=[value - 1.96 * sd, value + 1.96 * sd],
                ci95_method="the remainder fitted beside the findings, about the shift")
