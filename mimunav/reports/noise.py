"""`mimunav noise`: the random errors of an IMU channel over a static span of a log - Allan
deviation per axis with its 68 % band, the five IEEE-952 terms with intervals
(`mimunav.lab.allan`), a figure, and `noise.json` (`mimunav-noise/1`, SI units) that the lab fits
read as their noise model (`mimunav calibrate --noise`).

The span: given (`--span T0:T1`, s since the log's first sample of the channel, clipped to
the data), else the longest rest of the log's reference (`alignment.rest_intervals`: slower
than 0.2 m/s, 1 s cut where it meets motion), else the longest stretch whose 1 s mean outputs
stay still (gyro within 0.2 deg/s and accelerometer within 0.05 m/s^2 of the previous
second's) - at least 10 s. A span is refused when any second's mean steps that far from the
previous one (motion), or strays that far from the span's median by a slow drift (warm-up:
named as such). The fit's chi^2/dof is reported; above 3 the five-term model misses the
curve (e.g. the sawtooth of pulse quantization of a near-constant input) and the terms are
flagged approximate.
"""
import json
import math
import os

import numpy as np

from ..navigation.rests import rest_intervals
from ..lab import allan
from ..compensation.calibration_file import Calibration
from ..compensation.model import compensate
from ..errors import InputError
from ..files import atomic_folder, check_format, read_json
from ..flightlog import FlightLog
from .plots import figure, save

FORMAT = "mimunav-noise/1"
MIN_SPAN_S = 10.0                 # s: N from taus up to 1 s; B and K need far longer spans
STILL_GYRO = math.radians(0.2)       # rad/s between successive 1 s means
STILL_ACCEL = 0.05                   # m/s^2 between successive 1 s means
MISFIT = 3.0                         # chi^2/dof above which the terms are flagged approximate
SENSORS = {"gyro": ("rad/s", {"quantization": "rad", "random_walk": "rad/sqrt(s)",
                               "bias_instability": "rad/s", "rate_random_walk": "rad/s/sqrt(s)",
                               "rate_ramp": "rad/s^2"}),
           "accel": ("m/s^2", {"quantization": "m/s", "random_walk": "m/s/sqrt(s)",
                               "bias_instability": "m/s^2",
                               "rate_random_walk": "m/s^2/sqrt(s)", "rate_ramp": "m/s^3"})}
# datasheet units for the markdown table: (factor from SI, unit)
DATASHEET = {("gyro", "random_walk"): (180 / math.pi * 60, "deg/sqrt(h)"),
             ("gyro", "bias_instability"): (180 / math.pi * 3600, "deg/h"),
             ("gyro", "rate_random_walk"): (180 / math.pi * 3600 * 60, "deg/h/sqrt(h)"),
             ("accel", "random_walk"): (60.0, "m/s/sqrt(h)"),
             ("accel", "bias_instability"): (1e3 / 9.80665, "mg"),
             ("accel", "rate_random_walk"): (1e3 / 9.80665 * 60, "mg/sqrt(h)")}


def outputs(log_path, channel, cal=None):
    """(t s since the channel's first sample, w rad/s, f m/s^2) of an IMU channel:
    /mimu/imu, /fog/imu (sensor_msgs/Imu) or /mimu/raw through calibration `cal`."""
    if cal is not None and channel != "/mimu/raw":
        raise InputError(f"--cal reads /mimu/raw; {channel} is already in SI units")
    with FlightLog(log_path) as log:
        if channel not in log.channels:
            hint = ("; the MIMU's raw output: --channel /mimu/raw --cal CAL.json"
                    if channel == "/mimu/imu" and "/mimu/raw" in log.channels else "")
            raise InputError(f"{log_path}: no channel {channel}; it has "
                             f"{', '.join(sorted(log.channels))}{hint}")
        truth = log.read("/truth/state") if "/truth/state" in log.channels else None
        joint = (log.read("/mimu/platform", fields=("velocity",))
                 if channel.startswith("/mimu/") and "/mimu/platform" in log.channels else None)
        if channel == "/mimu/raw":
            if cal is None:
                raise InputError("/mimu/raw is in volts: give --cal CAL.json to read it in SI "
                                 "units (or choose /mimu/imu)")
            raw = log.read(channel)
            t0 = int(raw["log_time"][0])
            t = (raw["log_time"].astype(np.int64) - t0) / 1e9
            f, w, _ = compensate(cal, raw["accel_volts"], raw["gyro_volts"],
                                 raw["accel_temperature"], raw["gyro_frequency"], t=t)
        else:
            msg = log.read(channel, fields=("angular_velocity", "linear_acceleration"))
            if len(msg) == 0:
                raise InputError(f"{log_path}: {channel} has no messages")
            t0 = int(msg["log_time"][0])
            t = (msg["log_time"].astype(np.int64) - t0) / 1e9
            w = np.ascontiguousarray(msg["angular_velocity"], float)
            f = np.ascontiguousarray(msg["linear_acceleration"], float)
    rests = []
    if truth is not None and len(truth):
        tt = (truth["log_time"].astype(np.int64) - t0) / 1e9
        rests = rest_intervals(tt, truth["velocity_ned"], float(t[0]), float(t[-1]))
    if joint is not None:        # a MIMU turning on its platform is not at rest
        tj = (joint["log_time"].astype(np.int64) - t0) / 1e9
        turning = np.interp(t, tj, np.abs(joint["velocity"])) > 1e-9
        w = w.copy()
        w[turning] = np.nan       # refused by every span check (`_check_span`)
    return t, w, f, rests


def _runs(t, still):
    """[(t0, t1)] of the runs of `still` (bool per t)."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(int), [0]])))
    return [(float(t[a]), float(t[b - 1])) for a, b in zip(edges[::2], edges[1::2])]


def still_spans(t, w, f):
    """Spans (s) whose successive 1 s mean outputs stay within STILL_GYRO / STILL_ACCEL."""
    sec = np.floor(t - t[0]).astype(int)
    n = sec[-1] + 1
    counts = np.bincount(sec, minlength=n)
    ok = counts >= 0.5 * np.median(counts[counts > 0])      # as `_second_means`
    means = [np.column_stack([np.bincount(sec, x[:, j], minlength=n) for j in range(3)])
             / np.maximum(counts, 1)[:, None] for x in (w, f)]
    step_w = np.linalg.norm(np.diff(means[0], axis=0), axis=1)
    step_f = np.linalg.norm(np.diff(means[1], axis=0), axis=1)
    still = np.concatenate([[False], (step_w < STILL_GYRO) & (step_f < STILL_ACCEL)
                            & ok[1:] & ok[:-1]])
    return [(t[0] + a - 1, t[0] + b + 1) for a, b in _runs(np.arange(n), still)]


def choose_span(t, w, f, rests, span=None, option="--span"):
    """The static span (t0, t1) s to analyse and how it was chosen: the given one (clipped
    to the data), else the longest static candidate among the reference's rests, then the
    still stretches; `option`: the command's own option that gives one, for its messages
    (`mimunav noise --span`, `mimunav drift --static`)."""
    if span is not None:
        t0, t1 = max(span[0], float(t[0])), min(span[1], float(t[-1]))
        _check_span(t, w, f, t0, t1, option=None)
        clipped = (t0, t1) != tuple(span)
        return float(t0), float(t1), f"given ({option}" + (", clipped to the data)" if clipped
                                                          else ")")
    candidates = sorted(((b - a, a, b, "the longest static rest of the log's reference "
                          "(/truth/state)") for a, b in rests if b - a >= MIN_SPAN_S),
                        reverse=True)
    candidates += sorted(((b - a, a, b, "the longest stretch whose 1 s means stay still")
                          for a, b in still_spans(t, w, f) if b - a >= MIN_SPAN_S), reverse=True)
    refused = []
    for _, t0, t1, how in candidates:
        try:
            _check_span(t, w, f, t0, t1, option)
        except InputError as exc:
            refused.append(str(exc))
            continue
        return float(t0), float(t1), how + (f" ({len(refused)} longer candidate(s) refused: "
                                            f"{refused[0]})" if refused else "")
    longest = max((b - a for a, b in still_spans(t, w, f)), default=0.0)
    raise InputError(f"no static span of {MIN_SPAN_S:g} s found (longest still stretch "
                     f"{longest:.0f} s{'; ' + refused[0] if refused else ''}); give one with "
                     f"{option} T0:T1 (s)")


def _check_span(t, w, f, t0, t1, option="--span"):
    """Refuse a span [t0, t1] s that is no rest; option: how the command takes one (None:
    the span was given), for the hint."""
    k = (t >= t0) & (t <= t1)
    if np.isnan(w[k]).any():
        raise InputError(f"span {t0:g}:{t1:g} s: the MIMU turns on its platform "
                         "(/mimu/platform) there - not at rest")
    if t1 - t0 < MIN_SPAN_S or k.sum() < 100:
        raise InputError(f"span {t0:g}:{t1:g} s holds {k.sum()} samples over "
                         f"{t1 - t0:.0f} s; need >= {MIN_SPAN_S:g} s")
    hint = "" if option is None else f" (give {option})"
    for name, x, limit, unit, k_unit in (("gyro", w, STILL_GYRO, "deg/s", 180 / math.pi),
                                         ("accelerometer", f, STILL_ACCEL, "m/s^2", 1.0)):
        m = _second_means(t[k], x[k])
        steps = np.linalg.norm(np.diff(m, axis=0), axis=1)
        if len(steps) and steps.max() > limit:
            at = t0 + int(np.argmax(steps)) + 1
            raise InputError(f"span {t0:g}:{t1:g} s is not static: the {name}'s 1 s mean "
                             f"steps by {steps.max() * k_unit:.3g} {unit} near {at:.0f} s "
                             f"(motion; limit {limit * k_unit:g} {unit}){hint}")
        stray = np.linalg.norm(m - np.median(m, axis=0), axis=1)
        if stray.max() > limit:
            raise InputError(f"span {t0:g}:{t1:g} s drifts: the {name}'s 1 s means wander "
                             f"{stray.max() * k_unit:.3g} {unit} from their median without "
                             "a step (a warm-up or temperature drift the calibration does not "
                             "remove); choose a shorter or later span, or a calibration with "
                             f"temperature terms{hint}")


def _second_means(t, x):
    """Means of x over each whole second of t (seconds with under half the usual number of
    samples - the span's ragged ends, gaps - left out: their means are noise)."""
    sec = np.floor(t - t[0]).astype(int)
    counts = np.bincount(sec)
    keep = counts >= 0.5 * np.median(counts[counts > 0])
    means = np.column_stack([np.bincount(sec, x[:, j]) for j in range(3)])[keep]
    return means / counts[keep][:, None]


def analyse(t, w, f):
    """dict sensor -> axis -> {curve, terms} over samples (t, w, f) of a static span."""
    dt = np.diff(t)
    rate = 1.0 / float(np.median(dt))
    bad = np.flatnonzero(np.abs(dt * rate - 1) > 0.5)
    if len(bad):
        where = ", ".join(f"{t[k]:.2f} s ({dt[k]:.3g} s)" for k in bad[:5])
        raise InputError(f"the span {t[0]:.2f}-{t[-1]:.2f} s has {len(bad)} sample intervals "
                         f"off the median {1 / rate:.3g} s by over half a sample, at {where}"
                         f"{' ...' if len(bad) > 5 else ''}: Allan deviation needs uniform "
                         "sampling (choose a span between them with --span)")
    out = {"rate_hz": rate}
    for sensor, x in (("gyro", w), ("accel", f)):
        out[sensor] = {}
        for j, axis in enumerate("xyz"):
            curve = allan.allan_deviation(x[:, j] - x[:, j].mean(), rate)
            terms = allan.fit_terms(curve)
            out[sensor][axis] = {"curve": curve, "terms": terms,
                                 "chi2_dof": allan.goodness(curve, terms)}
    out["samples"] = len(t)
    return out


def as_document(result, log_path, channel, span, how, cal_path=None):
    doc = {"format": FORMAT, "log": os.path.abspath(log_path), "channel": channel,
           "calibration": os.path.abspath(cal_path) if cal_path else None,
           "span_s": [span[0], span[1]], "span_chosen": how, "rate_hz": result["rate_hz"],
           "samples": result["samples"],
           "quantization_convention": "Q = pulse or LSB weight / sqrt(12) (IEEE Std 952)",
           "model": "AVAR = 3Q^2/tau^2 + N^2/tau + (2 ln2/pi) B^2 + K^2 tau/3 + R^2 tau^2/2 "
                    "(IEEE Std 952-1997 Annex C); intervals 68 %"}
    for sensor, (unit, term_units) in SENSORS.items():
        doc[sensor] = {}
        for axis, r in result[sensor].items():
            c = r["curve"]
            doc[sensor][axis] = {
                "terms": {name: {"value": v, "interval68": list(iv), "unit": term_units[name]}
                          for name, (v, iv) in r["terms"].items()},
                "chi2_dof": r["chi2_dof"], "approximate": r["chi2_dof"] > MISFIT,
                "allan": {"tau_s": c["tau_s"].tolist(), "adev": c["adev"].tolist(),
                          "lo": c["lo"].tolist(), "hi": c["hi"].tolist(), "unit": unit}}
    return doc


def load(path):
    """A `mimunav-noise/1` file of a MIMU channel -> the bias instability the lab fits use:
    {"source": text, "instability": {sensor: B (SI, RMS over the axes that measured it)}};
    a sensor whose axes all report B = 0 (an upper bound only) or an approximate fit is left
    out (the fits then keep the unit class's), and the source says so."""
    doc = read_json(path, "noise file")
    check_format(doc, FORMAT, path)
    if doc.get("channel") not in ("/mimu/raw", "/mimu/imu"):
        raise InputError(f"{path}: measured on {doc.get('channel')!r}, not the MIMU "
                         "(/mimu/raw or /mimu/imu): not this unit's noise")
    try:
        measured, notes = {}, []
        for sensor in SENSORS:
            b = [doc[sensor][a]["terms"]["bias_instability"]["value"] for a in "xyz"
                 if not doc[sensor][a]["approximate"]]
            b = [v for v in b if v > 0]
            if b:
                measured[sensor] = float(np.sqrt(np.mean(np.square(b))))
                notes.append(f"{sensor} B measured on {len(b)} axes")
            else:
                notes.append(f"{sensor} B not measured (upper bounds only): unit class kept")
    except (KeyError, TypeError) as exc:
        raise InputError(f"{path}: noise file lacks {exc}") from None
    return {"source": f"{os.path.abspath(path)} ({doc['channel']}, span "
                      f"{doc['span_s'][0]:.0f}-{doc['span_s'][1]:.0f} s): " + "; ".join(notes)
                      + "; turn-on repeatability: unit class (one power-on cannot show it)",
            "instability": measured}


def plot(result, png, title):
    plt, fig, axes = figure(1, 2, (12, 4.8))
    for ax, (sensor, (unit, _)) in zip(axes[0], SENSORS.items()):
        for j, axis in enumerate("xyz"):
            r = result[sensor][axis]
            c = r["curve"]
            ax.fill_between(c["tau_s"], c["lo"], c["hi"], color=f"C{j}", alpha=0.2)
            ax.loglog(c["tau_s"], c["adev"], color=f"C{j}", label=f"{axis}")
            ax.loglog(c["tau_s"], allan.model_adev(r["terms"], c["tau_s"]), color=f"C{j}",
                      ls="--", lw=1)
        ax.set_xlabel("tau, s")
        ax.set_ylabel(f"Allan deviation, {unit}")
        ax.set_title(f"{sensor} (dashed: fitted IEEE-952 terms; band: 68 %)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.suptitle(title)
    save(plt, fig, png)


def markdown(doc):
    lines = [f"# Random errors of {doc['channel']}", "",
             f"Log `{doc['log']}`, span {doc['span_s'][0]:.1f}-{doc['span_s'][1]:.1f} s "
             f"({doc['span_chosen']}), {doc['rate_hz']:.4g} Hz. {doc['model']}.", "",
             "![Allan deviation](noise.png)", "",
             f"{doc['samples']} samples; calibration: {doc['calibration'] or 'none (SI channel)'}.",
             "", "| sensor | axis | random walk | bias instability B | rate random walk | "
             "quantization Q | rate ramp | fit chi^2/dof |", "|---|---|---|---|---|---|---|---|"]
    for sensor, (_, term_units) in SENSORS.items():
        for axis in "xyz":
            cells = []
            for name in allan.TERMS:
                term = doc[sensor][axis]["terms"][name]
                k, unit = DATASHEET.get((sensor, name), (1.0, term_units[name]))
                lo, hi = term["interval68"]
                cells.append(f"{term['value'] * k:.3g} [{lo * k:.3g}, {hi * k:.3g}] {unit}")
            chi = doc[sensor][axis]["chi2_dof"]
            flag = " (approximate: the model misses the curve)" if chi > MISFIT else ""
            lines.append(f"| {sensor} | {axis} | " + " | ".join(
                cells[i] for i in (1, 2, 3, 0, 4)) + f" | {chi:.3g}{flag} |")
    lines += ["", "68 % intervals. A term the data do not show is reported as 0 with its upper "
              "bound; bias instability needs spans of several times its correlation time, rate "
              "random walk spans of hours. B is the IEEE-952 coefficient: the Allan floor is "
              f"{allan.FLICKER_FLOOR:.3f} B (datasheets' \"bias stability\" is often that "
              "floor). Where chi^2/dof > 3 the five terms do not describe the curve (a sawtooth "
              "of pulse quantization on a near-constant input, vibration lines): read the "
              "figure, not the numbers.", ""]
    return "\n".join(lines)


def write(log_path, out_dir, channel="/mimu/imu", cal_path=None, span=None, force=False):
    """Run `mimunav noise`; returns the folder's path."""
    cal = Calibration.load(cal_path) if cal_path else None
    t, w, f, rests = outputs(log_path, channel, cal)
    t0, t1, how = choose_span(t, w, f, rests, span)
    k = (t >= t0) & (t <= t1)
    result = analyse(t[k], w[k], f[k])
    doc = as_document(result, log_path, channel, (t0, t1), how, cal_path)
    with atomic_folder(out_dir, force=force, inputs=[log_path, cal_path]) as tmp:
        (tmp / "noise.json").write_text(json.dumps(doc, indent=1) + "\n")
        plot(result, str(tmp / "noise.png"), f"{channel}, {t0:.0f}-{t1:.0f} s")
        (tmp / "noise.md").write_text(markdown(doc))
    return out_dir
