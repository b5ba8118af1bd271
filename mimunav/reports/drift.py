"""`mimunav drift`: seed S4's AR + Kalman treatment of the gyro drift on a log - the model
identified at rest, the variance reduction at rest, what the same filter does under motion,
and what it cannot do (`mimunav.lab.drift`) - into DIR/drift.md, drift.json, drift.png."""
import json
import os

import numpy as np

from ..lab import drift
from ..compensation.calibration_file import Calibration
from ..errors import InputError
from ..files import atomic_folder
from .noise import choose_span, outputs
from .plots import figure, save

FORMAT = "mimunav-drift/1"
DEG_H = 180 / np.pi * 3600


def analyse(t, w, static, dynamic, rate_hz, window_s, max_order):
    """Per gyro axis: the identified model, the variance reduction at rest, the filter's
    effect on the dynamic span (when given), and the series for the figure."""
    k = (t >= static[0]) & (t <= static[1])
    y_static = drift.decimate(w[k], rate_hz, window_s)
    y_static -= y_static.mean(axis=0)
    y_dyn = None
    if dynamic is not None:
        kd = (t >= dynamic[0]) & (t <= dynamic[1])
        if kd.sum() < 10 * window_s * rate_hz:
            raise InputError(f"dynamic span {dynamic[0]:g}:{dynamic[1]:g} s holds too few "
                             "samples (need 10 windows)")
        y_dyn = drift.decimate(w[kd], rate_hz, window_s)
        y_dyn -= y_dyn.mean(axis=0)
    out = {}
    for j, axis in enumerate("xyz"):
        try:
            bic, fit = drift.identify(y_static[:, j], max_order)
        except ValueError as exc:
            raise InputError(f"static span {static[0]:g}:{static[1]:g} s: {exc}; give a "
                             "longer one or a shorter --window-s") from None
        row = {"bic": bic, "model": drift.describe(fit),
               "static": drift.variance_reduction(fit, y_static[:, j]),
               "series": {"raw": y_static[:, j], "filtered": drift.apply(fit, y_static[:, j])}}
        if y_dyn is not None:
            row["dynamic"] = drift.under_motion(fit, y_dyn[:, j], row["static"]["raw_sd"])
            row["series"]["dynamic_raw"] = y_dyn[:, j]
            row["series"]["dynamic_filtered"] = drift.apply(fit, y_dyn[:, j])
        out[axis] = row
    return out


def document(result, log, channel, cal_path, static, dynamic, window_s):
    axes = {}
    for axis, r in result.items():
        axes[axis] = {k: v for k, v in r.items() if k != "series"}
        axes[axis]["bic"] = {str(p): b for p, b in r["bic"].items()}
        axes[axis]["model"] = {k: (list(map(float, v)) if k == "ar" else v)
                               for k, v in r["model"].items()}
        axes[axis]["model"]["q"] = float(axes[axis]["model"]["q"])
        axes[axis]["model"]["r"] = float(axes[axis]["model"]["r"])
    return {"format": FORMAT, "log": os.path.abspath(log), "channel": channel,
            "calibration": os.path.abspath(cal_path) if cal_path else None,
            "static_span_s": list(static), "dynamic_span_s": list(dynamic) if dynamic else None,
            "window_s": window_s, "units": "rad/s (output), (rad/s)^2 (q, r)", "gyro": axes}


def markdown(doc):
    lines = ["# Gyro drift: AR model and Kalman filter (seed S4)", "",
             f"Log `{doc['log']}`, {doc['channel']}"
             + (f" through `{doc['calibration']}`" if doc["calibration"] else "")
             + f"; rest {doc['static_span_s'][0]:.0f}-{doc['static_span_s'][1]:.0f} s, means over "
             f"{doc['window_s']:g} s, mean removed. Model: AR(p) drift + white measurement noise "
             "(state space, maximum likelihood, order by BIC); the filter is its Kalman filter.",
             "", "| axis | order | AR coefficients | drift q, (deg/h)^2 | noise r, (deg/h)^2 | "
             "converged | sd raw, deg/h | sd filtered, deg/h | variance ratio | under motion: "
             "removed / noise |", "|---|---|---|---|---|---|---|---|---|---|"]
    for axis, r in doc["gyro"].items():
        m, st = r["model"], r["static"]
        dyn = r.get("dynamic")
        lines.append(
            f"| {axis} | {m['order']} | {', '.join(f'{a:.3g}' for a in m['ar'])} | "
            f"{m['q'] * DEG_H**2:.3g} | {m['r'] * DEG_H**2:.3g} | "
            f"{'yes' if m['converged'] else 'no'} | {st['raw_sd'] * DEG_H:.3g} | "
            f"{st['filtered_sd'] * DEG_H:.3g} | "
            + (f"{st['variance_ratio']:.3g}" if m["identified"] else
               f"not identified (AR sum {sum(m['ar']):.2g}: white or oscillating, not a drift)") + " | "
            + (f"{dyn['removed_sd'] * DEG_H:.3g} / {dyn['noise_sd'] * DEG_H:.3g} = "
               f"{dyn['ratio']:.3g}" if dyn else "no dynamic span given") + " |")
    lines += ["", "![drift](drift.png)", "", "What this filter can and cannot do:",
              "- It is a low-pass filter fitted to the gyro's own output at rest. At rest it "
              "removes the part of the white noise the model separates from the drift: the "
              "variance ratio above (the seed's \"variance reduction\") is the filtered "
              "estimate's variance over the raw output's - a smaller ratio is a smoother "
              "estimate of the drift, not a smaller drift. Where the fitted AR coefficients sum "
              "to less than 0.3 the output is white (drift and noise not separable) or "
              "oscillating (vibration), not a drift, and no ratio is given. The ratio depends on the "
              "averaging (--window-s) and the record: compare units only at equal settings.",
              "- It cannot remove a constant bias: the mean is removed before the model and the "
              "filter passes a constant unchanged. Only a calibration (or an alignment at rest) "
              "removes it.",
              "- It cannot remove anything correlated with motion (scale factor, cross-coupling, "
              "g-sensitivity, nonlinearity): they are not in the model.",
              "- Under motion it treats the true rate changes as drift and smears them (the "
              "filtered output lags): a removed part far above the noise at rest "
              "(\"removed / noise\" >> 1) is motion taken out of the output, i.e. new error. "
              "The dynamic span's own mean is removed first (as at rest), so a steady turn "
              "rate itself is not counted - only its changes.", ""]
    return "\n".join(lines)


def plot(result, png, window_s):
    n_cols = 2 if any("dynamic_raw" in r["series"] for r in result.values()) else 1
    plt, fig, axes = figure(3, n_cols, (7 * n_cols, 8))
    for i, (axis, r) in enumerate(result.items()):
        s = r["series"]
        panels = [("static", "raw", "filtered")] + (
            [("dynamic", "dynamic_raw", "dynamic_filtered")] if n_cols == 2 else [])
        for c, (title, raw, filt) in enumerate(panels):
            ax = axes[i, c]
            t = np.arange(len(s[raw])) * window_s
            ax.plot(t, s[raw] * DEG_H, lw=0.6, label="output (mean removed)")
            ax.plot(t, s[filt] * DEG_H, lw=1.2, label="Kalman-filtered")
            ax.set_ylabel(f"gyro {axis}, deg/h")
            ax.set_title(f"{title} span")
            ax.grid(True, alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time in span, s")
    axes[0, 0].legend(fontsize=8)
    save(plt, fig, png)


def write(log, out_dir, channel="/mimu/imu", cal_path=None, static=None, dynamic=None,
          window_s=1.0, max_order=2, force=False):
    """Run `mimunav drift`; returns the folder."""
    cal = Calibration.load(cal_path) if cal_path else None
    t, w, f, rests = outputs(log, channel, cal)
    t0, t1, _ = choose_span(t, w, f, rests, static, option="--static")
    rate = 1.0 / float(np.median(np.diff(t)))
    result = analyse(t, w, (t0, t1), dynamic, rate, window_s, max_order)
    doc = document(result, log, channel, cal_path, (t0, t1), dynamic, window_s)
    with atomic_folder(out_dir, force=force, inputs=[log, cal_path]) as tmp:
        (tmp / "drift.json").write_text(json.dumps(doc, indent=1) + "\n")
        (tmp / "drift.md").write_text(markdown(doc))
        plot(result, str(tmp / "drift.png"), window_s)
    return out_dir
