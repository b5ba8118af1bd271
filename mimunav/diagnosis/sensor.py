"""Sensor-level diagnosis: the recorded MIMU, compensated with the user's calibration, against
what the reference motion says it should have read (`reference.predicted_mimu`).

Procedure (every choice is made on training segments and judged on held-out ones):
 1. residual = compensated MIMU - prediction, 6 channels, bad samples (flagged by the
    compensation, outside the reference) dropped with their bins;
 2. the flight is cut into SEGMENTS contiguous segments; even ones train, odd ones are held
    out (contiguous, so a held-out segment shares no noise with the training data beyond
    the wander that the nuisance carries);
 3. forward selection on the training rows: every candidate of the library is tested
    against the nuisance and the terms already chosen; the smallest p-value must pass
    Holm's step-down threshold over the whole library (family-wise error alpha). Candidates
    that are significant on their own but explain each other away (each one's p > alpha once
    the other is in) are named together: this trajectory cannot tell them apart;
 4. the chosen terms are refitted on the held-out rows alone: coefficient, 95 % interval and
    p-value there; a term is confirmed when p < alpha / (number chosen) with the training
    sign, and when it wins the block bootstrap of the training data in at least
    STABILITY of the replicates (against the ten nearest competitors of its tier);
 5. the residual left after the confirmed terms is scanned for localized excursions (2 s
    windows, robust z over the windows, Bonferroni at alpha): any found is reported as an
    unexplained residual with its place.
"""
import math
from dataclasses import dataclass, replace

import numpy as np
from scipy import stats

from .. import effects
from ..evaluation import compensated_mimu
from ..effects import AXES, Conditions, derivative
from ..sensors.mimu import G0, NoiseModel
from ..calibration import flicker_covariance
from . import inference, library
from .inference import Tier
from .reference import DERIVATIVE_WINDOW_S, predicted_mimu

FAST_BIN_S = 0.01
SLOW_BIN_S = 1.0
SEGMENTS = 10
MAX_TERMS = 4
STABILITY = 0.5
BOOTSTRAP = 200
SCAN_WINDOW_S = 2.0
SCAN_DOF = 5
MAP_SECONDS = 1.0
# What the reference itself may carry: a Table-4-grade FOG-IMU's residual scale factor and
# axis misalignment (3 sigma of `sensors.fog`: 1e-4 scale, 20 urad), which the MIMU's
# residual shows as scale, cross-coupling and misalignment terms of its own. A term of
# these kinds is charged to the MIMU only when its held-out interval lies beyond this.
REFERENCE_ACCURACY = {"scale_factor": 3e-4, "cross_coupling": 3e-4,
                      "mounting_misalignment": 3e-4}
CHANNELS = [("accel", a) for a in AXES] + [("gyro", a) for a in AXES]
DEG = math.pi / 180


@dataclass
class SensorDiagnosis:
    level = "sensor"
    findings: list              # contract findings (+ extra keys)
    unexplained: list           # [{"t0", "t1", "channel", "z"}]
    rejected: list              # chosen on training data, not confirmed (with why)
    tiers: dict
    train: dict                 # tier -> bool rows
    conditions: dict            # fast-bin condition masks for the map
    residual_map: dict          # "before"/"after": (conditions, 6) rms ratios
    candidates: int
    candidates_list: list       # [(tier, term, position in tier)]
    residual_after: dict        # tier -> residual with the confirmed terms removed


def residual(flight, cal):
    """(t s, residual (N, 6) accel m/s^2 then gyro rad/s, usable (N,), Conditions)."""
    temperature, frequency = flight.mimu_temperatures()
    w, f, flags = compensated_mimu(flight, cal, per_sample=True)
    f_p, w_p, inside = predicted_mimu(flight)
    t = flight.mimu_t
    cond = Conditions(t, f_p, w_p, derivative(t, f_p, DERIVATIVE_WINDOW_S),
                      derivative(t, w_p, DERIVATIVE_WINDOW_S),
                      temperature, frequency)
    res = np.hstack([f - f_p, w - w_p])
    usable = inside & (flags == 0) & np.isfinite(res).all(axis=1)
    usable[0] = False                       # the sample at the first stamp has no interval
    return t, res, usable, cond


def _bin(x, m, usable):
    """Means of m consecutive samples; bins with any unusable sample are NaN."""
    n = len(x) // m * m
    shape = (n // m, m) + x.shape[1:]
    out = x[:n].reshape(shape).mean(axis=1)
    bad = ~usable[:n].reshape(n // m, m).all(axis=1)
    out[bad] = np.nan
    return out


def diagnose(flight, cal, noise=None, alpha=0.05, seed=0, candidates=None):
    """Sensor-level diagnosis of `flight` (an `evaluation.Flight` with a reference IMU)
    against calibration `cal`. `noise`: the unit's noise model (default: the datasheet class
    of `sensors.mimu.NoiseModel`), whose flicker instability sets the slow tier's wander;
    `candidates`: the library to test (default `library.candidates()`)."""
    noise = noise or NoiseModel()
    t, res, usable, cond = residual(flight, cal)
    rate = 1.0 / np.median(np.diff(t))
    m_fast, m_slow = max(1, round(FAST_BIN_S * rate)), max(1, round(SLOW_BIN_S * rate))
    tiers, cands = _tiers(t, res, usable, cond, candidates or library.candidates(), m_fast,
                          m_slow, noise)
    t0, t1 = tiers["fast"].t[0], tiers["fast"].t[-1]
    seg = lambda tt: np.minimum(((tt - t0) / (t1 - t0) * SEGMENTS).astype(int), SEGMENTS - 1)  # noqa
    train = {k: seg(tr.t) % 2 == 0 for k, tr in tiers.items()}
    held = {k: ~v for k, v in train.items()}

    chosen = _select(tiers, cands, train, alpha)
    rng = np.random.default_rng(seed)
    findings, rejected = [], []
    for tier_name in ("fast", "linear", "slow"):
        terms = [c for c in chosen if cands[c["j"]][0] == tier_name]
        if not terms:
            continue
        tier = tiers[tier_name]
        idx = [cands[c["j"]][2] for c in terms]
        idx += [pos for pos in _current(cands, chosen, tier_name) if pos not in idx]
        fit_tr = inference.fit(tier, idx, train[tier_name])
        fit_ho = inference.fit(tier, idx, held[tier_name])
        for pos, c in enumerate(terms):
            finding, why = _judge(tier, cands, c, pos, fit_tr, fit_ho, len(chosen), alpha,
                                  train[tier_name], held[tier_name], rng, cond)
            (findings if why is None else rejected).append(
                finding if why is None else dict(finding, rejected=why))
    after = _remove(tiers, cands, findings)
    shown = tiers["linear"]                 # fast bins, bias wander removed only
    unexplained = _scan(shown, after["linear"], alpha)
    conds = _condition_masks(shown, cond, m_fast, usable)
    before_map = _map(shown, shown.residual, conds)
    after_map = _map(shown, after["linear"], conds)
    return SensorDiagnosis(findings, unexplained, rejected, tiers, train, conds,
                           {"before": before_map, "after": after_map}, len(cands), cands, after)


def verdict(diag):
    """The contract verdict: missing-physics when a term is confirmed, otherwise
    unexplained-residual when a localized excursion remains, otherwise no-missing-physics."""
    if diag.findings:
        return "missing-physics"
    return "unexplained-residual" if diag.unexplained else "no-missing-physics"


# ---- tiers ----------------------------------------------------------------------------
def _tiers(t, res, usable, cond, cands, m_fast, m_slow, noise):
    """Bin the residual and each candidate's regressor into its tier; drop candidates the
    flight cannot drive (no variation once the bias is removed)."""
    sigma = [_white_sigma(res[usable, c]) for c in range(6)]
    out = {}
    for name, m in (("fast", m_fast), ("slow", m_slow)):
        tb = _bin(t, m, usable)
        rb = _bin(res, m, usable)
        ok = np.isfinite(rb).all(axis=1)
        inputs = _bin(np.hstack([cond.f, cond.w]), m, usable)[ok]
        out[name] = Tier(name, name, tb[ok], rb[ok], [], [], samples_per_bin=m, kept=ok,
                         linear=[inputs[:, :3]] * 3 + [inputs[:, 3:]] * 3)
    out["fast"].knot_s = tuple(
        [inference.knot_spacing(noise.accel_white, noise.accel_flicker)] * 3
        + [inference.knot_spacing(noise.gyro_white, noise.gyro_flicker)] * 3)
    # the linear terms: the same bins and columns, without the linear nuisance
    out["linear"] = replace(out["fast"], name="linear", linear=None, _cache={})
    slow = out["slow"]
    slow.white = np.asarray(sigma) / math.sqrt(m_slow)
    b = [noise.accel_flicker] * 3 + [noise.gyro_flicker] * 3
    slow.flicker = np.asarray(b)
    half = 0.5 * SLOW_BIN_S
    span = t[-1] - t[0]
    slow.flicker_cov = flicker_covariance(slow.t - half, slow.t + half, 1 / (4 * span),
                                          0.5 / SLOW_BIN_S)
    means = {"accel": cond.T[usable].mean(axis=0), "gyro": cond.freq[usable].mean(axis=0)}
    kept = []
    for tier_name, term in cands:
        tier = out[tier_name]
        if term["effect"] in ("temperature_bias", "temperature_scale"):
            term["reference"] = float(means[term["sensor"]][AXES.index(term["axis"])])
        cols = {}
        for (sensor, i), x in effects.regressor(term, cond).items():
            cols[(0 if sensor == "accel" else 3) + i] = _bin(x, tier.samples_per_bin, usable)[tier.kept]
        scale = max(np.abs(x).max() for x in cols.values())
        spread = max(np.ptp(x, axis=0).max() for x in cols.values())
        if not np.isfinite(spread) or spread <= 1e-9 * max(scale, 1e-300):
            continue
        tier.columns.append(cols)
        tier.k.append(next(iter(cols.values())).shape[1])
        kept.append((tier_name, term, len(tier.columns) - 1))
    return out, kept


def _white_sigma(x):
    """White noise of one sample from first differences (robust: MAD)."""
    d = np.diff(x)
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2))


# ---- selection on training rows ---------------------------------------------------------
def _current(cands, chosen, tier_name):
    """Positions of the chosen terms a test in `tier_name` conditions on: its own, and for
    the linear tier also the fast ones (same bins and columns; in the fast tier the linear
    terms are part of the nuisance)."""
    own = ("fast", "linear") if tier_name == "linear" else (tier_name,)
    return [cands[c["j"]][2] for c in chosen if cands[c["j"]][0] in own]


def _select(tiers, cands, train, alpha):
    """Forward selection with Holm's step-down thresholds over the whole library."""
    chosen, excluded = [], set()
    m = len(cands)
    for step in range(MAX_TERMS):
        p, evidence = np.ones(m), np.ones(m)
        for j, (tn, _, pos) in enumerate(cands):
            if j not in excluded:
                cur = _current(cands, chosen, tn)
                fit = inference.fit(tiers[tn], cur + [pos], train[tn])
                p[j], evidence[j] = fit.test(len(cur))[1], fit.test(len(cur), nominal=True)[1]
        threshold = inference.holm_threshold(alpha, m, step)
        if p.min() > threshold:
            break
        # of the candidates that pass, the one the data favour most (nominal p: the Wald
        # statistic), so that a term whose regressor lives in fewer blocks (x^2 against |x|)
        # is not passed over for the size of its degrees-of-freedom correction
        passing = np.flatnonzero(p <= threshold)
        best = int(passing[np.argmin(evidence[passing])])
        tn, _, pos_b = cands[best]
        cur = _current(cands, chosen, tn)
        alternatives = []
        for j in np.flatnonzero(p <= threshold):
            if j == best or cands[j][0] != tn:
                continue
            pos_j = cands[j][2]
            p_j = inference.fit(tiers[tn], cur + [pos_b, pos_j], train[tn]).test(len(cur) + 1)[1]
            p_b = inference.fit(tiers[tn], cur + [pos_j, pos_b], train[tn]).test(len(cur) + 1)[1]
            if p_j > alpha and p_b > alpha:
                alternatives.append(int(j))
        same = [j for j in np.argsort(evidence) if cands[j][0] == tn and j not in excluded]
        chosen.append(dict(j=best, alternatives=alternatives, p_train=float(p[best]),
                           threshold=threshold, competitors=[int(j) for j in same[:10]],
                           prior=list(cur)))
        excluded |= {best, *alternatives}
    return chosen


# ---- confirmation on held-out rows -------------------------------------------------------
def _judge(tier, cands, c, pos, fit_tr, fit_ho, n_chosen, alpha, train, held, rng, cond):
    tn, term, _ = cands[c["j"]]
    s = fit_ho.slices[pos]
    b_tr, b_ho = fit_tr.beta[fit_tr.slices[pos]], fit_ho.beta[s]
    _, p_ho = fit_ho.test(pos)
    lo, hi = fit_ho.interval(pos)
    if term["effect"] in REFERENCE_ACCURACY:      # the reference's own error, 1 sigma, added
        half = np.hypot(hi - b_ho, 1.96 * REFERENCE_ACCURACY[term["effect"]] / 3)
        lo, hi = b_ho - half, b_ho + half
    stability = _stability(tier, cands, c, train, rng)
    contribution = _contribution(tier, cands[c["j"]][2], b_ho)
    where_rows = _where_rows(contribution)
    finding = estimate(term, b_ho, lo, hi)
    finding["where"] = _spans(tier, where_rows, term, cond)
    finding["fit"] = _rms_fit(tier, cands[c["j"]][2], b_tr, where_rows, train, held, term)
    for key in ("order", "window_s", "reference"):
        if key in term:
            finding[key] = term[key]
    finding.update(
        label=library.label(term), tier=tn, p_train=c["p_train"], holm_threshold=c["threshold"],
        p_heldout=p_ho, train_coefficient=b_tr.tolist() if len(b_tr) > 1 else float(b_tr[0]),
        bootstrap_stability=stability,
        indistinguishable_from=[_alternative(cands[j][1]) for j in c["alternatives"]])
    why = None
    if p_ho >= alpha / n_chosen:
        why = f"held-out p = {p_ho:.2g}, needs < {alpha / n_chosen:.2g}"
    elif float(b_tr @ b_ho) <= 0:
        why = "the held-out coefficient has the other sign"
    elif not _beyond_reference(term["effect"], lo, hi):
        why = (f"inside the reference's own accuracy (+-{REFERENCE_ACCURACY[term['effect']]:g}):"
               " cannot be charged to the MIMU")
    elif stability < STABILITY:
        why = f"chosen in {stability:.0%} of the block-bootstrap replicates (< {STABILITY:.0%})"
    return finding, why


def estimate(term, beta, lo, hi):
    """The contract's description of a term with its held-out estimate and 95 % interval
    (a vector parameter as `vector`, its largest component as `coefficient`)."""
    finding = {k: v for k, v in term.items() if k in ("effect", "sensor", "axis", "input_axis")}
    if len(beta) == 1:
        finding.update(coefficient=float(beta[0]), ci95=[float(lo[0]), float(hi[0])])
    else:
        big = int(np.argmax(np.abs(beta)))
        finding.update(coefficient=float(beta[big]), ci95=[float(lo[big]), float(hi[big])],
                       vector=beta.tolist(), vector_ci95=np.column_stack([lo, hi]).tolist())
    finding["units"] = effects.units(term)
    return finding


def _beyond_reference(effect, lo, hi):
    limit = REFERENCE_ACCURACY.get(effect)
    return limit is None or bool(np.any((lo > limit) | (hi < -limit)))


def _alternative(term):
    out = {k: term[k] for k in ("effect", "sensor", "axis", "input_axis", "order", "window_s")
           if k in term}
    out["label"] = library.label(term)
    return out


def _stability(tier, cands, c, train, rng):
    """Share of block-bootstrap replicates of the training rows in which the chosen term (or
    a candidate it cannot be told from) has the smallest p-value among its tier's ten
    strongest competitors."""
    winners = {c["j"], *c["alternatives"]}
    pvals, weights = [], None
    for j in c["competitors"]:
        s, q = inference.block_scores(tier, cands[j][2], c["prior"], train)
        if weights is None:
            weights = rng.multinomial(len(s), np.full(len(s), 1 / len(s)), size=BOOTSTRAP)
        with np.errstate(all="ignore"):
            try:
                w = inference.wald_from_blocks(s, q, weights.astype(float))
            except np.linalg.LinAlgError:
                w = np.zeros(BOOTSTRAP)
        pvals.append(stats.f.sf(np.nan_to_num(w), s.shape[1], len(s) - 1))
    best = np.asarray(c["competitors"])[np.argmin(np.array(pvals), axis=0)]
    return float(np.isin(best, list(winners)).mean())


def _contribution(tier, pos, beta):
    """(nb, 6) the term's contribution to each channel, natural units."""
    out = np.zeros((len(tier.t), tier.channels))
    for ch, cols in tier.columns[pos].items():
        out[:, ch] = cols @ beta
    return out


def _where_rows(contribution):
    """Rows where the term acts: its contribution above a quarter of its peak (99.9th
    percentile of the magnitude over the channels it drives)."""
    mag = np.linalg.norm(contribution / (np.abs(contribution).max(axis=0) + 1e-300), axis=1)
    peak = np.percentile(mag, 99.9)
    return mag >= 0.25 * peak if peak > 0 else np.zeros(len(mag), bool)


def clean(tier, resid):
    """Residual with the tier's nuisance removed over all rows (for display and rms): fast
    kind the piecewise-linear wander (and the linear response if the tier has it), slow
    kind the mean."""
    rows = np.ones(len(tier.t), bool)
    if tier.kind == "slow":
        return resid - resid.mean(axis=0)
    whiten, _, scale = tier.prepared(rows)
    return np.column_stack([whiten(resid[:, c], c) * scale[c] for c in range(6)])


def _rms_fit(tier, pos, b_tr, where, train, held, term):
    """Residual rms in the term's located rows before and after removing it with the
    training coefficient, on training and on held-out rows (nuisance removed)."""
    before = clean(tier, tier.residual)
    after = clean(tier, tier.residual - _contribution(tier, pos, b_tr))
    chans = sorted(tier.columns[pos])
    if term["sensor"] == "imu":         # report the sensor whose channels gain most
        gains = {s: [ch for ch in chans if (ch < 3) == (s == "accel")] for s in ("accel", "gyro")}
        ratio = {s: _rms(after, where, chs) / max(_rms(before, where, chs), 1e-300)
                 for s, chs in gains.items() if chs}
        sensor = min(ratio, key=ratio.get)
        chans = gains[sensor]
    else:
        sensor = term["sensor"]
    out = {}
    for part, rows in (("train", train), ("heldout", held)):
        out[f"{part}_rms_before"] = _rms(before, where & rows, chans)
        out[f"{part}_rms_after"] = _rms(after, where & rows, chans)
    out["units"] = "m/s^2" if sensor == "accel" else "rad/s"
    out["channels"] = [f"{CHANNELS[ch][0]}.{CHANNELS[ch][1]}" for ch in chans]
    out["basis"] = (f"{tier.name}-tier bin means ({FAST_BIN_S if tier.kind == 'fast' else SLOW_BIN_S:g} s)"
                    ", the tier's nuisance removed, rows where the term acts; 'after' uses "
                    "the training coefficient")
    return out


def _rms(x, rows, chans):
    v = x[np.ix_(rows, chans)]
    return float(np.sqrt(np.mean(v ** 2))) if v.size else float("nan")


def _spans(tier, rows, term, cond, gap_s=2.0, max_spans=20):
    """Contiguous time spans of the rows (gaps below gap_s merged) with the flight
    conditions met there."""
    t = tier.t
    if not rows.any():
        return []
    half = 0.5 * float(np.median(np.diff(t)))
    idx = np.flatnonzero(rows)
    breaks = np.flatnonzero(np.diff(t[idx]) > gap_s)
    starts, ends = np.r_[idx[0], idx[breaks + 1]], np.r_[idx[breaks], idx[-1]]
    order = np.argsort(-(t[ends] - t[starts]))[:max_spans]
    spans = []
    for a, b in sorted(zip(starts[order], ends[order])):
        t0, t1 = float(t[a] - half), float(t[b] + half)
        spans.append({"t0": t0, "t1": t1, "condition": _describe(cond, t0, t1, term)})
    return spans


def _describe(cond, t0, t1, term):
    """What the flight did in [t0, t1]: peak |f| (g), |w| (deg/s), temperature range."""
    k = (cond.t >= t0) & (cond.t <= t1)
    if not k.any():
        return library.label(term)
    f = np.linalg.norm(cond.f[k], axis=1).max() / G0
    w = np.linalg.norm(cond.w[k], axis=1).max() / DEG
    temp = cond.T[k].mean(axis=1)
    return (f"{library.label(term)} acting: |f| up to {f:.1f} g, |w| up to {w:.0f} deg/s, "
            f"T {temp.min():.1f}-{temp.max():.1f} degC")


# ---- after the fit: residual map and localized excursions -------------------------------
def _remove(tiers, cands, findings):
    """Each tier's residual with the findings on its bins removed."""
    out = {name: tier.residual.copy() for name, tier in tiers.items()}
    by_label = {library.label(term): (tn, pos) for tn, term, pos in cands}
    for fd in findings:
        tn, pos = by_label[fd["label"]]
        beta = np.asarray(fd.get("vector", [fd["coefficient"]]), float)
        for name, tier in tiers.items():
            if tier.kind == tiers[tn].kind:
                out[name] -= _contribution(tiers[tn], pos, beta)
    return out


def _scan(tier, resid, alpha):
    """Localized excursions of the cleaned residual: means over SCAN_WINDOW_S windows per
    channel, robust z across the windows, Bonferroni over windows x channels."""
    x = clean(tier, resid)
    win = np.floor((tier.t - tier.t[0]) / SCAN_WINDOW_S).astype(int)
    nwin = win.max() + 1
    counts = np.bincount(win, minlength=nwin)
    full = counts >= 0.5 * np.median(counts)
    # window means of the flicker-dominated accelerometers have heavier tails than a normal
    # law (the null recordings of the proof raised 4 false excursions in 40 with one):
    # Student t with SCAN_DOF degrees of freedom
    z_limit = stats.t.isf(alpha / (2 * nwin * 6), SCAN_DOF)
    spans = []
    for ch in range(6):
        means = np.bincount(win, x[:, ch], minlength=nwin)[full] / counts[full]
        centre = np.median(means)
        spread = 1.4826 * np.median(np.abs(means - centre))
        if spread == 0:
            continue
        z = (means - centre) / spread
        ids = np.flatnonzero(full)[np.abs(z) > z_limit]
        zz = z[np.abs(z) > z_limit]
        for w_id, zv in zip(ids, zz):
            t0 = tier.t[0] + w_id * SCAN_WINDOW_S
            if spans and spans[-1]["channel"] == ch and abs(spans[-1]["t1"] - t0) < 1e-9:
                spans[-1]["t1"] = t0 + SCAN_WINDOW_S
                spans[-1]["z"] = max(spans[-1]["z"], abs(float(zv)), key=abs)
            else:
                spans.append({"t0": float(t0), "t1": float(t0 + SCAN_WINDOW_S), "channel": ch,
                              "z": float(zv)})
    for s in spans:
        s["channel"] = f"{CHANNELS[s['channel']][0]}.{CHANNELS[s['channel']][1]}"
    return spans


CONDITIONS = ("quiet", "|f| > 2 g", "|w| > 60 deg/s", "|dw/dt| > 300 deg/s^2",
              "|dT/dt| > 0.5 degC/min")


def _condition_masks(tier, cond, m, usable):
    """Fast-bin masks of the flight conditions of the residual map."""
    ok = tier.kept
    f = _bin(np.linalg.norm(cond.f, axis=1)[:, None], m, usable)[ok, 0] / G0
    w = _bin(np.linalg.norm(cond.w, axis=1)[:, None], m, usable)[ok, 0] / DEG
    wd = _bin(np.linalg.norm(cond.w_dot, axis=1)[:, None], m, usable)[ok, 0] / DEG
    temperature = cond.T.mean(axis=1)[:, None]
    dT = (np.abs(_bin(derivative(cond.t, temperature, 30.0) * 60, m, usable)[ok, 0])
          if np.isfinite(temperature).all() else np.zeros(ok.sum()))   # none recorded
    masks = {"|f| > 2 g": f > 2, "|w| > 60 deg/s": w > 60, "|dw/dt| > 300 deg/s^2": wd > 300,
             "|dT/dt| > 0.5 degC/min": dT > 0.5}
    masks["quiet"] = ~np.any(list(masks.values()), axis=0)
    return {k: masks[k] for k in CONDITIONS}


def _map(tier, resid, conds, seconds=MAP_SECONDS):
    """(conditions, 6): rms of the cleaned residual averaged over `seconds` (so systematic
    terms stand out of the white noise) in each condition (a majority of its bins) over the
    same in quiet flight; NaN where a condition has fewer than 10 such averages."""
    x = clean(tier, resid)
    sec = np.floor((tier.t - tier.t[0]) / seconds).astype(int)
    n = sec.max() + 1
    count = np.maximum(np.bincount(sec, minlength=n), 1)
    means = np.column_stack([np.bincount(sec, x[:, c], minlength=n) / count for c in range(6)])
    full = np.bincount(sec, minlength=n) >= 0.5 * seconds / FAST_BIN_S
    share = {k: np.bincount(sec, m.astype(float), minlength=n) / count for k, m in conds.items()}
    quiet = full & (share["quiet"] > 0.5)
    quiet = quiet if quiet.sum() >= 10 else full
    ref = np.sqrt(np.mean(means[quiet] ** 2, axis=0))
    out = np.full((len(conds), 6), np.nan)
    for r, key in enumerate(conds):
        mask = full & (share[key] > 0.5)
        if mask.sum() >= 10:
            out[r] = np.sqrt(np.mean(means[mask] ** 2, axis=0)) / ref
    return out
