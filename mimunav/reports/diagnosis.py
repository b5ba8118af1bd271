"""The diagnosis report: REPORT_DIR/diagnosis.md with
  residual-map.png   condition x channel map of the residual, before and after the found
                     terms (sensor level)
  timeline.png       the residual along the flight with the located segments (and any
                     unexplained excursion) marked (sensor level); at the navigation level
                     the velocity error against the reference and the found terms' share
  navigation.png     navigation error of the model and of the model with the found terms
                     (`navigation_gain`)
  diagnosis.json     the `mimunav-diagnosis/1` document;  CAL+found.json  the calibration
                     with the found terms (when any), for `mimunav table`.
The folder is built beside its final place and renamed into it (nothing half-written).
"""
import math
from functools import cache
from types import SimpleNamespace
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..files import atomic_folder
from ..diagnosis.document import (band_text, charge_text, clock_text, clock_words, dumps,
                                  scale_alike_text, stated_errors, stated_sigma)
from ..diagnosis.design import term_contribution
from ..diagnosis import library
from ..diagnosis.inference import p_text
from ..diagnosis.outputs import block_index
from ..diagnosis.design import CHANNELS
from ..diagnosis.scan import CONDITIONS
from .navigation_gain import draw_navigation, model_navigation, navigation_gain, navigation_lines
from .plots import Painter, figure, save

CHANNEL_NAMES = [f"{s}.{a}" for s, a in CHANNELS]
FILES = ("diagnosis.md", "diagnosis.json", "CAL+found.json", "residual-map.png",
         "timeline.png", "navigation.png")          # all the report may write (module doc)


def write(out_dir, doc, diag, flight, cal, cal_found, cal_label, force=False, painter=None,
          model=None):
    """The report folder: diagnosis.json (with the navigation gain), CAL+found.json, the
    figures and diagnosis.md. The figures are drawn by `painter` (a `plots.Painter`, else
    here) while the navigations run on threads (matplotlib holds the interpreter; the
    navigator does not). model: what `model_navigation_beside` returns, else one made here;
    its `result()` is made in the thread of the navigation with the found terms, one after
    the other (two navigations in two threads: `model_navigation_beside`)."""
    painter = painter or Painter(fork=False)
    # left in reverse: the navigations joined, then the figures drawn (or the child stopped
    # on an error), then the folder committed (or removed)
    with atomic_folder(out_dir, force=force) as tmp, painter, ThreadPoolExecutor(2) as pool:
        if model is None:                   # made in the same thread as the found terms'
            own = getattr(diag, "compensated", None)     # the sensor level's, of this flight
            outputs = own[1:] if own and own[0] is flight else None
            model = SimpleNamespace(result=cache(lambda: model_navigation(flight, cal, outputs)))
        gain = pool.submit(navigation_gain, flight, cal_found, model, doc["findings"], cal,
                           diag.level)
        if diag.level in ("sensor", "track"):
            painter.draw(_residual_map, diag.residual_map, str(tmp / "residual-map.png"))
            painter.draw(_timeline, _timeline_lines(diag, doc), str(tmp / "timeline.png"))
        else:
            painter.draw(_velocity_timeline, _velocity_lines(diag, doc),
                         str(tmp / "timeline.png"))
        nav, t_nav, series = gain.result()
        doc["navigation"] = nav
        (tmp / "diagnosis.json").write_text(dumps(doc))
        if cal_found is not None:
            cal_found.save(str(tmp / "CAL+found.json"))
        painter.draw(draw_navigation, t_nav, series, nav, str(tmp / "navigation.png"))
        (tmp / "diagnosis.md").write_text(markdown(doc, diag, cal_label))
    return out_dir


def markdown(doc, diag, cal_label):
    """diagnosis.md: the verdict and method, what the reference predicts, the found terms,
    the unexplained residual, the terms set aside, the residual by flight condition and the
    navigation error with and without the found terms."""
    lines = _verdict_lines(doc, cal_label) + _reference_lines(doc) + _finding_lines(doc) \
        + _residual_lines(doc)
    if diag.level in ("sensor", "track"):
        lines += _condition_table(diag)
    else:
        lines += ["## Velocity error against the reference (timeline.png)", "",
                  "The MIMU navigated free-inertial from the initial state; the fit uses its "
                  f"velocity-error increments over {doc['epoch_s']:g} s. RMS of the velocity "
                  "error (N, E, D): " + ", ".join(f"{x:.3g}" for x in doc["velocity_error_rms"])
                  + " m/s.", ""]
    lines += navigation_lines(doc, cal_label)
    return "\n".join(lines) + "\n"


def _verdict_lines(doc, cal_label):
    verdict = (f"**{doc['verdict']}**" if doc["conclusive"] else
               f"**inconclusive** (contract verdict {doc['verdict']}; the reasons below)")
    lines = [f"# Diagnosis of {doc['log']} ({doc['level']} level)", "",
             f"Model: `{cal_label}`. Verdict: {verdict} "
             f"({doc['candidates_tested']} candidate terms, family-wise alpha {doc['alpha']}).",
             "", doc["method"] + ".", ""]
    if doc.get("bins", {}).get("why"):
        lines += [doc["bins"]["why"][0].upper() + doc["bins"]["why"][1:] + ".", ""]
    if not doc["conclusive"]:
        lines += ["**Inconclusive**: this recording cannot support a verdict on missing "
                  "physics (the contract's verdict field says "
                  f"`{doc['verdict']}`), because", ""]
        lines += [f"- {r}" for r in doc["inconclusive_reasons"]] + [""]
    if doc.get("untested"):
        lines += ["**Untested** beside the findings:", ""] + [
            f"- {r}" for r in doc["untested"]] + [""]
    return lines + _inflation_lines(doc)


def _inflation_lines(doc):
    """How far the library's test statistics stand above their chance level (median over
    its terms, chi-square 1 dof): a correction at the navigation level, a check on a
    recording at the sensor level."""
    lam = doc.get("variance_inflation")
    if lam:
        return [f"Every test's variance was multiplied by the inflation the rest of the library "
                f"shows beside the terms chosen (its median statistic over its chance value): "
                f"training {lam['training']:.2f}, held-out {lam['held_out']:.2f}.", ""]
    lib = doc.get("library_inflation")
    if lib and lib.get("lambda") is not None:     # as the terminal's reason says it
        searched = [f for f in doc.get("findings", []) if "library_inflation" in f]
        return [("Beside the library's findings its other terms" if searched else
                 "With no term of the library found, its terms") + f" stand {lib['lambda']:.2f} "
                f"times their chance level on the held-out blocks (at most {lib['limit']:g} where "
                "the tests' noise model holds" + (
                    f"; each finding of the search judged with its interval widened "
                    f"{lib['widened_by']:.2f}x" if searched else "") + ").", ""]
    return []


def _clock_lines(doc):
    """The reference IMU's clock as the diagnosis read it beside the findings, and what it
    leaves untested."""
    clock = doc.get("reference_clock")
    if not clock:
        return []
    text, latency = clock_text(clock), clock.get("latency")
    return [text[0].upper() + text[1:] + "."
            + (f" The {latency[0].lower()}{latency[1:]}." if latency else ""), ""]


def _reference_lines(doc):
    """What the reference predicts (the sensor level's agreement, the track level's check)
    and the time lag."""
    lines = _agreement_lines(doc.get("reference_agreement")) + _clock_lines(doc)
    check = doc.get("reference_check")
    if check:
        corr = check["correlation_1s"]
        lines += ["## What the reference predicts", "",
                  "Correlation of the 1 s means of the recorded and the reference-predicted "
                  f"output over trusted samples ({100 * check['trusted_fraction']:.0f} % of the "
                  f"samples; {check['usable_s']:.0f} s usable"
                  + (f"; {check['reversing_s']:.0f} s driven in reverse left out: the vehicle "
                     "model faces along the velocity" if check.get("reversing_s") else "")
                  + f"); below {check['threshold']:g} a "
                  "channel is not predicted and the terms it drives are not tested.", "",
                  "| 1 s means | " + " | ".join(corr) + " |", "|" + "---|" * (len(corr) + 1),
                  "| correlation | " + " | ".join("n/a" if v is None else f"{v:.3f}"
                                                  for v in corr.values()) + " |"]
        error = check.get("model_error_1s")
        if error:
            narrowed = check.get("fitted_on_channels", {})
            lines += ["| model error / size | " + " | ".join(
                "n/a" if v is None else f"{v:.3f}" for v in error.values()) + " |", "",
                "A term of the whole motion is fitted only on channels whose model error (the "
                "rms of the recorded means that no bias, scale or misalignment of the unit "
                "explains, over the predicted means' rms) is below "
                f"{check['model_error_threshold']:.2f}, with columns made of such inputs"
                + (":" if narrowed else "; here each keeps all its channels.")]
            own = {f["label"]: f["fit"]["channels"] for f in doc["findings"] if "fit" in f}
            lines += [f"- {label}: on {', '.join(chans)}" + (
                f" (the finding of this name is fitted on {', '.join(own[label])} alone)"
                if set(own.get(label, chans)) != set(chans) else "")
                for label, chans in narrowed.items()]
        if check.get("not_tested"):
            lines += ["", "Not tested on this recording (driven by an input, or acting on "
                      "channels, the reference does not predict): "
                      f"{', '.join(check['not_tested'])}."]
        lines += [""]
        lag = doc.get("time_lag", {})
        lines += [(f"Time lag of the IMU from the yaw rate: **{lag['tau_s'] * 1e3:.1f} ms** "
                   f"(95 % interval {lag['ci95'][0] * 1e3:.1f} to {lag['ci95'][1] * 1e3:.1f} ms "
                   f"from {len(lag['segments_s'])} segments; positive: the IMU lags)")
                  if "tau_s" in lag else f"Time lag not estimated: {lag.get('not_estimated')}",
                  ""]
        if "relative_to" in lag:
            lines += [f"The lag is relative to {lag['relative_to']}.", ""]
        if "not_a_finding" in lag:
            lines += [f"The lag is not a finding, and its interval no measure of it: "
                      f"{lag['not_a_finding']}.", ""]
    return lines


def _agreement_lines(check):
    """The sensor level's check that the reference IMU predicts the MIMU at all."""
    if not check:
        return []
    chans = check["channels"]
    judged = "judged where the predicted means spread beyond the noise"
    return ["## Does the reference IMU predict the MIMU?", "",
            f"Correlation of the recorded and predicted {check['bin_s']:g} s means ({judged}); "
            f"the mean specific forces are {check['gravity_angle_deg']:.2f} deg apart"
            + (f" ({check['gravity_note']})." if check.get("gravity_note") else "."), "",
            "| channel | " + " | ".join(chans) + " |", "|" + "---|" * (len(chans) + 1),
            "| correlation | " + " | ".join("n/a" if v["correlation"] is None else
                                           f"{v['correlation']:.3f}" for v in chans.values())
            + " |",
            "| predicted spread | " + " | ".join(f"{v['predicted_spread']:.3g}"
                                                for v in chans.values()) + " |", ""] + \
        [f"- {why}" for why in check["failures"]] + ([""] if check["failures"] else [])


def _size(f):
    """A finding's effect size (`confirmation.effect_size`) as the table shows it."""
    size = f.get("effect_size")
    if size is None:
        return "-"
    of_range = size.get("of_physical_range")
    return f"{size['heldout_variance_removed']:.2%} / " + ("-" if of_range is None else
                                                           f"{of_range:.0%}")


def _finding_lines(doc):
    """The found terms: the table, what their held-out rms says, where each acts."""
    lines = []
    if doc["findings"]:
        lines += ["## Found terms (coefficient and 95 % interval from the held-out segments)", "",
                  "| term | coefficient | 95 % interval | units | p train / Holm limit | "
                  "p held-out | held-out variance removed (as the fit weighs it) / of physical "
                  "range | attribution | held-out rms before -> after (bin means where it acts) "
                  "| cannot be told from |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
        for f in doc["findings"]:
            fit = f["fit"]
            alt = ", ".join(a["label"] for a in f["indistinguishable_from"]) or "-"
            vec = f" (vector {_vec(f['vector'])}, {f.get('frame', 'sensor')} axes" + (
                f"; turned {_vec(np.degrees(f['vector_vehicle']))} deg about the vehicle's "
                "forward, right, down axes" if "vector_vehicle" in f else "") + (
                "; the mounting that holds it: mimunav import --mounting-rpy-deg "
                + " ".join(f"{a:g}" for a in f["mounting_rpy_deg"])
                if "mounting_rpy_deg" in f else "") + ")" if "vector" in f else ""
            lines.append(
                f"| {f['label']} | {f['coefficient']:.4g}{vec} | [{f['ci95'][0]:.4g}, "
                f"{f['ci95'][1]:.4g}] | {f['units']} | {p_text(f['p_train'])} / "
                f"{f['holm_threshold']:.2g} | {p_text(f['p_heldout'])} | {_size(f)} | "
                f"{_support(f)} | {fit['heldout_rms_before']:.4g} -> "
                f"{fit['heldout_rms_after']:.4g} {fit['units']} | {alt} |")
        flat = [f for f in doc["findings"]
                if not f["fit"]["heldout_rms_after"] < f["fit"]["heldout_rms_before"]]
        slow = [f["label"] for f in flat if f["effect"] in library.SLOW_EFFECTS
                and doc["level"] != "navigation"]
        if slow:
            lines += ["", f"The held-out rms of {', '.join(slow)} does not fall: its basis "
                      "removes a piecewise-linear bias before the rms is taken, which takes "
                      "most of a slow thermal term with it, and white noise fills what "
                      "remains; such a term is confirmed by its test against the bias wander "
                      "(p held-out), not by this rms."]
        if len(slow) < len(flat):
            lines += ["", "The held-out rms of "
                      + ", ".join(f["label"] for f in flat if f["label"] not in slow)
                      + " does not fall on its basis: it is confirmed by its test (p "
                      "held-out), which this rms does not repeat."]
        wide = [f for f in doc["findings"] if isinstance(f.get("halves"), dict)
                and f["halves"]["widened_by"] > 1]
        if wide:
            lines += ["", "The recording's halves disagree on " + ", ".join(
                f"{f['label']} (p {f['halves']['p_same']:.2g}: its intervals widened "
                f"{f['halves']['widened_by']:.2f}x" + (
                    f", its held-out p {p_text(f['halves']['p_heldout_widened'])} with them"
                    if "p_heldout_widened" in f["halves"] else "") + ")"
                for f in wide) + "; the terms refitted on "
                "each half are in diagnosis.json (`halves`)."]
        noisy = [f for f in doc["findings"] if isinstance(f.get("errors_in_variables"), dict)]
        if noisy:
            own = noisy[0]["errors_in_variables"].get("own")
            lines += ["", ("The reference's own noise (measured in its quietest windows) "
                           "enters the residual and, differentiated, the regressors of a lever "
                           "arm, a proof-mass offset and a time skew: it" if own else
                           "The reference is of MEMS grade: its own noise, in the residual "
                           "and in the regressors,") +
                      " can bias a term (errors in variables). Refitted with as much noise "
                      "again (SIMEX, one step), each interval was widened to hold the estimate "
                      "read back to a noiseless reference: " + ", ".join(
                          f"{f['label']} {f['errors_in_variables']['widened_by']:.2f}x"
                          for f in noisy) + " (diagnosis.json: `errors_in_variables`)."]
        lines += [f"\n{f['label']}: {scale_alike_text(f['scale_alike'])}."
                  for f in doc["findings"] if "scale_alike" in f]
        lines += [f"\n{f['label']}: {band_text(f['band_left_out'])}."
                  for f in doc["findings"] if "band_left_out" in f]
        lines += [f"\n{f['label']}: the import measured {f['import_measured']['value']:.4g} "
                  f"{f['import_measured']['units']} - {f['import_measured']['basis']}."
                  for f in doc["findings"] if "import_measured" in f]
        lines += ["", "Where each term acts (first spans; all in diagnosis.json):", ""]
        for f in doc["findings"]:
            for w in f["where"][:5]:
                d = 1 if w["t1"] - w["t0"] >= 1.0 else 2     # a span of one bin: 0.08 s
                lines.append(f"- {f['label']}: {w['t0']:.{d}f}-{w['t1']:.{d}f} s, "
                             f"{w['condition']}")
        lines.append("")
    else:
        lines += ["No term of the library is confirmed on the held-out segments.", ""]
    return lines


def _residual_lines(doc):
    """The unexplained residual, the terms within the stated accuracies, those chosen on the
    training segments and not confirmed."""
    lines = []
    if doc["unexplained"]:
        lines += ["## Unexplained residual", "",
                  "Localized excursions no candidate explains (2 s windows, robust z, "
                  "Bonferroni over windows and channels):", ""]
        lines += [f"- {u['channel']}: {u['t0']:.1f}-{u['t1']:.1f} s, z = {u['z']:.1f}"
                  + (f", {u['size']:+.3g} {u['units']}" if "size" in u else "")
                  for u in doc["unexplained"][:20]]
        lines.append("")
    others = doc.get("reference_check", {}).get("excursions_not_predicted", [])
    if others:
        lines += ["## Excursions on channels the reference does not predict", "",
                  "Their residual holds the reference's own errors: these say nothing of "
                  "the IMU.", ""]
        lines += [f"- {u['channel']}: {u['t0']:.1f}-{u['t1']:.1f} s, z = {u['z']:.1f}, "
                  f"{u['size']:+.3g} {u['units']}" for u in others]
        lines.append("")
    steps = doc.get("reference_check", {}).get("excursions_at_refuted_fixes", [])
    if steps:
        lines += ["## Excursions at reference fixes left out", "",
                  "The IMU's forces refuted a reference fix near these (left out of the track); "
                  "where the reference jumped, its track still steps there, which its smoothing "
                  "spreads over the seconds around: the reference's, not the IMU's.", ""]
        lines += [f"- {u['channel']}: {u['t0']:.1f}-{u['t1']:.1f} s, z = {u['z']:.1f}, "
                  f"{u['size']:+.3g} {u['units']}" for u in steps]
        lines.append("")
    stops = doc.get("reference_check", {}).get("excursions_of_the_model", [])
    if stops:
        lines += ["## Excursions the vehicle model's own errors make", "",
                  "A stopped vehicle's pitch is the road's grade around the stop, not measured "
                  "at it, and the body tilts on its springs as it accelerates; both tilt g "
                  "into the accelerometers. These steps lie within the bound those errors "
                  "set there, so they are not charged to the IMU:", ""]
        lines += [f"- {u['channel']}: {u['t0']:.1f}-{u['t1']:.1f} s, z = {u['z']:.1f}, "
                  f"{u['size']:+.3g} {u['units']} (bound {u['bound']:.2g}: {u['why']})"
                  for u in stops]
        lines.append("")
    if doc.get("within_reference_accuracy"):
        acc = doc["reference_accuracy"]
        lines += ["## Within the stated accuracies", "",
                  "Significant against the noise alone, but not once the reference's stated "
                  f"error ({acc['source']}) and the calibration's stated covariance may share "
                  "it (for a lever arm or a proof-mass offset: the reference's gyro error "
                  "carried by the lever-arm transfer): with those priors the estimate's own uncertainty (total 1 sigma) is too "
                  "large at the selection's threshold - the data cannot tell the term from "
                  "them, so it is not charged to physics the model lacks.", ""]
        lines += [f"- {w['label']}: {_vec(w.get('vector', [w.get('coefficient')]))}, total "
                  f"1 sigma {_vec(w.get('total_1sigma', []))} ("
                  + f"{stated_errors(w)[0]}: 1 sigma {stated_sigma(w)}{clock_words(w)}"
                  + f"; p train against the noise alone {w['p_train']:.2g}); "
                  + charge_text(w)
                  for w in doc["within_reference_accuracy"]]
        lines.append("")
    if doc["not_confirmed"]:
        lines += ["## Chosen on the training segments, not confirmed", ""]
        lines += [f"- {f['label']}: {f['rejected']}" for f in doc["not_confirmed"]]
        lines.append("")
    return lines


def _condition_table(diag):
    lines = ["## Residual by flight condition", "",
              "RMS of the residual's 1 s means (bias wander removed) in each condition (the "
              "seconds spent mostly in it) over the same in quiet flight; before -> after the "
              "found terms (residual-map.png). White noise alone gives about 1.", "",
              "| condition | " + " | ".join(CHANNEL_NAMES) + " |",
              "|---|" + "---|" * 6]
    before, after = diag.residual_map["before"], diag.residual_map["after"]
    for r, cond in enumerate(CONDITIONS):
        cells = [f"{before[r, c]:.2f} -> {after[r, c]:.2f}" if np.isfinite(before[r, c]) else "n/a"
                 for c in range(6)]
        lines.append("| " + cond.replace("|", "\\|") + " | " + " | ".join(cells) + " |")
    return lines


def _support(f):
    """The sensor level's attribution, the navigation level's bootstrap share."""
    if "attribution" in f:
        return f["attribution"]
    return f"bootstrap {f['bootstrap_stability']:.0%}"


def _vec(v):
    return "[" + ", ".join(f"{x:.3g}" for x in v) + "]"


def _residual_map(residual_map, png):
    """The condition x channel map (`diag.residual_map`: "before", "after")."""
    plt, fig, axes = figure(1, 2, (13, 4.2))
    before, after = residual_map["before"], residual_map["after"]
    top = np.nanmax(np.r_[before.ravel(), after.ravel(), 1.5]) if np.isfinite(before).any() else 2
    for ax, data, title in ((axes[0, 0], before, "before"), (axes[0, 1], after, "after found terms")):
        im = ax.imshow(data, cmap="magma_r", vmin=1.0 if top > 1 else 0, vmax=top, aspect="auto")
        ax.set_xticks(range(6), CHANNEL_NAMES, rotation=30)
        ax.set_yticks(range(len(CONDITIONS)), CONDITIONS)
        ax.set_title(f"residual rms / quiet rms, {title}")
        for (r, c), v in np.ndenumerate(data):
            ax.text(c, r, "n/a" if not np.isfinite(v) else f"{v:.2f}", ha="center", va="center",
                    fontsize=8, color="grey")
        fig.colorbar(im, ax=ax, shrink=0.8)
    # room for the longest condition label (|dT/dt| > 0.5 degC/min) left of each panel
    save(plt, fig, png, margins=dict(left=0.14, right=0.98, bottom=0.15, top=0.92, wspace=0.45))


def _timeline_lines(diag, doc):
    """What `_timeline` draws: per channel the 1 s means of the cleaned fast residual before
    and after the found terms (mg, deg/s), with the located spans (green) and unexplained
    excursions (red), as (t_s, [(channel, unit, before, after, found spans, unexplained
    spans)])."""
    t = diag.design.t
    sec = block_index(t, 1.0)                 # the seconds of `scan.condition_map` and `excursions`
    n = sec.max() + 1
    count = np.maximum(np.bincount(sec, minlength=n), 1)
    t_s = t[0] + np.arange(n) + 0.5
    channels = []
    for c, name in enumerate(CHANNEL_NAMES):
        unit, scale = ("mg", 1e3 / 9.80665) if c < 3 else ("deg/s", 180 / math.pi)
        means = [np.bincount(sec, x[:, c], minlength=n) / count * scale
                 for x in (diag.before, diag.after)]
        found = [(w["t0"], w["t1"]) for f in doc["findings"]
                 if name in f["fit"]["channels"] or f["sensor"] == "imu" for w in f["where"]]
        unexplained = [(u["t0"], u["t1"]) for u in doc["unexplained"] if u["channel"] == name]
        channels.append((name, unit, *means, found, unexplained))
    return t_s, channels


def _timeline(lines, png):
    t_s, channels = lines
    plt, fig, axes = figure(6, 1, (13, 11))
    for ax, (name, unit, before, after, found, unexplained) in zip(axes[:, 0], channels):
        ax.plot(t_s, before, lw=0.8, label="before")
        ax.plot(t_s, after, lw=0.8, label="after")
        for t0, t1 in found:
            ax.axvspan(t0, t1, color="tab:green", alpha=0.15)
        for t0, t1 in unexplained:
            ax.axvspan(t0, t1, color="tab:red", alpha=0.3)
        ax.set_ylabel(f"{name}\n{unit}")
    axes[0, 0].legend(loc="upper right")
    axes[0, 0].set_title("residual, 1 s means (bias wander removed); green: where a found term "
                         "acts, red: unexplained")
    axes[-1, 0].set_xlabel("time since the log epoch, s")
    save(plt, fig, png, margins=dict(left=0.07, right=0.99, bottom=0.05, top=0.97, hspace=0.3))


def _velocity_lines(diag, doc):
    """What `_velocity_timeline` draws (navigation level): the velocity error against the
    reference per NED axis (m/s) and what the found terms (training coefficients) account
    for, with their located spans, as (t s since the first epoch, observed, explained or
    None, spans)."""
    t = diag.epochs - diag.epochs[0]
    explained = np.zeros_like(diag.observed)
    by_label = {library.label(term): pos for _, term, pos in diag.candidates_list}
    for f in doc["findings"]:
        beta = np.atleast_1d(np.asarray(f["train_coefficient"], float))
        inc = term_contribution(diag.tier, by_label[f["label"]], beta)
        explained[1:] += np.cumsum(inc, axis=0)
    spans = [(w["t0"] - diag.epochs[0], w["t1"] - diag.epochs[0])
             for f in doc["findings"] for w in f["where"]]
    return t, diag.observed, explained if doc["findings"] else None, spans


def _velocity_timeline(lines, png):
    from ..diagnosis.navigation import CHANNELS as NED
    t, observed, explained, spans = lines
    plt, fig, axes = figure(3, 1, (13, 8))
    for c in range(3):
        ax = axes[c, 0]
        ax.plot(t, observed[:, c], label="MIMU - reference")
        if explained is not None:
            ax.plot(t, explained[:, c], label="found terms (signature)")
        for t0, t1 in spans:
            ax.axvspan(t0, t1, color="green", alpha=0.15, lw=0)
        ax.set_ylabel(f"v error {NED[c]}, m/s")
    axes[0, 0].legend(fontsize=8)
    axes[-1, 0].set_xlabel("time since the first epoch, s")
    save(plt, fig, png)


def proof_markdown(cases, summary, meta):
    """The concealed-data proof as a report: rates with 95 % intervals, every case."""
    lines = ["# Diagnosis proof on concealed data", "",
             f"Command: `{meta['command']}` ({meta['machine']}, {meta['wall_s']:.0f} s wall).",
             "", "Each recording is the proof flight (`flights/diagnosis-proof.toml`, "
             f"{meta['duration_s']:.0f} s at 1 kHz: an ordinary sortie, each manoeuvre flown once "
             "or twice; MIMU mounted turned 30/20/45 deg) with a freshly drawn unit and at most "
             "one effect hidden in its MIMU (random axis, sign and a realistic magnitude: "
             "`mimunav/diagnosis/concealed.py`). The diagnosis sees the log data and a "
             "**lab-fitted** entire calibration of the unit (thermal chamber, rate table, "
             "centrifuge, with its covariance), never the unit's true coefficients. An effect "
             "counts as identified when a confirmed finding names it (effect, sensor, axis, "
             "input axis), or names it as indistinguishable on this trajectory; the effect "
             "outside the vocabulary (`bias_pulse`) when an unexplained residual is located on "
             "its channel and time and nothing is named.", "",
             "What this suite shares with the diagnosis, and what it does not: the hidden effects "
             "are sensor behaviour computed from the simulator's truth (`mimunav/sensors/hidden.py`,"
             " tested against closed forms in tests/test_hidden.py), not the regressors the "
             "diagnosis fits (`mimunav/effects.py`, built from the reference IMU). Shared: the "
             "simulated MIMU is the exact inverse of the 63-coefficient compensation, its noise "
             "model, the flight, truth and reference-IMU models are the project's. The check "
             "against what the project did not write is the foreign development set below.", "",
             "| measure | result (95 % interval) |", "|---|---|",
             f"| identified (named, incl. 'cannot be told from') | {_rate(summary['identified'])} |",
             f"| identified exactly | {_rate(summary['identified_exact'])} |",
             f"| false alarms on null recordings (verdict not no-missing-physics), lab-fitted "
             f"calibration | {_rate(summary['false_alarms'])} |",
             f"| the same null recordings against the unit's true coefficients (the "
             f"diagnosis' own false alarms) | {_rate(summary['false_alarms_true_model'])} |",
             f"| other effects named in effect recordings | "
             f"{summary['other_findings_in_effect_recordings']} |",
             f"| true value inside the held-out 95 % interval | {_rate(summary['interval_coverage'])} |",
             f"| held-out rms after / before where the term acts (median) | "
             f"{summary['heldout_rms_ratio_median']:.3f} |", "",
             "`z` is how detectable the hidden term was on its recording: the Wald z of the true "
             "term fitted alone on the whole flight. Below about 5 no honest test at a "
             "family-wise 5 % over ~100 candidates, on half the data, can be expected to find it.",
             "", "| hidden effect | sensor.axis (input) | true value | z | verdict | identified | "
             "held-out estimate [95 %] | covered | held-out rms ratio | other findings |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    lines += _proof_case_lines(cases)
    lines += _foreign_lines(meta.get("foreign"))
    return "\n".join(lines) + "\n"


def _rate(r):
    """A rate k/n with its 95 % interval, or n/a."""
    if not r.get("n"):
        return "n/a"
    return f"{r['k']}/{r['n']} = {r['rate']:.0%} [{r['ci95'][0]:.0%}, {r['ci95'][1]:.0%}]"


def _proof_case_lines(cases):
    """A row per effect case, then the null recordings' verdicts and their false alarms."""
    lines = []
    for c in cases:
        if not c["effect"]:
            continue
        h = c["hidden"]
        true = h.get("vector", h.get("coefficient"))
        est = c.get("coefficient")
        ci = c.get("ci95")
        inputs = f" ({h['input_axis']})" if "input_axis" in h else ""
        ratio = f"{c['heldout_rms_ratio']:.3f}" if "heldout_rms_ratio" in c else "-"
        estimate = f"{_fmt(est)} {_fmt(ci)}" if est is not None else "-"
        z = f"{c['z_detectable']:.1f}" if math.isfinite(c["z_detectable"]) else "-"
        lines.append(f"| {c['effect']} | {h['sensor']}.{h['axis']}{inputs} | {_fmt(true)} | "
                     f"{z} | {c['verdict']} | "
                     f"{'yes' if c['identified'] else 'no'} | {estimate} | "
                     f"{c.get('covered', '-')} | {ratio} | ")
        lines[-1] += (", ".join(c["others"]) or "-") + " |"
    nulls = [c for c in cases if not c["effect"]]
    lines += ["", f"Null recordings: {len(nulls)}; verdicts: " + ", ".join(
        f"{v} x{sum(c['verdict'] == v for c in nulls)}" for v in sorted({c['verdict'] for c in nulls})),
        ""]
    lines += [f"- null seed {c['seed']}: {', '.join(c['findings']) or 'unexplained residual'} "
              f"(against the true coefficients: {', '.join(c['findings_true_model']) or 'quiet'})"
              for c in nulls if c["false_alarm"] or c["false_alarm_true_model"]]
    lines.append("")
    return lines


def _foreign_lines(rows):
    """The development set of the independent simulator (`bench/diagnosis.py`), if run."""
    lines = []
    if rows:
        lines += ["## Development set of an independent simulator", "",
                  "`shared/data/foreign-flights`: six logs written by a simulator that shares no "
                  "code with mimunav, each diagnosed with its own calibration file and scored "
                  "against its answer key (correct: the hidden effect named with the truth "
                  "inside the 95 % interval; for the effect-free log, no-missing-physics). "
                  f"Correct: {sum(r['correct'] for r in rows)} of {len(rows)}.", "",
                  "| log | hidden | verdict | findings | correct | s |", "|---|---|---|---|---|---|"]
        lines += [f"| {r['log']} | {r.get('hidden', 'nothing')} | {r['verdict']} | "
                  f"{', '.join(r['findings']) or '-'} | {'yes' if r['correct'] else 'no'} | "
                  f"{r['seconds']:.1f} |" for r in rows]
        lines.append("")
    return lines


def _fmt(x):
    if x is None:
        return "-"
    if isinstance(x, (list, tuple)):
        return "[" + ", ".join(_fmt(v) for v in x) + "]"
    return f"{x:.3g}"
