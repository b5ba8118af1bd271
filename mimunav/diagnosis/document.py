"""The diagnosis as the contract writes it (`mimunav-diagnosis/1`: contract keys first,
then this tool's), and the calibration with the found terms (`CAL+found.json`).
"""
import json
import os

import numpy as np

from ..files import json_ready
from . import bias_models, navigation, outputs, sensor


FORMAT = "mimunav-diagnosis/1"
CONTRACT_KEYS = ("effect", "sensor", "axis", "input_axis", "coefficient", "ci95", "units",
                 "vector", "vector_ci95", "where", "fit")


def document(log_path, diag, alpha=0.05):
    """The `mimunav-diagnosis/1` document of a diagnosis (sensor or navigation level;
    contract keys first, then this tool's extra keys)."""
    findings = [{**{k: f[k] for k in CONTRACT_KEYS if k in f},
                 **{k: v for k, v in f.items() if k not in CONTRACT_KEYS}} for f in diag.findings]
    doc = {"format": FORMAT, "log": os.path.basename(str(log_path)),
           "verdict": sensor.verdict(diag), "findings": json_ready(findings),
           "unexplained": json_ready(diag.unexplained),
           "not_confirmed": json_ready(diag.rejected),
           "level": diag.level, "candidates_tested": diag.candidates, "alpha": alpha,
           "method": METHOD[diag.level]}
    if diag.level in ("sensor", "track"):
        doc["reference_accuracy"] = json_ready(diag.accuracy)
        if getattr(diag, "bias_null", None):
            doc["bias_null"] = json_ready(diag.bias_null)
        doc["within_reference_accuracy"] = json_ready(diag.within_reference)
    for key, spans in (("transfer_shocks_left_out", "shocks"),
                       ("clips_counted_left_out", "clips_counted"), ("gaps_left_out", "gaps"),
                       ("refuted_fixes_left_out", "fixes_refuted"),
                       ("rails_left_out", "rails")):
        if getattr(getattr(diag, "design", None), spans, None):
            doc[key] = json_ready(getattr(diag.design, spans))
    if getattr(diag, "reference_check", None):
        doc["reference_check"] = json_ready(diag.reference_check)
    if getattr(getattr(diag, "design", None), "bins_why", ""):
        doc["bins"] = {"bin_s": diag.design.bin_s, "why": diag.design.bins_why}
    if getattr(diag, "level_choice", None):
        doc["level_choice"] = diag.level_choice
    if getattr(diag, "library_inflation", None):
        doc["library_inflation"] = json_ready(diag.library_inflation)
    if getattr(diag, "reference_agreement", None):
        doc["reference_agreement"] = json_ready(diag.reference_agreement)
    if getattr(diag, "reference_clock", None):
        doc["reference_clock"] = json_ready(diag.reference_clock)
    if getattr(diag, "time_lag", None):
        doc["time_lag"] = json_ready(diag.time_lag)
    if getattr(diag, "untested", None):
        doc["untested"] = diag.untested
    reasons = getattr(diag, "inconclusive", None) or []
    doc["conclusive"] = not reasons
    if reasons:
        doc["inconclusive_reasons"] = reasons
    if diag.level == "navigation":
        doc.update(epoch_s=navigation.EPOCH_S, reference=diag.reference_kind,
                   velocity_error_rms=json_ready(np.sqrt(np.mean(diag.observed ** 2, axis=0))),
                   variance_inflation=diag.variance_inflation)
        if getattr(diag, "biases_removed", None):
            doc["biases_removed"] = json_ready(diag.biases_removed)
    return doc


METHOD = {
    "sensor": ("sensor level (the reference IMU predicts the MIMU's outputs): generalised "
               "least squares with a random-walk bias of fitted level and the reference's "
               "own linear error under a prior of its stated accuracy; forward selection on "
               f"alternate {sensor.SPLIT_BLOCK_S:g} s blocks with Holm's step-down "
               "thresholds over the library; "
               "the other blocks give the coefficient, its 95 % interval and the "
               "confirmation; saturation, quantization, bias shift and bias instability "
               f"tested on the outputs and on {bias_models.SPAN_S:g} s means of the bias over "
               f"quiet flight (longer where a flight holds more than {outputs.MAX_SPANS} of "
               "them: a bias finding's note says how long) "
               "against the MEMS class of seed S1 Table 1"),
    "navigation": ("navigation level (no reference IMU: the MIMU's free-inertial velocity "
                   "error against the reference trajectory is fitted to each candidate's "
                   "error signature on this trajectory, bias wander and initial attitude "
                   "error as nuisance; the terms' inputs from a simulation's exact truth "
                   "with attitude, else from the MIMU's outputs, and then a term made of them "
                   "is not a finding - the velocity error carries the same noise; every "
                   "test's variance times the inflation the rest of the library shows): the "
                   "same selection, held-out confirmation and "
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


def dumps(doc):
    return json.dumps(doc, indent=1, allow_nan=False, default=float) + "\n"


def scale_alike_text(alike):
    """The words of a bias found on an axis that reads gravity (`levels.beside_the_scales`)."""
    mean = alike["mean_input_m_s2"]
    return (f"read at a mean input of {mean:+.3g} m/s^2 on this axis (spread "
            f"{alike['spread_m_s2']:.2g}): a scale error k of the axis is in it as k x "
            f"{mean:+.3g} (0.5 % makes {0.005 * abs(mean):.2g} m/s^2) - no scale was found "
            "on this axis, and only the input's spread tells the two apart; the offset at "
            "zero input is this less that")


def band_text(band):
    """The words of a vibration rectification beside vibration below its regressor's corner
    (`levels.beside_the_band`)."""
    return (f"per the vibration power above {band['corner_hz']:g} Hz (its regressor's corner); "
            f"{band['share']:.0%} of the reference's vibration lies below it (strongest at "
            f"{band['line_hz']:.3g} Hz): what rectifies there reads into this coefficient, so "
            "a coefficient per the whole vibration is smaller by up to that share")


def stated_errors(w):
    """(words, key of their 1 sigma) of the stated errors a set-aside term was tested
    against (`selection._within`'s keys)."""
    if "reference_1sigma" in w:
        return ("the reference's and the calibration's stated linear errors together",
                "reference_1sigma")
    if "transfer_1sigma" in w:
        return ("the reference's stated gyro error carried by the lever-arm transfer",
                "transfer_1sigma")
    if "calibration_1sigma" in w:
        return "the calibration's stated covariance", "calibration_1sigma"
    return "the reference IMU's clock (fitted beside it, as the import measured it)", \
        "clock_1sigma_s"


def stated_sigma(w, values=None):
    """The 1 sigma values of `stated_errors(w)` (or `values` in their units), in words."""
    key = stated_errors(w)[1]
    said = ", ".join(f"{v:.3g}" for v in (w[key] if values is None else values))
    return said + " s" if key == "clock_1sigma_s" else said


def clock_words(w):
    """', with the reference IMU's clock fitted beside it (the import's 1 sigma, ms)' where a
    set-aside term was read so (`selection._within`'s clock_1sigma_s) beside other stated
    errors; else ''."""
    if "clock_1sigma_s" not in w or stated_errors(w)[1] == "clock_1sigma_s":
        return ""
    return (", with the reference IMU's clock fitted beside it (the import measured it to "
            f"{w['clock_1sigma_s'][0] * 1e3:.2g} ms)")


def charge_text(w):
    """What a set-aside term says of the MIMU against the reference: the two disagree along
    it, and how much smaller the stated linear errors it was tested against would have to be
    for it to pass the selection's test (a finding would still need the other checks)."""
    k = w.get("charged_at_accuracy")
    if k is None:
        return "the MIMU and the reference disagree along it"
    whose = stated_errors(w)[0]
    if k <= 0:
        return (f"the MIMU and the reference disagree along it; with {whose} even 1e4 times "
                "smaller it would not pass the selection's test on this flight")
    said = (f"the MIMU and the reference disagree along it: it would pass the selection's "
            f"test with {whose} at {k:.2g} of the stated (1 sigma "
            + stated_sigma(w, w["charged_at_1sigma"]) + ")")
    if not w.get("charged_at_monotone", True):
        said += ", though not at every smaller value (the test is not monotone here)"
    return said


def clock_text(clock):
    """The reference IMU's clock as the diagnosis read it beside the findings
    (`confirmation.clock_reading`), in words; what it leaves untested apart (its
    `latency`, `levels.latency_untested`)."""
    return (f"the reference IMU's clock, fitted beside the findings as time_skew imu.all "
            f"(positive: the MIMU lags): {clock['fitted_s'] * 1e3:+.3g} ms (1 sigma "
            f"{clock['sd_s'] * 1e3:.2g}; on the data alone {clock['data_s'] * 1e3:+.3g} +- "
            f"{clock['data_sd_s'] * 1e3:.2g} ms, the import measured it to "
            f"{clock['import_1sigma_s'] * 1e3:.2g} ms)")


def not_confirmed_said(doc):
    """([(label, why)] of the terms chosen in training and then not confirmed (`doc`'s
    not_confirmed: the held-out test, the physical range, a recording's halves or its library
    check) whose why the reasons the diagnosis is inconclusive do not say already, [the
    labels of those whose why they say]) - one reading for the terminal and the report (the
    report had dropped a term whose label began a reason)."""
    said = " ".join(doc.get("inconclusive_reasons", []))
    rejected = [r for r in doc.get("not_confirmed", []) if r.get("rejected")]
    label = [r.get("label", r.get("effect", "?")) for r in rejected]
    return ([(a, r["rejected"]) for a, r in zip(label, rejected) if r["rejected"] not in said],
            [a for a, r in zip(label, rejected) if r["rejected"] in said])

