"""What a term found, or neither found nor ruled out, does to the means of quiet flight that
the bias tests read (`outputs.bias_tests`): a found term's removal leaves its estimate's error
(`removal_sigma`); a term left in the residual is an offset there when its input is steady
(`unconfirmed_offset`), and so is the part of the reference's fitted linear error beyond its
stated accuracy (`reference_held_offset`) - an offset is read every way they allow and its
interval holds every reading (`offset_readings`, `with_other_readings`); a wander read
after such a reference error is set aside (`beside_reference`)."""
import math

import numpy as np
import quaternion
from scipy import stats

from ..frames import attitude
from . import library
from .confirmation import beta_of, position_of
from ..compensation.effects import AXES
from .design import CHANNELS, gamma_slots, term_contribution
from .fitting import plausible
from .scan import overlaps, spans_said


def removal_sigma(design, fit, findings, rows):
    """(6,) 1 sigma (SI) per channel of the mean over `rows` (bool, the design's bins) that
    removing `findings` at their estimates leaves in a residual: each term's contribution is
    taken out at its held-out estimate, and that estimate's error moves the channel's mean
    (a mounting's tilt of g is an offset on a quiet flight - an 8 s cut of a light aircraft
    read a 0.2 m/s^2 accelerometer bias shift off a roll of -2 deg [-4.1, +0.1] removed
    with the gyros' mounting). `fit`: the all-rows `Fitter.fit` of the found terms (their
    correlations); the standard errors are the findings' own (`finding_covariance`)."""
    var = np.zeros(len(CHANNELS))
    if not findings or not rows.any():
        return var
    for f in findings:
        j = position_of(design, f)
        cov = finding_covariance(design, f, fit.of(j)[1])
        jac = _mean_jacobian(design, j, len(cov), rows)
        var += np.einsum("ck,kl,cl->c", jac, cov, jac)
    return np.sqrt(var)


def _mean_jacobian(design, j, k, rows):
    """(6, k): how each channel's mean over `rows` moves per unit of term j's k parameters."""
    return np.column_stack([term_contribution(design, j, e)[rows].mean(axis=0)
                            for e in np.eye(k)])


def _means_jacobian(design, fit, rows):
    """(6, P): how each channel's mean over `rows` of what `fit` removes (the reference's
    error gamma, then its terms) moves per unit of the fit's parameters."""
    jac = np.zeros((len(CHANNELS), len(fit.beta)))
    for c in range(len(CHANNELS)):
        jac[c, gamma_slots(c)] = design.ref_columns(c)[rows].mean(axis=0)
    for j, part in zip(fit.terms, fit.slices):
        jac[:, part] = _mean_jacobian(design, j, part.stop - part.start, rows)
    return jac


def unconfirmed_offset(design, fitter, base, terms, rows, full_scale):
    """((6,) SI, (6,) SI 1 sigma, 6 lists of labels): how much more of each channel's mean
    over `rows` (bool, the design's bins) the fit removes when the terms neither found nor
    ruled out join the found ones (`base`: the all-rows fit of the found terms) - `terms`:
    those confirmation rejected or set aside and those the selection found within the
    stated errors, refitted with the found terms and the reference's error by `fitter`
    (the all-rows `Fitter`), so a term the reference's error already carries moves nothing
    twice; a term beyond its physical range is no physics and stays out, as it stands and as
    the refit beside the others reads it (a motorcycle's 41 mg accel.y bias had read -1.6 g
    with three terms refitted together, and been set aside) - and the 1 sigma
    that refit adds. On a quiet flight a linear
    term of a steady input is an offset: a bias read without it carries it (a rate table's
    accel.z offset read -0.204 [-0.2175, -0.1906] m/s^2 beside a scale factor 0.0022 and a
    coupling to f_y the halves had not confirmed; the unit's bias is -0.1878)."""
    labels = [library.label(term) for term in design.terms]
    idx, extra = list(base.terms), []
    for f in terms:
        j = labels.index(f["label"]) if f.get("label") in labels else None
        if j is None or j in idx + extra or not ({"coefficient", "vector"} & f.keys()):
            continue                # (a term not chosen as implausible carries no estimate)
        if plausible(design, j, beta_of(f), full_scale)[0]:
            extra.append(j)
    zeros = np.zeros(len(CHANNELS))
    both = fitter.fit(idx + extra) if extra and rows.any() else None
    while both is not None:     # pushed beyond its range by the others: no physics either
        out = [j for j in extra if not plausible(design, j, both.of(j)[0], full_scale)[0]]
        extra = [j for j in extra if j not in out]
        if not out:
            break
        both = fitter.fit(idx + extra) if extra else None
    if both is None:
        return zeros, zeros, [[] for _ in CHANNELS]
    jac_base, jac_both = _means_jacobian(design, base, rows), _means_jacobian(design, both, rows)
    shift = jac_both @ both.beta - jac_base @ base.beta
    added = (np.einsum("cp,pq,cq->c", jac_both, both.cov, jac_both)
             - np.einsum("cp,pq,cq->c", jac_base, base.cov, jac_base))
    moved = np.column_stack([_mean_jacobian(design, j, len(both.of(j)[0]), rows) @ both.of(j)[0]
                             for j in extra])
    names = [[labels[j] for j, m in zip(extra, moved[c]) if m != 0.0] for c in range(6)]
    return shift, np.sqrt(np.maximum(added, 0.0)), names


def finding_covariance(design, finding, cov_all):
    """Covariance (k, k) of a finding's parameters in the sensor axes (the fit's): its 95 %
    half-widths / 1.96 (the held-out fit's, widened where a recording's halves disagreed)
    as standard errors, correlated as in `cov_all` (the all-rows fit's, sensor axes); a
    lever arm's interval is in the vehicle frame (`interval_estimate`)."""
    ci = np.asarray(finding.get("vector_ci95", [finding["ci95"]]), float)
    se = (ci[:, 1] - ci[:, 0]) / (2 * 1.959964)
    turn = np.eye(len(se))
    if finding.get("frame") == "vehicle":
        turn = quaternion.as_rotation_matrix(attitude.from_wxyz(design.q_vs))
    cov = turn @ np.atleast_2d(cov_all) @ turn.T
    sd = np.sqrt(np.maximum(np.diag(cov), 1e-300))
    cov = cov / np.outer(sd, sd) * np.outer(se, se)
    return turn.T @ cov @ turn


REFERENCE_BEYOND_SIGMA = 5.0    # the reference's fitted linear error this many of its stated
                                # 1 sigma off: no draw of its prior (18 components: chance
                                # ~1e-5 a fit) - something the model lacks is charged to it


def reference_beyond_stated(design, fit):
    """Per channel (6): (the largest |gamma / stated 1 sigma| of its row of the reference's
    fitted linear error - `fit.gamma()`, the prior `design.prior` - and words naming that
    component). A component without a stated prior counts 0."""
    gamma, sd = fit.gamma(), np.sqrt(np.clip(np.diag(design.prior), 0.0, None))
    out = []
    for c, (sensor, axis) in enumerate(CHANNELS):
        s = gamma_slots(c)
        z = np.divide(np.abs(gamma[s]), sd[s], out=np.zeros(3), where=sd[s] > 0)
        k = int(np.argmax(z))
        symbol = "f" if sensor == "accel" else "w"
        out.append((float(z[k]), f"{sensor}.{axis} <- {symbol}_{AXES[k]} {gamma[s][k]:.3g} "
                                 f"({z[k]:.0f} times its stated 1 sigma {sd[s][k]:.3g})"))
    return out


def reference_held_offset(design, fit, rows):
    """((6,) SI, 6 words): how much less of each channel's mean over `rows` the fit would
    remove were the reference's fitted linear error (`fit.gamma()`) held to
    REFERENCE_BEYOND_SIGMA of its stated 1 sigma (`design.prior`), component by component,
    and words naming the component beyond (`reference_beyond_stated`; '' where none is) - a
    MEMS reference's accel.z scale fitted at -0.076 against its stated 0.0025, beside a
    plane's 0.2 m lever arm left out in 99 deg/s of handling, had taken 0.74 m/s^2 from a
    quiet mean and left a bias_shift of -0.64 [-0.83, -0.46] where the IMUs differ by +0.10.
    The words name the reference beyond its stated accuracy or the model incomplete."""
    gamma, sd = fit.gamma(), np.sqrt(np.clip(np.diag(design.prior), 0.0, None))
    limit = REFERENCE_BEYOND_SIGMA * sd
    beyond = np.where(sd > 0, gamma - np.clip(gamma, -limit, limit), 0.0)
    shift = np.array([-design.ref_columns(c)[rows].mean(axis=0) @ beyond[gamma_slots(c)]
                      if rows.any() else 0.0 for c in range(len(CHANNELS))])
    words = [why if z > REFERENCE_BEYOND_SIGMA else ""
             for z, why in reference_beyond_stated(design, fit)]
    return shift, words


def beside_reference(findings, beyond):
    """The bias wander findings (`outputs.bias_tests`), set aside (`rejected`) on a channel
    whose row of the reference's fitted linear error lies beyond REFERENCE_BEYOND_SIGMA
    (`reference_beyond_stated`): the means they read are what that fit left, and a wander
    has no second reading to hold beside it (an offset has: `reference_held_offset`)."""
    out = []
    for f in findings:
        z, words = beyond[CHANNELS.index((f["sensor"], f["axis"]))] \
            if (f["sensor"], f["axis"]) in CHANNELS else (0.0, "")
        if f["effect"] == "bias_instability" and z > REFERENCE_BEYOND_SIGMA \
                and not f.get("rejected"):
            f = dict(f, reference_fitted_beyond_stated=z, rejected=(
                f"read after the reference's fitted linear error, which lies beyond its "
                f"stated accuracy ({words}): the reference is worse than stated or the model "
                "lacks something charged to it - inconclusive"))
        out.append(f)
    return out


def held_excursions(spans, held, beyond):
    """(the excursions `spans` that an excursion of the residual read with the reference's
    error held at zero (`held`) overlaps on their channel, [why the others are set aside])
    - where the reference's fitted linear error lies beyond REFERENCE_BEYOND_SIGMA of its
    stated accuracy (`beyond`: `reference_beyond_stated`), an excursion it alone makes is
    that error's shape, not the IMU's (a phone beside a tactical INS: its coupling fitted
    41 times its stated 1 sigma left excursions of z 11 at the drive's two sharpest turns,
    where the two IMUs' outputs agree)."""
    stands = [any(overlaps(s, o) for o in held) for s in spans]
    aside = [s for s, kept in zip(spans, stands) if not kept]
    words = "; ".join(why for z, why in beyond if z > REFERENCE_BEYOND_SIGMA)
    return [s for s, kept in zip(spans, stands) if kept], [
        f"{len(aside)} excursion(s) ({spans_said(aside)}) stand only "
        f"with the reference's fitted error, which lies beyond its stated accuracy ({words}): "
        "the reference is worse than stated or the model lacks something charged to it - "
        "set aside"] if aside else []


def offset_readings(design, fitter, base, terms, rows, full_scale):
    """Per channel (6): the other readings of its quiet offset, [(how much less it reads
    (SI), the 1 sigma that adds (SI), words)] - with the terms neither found nor ruled out
    (`unconfirmed_offset`) and with the reference's fitted error held to its stated
    accuracy (`reference_held_offset`), where either moves it. base: the all-rows fit of
    the found terms; terms: those not confirmed; the rest as `unconfirmed_offset`'s."""
    shift, sigma, names = unconfirmed_offset(design, fitter, base, terms, rows, full_scale)
    held, words = reference_held_offset(design, base, rows)
    out = []
    for c in range(len(CHANNELS)):
        readings = [(shift[c], sigma[c], "with the terms not confirmed ("
                     + ", ".join(names[c]) + ") fitted too")] if names[c] else []
        if words[c]:
            readings.append((held[c], 0.0, "with the reference's fitted error held to "
                             f"{REFERENCE_BEYOND_SIGMA:g} sigma of its stated accuracy "
                             f"({words[c]})", REFERENCE_HELD))
        out.append(readings)
    return out


REFERENCE_HELD = "reference held"   # marks the reading of `reference_held_offset`
HULL_GROWTH = 0.05      # an interval that grows less than this share is left as it was (its
                        # printed four digits barely move; the note would be noise)


def with_other_readings(finding, readings):
    """The bias_shift `finding` with its 95 % interval the hull of its own and of its other
    readings [(how much less it reads, the 1 sigma that adds, words)]
    (`offset_readings`): the data cannot say which reading holds. Its p is the
    largest of the readings' (each against the class's offset, as `bias_models` tests it);
    set aside (`rejected`) when the hull holds zero, when that p misses its limit, or when
    the reading with the reference's error held to its stated accuracy (marked
    REFERENCE_HELD) lies outside its own interval (within it, it widens the interval only: a
    motorcycle's 0.2548 beside its own 0.2536 [0.2456, 0.2628], the reference's fitted error
    5.5 times its stated): the reference's fitted error beyond what was stated is the
    model's failure or the reference's, and the offset it leaves is no reading of the
    IMU's (a phone beside a tactical INS: an accel.z offset of 0.84 m/s^2 at p < 1e-300,
    its interval [0.24, 0.86] from that reading, where the phone's bias was 0.20).
    `ci95_alone` keeps its own interval, so that a later widening widens each reading's
    and not the distance between them (`confirmation.judged_wider`)."""
    mu, (lo, hi) = finding["coefficient"], finding["ci95"]
    se, s0 = (hi - lo) / (2 * 1.959964), finding["normal_offset_1sigma"]
    hull, others, p, held = [lo, hi], [], finding["p_heldout"], None
    for shift, sigma, words, *kind in readings:
        other, half = mu - shift, 1.959964 * math.hypot(se, sigma)
        if other - half >= lo and other + half <= hi:
            continue                        # inside its own interval: nothing to add
        hull = [min(hull[0], other - half), max(hull[1], other + half)]
        p_other = float(stats.chi2.sf(other ** 2 / (se ** 2 + sigma ** 2 + s0 ** 2), 1))
        p = max(p, p_other)
        others.append({"coefficient": other, "ci95": [other - half, other + half],
                       "reading": words, "p": p_other})
        held = others[-1] if kind == [REFERENCE_HELD] and not lo <= other <= hi else held
    if hull[1] - hull[0] <= (1 + HULL_GROWTH) * (hi - lo):
        return finding
    out = dict(finding, ci95=hull, ci95_alone=[lo, hi], other_readings=others,
               p_train=max(finding["p_train"], p), p_heldout=p)
    out["note"] += "".join(f"; {o['reading']} it reads {o['coefficient']:.4g} "
                           f"[{o['ci95'][0]:.4g}, {o['ci95'][1]:.4g}]" for o in others) \
        + ": the interval holds every reading"
    if held is not None:
        out["rejected"] = (f"{held['reading']} it reads {held['coefficient']:.4g}: the "
                           "reference is worse than stated or the model lacks something "
                           "charged to it, and the offset it leaves is no reading of the "
                           "IMU's - inconclusive")
    elif hull[0] <= 0.0 <= hull[1]:
        out["rejected"] = ("the interval of its readings holds zero ("
                           + "; ".join(f"{o['reading']} it reads {o['coefficient']:.4g}"
                                       for o in others) + ") - inconclusive")
    elif p >= finding["holm_threshold"]:
        weakest = max(others, key=lambda o: o["p"])
        out["rejected"] = (f"{weakest['reading']} it reads {weakest['coefficient']:.4g}, "
                           f"p {p:.2g} against the class's offset, above its limit "
                           f"{finding['holm_threshold']:.2g} - inconclusive")
    return out


def read_every_way(findings, readings):
    """The findings of the bias tests with each offset's interval holding its other
    readings (`with_other_readings`; readings: per channel, `offset_readings`')."""
    return [with_other_readings(f, readings[CHANNELS.index((f["sensor"], f["axis"]))])
            if f["effect"] == "bias_shift" and not f.get("rejected") else f for f in findings]
