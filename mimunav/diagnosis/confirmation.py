"""Confirmation of the chosen terms on the held-out rows: the coefficient with its 95 %
interval (profile likelihood or Wald), p-value, sign and physical range, attribution, where the
term acts (time spans and flight conditions) and what removing it does to the residual rms.
"""
import math
from dataclasses import dataclass

import numpy as np
import quaternion
from scipy import stats

from ..compensation import effects
from ..sensors.mimu import G0
from . import library
from ..frames import attitude
from .design import CHANNELS, DEG, detrended, term_contribution
from .fitting import Fitter, plausible, shares_a_nuisance, term_test
from .inference import median_inflation


# ---- confirmation on held-out rows -------------------------------------------------------
def confirmed(design, chosen, train, held, alpha, prep, recording, family=None):
    """(findings, rejected, of them those the recording's checks set aside, doubts, the
    library's record or None): the chosen terms through
    `confirm_chosen` and, on a recording, `recording_checks`, refitted without those either
    sets aside until none more is - a finding's coefficient is read beside the confirmed
    terms only (a rate table's gyro.y <- w_z had read 0.0031 beside a mounting turn the
    halves then set aside; alone it is the unit's 0.00107). Each term set aside is reported
    as judged in the fit it was set aside from; the threshold stays alpha over the number
    first chosen (or `family`). prep: full_scale and extremes (`sensor._prepare`'s)."""
    family, rejected, set_aside = family or len(chosen), [], []
    while True:
        findings, out = confirm_chosen(design, chosen, train, held, alpha, prep.full_scale,
                                       prep.extremes, family)
        doubts, record, aside = [], None, []
        if recording:
            findings, aside, doubts, record = recording_checks(design, findings, held)
        rejected, set_aside = rejected + out + aside, set_aside + aside
        if not (out or aside) or not findings:
            return findings, rejected, set_aside, doubts, record
        kept = {position_of(design, f) for f in findings}
        chosen = [c for c in chosen if c["j"] in kept]


def confirm_chosen(design, chosen, train, held, alpha, full_scale, extremes, family=None):
    """(findings, rejected) of the chosen terms refitted together on the `held` rows (their
    training coefficients from the `train` rows), each judged at alpha / family (default:
    the number chosen)."""
    if not chosen:
        return [], []
    idx = [c["j"] for c in chosen]
    held_fitter = Fitter(design, held)
    cleaned = detrended(design, design.residual)
    level = alpha / (family or len(chosen))
    findings, rejected = [], []
    for c in chosen:
        j = c["j"]
        term = design.terms[j]
        res = term_test(held_fitter, idx, j)
        b_tr, b_ho = c["b_train"], res["b"]
        interval = None
        if not res["linear"] and len(design.columns[j]) == 1 and design.k[j] == 1:
            interval = held_fitter.profile_interval(idx, j, float(np.sqrt(res["cov"][0, 0])))
            if not (np.all(np.isfinite(interval)) and interval[0] <= b_ho[0] <= interval[1]):
                interval = None     # unbounded, or the joint fit off the channel's: Wald's
        finding = interval_estimate(design, term, b_ho, res["cov"], interval)
        finding["ci95_method"] = "profile-likelihood" if interval is not None else "wald"
        where = where_rows(term_contribution(design, j, b_ho))
        finding["where"] = term_spans(design, where, term, extremes)
        finding["fit"] = _rms_fit(design, cleaned, j, b_tr, where, train, held, term)
        for key in ("order", "window_s", "reference"):
            if key in term:
                finding[key] = term[key]
        if term["effect"] == "vibration_rectification":     # what its coefficient multiplies
            finding["regressor"] = effects.VIBRATION_REGRESSOR
        p_ho, p_ref = math.exp(res["logp"]), math.exp(res["logp_ref"])
        finding.update(
            label=library.label(term), p_train=c["p_train"], holm_threshold=c["threshold"],
            p_heldout=p_ho, heldout_threshold=level,
            train_coefficient=b_tr.tolist() if len(b_tr) > 1 else float(b_tr[0]),
            attribution=_attribution(term, p_ref < level, res["linear"],
                                     _reference_may_carry(design, j, b_ho) or (
                                         p_ref >= level
                                         and (design.allowance_of[j] == "reference"
                                              or shares_a_nuisance(design, j)))),
            named_on=c.get("named_on", "training half"),
            indistinguishable_from=[alternative_of(design.terms[a]) for a in c["alternatives"]],
            not_chosen_as_implausible=c["implausible"])
        if res["linear"]:
            finding["p_heldout_with_reference_accuracy"] = p_ref
        ok, limit = plausible(design, j, b_ho, full_scale)
        finding["effect_size"] = effect_size(res["stat"], held_fitter.n * len(design.columns[j]),
                                             float(np.linalg.norm(b_ho)), limit)
        share = finding["effect_size"]["heldout_variance_removed"]
        why = None
        if p_ho >= level:
            why = f"held-out p = {p_ho:.2g}, needs < {level:.2g}"
        elif float(b_tr @ np.linalg.lstsq(res["cov"], b_ho, rcond=None)[0]) <= 0:
            # (a vector in the held-out fit's metric: its well-determined directions count)
            why = "the held-out coefficient has the other sign"
        elif not ok:
            why = (f"held-out magnitude {np.linalg.norm(b_ho):.3g} beyond the physical range "
                   f"{limit:.3g}" + (" of a calibrated unit (is the calibration this unit's?)"
                                     if design.calibrated and (term["effect"], term["sensor"])
                                     in library.CALIBRATED_RANGE else ""))
        elif share < library.MIN_VARIANCE_SHARE:
            why = (f"negligible: removes {share:.3%} of the held-out residual variance "
                   f"(at least {library.MIN_VARIANCE_SHARE:.1%})")
        (findings if why is None else rejected).append(
            finding if why is None else dict(finding, rejected=why))
    return findings, rejected


def effect_size(stat, rows, magnitude, limit):
    """The size of a held-out finding beside its significance: the share of the held-out
    residual variance its removal takes away - the likelihood-ratio (or Wald) statistic over
    the rows it is fitted on turned into a variance ratio, 1 - exp(-stat / rows) (Cox and
    Snell's R^2 of the generalised least squares, white noise and wander weighed as the fit
    weighs them) - and its magnitude against its physical range."""
    return {"heldout_variance_removed": float(-math.expm1(-max(stat, 0.0) / max(rows, 1))),
            "of_physical_range": magnitude / limit if np.isfinite(limit) else 0.0,
            "basis": "1 - exp(-held-out statistic / held-out rows x channels); |coefficient| "
                     "over the term's physical range"}


def _attribution(term, beyond_reference, linear, reference_may_carry=False):
    """Whom a finding is charged to: the MIMU's sensors, or for the whole unit's terms its
    installation (mounting, lever arm) or its timing (time_skew); '-or-reference' when the
    reference's stated accuracy could hold it (a linear term within its scale and
    misalignment; `_reference_may_carry`), '-or-calibration' when the calibration's stated
    covariance could."""
    who = {"mounting_misalignment": "installation", "lever_arm": "installation",
           "time_skew": "timing"}.get(term["effect"], "mimu")
    if beyond_reference:
        return who + ("-or-reference" if reference_may_carry and who == "mimu" else "")
    return who + ("-or-reference" if linear or reference_may_carry else "-or-calibration")


BIAS_SHAPED = ("bias_shift", "bias_instability", "temperature_bias", "temperature_rate",
               "thermal_hysteresis", "vibration_rectification")


def _reference_may_carry(design, j, b):
    """Whether the reference itself may make candidate j's signature at coefficient b: a
    reference of MEMS grade may carry any sensor physics (`Accuracy.mems_grade`); any
    reference, a bias-shaped term no larger than its own bias and logging step allow
    (`Accuracy.bias_allowance`: the term's 99.9th-percentile contribution)."""
    term = design.terms[j]
    if design.reference is None or term["sensor"] not in ("accel", "gyro"):
        return False
    if design.reference.mems_grade:
        return True
    if term["effect"] not in BIAS_SHAPED:
        return False
    touched = list(design.columns[j])
    peak = float(np.percentile(np.abs(term_contribution(design, j, b)[:, touched]), 99.9))
    return peak <= design.reference.bias_allowance(term["sensor"])


def interval_estimate(design, term, b, cov, interval=None):
    """`estimate` with the 95 % interval of covariance `cov` (or `interval`, (lo, hi) of a
    scalar: `Fitter.profile_interval`); a lever arm (fitted in the sensor axes) turned into
    the vehicle frame of the metadata's lever_arm_m, its sensor-axes vector kept for the
    compensation (`vector_sensor_axes`); a mounting misalignment (a rotation vector of the
    sensor axes, as the contract's `vector`) also as the same turn about the vehicle's
    axes (`vector_vehicle`, FRD, with `vector_vehicle_ci95`): a mounting that turns the
    sensor's z axis up reverses the sign of a yaw read off the sensor axes; and the mounting
    that holds it (`mounting_rpy_deg`: sensor -> vehicle roll, pitch, yaw, deg, as
    `--mounting-rpy-deg` takes it)."""
    if interval is not None:
        return estimate(term, b, np.array([interval[0]]), np.array([interval[1]]))
    if term["effect"] not in ("lever_arm", "mounting_misalignment"):
        half = 1.96 * np.sqrt(np.diag(cov))
        return estimate(term, b, b - half, b + half)
    c_vs = quaternion.as_rotation_matrix(attitude.from_wxyz(design.q_vs))
    b_v, cov_v = c_vs @ b, c_vs @ cov @ c_vs.T
    half_v = 1.96 * np.sqrt(np.diag(cov_v))
    if term["effect"] == "mounting_misalignment":    # the sensor axes' turn phi (q_vs q(phi))
        half = 1.96 * np.sqrt(np.diag(cov))          # is the turn C_vs phi of the vehicle
        yaw, pitch, roll = attitude.as_euler(        # axes (q(C_vs phi) q_vs): the mounting
            quaternion.from_rotation_vector(b_v) * attitude.from_wxyz(design.q_vs))  # it found
        return dict(estimate(term, b, b - half, b + half),
                    vector_vehicle=b_v.tolist(),
                    vector_vehicle_ci95=np.column_stack([b_v - half_v, b_v + half_v]).tolist(),
                    mounting_rpy_deg=[round(float(np.degrees(a)), 2) for a in (roll, pitch, yaw)])
    return dict(estimate(term, b_v, b_v - half_v, b_v + half_v), frame="vehicle",
                vector_sensor_axes=b.tolist())


def estimate(term, beta, lo, hi):
    """The contract's description of a term with its held-out estimate and 95 % interval
    (a vector parameter as `vector`, its largest component as `coefficient`, and the frame
    of its components: the MIMU's sensor axes here)."""
    finding = {k: v for k, v in term.items() if k in ("effect", "sensor", "axis", "input_axis")}
    if len(beta) == 1:
        finding.update(coefficient=float(beta[0]), ci95=[float(lo[0]), float(hi[0])])
    else:
        big = int(np.argmax(np.abs(beta)))
        finding.update(coefficient=float(beta[big]), ci95=[float(lo[big]), float(hi[big])],
                       vector=beta.tolist(), vector_ci95=np.column_stack([lo, hi]).tolist(),
                       frame="sensor")
    finding["units"] = effects.units(term)
    return finding


def alternative_of(term):
    out = {k: term[k] for k in ("effect", "sensor", "axis", "input_axis", "order", "window_s")
           if k in term}
    out["label"] = library.label(term)
    return out


def position_of(design, finding):
    labels = [library.label(t) for t in design.terms]
    return labels.index(finding["label"])


def beta_of(finding):
    """A finding's coefficients in the sensor axes: its vector there, else its vector (a set
    aside term's, in the fit's axes), else its one coefficient."""
    for key in ("vector_sensor_axes", "vector"):
        if key in finding:
            return np.asarray(finding[key], float)
    return np.asarray([finding["coefficient"]], float)


def where_rows(contribution):
    """Rows where the term acts: its contribution above a quarter of its peak (99.9th
    percentile of the magnitude over the channels it drives)."""
    mag = np.linalg.norm(contribution / (np.abs(contribution).max(axis=0) + 1e-300), axis=1)
    peak = np.percentile(mag, 99.9)
    return mag >= 0.25 * peak if peak > 0 else np.zeros(len(mag), bool)


def _rms_fit(design, before, j, b_tr, where, train, held, term):
    """Residual rms in the term's located rows before (`before`: the residual with its bias
    removed, `detrended`) and after removing the term with the training coefficient, on
    training and on held-out rows."""
    after = detrended(design, design.residual - term_contribution(design, j, b_tr))
    chans = sorted(design.columns[j])
    if term["sensor"] == "imu":         # report the sensor whose channels gain most
        gains = {s: [ch for ch in chans if (ch < 3) == (s == "accel")] for s in ("accel", "gyro")}
        ratio = {s: rms_in(after, where, chs) / max(rms_in(before, where, chs), 1e-300)
                 for s, chs in gains.items() if chs}
        sensor = min(ratio, key=ratio.get)
        chans = gains[sensor]
    else:
        sensor = term["sensor"]
    out = {}
    for part, rows in (("train", train), ("heldout", held)):
        out[f"{part}_rms_before"] = rms_in(before, where & rows, chans)
        out[f"{part}_rms_after"] = rms_in(after, where & rows, chans)
    out["units"] = "m/s^2" if sensor == "accel" else "rad/s"
    out["channels"] = [f"{CHANNELS[ch][0]}.{CHANNELS[ch][1]}" for ch in chans]
    out["basis"] = (f"bin means ({design.bin_s:.3g} s), piecewise-linear bias removed, rows where "
                    "the term acts; 'after' uses the training coefficient")
    return out


def rms_in(x, rows, chans):
    v = x[np.ix_(rows, chans)]
    return float(np.sqrt(np.mean(v ** 2))) if v.size else float("nan")


@dataclass
class Extremes:
    """The flight conditions `term_spans` says, per row (a sample or a bin) at times t (s):
    the largest |f| (m/s^2) and |w| (rad/s), the smallest and the largest mean temperature of
    the triad (degC; NaN unrecorded)."""
    t: np.ndarray
    f: np.ndarray
    w: np.ndarray
    temperature_low: np.ndarray
    temperature_high: np.ndarray

    @classmethod
    def of_conditions(cls, cond):
        """Of `effects.Conditions`, a row a sample."""
        temperature = cond.T.mean(axis=1)
        return cls(cond.t, np.linalg.norm(cond.f, axis=1), np.linalg.norm(cond.w, axis=1),
                   temperature, temperature)


def term_spans(tier, rows, term, extremes, gap_s=2.0, max_spans=20):
    """Contiguous time spans of the rows (gaps below gap_s merged) with the flight
    conditions met there (`Extremes`)."""
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
        spans.append({"t0": t0, "t1": t1, "condition": _condition(extremes, t0, t1, term)})
    return spans


def _condition(extremes, t0, t1, term):
    """What the flight did in [t0, t1]: peak |f| (g), |w| (deg/s), temperature range."""
    a = int(np.searchsorted(extremes.t, t0, "left"))
    b = int(np.searchsorted(extremes.t, t1, "right"))
    k = slice(a, b)                     # the rows t0 <= t <= t1 (the times increase)
    if a >= b:
        return library.label(term)
    f = extremes.f[k].max() / G0
    w = extremes.w[k].max() / DEG
    low, high = extremes.temperature_low[k], extremes.temperature_high[k]
    text = f"{library.label(term)} acting: |f| up to {f:.1f} g, |w| up to {w:.0f} deg/s"
    if np.isfinite(low).all() and np.isfinite(high).all():
        text += f", T {low.min():.1f}-{high.max():.1f} degC"
    return text


# ---- the halves of a recording ---------------------------------------------------------
HALVES_ALPHA = 0.05     # the halves' coefficients differ beyond their own intervals at 95 %


def halves_check(design, findings):
    """(kept, set aside) findings after refitting each found term on the recording's first
    and second halves (time, the found terms together): where the two halves disagree beyond
    their own intervals (chi-square of the difference at HALVES_ALPHA), the interval is
    widened by the square root of that statistic per parameter (says by how much), and a
    finding whose widened interval holds zero is set aside as inconclusive. A recording's
    errors need not stay the same over it (a reference's solution, a temperature, a
    mounting that settles) as a simulation's do; the held-out blocks interleave, so they do
    not see a drift from one end to the other. `findings`: `confirm_chosen`'s (terms of the
    library; the tests on the outputs are not refitted here)."""
    if not findings:
        return findings, []
    idx = [position_of(design, f) for f in findings]
    first = design.t < np.median(design.t)
    fits = [Fitter(design, rows).fit(idx) for rows in (first, ~first)]
    return halves_verdict(findings, [[fit.of(j) for fit in fits] for j in idx])


def halves_verdict(findings, halves, absorbed=None):
    """(kept, set aside) `findings` given each one's estimates on the recording's two halves,
    `halves`: per finding ((b1, cov1), (b2, cov2)), the first half's and the second's
    coefficients and covariances. The difference's chi-square (its covariance the sum of the
    halves', independent rows) tested at HALVES_ALPHA; beyond it the 95 % interval is widened
    by sqrt(statistic / parameters) / absorbed, at least 1, and a finding whose widened
    interval holds zero, or whose held-out p read with the wider interval (its chi-square
    over factor^2: a chi-square reading of whatever test gave it) misses the finding's own
    held-out limit (`heldout_threshold`, when it has one), is set aside as inconclusive.
    `absorbed` (per finding, default 1): how many times wider the finding's interval already
    is than the one its halves pool to (a block-robust interval carries a misfit between the
    halves as scatter of its own)."""
    kept, aside = [], []
    for n, (f, ((b1, c1), (b2, c2))) in enumerate(zip(findings, halves)):
        diff = b1 - b2
        stat = float(diff @ np.linalg.lstsq(c1 + c2, diff, rcond=None)[0])
        p = float(stats.chi2.sf(stat, len(diff)))
        record = {"first": b1.tolist(), "second": b2.tolist(), "p_same": p}
        factor = math.sqrt(stat / len(diff)) / (1.0 if absorbed is None else absorbed[n])
        if p >= HALVES_ALPHA or factor <= 1.0:
            kept.append(dict(f, halves=dict(record, widened_by=1.0)))
            continue
        ok, wide = judged_wider(f, factor, len(diff), f"the recording's halves disagree "
                                 f"(p {p:.2g})", "halves", record)
        (kept if ok else aside).append(wide)
    return kept, aside


def judged_wider(finding, factor, k, why, key, record, p_heldout=None):
    """(kept, the finding with its intervals widened by factor and `record` under `key`,
    with the held-out p read with the wider interval - its chi-square (k dof) over factor^2:
    a chi-square reading of whatever test gave it): set aside (`rejected`: `why` and the
    reading) when that p misses the finding's own held-out limit (`heldout_threshold`) or
    the widened interval holds zero. `p_heldout`: the p to read, when an earlier widening
    read the finding's own already (the halves')."""
    wide = _widened(finding, factor)
    wide[key] = record = dict(record, widened_by=factor)
    p_heldout = finding.get("p_heldout") if p_heldout is None else p_heldout
    if p_heldout is not None:
        stat_ho = stats.chi2.isf(max(p_heldout, 1e-300), k)
        record["p_heldout_widened"] = float(stats.chi2.sf(stat_ho / factor ** 2, k))
    lo, hi = wide["ci95"]
    if record.get("p_heldout_widened", 0.0) >= finding.get("heldout_threshold", 1.0):
        return False, dict(wide, rejected=(
            f"{why}: with its interval widened {factor:.2f}x its held-out p reads "
            f"{record['p_heldout_widened']:.2g}, above its limit "
            f"{finding['heldout_threshold']:.2g} - inconclusive"))
    if lo <= 0.0 <= hi:
        return False, dict(wide, rejected=f"{why}: its interval widened {factor:.2f}x holds "
                                          "zero - inconclusive")
    return True, wide


# The library's median held-out test statistic beside a recording's findings, over its chance
# value, at most this: on the independent simulator's 12 development logs (sensor level,
# beside their findings) it was 0.46-1.73 - a median of ~100 correlated chi-square values
# scatters by tens of percent; on the light aircraft's recording (shared onspeed-vn300: a
# cheap IMU, uncalibrated, beside a VN-300 logged in 0.01 steps) 35, and 21 on its first 8 s.
# At the track level (a vehicle model's IMU as the reference) on the 15 drives of
# bench/track_drive.py (an independent generator: null, lag, mounting, yaw scale; 1 Hz and
# 5 cm fixes, 5 m hills) 0.29-2.04; on the shared RTKLIB drive 8.4 (3.6 with its fixes at
# 1 Hz, 21 on its first 60 s) and on comma2k19's segment 7.0 - the car's roll, pitch on its
# springs and the reference's own filter, none of them in the model
LIBRARY_INFLATION_LIMIT = 3.0
LIBRARY_MIN_TERMS = 20


def library_inflation(design, rows, given):
    """lambda: the median over the library's terms other than `given` (positions) of each
    one's test statistic on `rows` beside them, as chi-square with 1 dof (from its p), over
    that law's median 0.455 (genomic control: Devlin & Roeder, Biometrics 55, 1999; the
    navigation level corrects every test by it, `inference.variance_inflation`) - about 1
    where the tests' noise model holds and the findings take what is there; None with fewer
    than LIBRARY_MIN_TERMS others (a median of a few is no measure of the bulk)."""
    fitter = Fitter(design, rows)
    others = [j for j in range(len(design.terms)) if j not in given and j not in design.nuisance]
    logp = np.array([term_test(fitter, list(given) + [j], j)["logp"] for j in others])
    logp = logp[np.isfinite(logp)]
    return median_inflation(logp) if len(logp) >= LIBRARY_MIN_TERMS else None


# the reference IMU's clock as the data read it, beside the findings, against the import's
# measure: beyond 3 combined 1 sigma the two disagree (p 0.003) - a clock-shaped residual the
# findings do not hold, or a clock the import mismeasured
CLOCK_Z = 3.0


def clock_reading(fitter, given):
    """The reference IMU's clock (`Design.nuisance`) in `fitter`'s fit of the found terms
    `given` (positions): {"fitted_s", "sd_s"} under the import's prior, {"data_s",
    "data_sd_s"} on the data alone (the prior 1e3 times wider), "import_1sigma_s" and "z":
    the data's reading over the combined 1 sigma of the two, and "contradicted" beyond
    CLOCK_Z; None without a clock nuisance."""
    if not fitter.design.nuisance:
        return None
    ((n, var),) = fitter.design.nuisance.items()
    given = [j for j in given if j != n]
    b, cov = fitter.fit(given).of(n)
    d, d_cov = fitter.fit(given, clock=1e3).of(n)
    z = abs(float(d[0])) / math.sqrt(var + float(d_cov[0, 0]))
    return {"fitted_s": float(b[0]), "sd_s": math.sqrt(float(cov[0, 0])),
            "data_s": float(d[0]), "data_sd_s": math.sqrt(float(d_cov[0, 0])),
            "import_1sigma_s": math.sqrt(var), "z": z, "contradicted": z > CLOCK_Z}


def out_of_the_shadow(findings, shadow):
    """(kept, set aside) of `findings` where the lever-arm transfer misses the reference's
    angular vibration (`shadow`: `reference.transfer_doubt`'s words; '' where it does not):
    each finding on the accelerometers (an accelerometer's or the unit's) is set aside with
    them - a quadrotor's rotor lines across a 4.7 cm lever arm had named an accel.z scale of
    -0.012 where +0.003 was hidden, and on its null twin a time skew of the accelerometers
    and an accel.z bias of +0.087 m/s^2 (truth -0.057), all at p < 1e-300."""
    if not shadow:
        return findings, []
    on = [f.get("sensor") in ("accel", "imu") for f in findings]
    return ([f for f, a in zip(findings, on) if not a],
            [dict(f, rejected=shadow) for f, a in zip(findings, on) if a])


def clock_doubt(clock):
    """Why a diagnosis whose clock reading (`clock_reading`) is contradicted is inconclusive;
    None where it is not (or there is none). Not asked in the shadow of an unfollowed
    vibration (`out_of_the_shadow`): that is clock-shaped on the accelerometers (a
    quadrotor's reference read 19 sigma off its import's clock, its true offset 0)."""
    if not (clock and clock["contradicted"]):
        return None
    return (f"the reference IMU's clock, fitted beside the findings, reads "
            f"{clock['data_s'] * 1e3:+.3g} ms (1 sigma {clock['data_sd_s'] * 1e3:.2g}) on the "
            f"data alone, where the import measured it to 1 sigma "
            f"{clock['import_1sigma_s'] * 1e3:.2g} ms ({clock['z']:.1f} sigma apart): something "
            "shaped as a clock offset is left, or the import's clock is off - the findings "
            "were read with a clock the data contradict")


def recording_checks(design, findings, held):
    """(kept, set aside, [reason], the library's record {lambda, limit, widened_by} or None)
    of a recording's findings: its halves (`halves_check`), then the library beside the kept
    ones on the held-out rows `held` (`library_inflation`; at the track level too, where the
    reference is a vehicle model's IMU: its own errors are residual the tests do not model).
    Beyond LIBRARY_INFLATION_LIMIT the residual is not the noise the tests assume (a
    reference's steps, its lag, vibration, errors the library has no term for): each
    finding's interval is widened by sqrt(lambda), judged as the halves' widening is
    (`judged_wider`), and the reason given - 'nothing else is missing' cannot be said."""
    kept, aside = halves_check(design, findings)
    lam = library_inflation(design, held, [position_of(design, f) for f in kept])
    record = {"lambda": lam, "limit": LIBRARY_INFLATION_LIMIT, "widened_by": 1.0}
    if lam is None or not lam > LIBRARY_INFLATION_LIMIT:
        return [dict(f, library_inflation=record) for f in kept], aside, [], record
    beside = ("beside the library's findings, its other terms" if kept
              else "with none of the library's terms found (the outputs' own tests aside), "
                   "its terms")
    why = (f"{beside} stand out {lam:.1f} times their chance level on the held-out blocks "
           f"(median test statistic; at most {LIBRARY_INFLATION_LIMIT:g} where the tests' "
           "noise model holds)")
    judged = [judged_wider(f, math.sqrt(lam), len(np.ravel(beta_of(f))), why,
                            "library_inflation", record,
                            f.get("halves", {}).get("p_heldout_widened"))
              for f in kept]
    dropped = sum(not ok for ok, _ in judged)
    return ([f for ok, f in judged if ok], aside + [f for ok, f in judged if not ok],
            [why + ": the residual is not the noise the tests assume (the reference's steps "
             "or lag, a GNSS antenna's lever arm not given, vibration, errors no term "
             "describes)"
             + (f"; each finding of the search judged with its interval {math.sqrt(lam):.2f}x "
                f"wider: {dropped} of {len(kept)} set aside by it" if kept else "")
             + " (of the tests on the outputs, a bias's wander is set aside and its offset "
             "judged with the same widening: `outputs_judged`)"],
            dict(record, widened_by=math.sqrt(lam)))


def outputs_judged(found, record):
    """(kept, set aside) of the tests on the outputs (`outputs`) where the library's check
    found the residual not the noise the tests assume (`record`'s widened_by above 1,
    `recording_checks`): a bias's wander is set aside - a random walk follows whatever slow
    structure no term describes (a rate table's cross-coupling on its rate steps had read as
    0.0016 rad/s of bias instability, a helicopter's unmodelled 1.2 deg mounting as 0.00085
    on gyro.y, at p < 1e-80); a bias's offset is judged with its interval as widened as the
    search's (`judged_wider`). A rail and a lattice (saturation, quantization) are read off
    the outputs themselves and stand. A test already rejected (`outputs.bias_tests`: a wander
    that follows an input) is set aside whatever the check."""
    aside = [f for f in found if f.get("rejected")]     # a wander that follows an input
    found = [f for f in found if not f.get("rejected")]
    factor = (record or {}).get("widened_by", 1.0)
    if not factor > 1.0:
        return found, aside
    why = (f"the residual stands out {factor ** 2:.1f} times the tests' chance level "
           "(the library's check)")
    kept = []
    for f in found:
        if f["effect"] == "bias_instability":
            aside.append(dict(f, library_inflation=record, rejected=(
                f"{why}: a wander follows whatever slow structure no term describes - not "
                "told from it, inconclusive")))
        elif f["effect"] == "bias_shift":
            ok, judged = judged_wider(f, factor, 1, why, "library_inflation", record)
            (kept if ok else aside).append(judged)
        else:
            kept.append(f)
    return kept, aside


def set_aside_reasons(rejected):
    """Why 'nothing is missing' cannot be said of a recording whose halves or library check
    set terms aside (`halves_verdict`, `recording_checks`): each such term, with its text -
    seen, but not the same throughout or not beyond what the residual makes of any term."""
    return [f"{r['label']}: {r['rejected']}" for r in rejected    # only those checks'
            if isinstance(r.get("halves"), dict)                  # rejections carry them
            or isinstance(r.get("library_inflation"), dict)]


def beyond_range(design, beyond):
    """The candidates `selection.select` left as beyond their physical range (`beyond`), as
    rejected terms (`beyond_range`: the range; `rejected`: why) - a signature in the residual
    that the term holds only at a size its first-order form does not describe."""
    out = []
    for c in beyond:
        term = design.terms[c["j"]]
        half = 1.96 * np.sqrt(np.diag(c["cov"]))
        entry = dict(interval_estimate(design, term, c["b"], c["cov"]) if len(c["b"]) > 1
                     else estimate(term, c["b"], c["b"] - half, c["b"] + half),
                     label=library.label(term), p_train=c["p_train"], beyond_range=c["limit"])
        size = float(np.linalg.norm(c["b"]))
        said = library.beyond_range_said(term, size, c["limit"], entry["units"])
        out.append(dict(entry, rejected=f"significant on the training half (p "
                                        f"{c['p_train']:.2g}) at {said}: not chosen"))
    return out


def beyond_range_reasons(rejected):
    """Why 'nothing is missing' cannot be said: the mounting misalignment fitted beyond its
    physical range (`beyond_range`) - a mounting given wrong by more than the small-angle
    term holds, which every other term is fitted through. (Other terms beyond their range
    are look-alikes the selection passes over - on null flights too - and are only listed.)"""
    return [f"{r['label']} {r['rejected']}" for r in rejected if "beyond_range" in r
            and r["effect"] == "mounting_misalignment"]



def _widened(finding, factor):
    """The finding with every 95 % interval's half-widths about its estimate times factor
    (an offset's other readings each about its own: `outputs.with_other_readings`)."""
    out = dict(finding)

    def wider(value, interval):
        lo, hi = interval
        return [value - factor * (value - lo), value + factor * (hi - value)]
    out["ci95"] = wider(finding["coefficient"], finding["ci95"])
    if "ci95_alone" in finding:     # an offset read two ways: each reading's own, not the
        parts = [wider(finding["coefficient"], finding["ci95_alone"])] + [   # distance
            wider(o["coefficient"], o["ci95"]) for o in finding["other_readings"]]
        out["ci95"] = [min(a for a, _ in parts), max(b for _, b in parts)]
    for vec, ci in (("vector", "vector_ci95"), ("vector_vehicle", "vector_vehicle_ci95")):
        if ci in finding:
            out[ci] = [wider(v, i) for v, i in zip(finding[vec], finding[ci])]
    return out
