"""The report's navigation of the MIMU through the model, with and without the found terms
(`mimunav diagnose -o`): free-inertial from the log's initial state against /truth/state (a
simulation's truth, a recording's reference trajectory), else the FOG-IMU navigated; position
errors in m (NED, the end's also ENU), block by block when the flight streams."""
from functools import cache
from types import SimpleNamespace

import numpy as np

from ..diagnosis.error_equations import recorded_bias
from ..diagnosis.levels import alignment_said, leveled_on_its_outputs
from ..frames import attitude
from ..evaluation.replay import (comparison_times, navigate_fog, navigate_mimu,
                                 navigate_mimu_at, ned_to_enu, resample)
from .plots import figure, on_screen, save


def model_navigation(flight, cal, compensated=None):
    """(comparison times t (s), the reference's trajectory at t, the position error (t, 3) m
    NED of the MIMU through `cal` at t, a recording's outputs less the biases its import
    measured - `import_biases`): the truth, else the FOG-IMU navigated, is the reference.
    compensated: the MIMU's (w rad/s, f m/s^2) through `cal` when already at hand. Block by
    block when the flight streams (only the states at t are kept). Needs nothing a diagnosis
    finds."""
    t = comparison_times(flight)
    ref = resample(flight.truth, t) if flight.truth is not None else navigate_fog(flight, at=t)
    return t, ref, _navigated(flight, cal, t, compensated,
                              import_biases(flight)).position_error(ref)


def import_biases(flight, findings=(), level="navigation"):
    """(gyro rad/s, accel m/s^2; sensor axes) the biases a recording's import measured at a
    rest (`diagnosis.error_equations.recorded_bias`), which the navigation level and
    `windows` take out of the outputs as recorded - a consumer unit's 0.5-1 deg/s gyro
    biases left in had tumbled the report's navigation to 4,016,748 m. With the found terms
    (`findings`) of the sensor or the track level, an axis whose constant bias was found
    keeps only that finding: it is the whole bias there (the navigation level's findings lie
    beside the import's, fitted after their removal)."""
    biases = [recorded_bias(flight, "gyro_bias_static_rad_s").copy(),
              recorded_bias(flight, "accel_bias_m_s2").copy()]
    for f in findings if level in ("sensor", "track") else ():
        if f["effect"] == "bias_shift" and f.get("sensor") in ("gyro", "accel"):
            biases[f["sensor"] == "accel"]["xyz".index(f["axis"])] = 0.0
    return tuple(biases)


def model_navigation_beside(flight, cal):
    """`model_navigation(flight, cal)` when its `result()` is first asked for, after the
    diagnosis (beside it on a thread, numpy-quaternion arrays in both crashed 1 run in 3-6
    with 'Reference count error detected', 2026-11-29)."""
    return SimpleNamespace(result=cache(lambda: model_navigation(flight, cal)))


def _navigated(flight, cal, at, outputs=None, less=(0.0, 0.0)):
    """The MIMU through `cal` navigated, at times `at` (s): from `outputs` (w, f) if given;
    `less` (gyro rad/s, accel m/s^2) taken out of its outputs first."""
    if outputs is not None:
        return resample(navigate_mimu(flight, outputs[0] - less[0], outputs[1] - less[1]), at)
    return navigate_mimu_at(flight, cal, at, less)


def navigation_gain(flight, cal_found, model, findings=(), cal=None, level="navigation"):
    """Position error (m, 3-D) against the truth (else the FOG-IMU) at the end and its
    maximum, for the model (`model`: what `model_navigation_beside` returns, awaited first;
    `cal`: its calibration, whose own found mounting is noted, `_model_tilt`) and the model
    with the found terms (`cal_found`, None: no found terms; `findings`: this diagnosis'
    own, `tilting_mountings`); and the series to plot, `plots.on_screen`'s samples of them
    (time s since the initial state, {name: 3-D error m})."""
    t, ref, err = model.result()
    errors = {"model": err}
    reference = ("FOG-IMU" if flight.truth is None else "truth" if flight.source != "recording"
                 else "recording's reference trajectory")
    out, series = {"reference": reference}, {}
    leveled = leveled_on_its_outputs(flight)
    if leveled:
        out["initial_state"] = "leveled on the MIMU's own outputs through the model"
    tilting = tilting_mountings(findings) if leveled else []
    if cal_found is not None and tilting:
        said, rpy = tilting[0]
        cut = "redone on the span" in alignment_said(flight)
        out["model+found"] = {"not_navigated": (
            f"the found {said} tilts the outputs the initial state was leveled on: from that "
            "state the navigation would charge the tilt to the terms - import the recording "
            f"again with the mounting that holds it, --mounting-rpy-deg "
            f"{' '.join(f'{a:g}' for a in rpy)}" + (", and cut it again," if cut else ",")
            + " to navigate with it")}
    elif cal_found is not None:
        errors["model+found"] = _navigated(flight, cal_found, t, less=import_biases(
            flight, findings, level)).position_error(ref)
    k = on_screen(len(t))
    for name, err in errors.items():
        norm = np.linalg.norm(err, axis=1)
        out[name] = {"end_m": float(norm[-1]), "max_m": float(norm.max()),
                     "end_enu_m": ned_to_enu(err[-1]).tolist()}
        series[name] = norm[k]
    note = _model_tilt(flight, cal) if leveled else ""
    if note:
        out["model"]["note"] = note
    return out, t[k] - t[0], series


def _model_tilt(flight, cal):
    """What the model's own found mounting (a calibration written by an earlier diagnosis)
    tilts about the vehicle's forward and right axes, when it does: the model's navigation
    from a state leveled on the outputs holds that tilt; '' otherwise."""
    for term in getattr(cal, "found", None) or []:
        if term["effect"] == "mounting_misalignment" and "vector" in term:
            turn = attitude.rotate(flight.mimu_mounting.q_vs, np.asarray(term["vector"], float))
            if np.any(turn[:2]):
                return (f"its calibration holds a found mounting_misalignment "
                        f"({_tilt_text(turn)}) that tilts the outputs the initial state was "
                        "leveled on: this error holds that tilt")
    return ""


def tilting_mountings(findings):
    """(what it is, with its turns about the forward and right axes in deg; the mounting that
    holds it, `mounting_rpy_deg`) of each found mounting that turns the MIMU about the
    vehicle's forward or right axis (95 % interval of the turn clear of 0:
    `vector_vehicle_ci95`) - a turn about the down axis leaves a leveled state level."""
    out = []
    for f in findings:
        ci = f.get("vector_vehicle_ci95")
        if f["effect"] == "mounting_misalignment" and ci and \
                any(lo > 0 or hi < 0 for lo, hi in ci[:2]):
            out.append((f"{f['label']} ({_tilt_text(f['vector_vehicle'])})",
                        f.get("mounting_rpy_deg", [])))
    return out


def _tilt_text(vector_vehicle):
    """A mounting's turn (rad, vehicle axes FRD) about the forward and right axes, in deg."""
    roll, pitch = np.degrees(vector_vehicle[:2])
    return f"{roll:+.2f} deg about the forward axis, {pitch:+.2f} about the right"


def navigation_lines(doc, cal_label=""):
    """The MIMU navigated through the model (`cal_label`: its file, or 'identity ...') with
    and without the found terms."""
    nav = doc["navigation"]
    lines = ["", f"## Navigation error against the {nav['reference']} (navigation.png)", "",
              "Free-inertial over the whole record from the initial state, the MIMU's outputs "
              "through the model alone (on an imported recording, its outputs as recorded "
              "less the biases its import measured at a rest, as the diagnosis and `windows` "
              "take them): every error the model does not hold grows into it.", "",
              "| compensation | end 3-D error, m | max 3-D error, m |", "|---|---|---|"]
    for name in ("model", "model+found"):
        if "end_m" in nav.get(name, {}):
            lines.append(f"| {name} | {nav[name]['end_m']:.1f} | {nav[name]['max_m']:.1f} |")
    if "note" in nav["model"]:
        lines += ["", f"The model's row: {nav['model']['note']}."]
    if "not_navigated" in nav.get("model+found", {}):
        lines += ["", f"Not navigated with the found terms: {nav['model+found']['not_navigated']}."]
    if "model+found" in nav:
        if nav["model+found"].get("end_m", 0.0) > nav["model"]["end_m"]:
            lines += ["", "Removing the found terms alone does not shorten the end error here: the "
                      "model's other errors dominate it (and errors can cancel in part), so one "
                      "term's removal can go either way; the held-out residual rms above is the "
                      "measure of each term." + (
                          " The initial state was leveled on the MIMU's own outputs, which "
                          "took up part of any accelerometer error the terms remove (its "
                          "removal then leaves a tilt of that size)."
                          if "initial_state" in nav else "")]
        model = "" if cal_label.startswith("identity") else f"--cal model={cal_label} "
        compare = (f"`mimunav table LOG {model}--cal found=CAL+found.json` "
                   + ("compares them" if model else "navigates with them beside the reference "
                      "IMU") if doc["level"] == "sensor" else
                   "`mimunav windows LOG --cal CAL+found.json -o DIR` navigates with them "
                   "(free-inertial windows against the reference; `mimunav table` needs a "
                   "reference IMU, which this log has not)")
        lines += ["", f"`CAL+found.json` holds the model with the found terms: {compare}."]
    return lines


def draw_navigation(t, series, nav, png):
    plt, fig, axes = figure(1, 1, (9, 4))
    ax = axes[0, 0]
    for name, norm in series.items():
        ax.plot(t, norm, label=name)
    ax.set_xlabel("time since the initial state, s")
    ax.set_ylabel("3-D position error, m")
    ax.set_title(f"against the {nav['reference']}")
    ax.legend()
    save(plt, fig, png, margins=dict(left=0.1, right=0.98, bottom=0.12, top=0.9))
