"""Calibration report: the entire lab on many drawn units, every recovered coefficient's
error against its reported standard error, fit residuals, and the held-out check of
`entire` vs `traditional` against seed S1 Table 1 (`mimunav report calibration`)."""
import collections
import math
import os
import re
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from tqdm import tqdm

from ..lab import procedures as lab
from ..lab.calibrate import calibrate, check, standard_errors
from ..lab.positions import fit_ellipsoid
from ..lab.runs import LabRun, TABLE1_FULL_SCALE, TABLE1_RESIDUAL
from ..errors import InputError
from ..evaluation.campaign import one_blas_thread
from ..compensation.model import poly2, raw_from_physics
from ..files import write_atomic
from ..sensors.mimu import MimuUnit
from .plots import figure, save

ENTIRE = ("thermal-chamber", "rate-table", "centrifuge")
TRADITIONAL = ("multi-position", "single-axis-rate")


def true_in_gauge(unit, cal):
    """The unit's true coefficients in the fit's gauge: temperature polynomials vanishing
    at the reference readings written in the calibration file."""
    ref = cal.extra["reference"]
    truth = unit.coefficients
    d_a = poly2(truth.ct, np.array([ref["accel_temperature_c"]]))[0]
    d_w = poly2(truth.cw, np.array([ref["gyro_frequency_hz"]]))[0]
    return truth.with_voltage_offset(d_a, d_w)


def z_scores(unit, cal):
    """{coefficient name: (fitted - true) / reported standard error}."""
    truth = true_in_gauge(unit, cal)
    out = {}
    for name, se in standard_errors(cal).items():
        key, *idx = re.findall(r"\w+", name)
        idx = tuple(int(i) for i in idx)
        out[name] = float((getattr(cal, key)[idx] - getattr(truth, key)[idx]) / se)
    return out


def compare(cal, unit):
    """A fitted `entire-63` calibration against a unit's truth, coefficient by coefficient,
    in the fit's gauge (`true_in_gauge`): rows (name, fitted, true, standard error, z) and
    the RMS z per coefficient family - what `mimunav report calibration` computes, for one
    file a user holds. Other models have no unique truth in their gauge (a linear fit
    absorbs the temperature terms at its run's temperature): refused."""
    if cal.model != "entire-63" or "reference" not in cal.extra:
        raise InputError(f"compare needs an entire-63 fit with its reference readings (this is "
                         f"{cal.model!r}); a {cal.model} fit has no unique truth in its gauge")
    truth = true_in_gauge(unit, cal)
    se = standard_errors(cal)
    z = z_scores(unit, cal)
    rows = []
    for name in se:
        key, *idx = re.findall(r"\w+", name)
        idx = tuple(int(i) for i in idx)
        rows.append((name, float(getattr(cal, key)[idx]), float(getattr(truth, key)[idx]),
                     se[name], z[name]))
    fam = collections.defaultdict(list)
    for name, value in z.items():
        fam[_family(name)].append(value)
    return rows, {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in sorted(fam.items())}


def _family(name):
    key = re.findall(r"[A-Za-z]+\d?", name)[0]
    if key in ("A1", "W1"):
        i, j = re.findall(r"\d+", name)[1:]
        key += " diagonal" if i == j else " off-diagonal"
    return key


def _one_unit(seed, beyond_model=True):
    """Entire lab + fit for unit `seed` in a scratch folder: z-scores, residuals, times.
    `beyond_model=False`: the unit is exactly the 63-coefficient model (`sensors.mimu`)."""
    unit = MimuUnit.draw(seed, beyond_model=beyond_model)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        paths = [lab.run(lab.plan(p), unit, os.path.join(tmp, f"{p}.mcap"), seed,
                         progress=False)[0] for p in ENTIRE]
        t1 = time.perf_counter()
        cal = calibrate(paths, "entire", unit=unit.name)
        t2 = time.perf_counter()
    return {"seed": seed, "beyond_model": beyond_model, "z": z_scores(unit, cal), "rms": cal.covariance["residual_rms"],
            "simulate_s": t1 - t0, "fit_s": t2 - t1}


# the reduced methods (seed S2, S4 field, the paper's traditional) fit linear models whose
# coefficients are not the unit's; compared in gauge-free form: the fitted zero-input output
# at the truth's zero-input voltage, over its stated standard error (as tests/test_calibration)
OFFSET_METHODS = {"traditional": TRADITIONAL, "twelve-position": ("twelve-position",),
                  "ellipsoid": ("hand-held",), "cold-start": ("cold-start",)}


def _zero_input_volts(unit, run):
    """The truth's zero-input voltages (accel, gyro; (3,) each) at the run's mean
    temperature readings (thermistor degC, resonance Hz), g-sensitivity left out; and those
    readings."""
    temp = run.means(run.raw["accel_temperature"]).mean(axis=0)
    freq = run.means(run.raw["gyro_frequency"]).mean(axis=0)
    u_a, u_w = raw_from_physics(unit.coefficients, np.zeros((1, 3)), np.zeros((1, 3)),
                                temp[None], freq[None], f_gyro=np.zeros((1, 3)))
    return u_a[0], u_w[0], temp, freq


def offset_z(unit, cal, run):
    """{"zero-g offset": z (3), "zero-rate offset": z (3)}: the fitted specific force (rate)
    at the truth's zero-input voltages (run's mean temperature readings, g-sensitivity left
    out) over the fit's A0 (W0) standard errors - rotation-invariant for the accelerometers
    (A1_true (u0_fit - u0_true)), so a fit in its own frame (ellipsoid) compares too."""
    if cal.model == "cold-start":
        return cold_start_offset_z(unit, cal, run)
    u_a, u_w, _, _ = _zero_input_volts(unit, run)
    c = unit.coefficients
    u0_fit = -np.linalg.solve(cal.A1, cal.A0)
    z_a = c.A1 @ (u0_fit - u_a) / _offset_se(cal, "A", u0_fit)
    z_w = (cal.W0 + cal.W1 @ u_w) / _offset_se(cal, "W", u_w)
    return {"zero-g offset": z_a.tolist(), "zero-rate offset": z_w.tolist()}


def cold_start_offset_z(unit, cal, run):
    """Seed S3's warm-up model (E = E(T) / (a + b T) + c + d T + e dT per axis) has no
    eqs. 1-4 counterpart; gauge-free, as `offset_z`: its steady output (dT = 0) at the
    truth's zero-input voltages and the run's mean readings, over its standard error from
    the file's per-axis covariance of a..e (first order)."""
    u_a, u_w, temp, freq = _zero_input_volts(unit, run)
    out = {}
    for triad, u, reading, quantity in (("accel", u_a, temp, "zero-g offset"),
                                        ("gyro", u_w, freq, "zero-rate offset")):
        k = cal.cold_start[triad]
        p0, p1 = (cal.A0, cal.A1) if triad == "accel" else (cal.W0, cal.W1)
        e = p0 + p1 @ u
        s = k["a"] + k["b"] * reading
        pred = e / s + k["c"] + k["d"] * reading
        grad = np.column_stack([-e / s**2, -e * reading / s**2, np.ones(3), reading,
                                np.zeros(3)])
        cov = np.asarray(cal.covariance[triad]["matrix"], float)
        se = np.sqrt(np.einsum("ij,ijk,ik->i", grad, cov, grad))
        out[quantity] = (pred / se).tolist()
    return out


def _offset_se(cal, triad, u):
    """Standard error (3,) of X0 + X1 @ u per axis (X = A or W) from the file's covariance:
    the offset at voltages u, where a nominal scale's error and the offset's it made cancel."""
    names = cal.covariance["names"]
    cov = np.asarray(cal.covariance["matrix"], float)
    where = {n: k for k, n in enumerate(names)}
    out = []
    for i in range(3):
        g = np.zeros(len(names))
        g[where[f"{triad}0[{i}]"]] = 1.0
        for j in range(3):
            if f"{triad}1[{i}][{j}]" in where:
                g[where[f"{triad}1[{i}][{j}]"]] = u[j]
        out.append(math.sqrt(float(g @ cov @ g)))
    return np.array(out)


def methods_unit(seed, beyond_model=False):
    """The reduced methods on unit `seed` (exactly eqs. 1-4 by default): {method: offset_z}."""
    unit = MimuUnit.draw(seed, beyond_model=beyond_model)
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for method, procedures in OFFSET_METHODS.items():
            paths = [lab.run(lab.plan(p), unit, os.path.join(tmp, f"{p}.mcap"), seed,
                             progress=False, force=True)[0] for p in procedures]
            cal = calibrate(paths, method, unit=unit.name)
            out[method] = offset_z(unit, cal, LabRun.load(paths[0]))
    return out


def _methods_markdown(results):
    lines = ["## Every method's stated uncertainty, over units", "",
             f"The reduced methods on the same {len(results)} units exactly eqs. 1-4 "
             "(`mimunav report calibration`, `reports.calibration.offset_z`): their linear "
             "models' coefficients are not the unit's, so the comparison is gauge-free - the "
             "fitted output at the truth's zero-input voltage over its standard error from the "
             "file's covariance "
             "(accelerometers rotation-invariant: A1_true (u0_fit - u0_true)). Target RMS z "
             "0.7-1.4. `entire` is above, `rotation` in reports/rotation-calibration.md. "
             "`cold-start` fits S3's warm-up model, whose terms have no eqs. 1-4 counterpart: "
             "its steady output (dT = 0) at the same voltages and the run's mean readings, "
             "over the standard error from its per-axis a..e covariance "
             "(`cold_start_offset_z`). The reduced models state what they leave out as "
             "random effects of the class: the linear fits seed S1 Table 1's nonlinearity "
             "bound, cold-start Table 2's cross-coupling and g-sensitivity.", "",
             "| method | quantity | n | RMS z | mean z | max abs z |", "|---|---|---|---|---|---|"]
    for method in OFFSET_METHODS:
        for quantity in ("zero-g offset", "zero-rate offset"):
            z = np.ravel([r[method][quantity] for r in results])
            lines.append(f"| {method} | {quantity} | {len(z)} | {np.sqrt(np.mean(z ** 2)):.2f} | "
                         f"{z.mean():+.2f} | {np.abs(z).max():.2f} |")
    return "\n".join(lines + [""])


def held_out(seed, folder):
    """Entire and traditional calibrations of unit `seed` (with its physics beyond the model)
    and their errors on fresh runs."""
    unit = MimuUnit.draw(seed)
    path = lambda p, s: os.path.join(folder, f"{p}-{s}.mcap")          # noqa: E731
    cals = {"entire": calibrate(
        [lab.run(lab.plan(p), unit, path(p, 1), 1, progress=False)[0] for p in ENTIRE],
        "entire"), "traditional": calibrate(
        [lab.run(lab.plan(p), unit, path(p, 1), 1, progress=False)[0] for p in TRADITIONAL],
        "traditional")}
    fresh = {p: LabRun.load(lab.run(lab.plan(p), unit, path(p, 2), 2,
                                                 progress=False)[0]) for p in ENTIRE}
    return {(name, p): check(cal, run) for name, cal in cals.items()
            for p, run in fresh.items()}


ORIENTATIONS = (10, 12, 15, 18, 24)         # the fit has 9 unknowns: 10 is the least with a residual


def orientations_study(seeds, folder):
    """Field calibration against the turntable (seed S4 vs S2) on the same units: the
    ellipsoid fit on the first N of a hand-held run's orientations, and the twelve-position
    fit, each checked on a fresh twelve-position run it was not fitted on by the rotation-
    invariant specific-force error ||f| - g| (RMS over the windows, m/s^2) and against the
    unit's truth by its zero-g offset error |A1_true (u0_fit - u0_true)| (m/s^2).
    Returns {"ellipsoid": {N: [(magnitude, offset) per unit]}, "twelve-position": [...]}."""
    out = {"ellipsoid": {n: [] for n in ORIENTATIONS}, "twelve-position": []}
    path = lambda p, s: os.path.join(folder, f"{p}-{s}.mcap")          # noqa: E731
    for seed in seeds:
        unit = MimuUnit.draw(seed)
        hand = LabRun.load(lab.run(lab.plan("hand-held"), unit,
                                               path("hand-held", seed), seed, progress=False)[0])
        twelve = lab.run(lab.plan("twelve-position"), unit, path("twelve", seed), seed,
                         progress=False)[0]
        fresh = LabRun.load(lab.run(lab.plan("twelve-position"), unit,
                                                path("fresh", seed), seed + 1, progress=False)[0])
        g = fresh.site["gravity_m_s2"]
        u_fresh = fresh.means(fresh.raw["accel_volts"])
        truth = unit.coefficients

        def score(a0, a1, run):
            """(held-out magnitude error, zero-g offset error at the fitted run's mean
            temperature) m/s^2."""
            temp = run.means(run.raw["accel_temperature"]).mean(axis=0)
            u0_true = poly2(truth.ct, temp[None])[0] - np.linalg.solve(truth.A1, truth.A0)
            magnitude = np.sqrt(np.mean((np.linalg.norm(a0 + u_fresh @ a1.T, axis=1) - g) ** 2))
            offset = np.linalg.norm(truth.A1 @ (-np.linalg.solve(a1, a0) - u0_true))
            return float(magnitude), float(offset)
        for n in ORIENTATIONS:
            fit = fit_ellipsoid(hand, windows=range(n))
            a0 = np.array([fit.values[f"A0[{i}]"] for i in range(3)])
            a1 = np.array([[fit.values[f"A1[{i}][{j}]"] for j in range(3)] for i in range(3)])
            out["ellipsoid"][n].append(score(a0, a1, hand))
        cal = calibrate([twelve], "twelve-position")
        out["twelve-position"].append(score(cal.A0, cal.A1, LabRun.load(twelve)))
    return out


def plot_orientations(study, out_png):
    plt, fig, axes = figure(1, 2, (11, 4.2))
    n = np.array(ORIENTATIONS)
    for ax, k, label in ((axes[0, 0], 0, "held-out ||f| - g| RMS"),
                         (axes[0, 1], 1, "zero-g offset error vs truth")):
        per_n = np.array([[u[k] for u in study["ellipsoid"][m]] for m in ORIENTATIONS]) * 1e3 / 9.80665
        ax.plot(n, np.median(per_n, axis=1), "o-", label="ellipsoid (hand-held), median")
        ax.fill_between(n, per_n.min(axis=1), per_n.max(axis=1), alpha=0.2, label="range")
        tw = np.array([u[k] for u in study["twelve-position"]]) * 1e3 / 9.80665
        ax.axhline(np.median(tw), color="k", ls="--", label="twelve-position (turntable), median")
        ax.set_xlabel("orientations used")
        ax.set_ylabel(f"{label}, mg")
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    save(plt, fig, out_png)


def plot_held_out(checks, out_png):
    """Held-out error (% of Table 1 full scale) against the condition it grows with."""
    fs, lim = TABLE1_FULL_SCALE, TABLE1_RESIDUAL
    panels = [("centrifuge", "accel", lambda c: np.abs(c["accel_input"]).max(axis=1) / 9.80665,
               "applied specific force, g"),
              ("rate-table", "gyro", lambda c: np.degrees(np.abs(c["gyro_input"]).max(axis=1)),
               "applied rate, deg/s"),
              ("thermal-chamber", "accel", lambda c: c["temperature"].mean(axis=1),
               "accelerometer temperature, degC"),
              ("thermal-chamber", "gyro", lambda c: c["temperature"].mean(axis=1),
               "accelerometer temperature, degC")]
    plt, fig, axes = figure(2, 2, (11, 8))
    for ax, (proc, sensor, x_of, xlabel) in zip(axes.ravel(), panels):
        for name, marker in (("traditional", "x"), ("entire", "o")):
            c = checks[name, proc]
            err = 100 * np.abs(c[f"{sensor}_error"]).max(axis=1) / fs[sensor]
            ax.semilogy(x_of(c), err, marker, label=name, alpha=0.7)
        ax.axhline(100 * lim[sensor], color="k", ls="--", label="Table 1 fit residual")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(f"{sensor} error, % FS (worst axis)")
        ax.set_title(f"held-out {proc}: {sensor}")
        ax.grid(True, which="both", alpha=0.3)
    axes[0, 0].legend()
    save(plt, fig, out_png)


def drawn_units(job, seeds, workers=2, progress=True):
    """job(seed, beyond_model) for every seed drawn exactly as eqs. 1-4 and then with its
    physics beyond them, in `workers` processes: the results in that order."""
    with ProcessPoolExecutor(workers, initializer=one_blas_thread) as pool:
        return list(tqdm(pool.map(job, seeds * 2, [False] * len(seeds) + [True] * len(seeds)),
                         total=2 * len(seeds), desc="units", disable=not progress))


def write(out_dir, n_units=20, first_seed=1000, workers=2, progress=True, force=False):
    """Run the study and write OUT_DIR/calibration.md and calibration-held-out.png."""
    md = os.path.join(out_dir, "calibration.md")
    png = os.path.join(out_dir, "calibration-held-out.png")
    if os.path.exists(md) and not force:
        raise FileExistsError(f"{md} exists; use --force to replace it")
    os.makedirs(out_dir, exist_ok=True)
    seeds = list(range(first_seed, first_seed + n_units))
    units = drawn_units(_one_unit, seeds, workers, progress)
    with tempfile.TemporaryDirectory() as tmp:
        checks = held_out(first_seed, tmp)
        study = orientations_study(seeds[:8], tmp)
    plot_held_out(checks, png)
    plot_orientations(study, os.path.join(out_dir, "calibration-orientations.png"))
    with ProcessPoolExecutor(workers, initializer=one_blas_thread) as pool:
        methods = list(tqdm(pool.map(methods_unit, seeds), total=len(seeds), desc="methods",
                            disable=not progress))
    write_atomic(md, _markdown(units, checks, os.path.basename(png)) + _orientations_markdown(
        study) + "\n" + _methods_markdown(methods), force=True)
    return md, png


def _orientations_markdown(study):
    mg = 1e3 / 9.80665
    lines = ["## Field calibration without a turntable: how many orientations", "",
             f"`mimunav calibrate --method ellipsoid` on the first N orientations of a hand-held "
             f"run (seed S4; nobody measured the attitudes) against `--method twelve-position` "
             f"on a turntable "
             f"(seed S2), the same {len(study['twelve-position'])} units, both checked on a fresh "
             "twelve-position run: the rotation-invariant error ||f| - g| (RMS over its windows) "
             "and the zero-g offset against the truth (median [min, max] over units, mg).", "",
             "| method | orientations | held-out ||f| - g|, mg | zero-g offset error, mg |",
             "|---|---|---|---|"]

    def cell(values):
        v = np.array(values) * mg
        return f"{np.median(v):.3g} [{v.min():.3g}, {v.max():.3g}]"
    for n, scores in study["ellipsoid"].items():
        lines.append(f"| ellipsoid | {n} | {cell([s[0] for s in scores])} | "
                     f"{cell([s[1] for s in scores])} |")
    tw = study["twelve-position"]
    lines.append(f"| twelve-position | 12 (known) | {cell([s[0] for s in tw])} | "
                 f"{cell([s[1] for s in tw])} |")
    lines += ["", "![orientations](calibration-orientations.png)", ""]
    return "\n".join(lines)


def z_families(units, family):
    """{family(name): [z over units]} of the units' z-scores ({name: z} under "z")."""
    fam = collections.defaultdict(list)
    for u in units:
        for name, z in u["z"].items():
            fam[family(name)].append(z)
    return fam


def z_table(units, family=_family, order=None):
    """Markdown lines: z-scores by coefficient family over `units` (families in `order`,
    default sorted)."""
    fam = z_families(units, family)
    allz = np.concatenate([np.array(v) for v in fam.values()])
    lines = [f"All coefficients: n = {len(allz)}, RMS z = {np.sqrt(np.mean(allz**2)):.2f}, "
             f"max |z| = {np.abs(allz).max():.2f}, mean z = {allz.mean():+.2f}.", "",
             "| term | n | RMS z | mean z | max abs z |", "|---|---|---|---|---|"]
    for k in order or sorted(fam):
        v = np.array(fam[k])
        lines.append(f"| {k} | {len(v)} | {np.sqrt(np.mean(v**2)):.2f} | {v.mean():+.2f} | "
                     f"{np.abs(v).max():.2f} |")
    return lines


def _markdown(units, checks, png_name):
    exact = [u for u in units if not u["beyond_model"]]
    real = [u for u in units if u["beyond_model"]]
    lines = ["# Calibration lab: recovery of the 63 coefficients and held-out check", "",
             "Generated by `mimunav report calibration` "
             f"({len(exact)} units, seeds {exact[0]['seed']}-{exact[-1]['seed']}, each twice). "
             "Each unit is drawn from seed S1 Table 2 and datasheet values "
             "(`mimunav.sensors.mimu`), run through the simulated thermal chamber, rate table "
             "and centrifuge (`mimunav.lab`) and fitted with `mimunav calibrate --method entire` "
             "(`mimunav.lab.calibrate`). z = (fitted - true) / reported standard error, the truth "
             "expressed in the fit's gauge (temperature polynomials vanish at the file's "
             "reference readings).", "",
             "## The fit, on units that are exactly its model", "",
             "The unit drawn with `beyond_model=False`: the simulated sensor is exactly eqs. "
             "1-4, so this checks the fit and its standard errors (target: RMS z 0.7-1.3, all "
             "|z| < 4). It says nothing about how well eqs. 1-4 describe a real unit.", ""]
    lines += z_table(exact)
    lines += ["", "## The same units with physics beyond the model (the default unit)", "",
              "The default unit is simulated as sensing elements written forward "
              "(`sensors.response`: an element's own nonlinearity before the cross-coupling, so "
              "each nonlinearity also reaches the other outputs) and has a scale-factor "
              "asymmetry k|x| (50-200 ppm) and seed S3's thermal-gradient term e*dT on every "
              "axis (`sensors.mimu`, module doc), none of which eqs. 1-4 can represent. The fit absorbs what it can into the nearest terms - "
              "the asymmetry into the even 2nd-order scale factors A2, W2 - so those "
              "coefficients move away from the truth by more than their reported uncertainty: "
              "the z-scores below are model error, not a defect of the fit, and this is what a "
              "real unit's calibration looks like (the held-out check below uses this unit).", ""]
    lines += z_table(real)
    rms = collections.defaultdict(list)
    for u in real:
        for stage, per_axis in u["rms"].items():
            rms[stage] += list(per_axis.values())
    lines += ["", "Fit residual RMS of the window means (median over units and axes), "
              "against the noise model's bias instability B (accel 0.5 mg, gyro 15 deg/h) "
              "that dominates a 10 s mean:", "", "| stage | residual RMS |", "|---|---|"]
    for stage, v in rms.items():
        unit, scale = ("mg", 1e3 / 9.80665) if "accel" in stage else ("deg/h", 180 / np.pi * 3600)
        lines.append(f"| {stage} | {np.median(v) * scale:.3g} {unit} |")
    sim = np.array([u["simulate_s"] for u in units])
    fit = np.array([u["fit_s"] for u in units])
    lines += ["", f"Time per unit (2 workers sharing 2 cores): lab simulation "
              f"{np.median(sim):.1f} s, fit {np.median(fit):.1f} s (median); single-unit "
              "timing on an idle machine: `python bench/lab.py`.", "",
              "## Held-out check (unit " f"{units[0]['seed']}, fresh runs not fitted on)", "",
              "Worst window error over the run, % of Table 1 full scale (30 g, 400 deg/s); "
              "Table 1 fit residuals are 0.05 % FS (accelerometer) and 0.2 % FS (gyro).", "",
              "| calibration | run | accel % FS | gyro % FS |", "|---|---|---|---|"]
    fs = TABLE1_FULL_SCALE
    for (name, proc), c in checks.items():
        lines.append(f"| {name} | {proc} | {100 * np.abs(c['accel_error']).max() / fs['accel']:.3f}"
                     f" | {100 * np.abs(c['gyro_error']).max() / fs['gyro']:.3f} |")
    lines += ["", f"![held-out errors]({png_name})", ""]
    return "\n".join(lines)
