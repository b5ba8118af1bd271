"""What a term found, or neither found nor ruled out, does to the means of quiet flight that
the bias tests read (`outputs.bias_tests`): a found term's removal leaves its estimate's error
(`removal_sigma`), and a term left in the residual is an offset there when its input is
steady (`unconfirmed_offset`), and what the reference's fitted linear error took away is no
reading when that fit lies beyond the reference's stated accuracy (`beside_reference`)."""
import numpy as np
import quaternion

from ..frames import attitude
from . import library
from .confirmation import beta_of, position_of
from ..compensation.effects import AXES
from .design import CHANNELS, gamma_slots, term_contribution
from .fitting import plausible


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


def unconfirmed_offset(design, terms, rows, full_scale):
    """((6,) SI, (6,) SI 1 sigma, 6 lists of labels): the offset of each channel's mean over
    `rows` (bool, the design's bins) that the terms tested and neither found nor ruled out
    would make at their estimates - `terms`: those confirmation rejected or set aside and
    those the selection found within the stated errors (their `total_1sigma`); a term
    beyond its physical range is no physics and is left out. On a quiet flight a linear
    term of a steady input is an offset: a bias read without it carries it (a rate table's
    accel.z offset read -0.204 [-0.2175, -0.1906] m/s^2 beside a scale factor 0.0022 and a
    coupling to f_y the halves had not confirmed; the unit's bias is -0.1878)."""
    labels = [library.label(term) for term in design.terms]
    shift, var, names = np.zeros(len(CHANNELS)), np.zeros(len(CHANNELS)), [[] for _ in CHANNELS]
    for f in terms:
        if f.get("label") not in labels or not rows.any() or not (
                {"coefficient", "vector"} & f.keys()):
            continue                # (a term not chosen as implausible carries no estimate)
        j, b = labels.index(f["label"]), beta_of(f)
        if not plausible(design, j, b, full_scale)[0]:
            continue
        cov = (np.diag(np.square(f["total_1sigma"])) if "total_1sigma" in f
               else finding_covariance(design, f, np.eye(len(b))))
        jac = _mean_jacobian(design, j, len(b), rows)
        move = jac @ b
        shift += move
        var += np.einsum("ck,kl,cl->c", jac, cov, jac)
        for c in np.flatnonzero(move):
            names[c].append(f["label"])
    return shift, np.sqrt(var), names


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
BIAS_EFFECTS = ("bias_shift", "bias_instability")


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


def beside_reference(findings, beyond):
    """The bias findings (`outputs.bias_tests`), set aside (`rejected`) on a channel whose
    row of the reference's fitted linear error lies beyond REFERENCE_BEYOND_SIGMA
    (`reference_beyond_stated`): the quiet means they read are what that fit left - a
    MEMS reference's accel.z scale fitted at -0.076 against its stated 0.0025, beside a
    plane's 0.2 m lever arm left out in 99 deg/s of handling, took 0.74 m/s^2 from a quiet
    mean and left a bias_shift of -0.64 [-0.83, -0.46] where the IMUs differ by +0.10."""
    out = []
    for f in findings:
        z, words = beyond[CHANNELS.index((f["sensor"], f["axis"]))] \
            if (f["sensor"], f["axis"]) in CHANNELS else (0.0, "")
        if f["effect"] in BIAS_EFFECTS and z > REFERENCE_BEYOND_SIGMA and not f.get("rejected"):
            f = dict(f, reference_fitted_beyond_stated=z, rejected=(
                f"read after the reference's fitted linear error, which lies beyond its "
                f"stated accuracy ({words}): something the model lacks is charged to the "
                "reference, and the offset left is that fit's - inconclusive"))
        out.append(f)
    return out
