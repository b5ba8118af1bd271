"""Diagnosis: when a simulation and a recording of the same flight disagree, find where,
name the physics the model left out (the effect vocabulary of log contract section 3), fit
it with an interval and show the fit improve on held-out data.

    sensor       sensor level: the reference IMU predicts the MIMU's outputs
    navigation   navigation level: only a reference trajectory; candidates' error signatures
    track        track level: a land vehicle's trajectory simulated into a reference IMU
    library      the candidate terms;  inference  the tests and their nuisance
    outputs      saturation, quantization, bias shift and bias instability: tests on the
                 outputs themselves (no regressor)
    reference    the reference motion moved to the MIMU's mounting
    concealed    the proof on simulated recordings with hidden effects
    transplant   every effect class put into the foreign flights (their own effect out)
`diagnose_log` is what `mimunav diagnose` runs: the contract document (`mimunav-diagnosis/1`)
and the calibration with the found terms (`CAL+found.json`).
"""
import json
import math
import os

import numpy as np

from ..compensation import FOUND_SUFFIX, Calibration
from ..effects import EFFECTS as APPLICABLE
from . import navigation, sensor

FORMAT = "mimunav-diagnosis/1"
CONTRACT_KEYS = ("effect", "sensor", "axis", "input_axis", "coefficient", "ci95", "units",
                 "vector", "vector_ci95", "where", "fit")


def document(log_path, diag, alpha=0.05):
    """The `mimunav-diagnosis/1` document of a diagnosis (sensor or navigation level;
    contract keys first, then this tool's extra keys)."""
    findings = [{**{k: f[k] for k in CONTRACT_KEYS if k in f},
                 **{k: v for k, v in f.items() if k not in CONTRACT_KEYS}} for f in diag.findings]
    doc = {"format": FORMAT, "log": os.path.basename(str(log_path)),
           "verdict": sensor.verdict(diag), "findings": _plain(findings),
           "unexplained": _plain(diag.unexplained),
           "not_confirmed": _plain(diag.rejected),
           "level": diag.level, "candidates_tested": diag.candidates, "alpha": alpha,
           "method": METHOD[diag.level]}
    if diag.level in ("sensor", "track"):
        doc["reference_accuracy"] = _plain(diag.accuracy)
        if getattr(diag, "bias_null", None):
            doc["bias_null"] = _plain(diag.bias_null)
        doc["within_reference_accuracy"] = _plain(diag.within_reference)
    if getattr(diag, "reference_check", None):
        doc["reference_check"] = _plain(diag.reference_check)
    if getattr(diag, "time_lag", None):
        doc["time_lag"] = _plain(diag.time_lag)
    reasons = getattr(diag, "inconclusive", None) or []
    doc["conclusive"] = not reasons
    if reasons:
        doc["inconclusive_reasons"] = reasons
    if diag.level == "navigation":
        doc.update(epoch_s=navigation.EPOCH_S, reference="truth (/truth/state)",
                   velocity_error_rms=_plain(np.sqrt(np.mean(diag.observed ** 2, axis=0))))
    return doc


METHOD = {
    "sensor": ("sensor level (the reference IMU predicts the MIMU's outputs): generalised "
               "least squares with a random-walk bias of fitted level and the reference's "
               "own linear error under a prior of its stated accuracy; forward selection on "
               "alternate 0.5 s blocks with Holm's step-down thresholds over the library; "
               "the other blocks give the coefficient, its 95 % interval and the "
               "confirmation; saturation, quantization, bias shift and bias instability "
               "tested on the outputs and on 10 s means of the bias over quiet flight "
               "against the MEMS class of seed S1 Table 1"),
    "navigation": ("navigation level (no reference IMU: the MIMU's free-inertial velocity "
                   "error against the reference trajectory is fitted to each candidate's "
                   "error signature on this trajectory, bias wander and initial attitude "
                   "error as nuisance): the same selection, held-out confirmation and "
                   "bootstrap as the sensor level; inconclusive when a chosen term is neither "
                   "confirmed nor refuted on the held-out segments, or holds there but not in "
                   "the bootstrap; 'no-missing-physics' means none detected, not a statement "
                   "of power"),
    "track": ("track level (no reference IMU; a vehicle's reference trajectory, whose own "
              "attitude, if any, is not used): the ideal IMU simulated along the trajectory "
              "(attitude from the velocity: no side slip, roll 0) is the reference of the "
              "sensor level - residual, "
              "Holm selection on alternate blocks, held-out confirmation on the others, the "
              "IMU in the track's band, bins as long as the track's errors stay correlated and "
              "blocks of two bins (reference_check: bin_s, block_s), the yaw rate weighted by "
              "its 1/speed error law; samples below 2 m/s in motion left out")}


def with_found(cal, findings):
    """A copy of calibration `cal` that also removes the found terms (model '<base>+found');
    None when no finding is a term a compensation can remove."""
    if not any(f["effect"] in APPLICABLE for f in findings):
        return None
    doc = cal.as_dict()
    doc["model"] = cal.base_model + FOUND_SUFFIX
    terms = list(cal.found)
    for f in findings:
        if f["effect"] not in APPLICABLE:       # a clipped, quantized or wandering output
            continue                            # is no term a compensation can remove
        term = {k: f[k] for k in ("effect", "sensor", "axis", "input_axis", "order", "window_s",
                                  "reference") if k in f}
        # a lever arm is reported in the vehicle frame and removed in the sensor axes
        vector = f.get("vector_sensor_axes", f.get("vector"))
        term.update({"vector": vector} if vector is not None else {"coefficient": f["coefficient"]})
        terms.append(_plain(term))
    doc["found"] = terms
    doc["procedure"] = (cal.procedure + " + " if cal.procedure else "") + "mimunav diagnose"
    return Calibration.from_dict(doc)


def _plain(x):
    """JSON-ready copy (numpy scalars and arrays to Python)."""
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None                     # e.g. an rms over no rows
    return x


def dumps(doc):
    return json.dumps(doc, indent=1, allow_nan=False, default=float) + "\n"
