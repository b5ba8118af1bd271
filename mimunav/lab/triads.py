"""Seed S1 eqs. 2-10: the temperature polynomials, the gyro and accelerometer triads
(eqs. 1 and 3) and the gyros' g-sensitivity, fitted stage by stage with their covariance.
"""
import math

import numpy as np

from ..compensation.model import poly2
from .runs import AXES, NOMINAL_SCALE, POSITION_NAMES, T_REF, known_inputs, setting_perturbations
from .gls import FitError, Fitted, add_covariance_sources, merge_errors, propagated, gls


# ---- stage 1: temperature (eqs. 2, 4) ----------------------------------------------------
def fit_temperature(run):
    """Chamber: per axis U = c0 + c1 x + c2 x^2 on window means (x = T, or f), gauge fixed
    at the reference reading. Returns (Fitted, reference dict)."""
    temps = sorted({round(w.chamber_c, 3) for w in run.windows})
    if len(temps) < 4 or temps[-1] - temps[0] < 30:
        raise FitError(f"{run.path}: the chamber run has steady set points at {temps} degC; "
                       "eqs. 2/4 need at least 4 set points spanning 30 degC or more")
    room = min(range(len(run.windows)), key=lambda k: abs(run.windows[k].chamber_c - T_REF))
    fitted = Fitted({})
    reference = {"accel_temperature_c": [T_REF] * 3, "gyro_frequency_hz": []}
    for sensor, volts, reading in (("accel", "accel_volts", "accel_temperature"),
                                   ("gyro", "gyro_volts", "gyro_frequency")):
        u, x = run.raw[volts], run.raw[reading]
        u_mean, u_var = run.means(u), run.mean_variances(u)
        for i in range(3):
            x_ref = T_REF if sensor == "accel" else float(run.means(x[:, i])[room])
            span = 10.0 if sensor == "accel" else 1.0      # scaled reading for conditioning
            s = (x[:, i] - x_ref) / span
            design = np.column_stack([np.ones(len(run.windows)), run.means(s), run.means(s * s)])
            instability = run.instability(sensor) / NOMINAL_SCALE[sensor]        # V
            b, cov, _, _ = gls(design, u_mean[:, i], np.diag(u_var[:, i])
                               + instability**2 * run.flicker())
            # gauge: b0 = 0 (the polynomial vanishes at x_ref); back to raw-reading powers
            jac = np.array([[0.0, -x_ref / span, x_ref**2 / span**2],
                            [0.0, 1 / span, -2 * x_ref / span**2],
                            [0.0, 0.0, 1 / span**2]])
            c = jac @ b
            key = "ct" if sensor == "accel" else "cw"
            names = [f"{key}[{i}][{j}]" for j in range(3)]
            for j in range(3):
                fitted.values[names[j]] = float(c[j])
            add_covariance_sources(fitted, names, jac @ cov @ jac.T, f"chamber-{key}{i}")
            if sensor == "gyro":
                reference["gyro_frequency_hz"].append(x_ref)
    return fitted, reference


def _poly_matrix(fitted, key):
    return np.array([[fitted.values.get(f"{key}[{i}][{j}]", 0.0) for j in range(3)]
                     for i in range(3)])


# ---- stage 2/3: triads (eqs. 5-7) ----------------------------------------------------------
def _block_names(sensor, order, i):
    p = "A" if sensor == "accel" else "W"
    names = [f"{p}0[{i}]"] + [f"{p}1[{i}][{j}]" for j in range(3)]
    return names + ([f"{p}2[{i}]", f"{p}3[{i}]"] if order == 3 else [])


def _require_positions(run, n):
    """Refuse a run that lacks any of its procedure's n fixture positions."""
    have = {w.position for w in run.windows}
    missing = [p for p in range(n) if p not in have]
    if missing:
        names = [POSITION_NAMES[p % 6] + (" turned 180 deg" if p >= 6 else "") for p in missing]
        raise FitError(f"{run.path}: the {run.procedure} run has no steady data in fixture "
                       f"position(s) {', '.join(names)}; each sensor axis must be measured "
                       "pointing both ways along the input axis")


def _pairs(run):
    """Window index pairs (axis up at +W, axis down at -W) for the rate table; refuses a run
    whose positions or rates do not pair."""
    _require_positions(run, 6)
    by = {}
    for k, w in enumerate(run.windows):
        by.setdefault(w.position, []).append(k)
    pairs = []
    for p in range(0, 6, 2):
        up, down = by[p], list(by[p + 1])
        for k in up:
            target = -run.windows[k].rate
            match = [m for m in down if abs(run.windows[m].rate - target) < 1e-9]
            if not match:
                raise FitError(f"{run.path}: rate {math.degrees(run.windows[k].rate):.1f} "
                               f"deg/s in position {p} has no reverse-rate partner in "
                               f"position {p + 1}")
            down.remove(match[0])
            pairs.append((k, match[0]))
    return pairs


def _fit_triad_blocks(run, design, y_rows, rows, sensor):
    """GLS of every output axis on the design's regressors; returns (values (3, p), covs,
    rms residuals). Row covariance: white variance of each window's mean model output
    (from a first OLS pass) plus the datasheet bias instability as flicker; an order-1 fit's
    covariance also carries the nonlinearity it leaves out (`WindowDesign.omitted`)."""
    out, covs, rms = [], [], []
    for i in range(3):
        x = design.regressors(i, rows)
        b, *_ = np.linalg.lstsq(x, y_rows[:, i], rcond=None)
        cov = run.row_covariance(design.variances(i, b), run.instability(sensor), rows)
        b, cov, _, r = gls(x, y_rows[:, i], cov, design.omitted(i, rows, sensor))
        out.append(b), covs.append(cov), rms.append(r)
    return np.array(out), covs, rms


def _voltage_design(run, sensor, poly, order):
    """Design of the temperature-compensated voltages (eqs. 2, 4) with polynomial `poly`."""
    if sensor == "accel":
        v = run.raw["accel_volts"] - poly2(poly, run.raw["accel_temperature"])
    else:
        v = run.raw["gyro_volts"] - poly2(poly, run.raw["gyro_frequency"])
    return run.design(v, order)


def _check_levels(values, need, what, path):
    """Refuse inputs with fewer than `need` levels apart by 1 % of the largest input."""
    step = 0.01 * np.abs(values).max()
    levels = np.unique(np.round(values / step)) * step if step > 0 else np.zeros(1)
    if len(levels) < need:
        raise FitError(f"{path}: {what} takes only {len(levels)} distinct input levels "
                       f"({', '.join(f'{x:.4g}' for x in levels)}); the fit needs at least "
                       f"{need} to separate its polynomial terms")


def fit_gyro_triad(run, temp, order=3, propagate=True):
    """Rate table (paired positions) -> W0, W1 (, W2, W3), errors propagated from `temp`
    (the chamber fit, or None for no temperature model) and the lab settings."""
    pairs = _pairs(run)
    cw = _poly_matrix(temp, "cw") if temp else np.zeros((3, 3))
    design = _voltage_design(run, "gyro", cw, order)

    def solve(cw_=None, **perturb):
        d = design if cw_ is None else _voltage_design(run, "gyro", cw_, order)
        _, w_in = known_inputs(run, **perturb)
        y = np.array([w_in[list(r)].mean(axis=0) for r in pairs])
        return _fit_triad_blocks(run, d, y, pairs, "gyro")
    _, w_in = known_inputs(run)
    y = np.array([w_in[list(r)].mean(axis=0) for r in pairs])
    for i in range(3):
        _check_levels(y[:, i], order + 1 if order == 3 else 2,
                      f"gyro {AXES[i]} (paired rate points, rad/s)", run.path)
    coef, covs, rms = solve()
    return _assemble(run, "gyro", order, coef, covs, rms, solve, cw, temp, "cw",
                     tag=run.procedure, propagate=propagate)


def fit_accel_triad(run, temp, order=3, propagate=True):
    """Centrifuge (or static positions) -> A0, A1 (, A2, A3)."""
    ct = _poly_matrix(temp, "ct") if temp else np.zeros((3, 3))
    rows = [(k,) for k in range(len(run.windows))]
    _require_positions(run, 12 if run.procedure == "twelve-position" else 6)
    f_in, _ = known_inputs(run)
    for i in range(3):
        _check_levels(f_in[:, i], order + 1, f"accelerometer {AXES[i]} (m/s^2)", run.path)

    design = _voltage_design(run, "accel", ct, order)

    def solve(ct_=None, **perturb):
        d = design if ct_ is None else _voltage_design(run, "accel", ct_, order)
        f, _ = known_inputs(run, **perturb)
        return _fit_triad_blocks(run, d, f, rows, "accel")
    coef, covs, rms = solve()
    return _assemble(run, "accel", order, coef, covs, rms, solve, ct, temp, "ct",
                     tag=run.procedure, propagate=propagate)


def _assemble(run, sensor, order, coef, covs, rms, solve, poly, temp, key, tag, propagate):
    """Fitted values with their error sources; `propagate=False` keeps only each stage's
    own GLS covariance and the turn-on term (fast, for campaigns that need no covariance)."""
    fitted = Fitted({})
    names = []
    for i in range(3):
        block = _block_names(sensor, order, i)
        names += block
        for n, val in zip(block, coef[i]):
            fitted.values[n] = float(val)
        add_covariance_sources(fitted, block, covs[i], f"{tag}-{sensor}{i}")
    base = np.concatenate(list(coef))
    for label, perturb in setting_perturbations(run) if propagate else []:
        new = np.concatenate(list(solve(**perturb)[0]))
        for n, d in zip(names, new - base):
            merge_errors(fitted.errors, n, {f"{tag}-setting-{label}": d})
    # the turn-on bias of this power-on sits in the bias terms
    p0 = "A0" if sensor == "accel" else "W0"
    for i in range(3):
        merge_errors(fitted.errors, f"{p0}[{i}]", {f"{tag}-turn-on-{sensor}{i}": run.turn_on(sensor)})
    if temp and propagate:
        parents = [f"{key}[{i}][{j}]" for i in range(3) for j in range(3)]

        def refit(delta):
            moved = poly + np.array([[delta[f"{key}[{i}][{j}]"] for j in range(3)]
                                     for i in range(3)])
            return np.concatenate(list(solve(moved)[0]))
        propagated(fitted, names, refit, base, temp, parents)
    fitted.rms = dict(zip(AXES, rms))
    fitted.stage = f"{tag} {sensor}"
    return fitted


# ---- stage 3b: g-sensitivity (eqs. 8-10) ---------------------------------------------------
def fit_g_sensitivity(run, temp, gyro, propagate=True):
    """Centrifuge: R = w_known - w_model(V_w) (eq. 10) regressed on the applied specific force,
    R_i = C_i . f + b_i (b_i the turn-on nuisance). Errors from `temp`, `gyro`, settings."""
    cw = _poly_matrix(temp, "cw")
    f_in, w_in = known_inputs(run)

    design = _voltage_design(run, "gyro", cw, 3)
    rows = [(k,) for k in range(len(run.windows))]

    def solve(cw_, g_vals, **perturb):
        f, w = known_inputs(run, **perturb) if perturb else (f_in, w_in)
        d = design if cw_ is None else _voltage_design(run, "gyro", cw_, 3)
        x = np.column_stack([f, np.ones(len(f))])
        res = []
        for i in range(3):
            b = np.array([g_vals[n] for n in _block_names("gyro", 3, i)])
            w_model = d.regressors(i, rows) @ b
            cov = run.row_covariance(d.variances(i, b), run.instability("gyro"), rows)
            res.append(gls(x, w[:, i] - w_model, cov))
        return np.array([r[0][:3] for r in res]), [r[1][:3, :3] for r in res], \
            [r[3] for r in res]
    c, covs, rms = solve(None, gyro.values)
    fitted = Fitted({})
    names = [f"C[{i}][{j}]" for i in range(3) for j in range(3)]
    for i in range(3):
        block = names[3 * i:3 * i + 3]
        for n, val in zip(block, c[i]):
            fitted.values[n] = float(val)
        add_covariance_sources(fitted, block, covs[i], f"centrifuge-C{i}")
    base = c.ravel()
    if not propagate:
        fitted.rms, fitted.stage = dict(zip(AXES, rms)), "centrifuge C"
        return fitted
    for label, perturb in setting_perturbations(run):
        new = solve(None, gyro.values, **perturb)[0].ravel()
        for n, d in zip(names, new - base):
            merge_errors(fitted.errors, n, {f"centrifuge-setting-{label}": d})
    # upstream: every source of cw and of W moves C; refit with both moved
    parents = [f"cw[{i}][{j}]" for i in range(3) for j in range(3)]
    w_names = list(gyro.values)
    upstream = Fitted({**temp.values, **gyro.values}, {**temp.errors})
    for n in w_names:
        upstream.errors[n] = gyro.errors.get(n, {})

    def refit(delta):
        dcw = np.array([[delta.get(f"cw[{i}][{j}]", 0.0) for j in range(3)] for i in range(3)])
        g_vals = {n: gyro.values[n] + delta.get(n, 0.0) for n in w_names}
        # a source of W alone leaves the compensated voltages, so their design, as they are
        return solve(cw + dcw if dcw.any() else None, g_vals)[0].ravel()
    propagated(fitted, names, refit, base, upstream, parents + w_names)
    fitted.rms = dict(zip(AXES, rms))
    fitted.stage = "centrifuge C"
    return fitted
