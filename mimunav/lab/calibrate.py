"""The calibration methods (`METHODS`: entire, traditional, twelve-position, cold-start,
ellipsoid, rotation) run on lab recordings into a calibration file, and the held-out check of
a fit on a run it did not use.
"""
import numpy as np

from ..compensation.calibration_file import Calibration
from ..compensation.model import compensate
from .gls import FitError, Fitted
from .runs import LabRun, known_inputs
from .triads import fit_accel_triad, fit_g_sensitivity, fit_gyro_triad, fit_temperature
from .cold_start import fit_cold_start
from .positions import fit_ellipsoid, fit_gyro_bias, fit_gyro_bias_unknown_attitude


METHODS = ("entire", "traditional", "twelve-position", "cold-start", "ellipsoid", "rotation")


# ---- methods -------------------------------------------------------------------------------
def _runs_by_procedure(runs, need, method):
    by = {r.procedure: r for r in runs}
    missing = [p for p in need if p not in by]
    if missing:
        have = ", ".join(sorted(by)) or "none"
        raise FitError(f"method {method!r} needs lab runs {', '.join(need)}; missing "
                       f"{', '.join(missing)} (given: {have})")
    return by


def calibrate(runs, method, unit="", propagate=True, noise=None):
    """Fit `method` to lab runs (log paths or `LabRun`s); returns a `Calibration` with
    covariance (`propagate=False`: each stage's own only, for speed). `noise`: the unit's
    measured random errors, {"source": str, "instability": {"accel": m/s^2, "gyro": rad/s}}
    (e.g. `reports.noise.load` of a `mimunav noise` file; a sensor left out keeps the unit
    class's), used instead of the unit class's assumed bias instability."""
    if method not in METHODS:
        raise FitError(f"unknown method {method!r}; one of {', '.join(METHODS)}")
    if method == "rotation":            # seed S4 eqs. 4-5: its own model and file
        from .rotation import fit
        return fit(runs, unit=unit, noise=noise)
    runs = [r if isinstance(r, LabRun) else LabRun.load(r) for r in runs]
    for r in runs if noise else []:
        r.noise = dict(r.noise, instability={**r.noise["instability"], **noise["instability"]},
                       source=noise["source"])
    if method == "entire":
        by = _runs_by_procedure(runs, ("thermal-chamber", "rate-table", "centrifuge"), method)
        temp, reference = fit_temperature(by["thermal-chamber"])
        gyro = fit_gyro_triad(by["rate-table"], temp, propagate=propagate)
        accel = fit_accel_triad(by["centrifuge"], temp, propagate=propagate)
        g_sens = fit_g_sensitivity(by["centrifuge"], temp, gyro, propagate=propagate)
        parts = (temp, gyro, accel, g_sens)
        cal = Calibration(model="entire-63", unit=unit,
                          procedure="thermal-chamber+rate-table+centrifuge")
        cal.extra["reference"] = reference
    elif method == "traditional":
        by = _runs_by_procedure(runs, ("multi-position", "single-axis-rate"), method)
        accel = fit_accel_triad(by["multi-position"], None, order=1, propagate=propagate)
        gyro = fit_gyro_triad(by["single-axis-rate"], None, order=1, propagate=propagate)
        parts = (accel, gyro)
        cal = Calibration(model="linear", unit=unit, procedure="multi-position+single-axis-rate")
    elif method == "ellipsoid":
        by = _runs_by_procedure(runs, ("hand-held",), method)
        accel = fit_ellipsoid(by["hand-held"])
        gyro = fit_gyro_bias_unknown_attitude(by["hand-held"], accel)
        parts = (accel, gyro)
        cal = Calibration(model="linear", unit=unit,
                          procedure="hand-held orientations, ellipsoid fit (seed S4)")
        cal.extra["frame"] = ("the accelerometers' own (z along sensor z, x in the sensor x-z "
                              "plane); the gyro frame may differ by the triad's misalignment "
                              "(up to about 1-2 deg), which magnitudes cannot show")
    elif method == "twelve-position":
        by = _runs_by_procedure(runs, ("twelve-position",), method)
        accel = fit_accel_triad(by["twelve-position"], None, order=1)
        gyro = fit_gyro_bias(by["twelve-position"])
        parts = (accel, gyro)
        cal = Calibration(model="linear", unit=unit, procedure="twelve-position (seed S2)")
    else:
        by = _runs_by_procedure(runs, ("cold-start",), method)
        return fit_cold_start(by["cold-start"], unit=unit)
    merged = Fitted({})
    for part in parts:
        merged.values.update(part.values)
        merged.errors.update(part.errors)
    _fill(cal, merged.values)
    names = list(merged.values)
    cov = merged.covariance(names)
    se = np.sqrt(np.diag(cov))
    cal.covariance = {"names": names, "standard_error": se.tolist(), "matrix": cov.tolist(),
                      "residual_rms": {p.stage: p.rms for p in parts if p.rms},
                      "note": "GLS + setting errors + turn-on repeatability + upstream "
                              "coefficients, first-order propagation (mimunav.lab.calibrate)",
                      "noise_model": runs[0].noise}
    return cal


def _fill(cal, values):
    import re
    for name, val in values.items():
        key, *idx = re.findall(r"\w+", name)
        arr = getattr(cal, key)
        arr[tuple(int(i) for i in idx)] = val


def standard_errors(cal):
    """{name: standard error} from a fitted file's covariance block."""
    cov = cal.covariance
    return dict(zip(cov.get("names", []), cov.get("standard_error", [])))


def check(cal, run):
    """Held-out check of a calibration on a lab run it was not fitted on: per steady window,
    compensated mean output minus the known input. Returns a dict of (n_windows, 3) arrays:
    accel_error m/s^2, gyro_error rad/s, accel_input m/s^2, gyro_input rad/s,
    temperature degC (accelerometer thermistors)."""
    r = run.raw
    f, w, _ = compensate(cal, r["accel_volts"], r["gyro_volts"], r["accel_temperature"],
                         r["gyro_frequency"], t=run.t)
    f_in, w_in = known_inputs(run)
    return {"accel_error": run.means(f) - f_in, "gyro_error": run.means(w) - w_in,
            "accel_input": f_in, "gyro_input": w_in,
            "temperature": run.means(r["accel_temperature"])}
