"""The report of any recording: a contract log with /mimu/imu and a reference trajectory
(`mimunav import ...` of a drive, a flight, a walk), read as an engineer would (without a
reference trajectory: what it is, its channels, the sensor level when it has a reference IMU,
and why the rest cannot be made):

    what it is      the import's metadata: source, rate, span, reference and whether it is
                    independent, what was measured and what assumed, the alignment
    channels        counts, rates, gaps against the sampling grid, jitter (`mimunav info`)
    windows         free-inertial windows restarted from the reference (`mimunav windows`)
    diagnosis       the automatic level (`mimunav diagnose`): findings, what the reference
                    predicts, the time lag, or why it is inconclusive

    mimunav report recording LOG.mcap -o DIR

DIR gets recording.md, windows.json, windows.png and diagnosis/ (its own report), all
written at once (`files.atomic_folder`): an error leaves no half-written folder. Every
number in the text is computed in this run; a part the recording cannot support (no window
fits, nothing to diagnose against) says why instead of stopping the rest."""
import json
import os
import time
from pathlib import Path

import numpy as np

from ..frames import attitude
from ..evaluation import windows
from ..evaluation.flight import Flight, no_reference
from ..compensation.calibration_file import Calibration
from ..diagnosis import levels
from ..diagnosis.document import document, not_confirmed_said
from ..compensation.calibration_file import with_found
from ..errors import InputError
from ..files import atomic_folder, refuse_inputs
from ..flightlog import FlightLog
from ..flightlog.inspect import describe
from . import diagnosis as diagnosis_report
from . import windows as windows_report

IDENTITY = "identity (the recorded /mimu/imu)"


def _tilt_caveat(rec):
    """What a roll and pitch leveled on the IMU's own specific force cannot tell apart: an
    accelerometer bias across gravity (a rest measures it along gravity only) - 1 mg reads as
    0.057 deg of tilt (a phone's 35 mg as 2 deg); '' where the reference gave the attitude or
    the biases."""
    basis = rec.get("bias_basis") if isinstance(rec.get("bias_basis"), dict) else {}
    if rec.get("initial_attitude") != "leveled" or basis.get("accel") == "all":
        return ""
    return (" Roll and pitch are leveled on the IMU's own specific force: an accelerometer "
            "bias across gravity, which no rest measures, reads as tilt - 1 mg as 0.057 deg.")


def write(log_path, out_dir, force=False, progress=True, min_speed=None,
          lengths=windows.WINDOW_LENGTHS_S, level="auto", vehicle=None):
    """Run every part on the log at `log_path` and write the report folder `out_dir`;
    returns the markdown's path. min_speed (m/s) and lengths (s) as `mimunav windows`;
    level and vehicle as `mimunav diagnose --level --vehicle` (`levels.choose`)."""
    refuse_inputs([out_dir], [log_path])
    asked = level                   # the level given; `level` becomes the one chosen
    if os.path.exists(out_dir) and not force:       # before the work, not after it
        raise FileExistsError(f"{out_dir} exists; use --force to replace it")
    started = time.perf_counter()
    with FlightLog(log_path) as log:
        meta = log.metadata()
        channels = describe(log)
    flight = Flight.load(log_path, reference_imu=False, max_gap_s=np.inf)
    if flight.mimu_raw is not None:
        raise InputError(f"{log_path}: a raw /mimu/raw needs its calibration; the recording "
                         "report takes a recorded /mimu/imu (mimunav import ...)")
    cal = Calibration.identity()
    diag = doc = no_diagnosis = None
    try:
        if flight.truth is None and flight.fog_t is None and level != "sensor":
            raise no_reference(log_path, ("the navigation and track levels" if level == "auto"
                                          else f"the {level} level")
                               + ", and no reference IMU (/fog/imu) for the sensor level")
        level, why = levels.choose(flight, level, vehicle)
        levels.refuse_level(flight, log_path, level, vehicle)
        diag = levels.diagnose(flight, cal, level, vehicle=vehicle)
        diag.level_choice = why
        doc = document(Path(log_path).name, diag)
    except InputError as exc:
        no_diagnosis = str(exc)
    results, docs, no_windows = {}, {}, None
    if flight.truth is None:
        no_windows = str(no_reference(log_path, "the windows to restart from"))
    else:
        results, docs, no_windows = _windows(flight, doc, lengths, min_speed, progress)
    with atomic_folder(out_dir, force=force, inputs=[log_path]) as tmp:
        if results:
            windows_report.plot(results, str(tmp / "windows.png"))
            (tmp / "windows.json").write_text(json.dumps(docs, indent=1) + "\n")
        if doc is not None:
            diagnosis_report.write(tmp / "diagnosis", doc, diag, flight, cal,
                                   with_found(cal, doc["findings"]), IDENTITY)
        given = "".join(f" --{k} {v}" for k, v in (("level", asked), ("vehicle", vehicle))
                        if v not in (None, "auto"))
        text = markdown(log_path, meta, channels, flight, docs, no_windows, doc,
                        no_diagnosis, time.perf_counter() - started, given)
        (tmp / "recording.md").write_text(text)
    return Path(out_dir) / "recording.md"


def _windows(flight, doc, lengths, min_speed, progress):
    """(results, documents per time shift, why there are none or what changed) of the
    free-inertial windows: as recorded, and with a yaw-rate lag the diagnosis `doc` kept
    removed."""
    span = float(flight.truth.t[-1] - flight.truth.t[0])
    shortened = not any(x < span for x in lengths)
    lengths = tuple(x for x in lengths if x < span) or (max(0.1, round(span / 2, 1)),)
    step = min(windows.START_STEP_S, min(lengths) / 2)
    lag = (doc or {}).get("time_lag", {})
    shifts = {"as recorded": 0.0}
    if "tau_s" in lag and "not_a_finding" not in lag:       # only a lag the diagnosis kept
        shifts[f"the yaw-rate lag {lag['tau_s'] * 1e3:.0f} ms removed"] = -lag["tau_s"]
    results, docs, no_windows = {}, {}, None
    try:
        for label, shift in shifts.items():
            results[label], rest = windows.run_all(flight, None, lengths=lengths, step=step,
                                                   time_shift_s=shift, progress=progress,
                                                   min_speed=min_speed)
            docs[label] = windows_report.document(flight, results[label], rest, IDENTITY, shift)
    except InputError as exc:
        results, docs, no_windows = {}, {}, str(exc)
    if shortened and docs:
        no_windows = (f"the reference spans {span:.1f} s, shorter than every default window "
                      f"length: one length of {lengths[0]:g} s (half the span), windows every "
                      f"{step:g} s")
    return results, docs, no_windows


def _sigma_m(text):
    """A stated sigma with its unit when it is a bare number, else what the metadata says
    ('0.5 m (DGNSS)' as it is: it had read '0.5 m (DGNSS) m')."""
    text = str(text or "not stated")
    try:
        float(text)
    except ValueError:
        return _cell(text)
    return _cell(text + " m")


def _what_it_is(fl, rec, ref, mimu, flight):
    """The markdown lines of the recording's table (`markdown`'s 'What it is'): source, IMU,
    reference, and what the import measured and assumed, in its own words - an option they
    name is `mimunav import`'s, and the table says so."""
    lines = ["## What it is", "",
             "The rows 'at import' are `mimunav import`'s own words: an option they name is "
             "one of `mimunav import`'s.", "",
             "| item | value |", "|---|---|",
             f"| source | {_cell(rec.get('real', {}).get('source', fl.get('source', '?')))} |",
             f"| IMU | {_cell(mimu.get('model', '?'))}, {_cell(mimu.get('sample_rate_hz', '?'))} Hz, "
             f"mounting sensor -> vehicle roll/pitch/yaw {_rpy(flight.mimu_mounting)} deg, "
             f"lever arm {flight.mimu_mounting.lever_arm_m.tolist()} m |",
             f"| reference | {_cell(ref.get('source', 'none'))}; attitude "
             f"{_cell(ref.get('attitude', '?'))}; independent of this IMU: "
             f"{_cell(ref.get('independent', 'not stated'))}; position sigma "
             f"{_sigma_m(ref.get('position_sigma_m'))} |"]
    lines += [f"| measured at import: {key} | {_cell(value)} |"
              for key, value in (rec.get("real") or {}).items() if key != "source"]
    return lines + [f"| assumed at import: {key} | {_cell(value)} |"
                    for key, value in (rec.get("assumed") or {}).items()]


def markdown(log_path, meta, channels, flight, docs, no_windows, doc, no_diagnosis, elapsed,
             given=""):
    """recording.md's text; `given`: the options the command was given (' --level track')."""
    fl, rec, ref = meta.get("flight", {}), meta.get("recording", {}), meta.get("reference", {})
    mimu = meta.get("sensor/mimu", {})
    lines = [f"# Recording {fl.get('name', Path(log_path).stem)}", "",
             fl.get("description", ""), "",
             f"Generated by `mimunav report recording {Path(log_path).name}{given}` in "
             f"{elapsed:.0f} s.",
             "",
             *_what_it_is(fl, rec, ref, mimu, flight)]
    q = flight.initial.q_nb
    yaw, pitch, roll = (float(np.degrees(a)) for a in attitude.as_euler(q))
    lines += ["", f"Initial state at t = {flight.initial.t:.2f} s: roll {roll:.2f}, pitch "
              f"{pitch:.2f}, heading {round(yaw, 1) % 360 + 0.0:.1f} deg "
              f"({rec.get('initial_heading', 'heading source not stated')}), speed "
              f"{np.linalg.norm(flight.initial.v_ned):.2f} m/s." + _tilt_caveat(rec), "",
              "## Channels (`mimunav info`)", "", "```", channels, "```", "",
              "## Free-inertial windows against the reference (`mimunav windows`)", ""]
    if not docs:
        lines += [f"No window: {no_windows}", ""]
    else:
        first = next(iter(docs.values()))
        lines += [first["rest"]["alignment"] + ".", ""]
        if no_windows:
            lines += [f"Window length: {no_windows}.", ""]
        for label, d in docs.items():
            lines += [f"**{label}** (IMU stamps shifted by {d['time_shift_s'] * 1e3:+.0f} ms)", "",
                      windows_report.markdown_table(d), ""]
        lines += ["![windows](windows.png)", "",
                  "Windows overlap (the count of disjoint ones in brackets): percentiles over "
                  "them are not independent samples. The reference's own position error ("
                  + (f"sigma {_sigma_m(ref['position_sigma_m'])}" if "position_sigma_m" in ref
                     else "its size not stated") + ") is part of every window's error.", ""]
    lines += ["## Diagnosis (`mimunav diagnose`)", ""]
    if doc is None:
        return "\n".join(lines + [f"Not run: {no_diagnosis}"]) + "\n"
    lines += [f"Level: {doc['level']}. Verdict: "
              + (f"**{doc['verdict']}**." if doc["conclusive"] else
                 f"**inconclusive** (contract verdict `{doc['verdict']}`)."), ""]
    if not doc["conclusive"]:
        lines += [f"- {r}" for r in doc["inconclusive_reasons"]] + [""]
    for f in doc["findings"]:
        value = (f"vector [{', '.join(f'{x:.4g}' for x in f['vector'])}] {f['units']} "
                 f"({f.get('frame', 'sensor')} axes; the largest component's 95 % interval "
                 if "vector" in f else f"{f['coefficient']:.4g} {f['units']} (95 % interval ")
        lines.append(f"- found {f['label']}: {value}[{f['ci95'][0]:.4g}, {f['ci95'][1]:.4g}]; "
                     f"attribution {f.get('attribution', '')})")
    alone, again = not_confirmed_said(doc)
    lines += [f"- not confirmed {label}: {why}" for label, why in alone]
    if again:
        lines.append(f"- not confirmed, for a reason the diagnosis is inconclusive: "
                     f"{', '.join(again)}")
    lag = doc.get("time_lag", {})
    if "tau_s" in lag:
        lines.append(f"- time lag of the IMU from the yaw rate: {lag['tau_s'] * 1e3:.1f} ms "
                     f"[{lag['ci95'][0] * 1e3:.1f}, {lag['ci95'][1] * 1e3:.1f}]"
                     + (f", relative to {lag['relative_to']}" if "relative_to" in lag else "")
                     + (f"; not a finding: {lag['not_a_finding']}" if "not_a_finding" in lag
                        else ""))
    elif "not_estimated" in lag:
        lines.append(f"- time lag of the IMU from the yaw rate not estimated: "
                     f"{lag['not_estimated']}")
    # the excursions the model leaves set the contract verdict: said here too
    lines += [f"- unexplained residual {u['channel']} {u['t0']:.1f}-{u['t1']:.1f} s "
              f"(robust z {u['z']:.1f})" for u in doc["unexplained"]]
    lines += ["", "The diagnosis's own report: `diagnosis/diagnosis.md` (what the reference "
              "predicts, residual map, timeline, contract JSON)."]
    return "\n".join(lines) + "\n"


def _rpy(mounting):
    yaw, pitch, roll = attitude.as_euler(mounting.q_vs)
    return "[" + ", ".join(f"{float(np.degrees(a)) + 0.0:.2f}" for a in (roll, pitch, yaw)) + "]"


def _cell(x):
    if isinstance(x, dict):
        x = "; ".join(f"{k}: {v}" for k, v in x.items())
    return str(x).replace("|", "\\|").replace("\n", " ")     # a table cell: |w| kept
