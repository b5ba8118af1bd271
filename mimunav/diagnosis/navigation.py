"""Navigation-level diagnosis: when the only reference is a trajectory (position and velocity:
a simulation's truth, a GNSS/INS solution, RTK), not a second IMU.

The compensated MIMU is navigated from the log's initial state with the project's strapdown
navigator (`evaluation.navigate_mimu`); its velocity error against the reference, sampled every
EPOCH_S, is the observation. Every candidate term of the library (`library.candidates`)
has an error signature on this trajectory: the velocity error its regressor, at unit
coefficient, produces through the linearised strapdown error equations (`error_equations`;
tested against the full navigator in tests/diagnosis/test_diagnosis.py). The regressors'
inputs come from a simulation's exact truth where it has an attitude; otherwise (a recorded
reference's noise would sit in both them and the velocity error) from the MIMU's own
outputs, and a term made of those (`library.reads_own_outputs`) is not a finding: the
velocity error carries the same noise (errors in variables, `OWN_NOISE`).

The fit is on velocity-error increments over EPOCH_S (white accelerometer noise gives
independent increments; gyro noise and wander give correlated ones, handled by HAC blocks of
BLOCK_S with Satterthwaite's degrees of freedom, `inference`), with nuisance signatures:
constant accelerometer and gyro biases, the initial attitude error, and a piecewise-linear
bias wander of both with knots every `error_equations.WANDER_KNOT_S`. Selection, Holm thresholds, held-out
confirmation and block-bootstrap stability are those of the sensor level (`sensor`).
"""
from dataclasses import dataclass

import numpy as np
import quaternion
from scipy import stats

from ..compensation import effects
from ..evaluation.replay import resample
from . import inference, library, vehicle_kind
from .confirmation import (alternative_of, beta_of, effect_size, estimate, set_aside_reasons,
                           halves_verdict, rms_in, term_spans, where_rows, Extremes)
from .design import term_contribution
from .error_equations import (EARTH_RADIUS_M, G0, error_model, independent_inputs, nuisance,
                              observed_error, recorded_bias, signature)
from .inference import Tier
from .untested import beside_untested
from ..errors import InputError

EPOCH_S = 1.0
BLOCK_S = 30.0
MIN_EPOCHS = 40                 # shortest reference overlap, in epochs
CHANNELS = ("north", "east", "down")
SEGMENTS = 10                   # contiguous segments: even ones train, odd ones held out
MAX_TERMS = 4
CALIBRATED = 10                 # candidates per selection step whose variance inflation is
                                # measured (each costs a fit of the library): the strongest
STABILITY = 0.5                 # share of bootstrap replicates a term must win
BOOTSTRAP = 200
# the psi-angle error equations are first order in the attitude error phi: their neglected
# terms are ~phi/2 of every signature, 5 % at 0.1 rad (5.7 deg). A free-inertial solution
# whose horizontal velocity error grows (slope over GROWTH_WINDOW_S, median over windows) as
# a larger tilt would - or as an accelerometer bias of g times that, far beyond the class -
# is beyond them: the diagnosis is inconclusive, never "no missing physics"
MAX_IMPLIED_TILT_RAD = 0.1
GROWTH_WINDOW_S = 30.0
RELINEARIZE_PASSES = 3          # refits of the found terms about their own estimate
RELINEARIZE_TOLERANCE = 0.1     # ... until the correction is below this many standard errors
TERM_KEYS = ("effect", "sensor", "axis", "input_axis", "order", "window_s", "reference")


@dataclass
class NavigationDiagnosis:
    level = "navigation"
    findings: list
    rejected: list
    tier: Tier
    train: np.ndarray
    candidates: int
    candidates_list: list
    observed: np.ndarray            # (ne, 3) velocity error at the epochs, NED m/s
    epochs: np.ndarray              # (ne,) s
    unexplained: list
    inconclusive: list              # why the error equations cannot judge this flight
    biases_removed: dict | None = None  # a recording's import-measured biases, taken out
    variance_inflation: dict | None = None  # training / held-out lambda beside the chosen
    reference_kind: str = "truth (/truth/state)"


def diagnose(flight, cal, alpha=0.05, seed=0, reference=None):
    """Navigation-level diagnosis of `flight` (an `evaluation.Flight`) against calibration
    `cal`, with `reference` (a Trajectory; default the log's /truth/state)."""
    reference = reference or flight.truth
    if reference is None:
        raise InputError(f"{flight.path}: no reference trajectory (/truth/state) for the "
                         "navigation-level diagnosis")
    tier, cands, cond, observed, epochs, (t0, t1) = _tier(flight, cal, reference)
    seg = np.minimum(((tier.t - t0) / (t1 - t0) * SEGMENTS).astype(int),
                     SEGMENTS - 1)
    train = seg % 2 == 0
    chosen = _select({"navigation": tier}, cands, {"navigation": train}, alpha)
    limit = physical_limits(flight, cal)
    own = independent_inputs(flight, reference) is None
    noisy = lambda term: own and library.reads_own_outputs(term)             # noqa: E731
    findings, rejected = _confirm(tier, cands, chosen, train, alpha, seed, cond, limit, noisy)
    idx = [cands[c["j"]][2] for c in chosen]
    inflation = {name: inference.variance_inflation(tier, rows, idx)
                 for name, rows in (("training", train), ("held_out", ~train))}
    given = _columns(cands, findings)
    findings, at = _relinearized(flight, cal, reference, findings, ~train,
                                 inference.variance_inflation(tier, ~train, given))
    at = at or (tier, given, None)
    findings, beyond, at = _within_range(findings, limit, at)
    rejected = rejected + beyond
    if flight.source == "recording":        # a real record's halves may differ
        first = tier.t < np.median(tier.t)
        given = _columns(cands, findings)
        inflations = [inference.variance_inflation(tier, rows, given)
                      for rows in (first, ~first, ~train)]
        findings, aside = halves_check(*at, findings, ~train, inflations)
        rejected = rejected + aside
        findings, aside = beside_untested(tier, cands, findings, noisy, ~train)
        rejected = rejected + aside
    q_vs = flight.mimu_mounting.q_vs
    findings, rejected = ([in_vehicle_frame(f, q_vs) for f in x] for x in (findings, rejected))
    diag = NavigationDiagnosis(findings, rejected, tier, train, len(cands), cands, observed,
                               epochs, [], beyond_small_angles(observed, flight.source)
                               + vehicle_kind.mounting_beyond_range(rejected, flight)
                               + ([] if findings else unsettled(rejected)
                                  + set_aside_reasons(rejected))
                               + untestable(cands, noisy, findings))
    diag.variance_inflation = inflation
    diag.reference_kind = ("truth (/truth/state)" if flight.source == "simulation" else
                           "the recording's reference trajectory (/truth/state)")
    removed = {k: recorded_bias(flight, k).tolist()
               for k in ("gyro_bias_static_rad_s", "accel_bias_m_s2")}
    if any(any(v) for v in removed.values()):
        diag.biases_removed = dict(removed, source="the recording's import (its alignment)",
                                   **_what_was_measured(flight))
    return diag


def _what_was_measured(flight):
    """{basis, not_removed}: what the import's alignment measured of the biases it removed
    (the recording's `bias_basis`) and, where a rest gave the accelerometers', what stays:
    a rest measures their bias along gravity only - across it a bias reads as tilt."""
    basis = (flight.recording or {}).get("bias_basis")
    if not isinstance(basis, dict):
        return {}
    out = {"basis": basis}
    if basis.get("accel") == "along_gravity":
        out["not_removed"] = ("the accelerometers' bias across gravity (at the rest it reads "
                              "as a tilt, so the rest cannot measure it)")
    return out


def physical_limits(flight, cal):
    """term -> the largest plausible magnitude of its coefficient (`library.physical_limit`:
    the MIMU's full scale, and a calibrated unit's bound on its linear terms); a lever arm
    here is the MIMU's from the point the reference trajectory describes, anywhere in the
    vehicle (library.TRAJECTORY_LEVER_ARM), not from a reference IMU beside it."""
    scale = library.full_scale(flight.mimu_range)
    return lambda term: (library.TRAJECTORY_LEVER_ARM if term["effect"] == "lever_arm" else
                         library.physical_limit(term, scale, not cal.is_identity))


BEYOND_RANGE = ("its coefficient is beyond the term's physical range ({limit:.3g} {units}): "
                "something else makes that signature on this flight - another term's, or "
                "a motion the error equations do not follow")


OWN_NOISE = ("its regressor is made of the MIMU's own outputs (only a simulation's exact truth "
             "with attitude gives them otherwise: a recorded reference's noise would sit in "
             "both), whose noise the velocity error integrates too: a fit of that noise "
             "(errors in variables) cannot be told from the term")


def _within_range(findings, limit, at):
    """(kept, rejected, the linearization `at` = (tier, columns, point) of the kept ones):
    a relinearized estimate beyond its term's physical range is rejected (`BEYOND_RANGE`)."""
    inside = [float(np.linalg.norm(beta_of(f))) <= limit(f) for f in findings]
    beyond = [dict(f, beyond_range=limit(f), rejected=BEYOND_RANGE.format(
        limit=limit(f), units=f["units"])) for f, ok in zip(findings, inside) if not ok]
    tier, columns, point = at
    pick = lambda xs: [x for x, ok in zip(xs, inside) if ok]                 # noqa: E731
    return pick(findings), beyond, (tier, pick(columns),
                                    None if point is None else pick(point))


def untestable(cands, noisy, findings=()):
    """[reason] when the library's terms made of the MIMU's own outputs (`noisy`) cannot be
    tested on this reference: 'nothing found' does not cover them, and what is found is read
    without them (`findings`: their sizes not measured beyond the widening beside the
    largest single one, `untested.beside_untested` - a survey ship's lever arm from its INS,
    1.5 m, read 1.15 m [0.89, 1.42] beside a mounting 1.5 deg off and a 0.6 % scale)."""
    n = sum(noisy(term) for _, term, _ in cands)
    if not n:
        return []
    said = ("what is found is read without them - a scale, misalignment or mounting error "
            "of the unit moves it (its interval widened beside the one that moves it most, "
            "not beside them together): the sizes found are not measured here"
            if findings else "'nothing found' does not cover them")
    return [f"{n} of the {len(cands)} candidate terms (scale, cross-axis, asymmetry, "
            "nonlinearity, misalignment, time skew) are made of the MIMU's own outputs here - "
            "only a simulation's exact truth with attitude gives their inputs otherwise - and "
            f"cannot be told from the noise the velocity error shares with them: {said}; a "
            "reference IMU of gyros and accelerometers beside it (the sensor level) or, "
            "if a car carried it, its track (--level track) can test them"]


def unsettled(rejected):
    """Why 'nothing found' cannot be said although no term was confirmed: a term chosen on
    the training segments whose held-out interval holds the training coefficient (not
    refuted there, only not testable: an effect excited once, by a boost in a training
    segment), or one the held-out segments confirm but the block bootstrap does not choose
    (something is missing that this flight cannot name)."""
    reasons = []
    for r in rejected:
        train = ", ".join(f"{b:.3g}" for b in np.ravel(r["train_coefficient"]))
        held = ", ".join(f"{b:.3g}" for b in r.get("vector", [r["coefficient"]]))
        if "beyond_range" in r:
            units = "" if r["units"] == "1" else f" {r['units']}"
            reasons.append(f"{r['label']} fits the velocity error (held-out p "
                           f"{r['p_heldout']:.2g}) at {held}{units}, beyond its physical "
                           f"range ({r['beyond_range']:.3g}): something this level cannot name "
                           "makes its signature")
        elif r.get("errors_in_variables") and _beyond(r) > 1:
            reasons.append(f"{r['label']} fits the velocity error (held-out p "
                           f"{r['p_heldout']:.2g}) only at {_beyond(r):.3g} times its physical "
                           f"range, and {OWN_NOISE}: no such term, but something this level "
                           "cannot name makes its signature")
        elif r.get("errors_in_variables"):
            reasons.append(f"{r['label']} fits the velocity error (held-out p "
                           f"{r['p_heldout']:.2g}) at {held} {r['units']}, but {OWN_NOISE}; a "
                           "reference IMU (the sensor level) can tell them apart")
        elif r.get("heldout_untestable") and "train_beyond_range" in r:
            reasons.append(f"{r['label']} was chosen on the training segments (p "
                           f"{r['p_train']:.2g}) at {_beyond(r, 'train'):.3g} times its "
                           "physical range, and the held-out ones cannot test it: no such "
                           "term, but something this level cannot name makes its signature")
        elif r.get("heldout_untestable"):
            reasons.append(f"{r['label']} was chosen on the training segments (p "
                           f"{r['p_train']:.2g}) and the held-out ones cannot confirm it at "
                           f"the Holm limit: their 95 % interval holds the training "
                           f"coefficient ({train} {r['units']}; held-out {held}, p "
                           f"{r['p_heldout']:.2g}) - not refuted there, only not confirmed")
        elif r.get("confirmed_unnamed"):
            reasons.append(f"{r['label']} holds on the held-out segments (p {r['p_heldout']:.2g}, "
                           f"{held} {r['units']}) but is chosen in only "
                           f"{r['bootstrap_stability']:.0%} of the block-bootstrap replicates: "
                           "something is missing that this flight cannot name")
    return reasons


def in_vehicle_frame(finding, q_vs):
    """A lever-arm finding (fitted in the sensor axes) with its vector and interval turned
    into the vehicle frame of the metadata's lever_arm_m (q_vs: sensor -> vehicle), the
    sensor-axes vector kept for the compensation (`vector_sensor_axes`), as the sensor level
    reports it (`confirmation.interval_estimate`); any other finding as it is. The interval
    turns with the components' standard errors taken as independent (exact for a mounting
    along the vehicle's axes, FLU, RFU...; its covariance is not kept this far)."""
    if finding.get("effect") != "lever_arm" or finding.get("frame") == "vehicle":
        return finding
    c_vs = quaternion.as_rotation_matrix(q_vs)
    b = np.asarray(finding["vector"], float)
    lo, hi = np.asarray(finding["vector_ci95"], float).T
    b_v = c_vs @ b
    half_v = np.sqrt((c_vs ** 2) @ ((hi - lo) / 2) ** 2)
    term = {k: finding[k] for k in ("effect", "sensor", "axis") if k in finding}
    return {**finding, **estimate(term, b_v, b_v - half_v, b_v + half_v), "frame": "vehicle",
            "vector_sensor_axes": b.tolist()}


def _beyond(rejected, which="held_out"):
    """How many times its physical range a rejected term's coefficient is (held-out, or
    the training one's with which="train")."""
    if which == "train":
        return float(np.linalg.norm(np.ravel(rejected["train_coefficient"]))) \
            / rejected["train_beyond_range"]
    return float(rejected.get("effect_size", {}).get("of_physical_range", 0.0))


def _tier(flight, cal, reference, terms=None):
    """(the Tier of velocity-error increments over EPOCH_S with every candidate's signature
    as a column, the candidates [("navigation", term, column)], the bins' Conditions, the
    velocity error (ne, 3) NED m/s at the epochs (s), the span (t0, t1) s of the MIMU and the
    reference) of the MIMU compensated by `cal` and navigated; terms: the candidates
    (default the library's)."""
    nav, w, f = observed_error(flight, cal)
    model, cond = error_model(flight, nav, w, f, reference)
    t0 = max(model.t[0], reference.t[0])
    t1 = min(model.t[-1], reference.t[-1])
    epochs = np.arange(t0, t1 + 1e-9, EPOCH_S)
    if len(epochs) < MIN_EPOCHS:
        raise InputError(f"{flight.path}: {t1 - t0:.0f} s of reference overlap is too short "
                         f"for a navigation-level diagnosis (it needs {MIN_EPOCHS * EPOCH_S:g} "
                         "s: its bias wander and initial attitude are fitted beside the terms)")
    observed = resample(nav, epochs).velocity_error(resample(reference, epochs))
    at = np.clip(np.searchsorted(model.t, epochs), 0, len(model.t) - 1)
    increments = lambda x: np.diff(x[at], axis=0)                            # noqa: E731
    z = np.diff(nuisance(model, at), axis=0)
    tier = Tier("navigation", epochs[1:], np.diff(observed, axis=0), [], [],
                knot_s=(t1 - t0,) * 3, linear=[z[:, c, :] for c in range(3)], block_s=BLOCK_S,
                kept=np.ones(len(epochs) - 1, bool))
    cands = []
    for term in (library.candidates() if terms is None else terms):
        if term["effect"] in ("temperature_bias", "temperature_scale"):
            sens = cond.T if term["sensor"] == "accel" else cond.freq
            term["reference"] = float(np.mean(sens[:, effects.AXES.index(term["axis"])]))
        reg = effects.regressor(term, cond)
        k = next(iter(reg.values())).shape[1]
        if not all(np.isfinite(x).all() for x in reg.values()):
            continue
        sig = increments(signature(model, reg, k))
        if np.ptp(sig) <= 1e-12 * max(np.abs(sig).max(), 1e-300):
            continue
        tier.columns.append({c: sig[:, c, :] for c in range(3)})
        tier.k.append(k)
        cands.append(("navigation", term, len(tier.columns) - 1))
    return tier, cands, cond, observed, epochs, (t0, t1)


def _relinearized(flight, cal, reference, findings, held, inflation):
    """The findings with their held-out estimates refitted about themselves (Gauss-Newton on
    the navigation): the error equations are linear in the attitude error and are evaluated
    along the MIMU's own navigation, whose attitude drifts with the very terms found, so the
    first estimate is biased towards zero (a 0.1 deg/s/g gyro g-sensitivity came out 0.84-0.97
    of the truth on recordings 803-806, 0.94-1.03 after one refit). The MIMU compensated with
    the found terms is navigated again, their signatures rebuilt along it, and the held-out
    fit of the same terms on the remaining error gives a correction; repeated until the
    correction is below RELINEARIZE_TOLERANCE of its standard error (at most
    RELINEARIZE_PASSES). The interval is the last refit's, about the point it linearized at,
    its covariance times `inflation` (the held-out rows' `inference.variance_inflation`
    beside the found terms on the whole library: this tier has the found terms only).
    Findings a compensation cannot remove are returned as they are. Returns (findings, the
    last linearization (tier, the findings' columns, its point) or None)."""
    if not findings:
        return findings, None
    from ..compensation.calibration_file import with_found
    terms = [{k: f[k] for k in TERM_KEYS if k in f} for f in findings]
    point = [beta_of(f) for f in findings]
    for passes in range(1, RELINEARIZE_PASSES + 1):
        at = [dict(f, **estimate(term, b, b, b))
              for f, term, b in zip(findings, terms, point)]
        corrected = with_found(cal, at)
        if corrected is None or len(corrected.found) - len(cal.found) != len(findings):
            return findings, None
        tier, cands, _, _, _, _ = _tier(flight, corrected, reference, [dict(t) for t in terms])
        if len(cands) != len(terms):
            return findings, None
        fit = inference.fit(tier, [pos for _, _, pos in cands], held, inflation)
        delta = [fit.beta[fit.slices[k]] for k in range(len(terms))]
        intervals = [fit.interval(k) for k in range(len(terms))]
        estimates = [b + d for b, d in zip(point, delta)]
        moved = max(float(np.max(np.abs(d) / np.maximum((hi - lo) / 3.92, 1e-300)))
                    for d, (lo, hi) in zip(delta, intervals))
        if moved < RELINEARIZE_TOLERANCE or passes == RELINEARIZE_PASSES:
            break
        point = estimates
    out = []
    for f, term, b, e, (lo, hi) in zip(findings, terms, point, estimates, intervals):
        fit_doc = dict(f["fit"], relinearized_passes=passes,
                       first_pass_coefficient=f["coefficient"])
        out.append(dict(f, **estimate(term, e, b + lo, b + hi), fit=fit_doc))
    return out, (tier, [pos for _, _, pos in cands], point)


def halves_check(tier, columns, point, findings, held, inflations=(1.0, 1.0, 1.0)):
    """(kept, set aside) findings after refitting the found terms together on the first and
    the second half (time) of the velocity-error increments of `tier` (their `columns`),
    linearized at `point` (per finding its coefficients, None: at zero): the sensor level's
    rule (`confirmation.halves_verdict`). The held-out segments interleave with the training
    ones, so they cannot see a term that drifts from one end of a recording to the other (a
    reference solution that settles, a temperature, a mounting); the halves can. `held`:
    the rows the findings' intervals were fitted on (`_absorbed`); `inflations`: the
    variance inflations of the first half, the second and `held` (`inference`)."""
    if not findings:
        return findings, []
    first = tier.t < np.median(tier.t)
    fits = [inference.fit(tier, columns, rows, lam)
            for rows, lam in zip((first, ~first), inflations)]
    point = point or [np.zeros(tier.k[c]) for c in columns]
    halves = [[(b0 + fit.beta[fit.slices[k]], fit.cov[fit.slices[k], fit.slices[k]])
               for fit in fits] for k, b0 in enumerate(point)]
    fit_ho = inference.fit(tier, columns, held, inflations[2])
    share = len(tier.t) / max(int(held.sum()), 1)
    absorbed = [_absorbed(fit_ho.cov[fit_ho.slices[k], fit_ho.slices[k]], h, share)
                for k, h in enumerate(halves)]
    return halves_verdict(findings, halves, absorbed)


def _absorbed(cov_held, halves, share):
    """How many times the held-out fit's standard errors (`cov_held`, the findings'
    intervals') exceed what its rows would give without a misfit between the halves - the
    halves' pooled (inverse-variance) covariance over all rows times `share` (all rows over
    held-out rows) - the smallest over the parameters, at least 1: a block-robust variance
    carries such a misfit as scatter of its own."""
    (_, c1), (_, c2) = halves
    pooled = np.diag(np.linalg.pinv(np.linalg.pinv(c1) + np.linalg.pinv(c2))) * share
    ratio = np.sqrt(np.diag(cov_held) / np.maximum(pooled, 1e-300))
    return max(float(np.min(ratio)), 1.0)


def _columns(cands, findings):
    """The tier columns of `findings` (terms of `cands`, matched on their labels)."""
    column = {library.label(term): pos for _, term, pos in cands}
    return [column[f["label"]] for f in findings]


def beyond_small_angles(observed, source="simulation"):
    """[reason] when the velocity error (ne, 3) NED m/s at EPOCH_S epochs grows, over
    GROWTH_WINDOW_S windows, as a tilt beyond MAX_IMPLIED_TILT_RAD would make it in the
    horizontal, or as an accelerometer error of as many g in the vertical (the same 0.1 g:
    a hundred times a MEMS unit's bias class - another unit's calibration, a unit's error
    the bias-wander nuisance would absorb and call nothing missing), else []; source: the
    flight's, whose remedy the reason names (a recording's /mimu/imu takes no calibration
    of raw outputs: a reference IMU flown beside it)."""
    remedy = ("calibrate the MIMU first" if source != "recording" else
              "a recording's outputs are taken as recorded (no calibration of raw outputs "
              "applies to them): diagnose against a reference IMU flown beside it")
    m = max(int(round(GROWTH_WINDOW_S / EPOCH_S)), 3)
    k = len(observed) // m
    if k < 1:
        return []
    x = (np.arange(m) - (m - 1) / 2) * EPOCH_S
    slopes = np.einsum("j,kjc->kc", x, observed[:k * m].reshape(k, m, 3)) / float(x @ x)
    growth = float(np.median(np.linalg.norm(slopes[:, :2], axis=1)))
    # the free-inertial vertical channel diverges: a constant accelerometer error b grows the
    # down velocity error as b cosh(t / tau), tau = sqrt(R / 2 g) (570 s): each window's
    # slope is read back to the error at the start
    mid = (np.arange(k) + 0.5) * m * EPOCH_S
    down = float(np.median(np.abs(slopes[:, 2])
                           / np.cosh(mid / np.sqrt(EARTH_RADIUS_M / (2 * G0)))))
    reasons = []
    if down / G0 > MAX_IMPLIED_TILT_RAD:
        reasons.append(f"the free-inertial vertical velocity error grows at {down:.2g} m/s^2 "
                       f"(median of {GROWTH_WINDOW_S:g} s slopes), as a {down / G0 * 1e3:.0f} "
                       "mg accelerometer error would - far beyond a MEMS unit's bias: the "
                       "calibration does not describe this unit, and the bias wander the "
                       f"fit takes as nuisance would hide it; {remedy}")
    tilt = growth / G0
    if not tilt > MAX_IMPLIED_TILT_RAD:
        return reasons
    return reasons + [f"the free-inertial velocity error grows at {growth:.2g} m/s^2 (median of "
            f"{GROWTH_WINDOW_S:g} s slopes), as a {np.degrees(tilt):.1f} deg tilt or a "
            f"{growth / G0 * 1e3:.0f} mg accelerometer bias would: beyond the small-angle error "
            f"equations of the navigation level (valid to {np.degrees(MAX_IMPLIED_TILT_RAD):.1f}"
            f" deg); {remedy}" + ("" if source == "recording"
                                   else " or diagnose against a reference IMU")]


def _confirm(tier, cands, chosen, train, alpha, seed, cond, limit, noisy):
    """Held-out refit of the chosen terms; the sensor level's rules (physical range,
    held-out p, effect size, sign, bootstrap stability); `limit`: term -> its physical
    range (`physical_limits`); `noisy`: term -> whether its regressor carries the MIMU's own
    noise (`OWN_NOISE`)."""
    if not chosen:
        return [], []
    rng = np.random.default_rng(seed)
    held = ~train
    idx = [cands[c["j"]][2] for c in chosen]
    lam_tr, lam_ho = (inference.variance_inflation(tier, rows, idx) for rows in (train, held))
    fit_tr, fit_ho = inference.fit(tier, idx, train, lam_tr), inference.fit(tier, idx, held, lam_ho)
    findings, rejected = [], []
    for pos, c in enumerate(chosen):
        _, term, col = cands[c["j"]]
        b_tr, b_ho = fit_tr.beta[fit_tr.slices[pos]], fit_ho.beta[fit_ho.slices[pos]]
        _, p_ho = fit_ho.test(pos)
        lo, hi = fit_ho.interval(pos)
        stability = _stability(tier, cands, c, train, rng)
        finding = dict(estimate(term, b_ho, lo, hi), ci95_method="student-t")
        finding.update({k: term[k] for k in ("order", "window_s", "reference") if k in term})
        contribution = term_contribution(tier, col, b_tr)
        rows = where_rows(contribution)
        before = tier.residual
        after = before - contribution
        chans = list(range(tier.channels))
        rms = lambda x, r: rms_in(x, r, chans)                               # noqa: E731
        finding.update(
            where=term_spans(tier, rows, term, Extremes.of_conditions(cond)),
            fit={"train_rms_before": rms(before, rows & train),
                 "train_rms_after": rms(after, rows & train),
                 "heldout_rms_before": rms(before, rows & held),
                 "heldout_rms_after": rms(after, rows & held),
                 "units": "m/s", "basis": f"velocity-error increments over {EPOCH_S:g} s (NED), "
                 "epochs where the term acts; 'after' uses the training coefficient",
                 "variance_inflation": {"training": lam_tr, "held_out": lam_ho}},
            label=library.label(term), level="navigation", p_train=c["p_train"],
            holm_threshold=c["threshold"], p_heldout=p_ho,
            heldout_threshold=alpha / len(chosen),
            train_coefficient=b_tr.tolist() if len(b_tr) > 1 else float(b_tr[0]),
            bootstrap_stability=stability,
            indistinguishable_from=[alternative_of(cands[j][1]) for j in c["alternatives"]])
        stat_ho = fit_ho.test(pos)[0] * len(b_ho)
        finding["effect_size"] = effect_size(stat_ho, int(held.sum()) * tier.channels,
                                             float(np.linalg.norm(b_ho)), limit(term))
        share = finding["effect_size"]["heldout_variance_removed"]
        why = None
        if p_ho >= alpha / len(chosen):
            why = f"held-out p = {p_ho:.2g}, needs < {alpha / len(chosen):.2g}"
            # the held-out interval holds the training coefficient: those segments can
            # neither confirm nor refute the term (it acts where they have little of it)
            finding["heldout_untestable"] = bool(np.all((lo <= b_tr) & (b_tr <= hi)))
            if float(np.linalg.norm(b_tr)) > limit(term):   # no such term: its signature
                finding["train_beyond_range"] = limit(term)
        elif noisy(term):                   # held out, it is there - or the noise is
            why = OWN_NOISE
            finding["errors_in_variables"] = True
        elif float(np.linalg.norm(b_ho)) > limit(term):     # held out, it is there
            why = BEYOND_RANGE.format(limit=limit(term), units=finding["units"])
            finding["beyond_range"] = limit(term)
        elif float(b_tr @ b_ho) <= 0:
            why = "the held-out coefficient has the other sign"
        elif share < library.MIN_VARIANCE_SHARE:
            why = (f"negligible: removes {share:.3%} of the held-out residual variance as the "
                   f"fit weighs it (below {library.MIN_VARIANCE_SHARE:.1%})")
        elif stability < STABILITY:
            why = f"chosen in {stability:.0%} of the block-bootstrap replicates"
            finding["confirmed_unnamed"] = True     # held out, it holds: something is there
        (findings if why is None else rejected).append(
            finding if why is None else dict(finding, rejected=why))
    return findings, rejected


# ---- selection (Holm over the library, HAC blocks, block bootstrap) ------------------
def _current(cands, chosen, tier_name):
    """Positions of the chosen terms a test in `tier_name` conditions on: its own, and for
    the linear tier also the fast ones (same bins and columns; in the fast tier the linear
    terms are part of the nuisance)."""
    own = ("fast", "linear") if tier_name == "linear" else (tier_name,)
    return [cands[c["j"]][2] for c in chosen if cands[c["j"]][0] in own]


def _select(tiers, cands, train, alpha):
    """Forward selection with Holm's step-down thresholds over the whole library; each step
    tests the CALIBRATED strongest candidates (nominal evidence) with the variance inflation
    measured beside them (`inference.variance_inflation`), the others count as not passing."""
    chosen, excluded = [], set()
    m = len(cands)
    for step in range(MAX_TERMS):
        evidence = np.ones(m)
        for j, (tn, _, pos) in enumerate(cands):
            if j not in excluded:
                cur = _current(cands, chosen, tn)
                evidence[j] = inference.fit(tiers[tn], cur + [pos], train[tn]).test(
                    len(cur), nominal=True)[1]
        p, lam = np.ones(m), {}
        for j in [j for j in np.argsort(evidence) if j not in excluded][:CALIBRATED]:
            tn, _, pos = cands[j]
            cur = _current(cands, chosen, tn)
            lam[j] = inference.variance_inflation(tiers[tn], train[tn], cur + [pos])
            p[j] = inference.fit(tiers[tn], cur + [pos], train[tn], lam[j]).test(len(cur))[1]
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
        for j in passing:
            if j == best or cands[j][0] != tn:
                continue
            pos_j = cands[j][2]
            p_j = inference.fit(tiers[tn], cur + [pos_b, pos_j], train[tn],
                                lam[best]).test(len(cur) + 1)[1]
            p_b = inference.fit(tiers[tn], cur + [pos_j, pos_b], train[tn],
                                lam[j]).test(len(cur) + 1)[1]
            if p_j > alpha and p_b > alpha:
                alternatives.append(int(j))
        same = [j for j in np.argsort(evidence) if cands[j][0] == tn and j not in excluded]
        chosen.append(dict(j=best, alternatives=alternatives, p_train=float(p[best]),
                           threshold=threshold, competitors=[int(j) for j in same[:10]],
                           prior=list(cur), variance_inflation=lam[best]))
        excluded |= {best, *alternatives}
    return chosen


def _stability(tier, cands, c, train, rng):
    """Share of block-bootstrap replicates of the training rows in which the chosen term (or
    a candidate it cannot be told from) has the smallest p-value among its tier's ten
    strongest competitors - of the replicates in which each of them can be tested
    (`inference.wald_from_blocks`); 0 where none can."""
    winners = {c["j"], *c["alternatives"]}
    pvals, weights = [], None
    for j in c["competitors"]:
        s, q = inference.block_scores(tier, cands[j][2], c["prior"], train)
        if weights is None:
            weights = rng.multinomial(len(s), np.full(len(s), 1 / len(s)), size=BOOTSTRAP)
        with np.errstate(all="ignore"):
            w = inference.wald_from_blocks(s, q, weights.astype(float))
        pvals.append(stats.f.sf(w, s.shape[1], len(s) - 1))
    pvals = np.array(pvals)
    tested = np.all(np.isfinite(pvals), axis=0)
    if not tested.any():
        return 0.0
    best = np.asarray(c["competitors"])[np.argmin(pvals[:, tested], axis=0)]
    return float(np.isin(best, list(winners)).mean())