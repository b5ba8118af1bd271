"""After the fit: localized excursions of the residual (2 s windows against a local
baseline, robust z, Bonferroni), and the residual map - rms in each flight condition over the
same in quiet flight.
"""
import numpy as np
from scipy import stats

from ..compensation.effects import derivative
from ..sensors.mimu import G0
from . import outputs
from .design import CHANNELS, DEG


SCAN_WINDOW_S = 2.0
SCAN_DOF = 10
MAP_SECONDS = 1.0


def near_spans(t, spans, margin_s):
    """(n,) bool: the times t (s) within margin_s of any span {"t0", "t1"} (s)."""
    out = np.zeros(len(t), bool)
    for span in spans:
        out |= (t >= span["t0"] - margin_s) & (t <= span["t1"] + margin_s)
    return out


# ---- after the fit: residual map and localized excursions -------------------------------
def excursions(design, x, alpha):
    """Localized excursions of the residual x: per channel, the mean over SCAN_WINDOW_S
    windows started every second against its local baseline (the windows starting 4 and 5 s
    before and after, so a slow wander cancels and an excursion of a few seconds does not
    hide in its own baseline); robust z across the windows (MAD), Bonferroni over windows x
    channels with Student-t tails of SCAN_DOF degrees of freedom. Where the bins' white
    variance varies (`design.scan_shape`, else `shape`) each window's step is first divided by its own standard
    deviation under that shape, so the MAD compares like with like (a vehicle model's yaw
    rate at 2 m/s errs ten times more than at 20 m/s: departures from stops had stood out at
    z 10-25 on null drives). Returns spans [{"t0", "t1", "channel", "z", "size", "units",
    "peak_t0"}] (overlapping windows merged; z and size - the effect: the window's mean less
    its baseline's, in the channel's SI units - of the window of largest |z|, which starts
    at peak_t0 s). Bins further apart than SCAN_WINDOW_S (a 1 Hz track's 4-6 s) stretch
    the scan's second to half their median spacing, so a window holds one bin and its
    baseline its neighbours' (`scan_unit_s`)."""
    t = design.t
    unit = scan_unit_s(t)
    sec = outputs.block_index(t, unit)
    n = sec.max() + 1
    counts = np.bincount(sec, minlength=n).astype(float)
    length = int(round(SCAN_WINDOW_S))
    kernel = np.ones(length)
    win_counts = np.convolve(counts, kernel, "valid")
    # a window holds half the median window's bins, and one at least: bins longer than the
    # window (a 1 Hz track's 4 s) leave half the windows empty, the median 0, and an empty
    # window's 'mean' of 0 against its neighbours' bins had stood out as an excursion where
    # no bin lies, twice for each real one
    full = (win_counts > 0) & (win_counts >= 0.5 * np.median(win_counts))
    nwin = len(win_counts)
    z_limit = stats.t.isf(alpha / (2 * nwin * 6), SCAN_DOF)
    spans = []
    shape = design.shape if getattr(design, "scan_shape", None) is None else design.scan_shape
    def around(w):                  # (4, nwin): the baseline windows of each window
        pad = np.concatenate([np.full(5, np.nan), w, np.full(5, np.nan)])
        return np.stack([pad[5 + d:5 + d + nwin] for d in (-5, -4, 4, 5)])
    for ch in range(6):
        sums = np.convolve(np.bincount(sec, x[:, ch], minlength=n), kernel, "valid")
        means = np.where(full, sums / np.maximum(win_counts, 1), np.nan)
        base_windows = around(means)
        count = np.isfinite(base_windows).sum(axis=0)
        base = np.nansum(base_windows, axis=0) / np.maximum(count, 1)
        step = size = np.where(count >= 2, means - base, np.nan)
        if shape is not None:                   # each step over its own sd (the shape's)
            var = np.convolve(np.bincount(sec, shape[:, ch], minlength=n), kernel,
                              "valid") / np.maximum(win_counts, 1) ** 2
            var = np.where(full, var, np.nan)
            # a window without samples: NaN, left out below
            with np.errstate(invalid="ignore", divide="ignore"):
                step = step / np.sqrt(var + np.nansum(around(var), axis=0) /
                                      np.maximum(count, 1) ** 2)
        good = np.isfinite(step)
        if good.sum() < 10:
            continue
        z = np.zeros(len(step))
        overall = 1.4826 * np.median(np.abs(step[good] - np.median(step[good])))
        for group in _strata(good, var if shape is not None else None, around, count):
            centre = np.median(step[group])
            spread = max(1.4826 * np.median(np.abs(step[group] - centre)), overall)
            if spread > 0:
                z[group] = (step[group] - centre) / spread
        # an excursion also shows, halved and reversed, where it sits in a baseline (4-6 s
        # away): keep only windows that are the largest within that reach
        largest = np.abs(z) >= _running_max(np.abs(z), 6)
        for w_id in np.flatnonzero((np.abs(z) > z_limit) & largest):
            t0 = t[0] + w_id * unit
            peak = {"z": float(z[w_id]), "size": float(size[w_id]), "peak_t0": float(t0)}
            if spans and spans[-1]["channel"] == ch and spans[-1]["t1"] >= t0 - 1e-9:
                spans[-1]["t1"] = t0 + SCAN_WINDOW_S * unit
                if abs(peak["z"]) > abs(spans[-1]["z"]):
                    spans[-1].update(peak)
            else:
                spans.append({"t0": float(t0), "t1": float(t0 + SCAN_WINDOW_S * unit),
                              "channel": ch, **peak})
    for s in spans:
        s["units"] = "m/s^2" if CHANNELS[s["channel"]][0] == "accel" else "rad/s"
        s["channel"] = f"{CHANNELS[s['channel']][0]}.{CHANNELS[s['channel']][1]}"
    return spans


def scan_unit_s(t):
    """The scan's second (s) over bins at times t (s): 1, or half the bins' median spacing
    where that is longer than SCAN_WINDOW_S."""
    spacing = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    return 0.5 * spacing if spacing > SCAN_WINDOW_S else 1.0


def overlaps(a, b, margin_s=0.0):
    """Whether spans a and b {"channel", "t0", "t1"} (s) lie on one channel and overlap, or
    come within margin_s of each other."""
    return (a["channel"] == b["channel"] and a["t0"] < b["t1"] + margin_s
            and b["t0"] < a["t1"] + margin_s)


def spans_said(spans, shown=3):
    """The spans {"channel", "t0", "t1"} in words, the first `shown` of them."""
    return ", ".join(f"{u['channel']} {u['t0']:.1f}-{u['t1']:.1f} s" for u in spans[:shown]) \
        + (", ..." if len(spans) > shown else "")


ECHO_S = 5.0    # s: an excursion shows, halved and reversed, in the windows whose baselines
#                 hold it (4 and 5 s away): a span stands where either stands again


def excursions_left_out(design, residual_on, alpha, spans):
    """The excursions `spans` of the all-rows fit that stand again on a residual whose fit
    leaves out the bins near all of them (SCAN_WINDOW_S either side), as the all-rows fit
    reads them: an excursion is no sample of the model, and a fit that takes it spreads it
    into the reference's fitted error elsewhere (a catapult's clipped launch had pulled the
    reference's accel.x <- f_z coupling to -0.013, and the belly landing stood out as an
    excursion of 0.09 m/s^2 the two IMUs' outputs do not hold: left out too, it is read on
    a fit that never took the launch, and is quiet). The refit only decides which stand: on
    the bins it left out it extrapolates, and over a manoeuvre it never saw - a bias pulse
    inside a 120 deg/s turn - its own error stands out on other channels and swells the
    excursions (an independent review: one true excursion had become four; a z of 6.3 had
    read 22.7). A span stands where the refit finds one on its channel within ECHO_S of it
    (a car's departure, +2.8 m/s^2, shows in the all-rows scan as its echo 4 s later).
    residual_on(rows): (nb, 6) the residual of the fit on `rows` (bool, nb) alone."""
    if not spans:
        return spans
    again = excursions(design, residual_on(~near_spans(design.t, spans, SCAN_WINDOW_S)), alpha)
    return [first for first in spans if any(overlaps(first, s, ECHO_S) for s in again)]


STRATUM_WINDOWS = 30    # windows a stratum needs for its own robust scale


def _strata(good, var, around, count):
    """The windows (`good`, bool) judged together: all of them, or - where the bins' shape
    gives each window's variance `var` - those at its floor (within 1.5 times its least: a
    vehicle model's rest, held exact) apart from the others, each with STRATUM_WINDOWS at
    least: the shape's law for moving bins is a model, and its scale is not the rest's (a
    car's pose-referenced null drive: moving windows' steps spread 7.1e-5, its stops' 2.3e-4
    under that shape, and a stop's 3.6-sigma gyro.z noise stood out at z 8.9). A stratum is
    never judged by a scale smaller than all the windows' together (`excursions`): on its
    own, a null hilly drive's moving pitch rate stood out at z 8.5-9.8 three times."""
    if var is None:
        return [good]
    total = var + np.nansum(around(var), axis=0) / np.maximum(count, 1) ** 2
    floor = good & (total <= 1.5 * np.nanmin(np.where(good, total, np.nan)))
    groups = [floor, good & ~floor]
    if min(int(g.sum()) for g in groups) < STRATUM_WINDOWS:
        return [good]
    return groups


def _running_max(x, reach):
    """max(x[i - reach .. i + reach]) for every i."""
    pad = np.concatenate([np.zeros(reach), x, np.zeros(reach)])
    return np.max(np.stack([pad[k:k + len(x)] for k in range(2 * reach + 1)]), axis=0)


CONDITIONS = ("quiet", "|f| > 2 g", "|w| > 60 deg/s", "|dw/dt| > 300 deg/s^2",
              "|dT/dt| > 0.5 degC/min")


def condition_masks(design, norms):
    """Bin masks of the flight conditions of the residual map; norms (nb, 4): the design's
    bins' mean |f| m/s^2, |w| rad/s, |dw/dt| rad/s^2 and temperature degC
    (`samples.Bins.norms`)."""
    f, w, wd = norms[:, 0] / G0, norms[:, 1] / DEG, norms[:, 2] / DEG
    temperature = norms[:, 3:]                          # slope on the bins
    dT = (np.abs(derivative(design.t, temperature, 30.0)[:, 0] * 60)
          if np.isfinite(temperature).all() else np.zeros(len(norms)))   # none recorded
    masks = {"|f| > 2 g": f > 2, "|w| > 60 deg/s": w > 60, "|dw/dt| > 300 deg/s^2": wd > 300,
             "|dT/dt| > 0.5 degC/min": dT > 0.5}
    # quiet: no manoeuvre (a warm-up's temperature change alone does not make a bin busy,
    # else a flight that warms throughout would have no quiet reference at all)
    masks["quiet"] = ~np.any([masks[k] for k in CONDITIONS[1:4]], axis=0)
    return {k: masks[k] for k in CONDITIONS}


def condition_map(design, x, conds, seconds=MAP_SECONDS):
    """(conditions, 6): rms of the cleaned residual x averaged over `seconds` (so systematic
    terms stand out of the white noise) in each condition (a majority of its bins) over the
    same in quiet flight; NaN where a condition has fewer than 10 such averages."""
    t = design.t
    sec = outputs.block_index(t, seconds)
    n = sec.max() + 1
    count = np.maximum(np.bincount(sec, minlength=n), 1)
    means = np.column_stack([np.bincount(sec, x[:, c], minlength=n) / count for c in range(6)])
    full = np.bincount(sec, minlength=n) >= 0.5 * seconds / design.bin_s
    share = {k: np.bincount(sec, m.astype(float), minlength=n) / count for k, m in conds.items()}
    quiet = full & (share["quiet"] > 0.5)
    quiet = quiet if quiet.sum() >= 10 else full
    out = np.full((len(conds), 6), np.nan)
    if quiet.sum() < 10:            # no quiet flight to measure against (short bins' seconds
        return out                  # not half full): nothing to map, said as NaN
    ref = np.sqrt(np.mean(means[quiet] ** 2, axis=0))
    for r, key in enumerate(conds):
        mask = full & (share[key] > 0.5)
        if mask.sum() >= 10:
            out[r] = np.sqrt(np.mean(means[mask] ** 2, axis=0)) / ref
    return out
